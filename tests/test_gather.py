"""The final gather of the bounced light into the voxel solution
(baker/solve/gather.py), against the form factor of a lit ceiling."""
import math
from dataclasses import replace

import numpy as np
import pytest

from baker.config import SolverConfig
from baker.solve.gather import gather_bounced, gather_directions
from baker.scene import prepare
from baker.solve import solve
from scenes.generate import GltfBuilder, box, quad

C = 2.0      # the ceiling's bounced radiosity
TINT = np.array([0.8, 0.5, 0.25])


def _corner_ff(x, y):
    """Form factor from a point to a parallel x-by-y rectangle at unit
    height with one corner straight above it."""
    a, b = math.sqrt(1 + x * x), math.sqrt(1 + y * y)
    return (x / a * math.atan(y / a) + y / b * math.atan(x / b)) / (2 * math.pi)


def ceiling_ff(px, pz):
    """Form factor from floor point (px, 0, pz) of the unit cube to its
    ceiling (0..1 squared at height 1): four corner rectangles."""
    return sum(_corner_ff(w, d) for w in (px, 1 - px) for d in (pz, 1 - pz))


def _lit_ceiling(make_scene, glass):
    b = GltfBuilder()
    wall = b.material("wall", (0.5,) * 3)
    b.mesh("box", *box((0, 0, 0), (1, 1, 1), inward=True), wall)
    if glass:
        pane = b.material("glass", tuple(TINT), double_sided=True, transmission=1.0)
        b.mesh("pane", *quad((0, 0.5, 0), (1, 0.5, 0), (1, 0.5, 1), (0, 0.5, 1), facing=(0, -1, 0)), pane)
    b.light("bulb", "point", intensity=1.0, position=(0.5, 0.2, 0.5))
    prep = prepare(make_scene(b, f"gather_ceiling_{glass}"))
    sol = solve(prep, SolverConfig(resolution=16, photons=20_000, radius=3, max_bounces=2))
    v = sol.voxels
    ceiling = (v.normal[:, 1] < -0.99) & (v.centroid[:, 1] > 0.9)
    assert ceiling.sum() >= 200
    b_ind = np.where(ceiling[:, None], C, 0.0) * np.ones(3)
    return prep, replace(sol, radiosity=v.emission + b_ind)


@pytest.mark.parametrize("glass", [False, True])
def test_gather_reads_a_lit_ceiling_by_its_form_factor(make_scene, glass):
    """Only the ceiling's voxels carry bounced light (B = C): the gather at
    floor points is C x the point's form factor to the ceiling, through a
    pane of thin glass across the room C x F x its tint (the pane's own
    voxels carry none). 4096 rays: within 0.5% of the exact value."""
    prep, sol = _lit_ceiling(make_scene, glass)
    pts = np.array([[0.5, 0.0, 0.5], [0.3, 0.0, 0.6], [0.15, 0.0, 0.8], [0.9, 0.0, 0.1]])
    nrm = np.tile([0.0, 1.0, 0.0], (len(pts), 1))
    h = gather_bounced(prep, sol, pts, nrm, 1e-4, 4096)
    want = np.array([C * ceiling_ff(p[0], p[2]) for p in pts])[:, None] * (TINT if glass else np.ones(3))
    assert np.allclose(h, want, rtol=5e-3), (h, want)


def test_gather_directions_are_cosine_distributed():
    d = gather_directions(4096)
    assert np.allclose(np.linalg.norm(d, axis=1), 1) and np.all(d[:, 2] >= 0)
    # E[cos] under p = cos / pi is 2/3; E[cos^2] = 1/2
    assert abs(d[:, 2].mean() - 2 / 3) < 2e-3 and abs((d[:, 2] ** 2).mean() - 0.5) < 2e-3


def test_gather_does_not_depend_on_the_thread_count(make_scene):
    import numba
    prep, sol = _lit_ceiling(make_scene, False)
    rng = np.random.default_rng(3)
    pts = np.c_[rng.uniform(0.05, 0.95, 200), np.zeros(200), rng.uniform(0.05, 0.95, 200)]
    nrm = np.tile([0.0, 1.0, 0.0], (200, 1))
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = gather_bounced(prep, sol, pts, nrm, 1e-4, 64)
        numba.set_num_threads(before)
        many = gather_bounced(prep, sol, pts, nrm, 1e-4, 64)
    finally:
        numba.set_num_threads(before)
    assert np.array_equal(one, many) and one.min() > 0



@pytest.mark.parametrize("glass", [False, True])
def test_recorded_rays_read_what_traced_rays_read(make_scene, glass):
    """The solver's bounces at the floor's ray count cast the same rays
    each time, so gather_voxels records the voxel each ray reads once and
    reads those at later bounces (voxels with a ray through glass are
    traced afresh): the same bits as tracing at every bounce, for any
    radiosity, the pane's tint included."""
    from baker.solve.gather import GATHER_FLOOR, gather_voxels
    prep, sol = _lit_ceiling(make_scene, glass)
    rng = np.random.default_rng(2)
    targets = {}
    for _ in range(3):
        b = rng.uniform(0, 2, (len(sol.voxels), 3))
        traced = gather_voxels(prep, sol.voxels, b, GATHER_FLOOR)
        read = gather_voxels(prep, sol.voxels, b, GATHER_FLOOR, targets)
        np.testing.assert_array_equal(read, traced)
        assert traced.max() > 0
    target, live = targets[GATHER_FLOOR]
    if glass:   # the pane spans the room: every voxel sees it
        assert len(live) > 100
    else:
        assert len(live) == 0 and (target >= 0).mean() > 0.5
