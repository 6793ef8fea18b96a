"""The voxel solution on real-world meshes against the path tracer, at the
default preset a user runs (docs/design.md section 2, "Which geometry is
handled how"): a scan-like two-sided noisy shell standing in a room
(scenes/scan_room.glb) and the public Cornell box OBJ with its duplicated
faces (McGuire's CornellBox-Original.obj, read from ../shared), and the small scenes that each
reproduce one failure (scenes.generate.reproduction_case).

The comparison: the voxel view against the path tracer, 64 x 64 pixels,
the same camera; luminance; the lamp's pixels (any of whose 4 x 4
sub-pixel camera rays meets an emitter) left out. Mean ratio, the worst 8 x 8
block, and lit pixels that come out black. The path tracer's own noise at
these settings is about 1% per block (measured between seeds)."""
import os
import warnings

import pytest

from baker import load_scene, render, solve, solver_config
from baker.render.compare import compare, lamp_pixels
from baker.scene import build_scene_bvh, pack
from scenes.generate import REPRODUCTION_CASES, reproduction_case
from baker.scene import camera_for

from .conftest import MCGUIRE_CORNELL, skip_without_shared

HERE = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def compare_at_default(scene, spp, res=64, frame=False):
    """The voxel view at the default preset against the path tracer (and
    with frame, the lightcuts frame's comparison after it)."""
    bvh, surf = build_scene_bvh(scene), pack(scene)
    cam = camera_for(scene, None, bvh)
    pt = render(scene, cam, res, res, "pathtrace", spp=spp, seed=1, bvh=bvh, surfaces=surf)
    sol = solve(scene, solver_config("default"), bvh=bvh, surfaces=surf)
    lamp = lamp_pixels(bvh, surf, cam, res, res)
    c = compare(render(scene, cam, res, res, "voxels", solution=sol, bvh=bvh, surfaces=surf), pt, lamp=lamp)
    if not frame:
        return c
    return c, compare(render(scene, cam, res, res, "lightcuts", solution=sol, bvh=bvh, surfaces=surf), pt, lamp=lamp)


@pytest.mark.slow
def test_scanned_shell_in_a_room():
    """A two-sided noisy shell of 17,702 triangles (several per cell) resting
    on the floor: before the smooth patches and the own-back rules its
    voxel view was 0.80-0.90 of the path tracer with near-black patches;
    then 0.976-0.997 depending on how the grid fell on the room (walls on
    the scene's bounds rounded into the cells outside the room: corner
    lines found nothing, 1% of each bounce lost). Measured since the
    grid snap and the silhouette and edge clauses: mean 0.9993, worst block
    0.943 (the floor at the scan's base), 98% of blocks within 5%. The lamp is
    not in view: all lit pixels count, the scan's included."""
    c, f = compare_at_default(load_scene(os.path.join(HERE, "scenes", "scan_room.glb")), spp=512, frame=True)
    assert abs(c.mean - 1) < 0.02
    assert c.worst < 0.08
    assert c.black == 0
    # the lightcuts frame, its bounced light gathered (contacts at the point): 0.99-1.01 at 128 px, 4096 spp
    assert abs(f.mean - 1) < 0.02 and f.worst < 0.05 and f.black == 0, (f.mean, f.worst)


@pytest.mark.slow
@pytest.mark.parametrize("one_sided", [True, False])
def test_public_cornell_box_obj_with_duplicate_faces(one_sided):
    """McGuire's Cornell box OBJ repeats each box's front face as its
    'bottom' (dropped by the loader: one surface counts once); read from
    ../shared, where the public file lies (its short box takes the red
    wall's material: its faces come before their `usemtl`). Read
    one-sided: mean 1.0100, worst block 0.907 (measured; 1.0196 before the
    edge clause, when the ceiling saw the boxes' lit tops enlarged by the
    lines' thickness). Read two-sided, as OBJ is by default: the lamp also
    emits up into the 1 cm gap under the ceiling, light the voxels trap
    there (docs/design.md): mean 1.0043, the ceiling beside the lamp the
    worst block (0.862)."""
    skip_without_shared(MCGUIRE_CORNELL, "McGuire's Cornell box OBJ")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        scene = load_scene(MCGUIRE_CORNELL, one_sided=one_sided)
    assert any("dropped 4 duplicate triangles" in str(w.message) for w in caught)
    c = compare_at_default(scene, spp=1024)
    assert abs(c.mean - 1) < 0.02
    assert c.worst < (0.12 if one_sided else 0.17)
    assert c.black == 0


CASE_BOUNDS = {  # (bound on the worst 8x8 block's |ratio - 1|, as measured at 64 px and 512 spp; the lightcuts
    #               frame's bound: 5% where its blocks were all within it at 128 px and 4096 spp, plus the
    #               path tracer's noise at 512 spp)
    "hole_shell": (0.12, 0.085, 0.07),    # the shell's inside seen through the hole
    "noisy_shell": (0.07, 0.042, 0.07),
    "duplicates": (0.05, 0.011, 0.05),    # every face of the box twice, a slab on the floor's plane
    "lamp_edges": (0.06, 0.022, 0.09),    # the ceiling beside a lamp 1 cm under it, seen from below
    "flush_lamp": (0.12, 0.081, 0.12),    # a lamp in the ceiling's plane
    "box_floor": (0.05, 0.011, 0.05),
    "sphere_floor": (0.06, 0.028, 0.05),
}


@pytest.mark.slow
@pytest.mark.parametrize("name", REPRODUCTION_CASES)
def test_reproduction_case(make_scene, name):
    """Each way real meshes went wrong, reproduced on a small scene of its
    own in one closed room (scenes.generate.reproduction_case): the voxel
    view at the default preset against the path tracer, 64 x 64, the lamp's
    pixels left out. Mean within 2%, no lit pixel black, the worst block
    within its bound (CASE_BOUNDS: the measured worst plus the path
    tracer's noise at 512 spp, about 2% per block); the same for the
    lightcuts frame at the default preset."""
    scene = make_scene(reproduction_case(name), "case_" + name)
    c, f = compare_at_default(scene, spp=512, frame=True)
    assert abs(c.mean - 1) < 0.02, c.mean
    assert c.black == 0
    assert c.worst < CASE_BOUNDS[name][0], c.worst
    assert abs(f.mean - 1) < 0.02 and f.black == 0, f.mean
    assert f.worst < CASE_BOUNDS[name][2], f.worst


def test_comparison_leaves_the_lamp_out_and_counts_black_lit_pixels():
    import numpy as np
    ref = np.full((16, 16, 3), 0.5)
    ref[0:2, 6:10] = 100.0                  # the lamp: left out with two rings of pixels around it
    img = ref.copy()
    img[0:2, 6:10] = 0.0                    # wrong only on the lamp ...
    img[2, 6] = img[0, 4] = 0.0             # ... and pixels of its rings (one and two pixels out)
    img[10:16, 0:8] *= 0.9                  # a darker region in the bottom-left block
    img[15, 15] = 0.0                       # one lit pixel black
    c = compare(img, ref, block=8)
    assert c.black == 1
    assert sorted(c.blocks) == pytest.approx([(2 + 6 * 0.9) / 8, 63 / 64, 1.0, 1.0])  # 6 rows at 0.9; one black
    assert c.worst == pytest.approx(1 - c.blocks.min())
    assert 0.9 < c.mean < 1.0


def gathers(sol, bvh, surf, voxels, radius=4):
    """(discrete, continuous) luminance each of `voxels` gathers from a
    solved radiosity: the propagation's gather along direction_set(radius),
    and rays from the same centroids along the same directions (the first
    surface hit through the BVH, its voxel's radiosity), both as the mean
    radiosity seen (cosine-weighted)."""
    import numpy as np
    from baker.solve.directions import direction_set
    from baker.solve.propagate import TAU, LineSweeper
    from baker.voxels.lookup import voxel_of_hit
    v, b = sol.voxels, sol.radiosity
    lum = np.array([0.2126, 0.7152, 0.0722])
    sw = LineSweeper(v)
    dirs = direction_set(radius)
    discrete = sw.irradiance(b, dirs, sw.offsets(dirs, 0, 1))[voxels] @ lum
    h = v.cell_size
    corners = surf.arrays.corners
    continuous = []
    for i in voxels:
        sign = np.sign(dirs.unit @ v.normal[i])
        u = dirs.unit * sign[:, None]
        w = (u @ v.normal[i]) * dirs.solid_angle
        o = np.repeat((v.centroid[i] + v.normal[i] * TAU * h)[None], len(u), 0)
        t, tri, _, _ = bvh.closest(o, u)
        got = np.zeros(len(u))
        for k in np.nonzero((tri >= 0) & (w > 0))[0]:
            c = corners[tri[k]]
            back = np.cross(c[1] - c[0], c[2] - c[0]) @ u[k] > 0
            y = voxel_of_hit(int(tri[k]), bool(back), *(o[k] + t[k] * u[k]), v.lookup())
            if y >= 0:
                got[k] = b[y] @ lum
        continuous.append((got * w).sum() / w[w > 0].sum())
    return discrete, np.array(continuous)


def test_box_foot_gathers_the_floor_where_its_rays_meet_it(cornell):
    """The bottom row of voxels of the Cornell box's short block's front
    face, standing on the floor, half a cell above it: their discrete
    gather of a solved radiosity against a continuous one (rays from the
    same centroids along the same directions, the first surface hit
    through the BVH, its voxel's radiosity). A grazing ray from there meets
    the floor cells away; the line, a cell thick, meets it in the box's own
    contact shadow at once. Measured over the row's 27 voxels, at 64 cells
    (preview, r = 4): 0.23 of the continuous gather before the deferral
    over flat surfaces, the cut-floor clause and the convex-corner marking
    (cells.separating_planes), 0.92 after (default, r = 8: 0.25 and 0.90;
    0.97 since the deferral reaches 8 cells, not 3); the worst voxel 0.66
    (it was 0). Without the corner marking: 0.73, the
    corner voxel near 0 (its piece took the side's plane as a surface
    standing across its cell). Bound: 0.8-1.1."""
    import numpy as np
    bvh, surf = build_scene_bvh(cornell), pack(cornell)
    sol = solve(cornell, solver_config("preview", resolution=64), bvh=bvh, surfaces=surf)
    v = sol.voxels
    front = np.array([0.293, 0.0, -0.956])  # the short block's front face
    on = np.nonzero(np.abs(v.normal - front).max(axis=1) < 0.01)[0]
    foot = on[v.cell[on, 1] == v.cell[on, 1].min()]
    assert len(foot) >= 4
    discrete, continuous = gathers(sol, bvh, surf, foot)
    ratio = discrete.sum() / continuous.sum()
    assert 0.8 < ratio < 1.1, ratio


@pytest.mark.slow
def test_floor_beside_a_scans_base_gathers_the_room():
    """The floor's voxels around the scan's base in scan_room, cut by the
    scan's local plane (the scan's sheet crosses their cells): their
    discrete gather against a continuous one, weighted by area (the light
    they carry), at the preview preset. A line a cell thick meets the
    scan's pieces in the floor's own cells where a continuous ray passes
    them by; the visibility rule passes a surface (crossing the cell, or
    cutting its pieces) whose plane the ray meets only beyond the voxel,
    or runs away from, both its faces (docs/design.md section 4, test 6).
    Measured: 0.60 before those refinements, 0.84 after. Bound: 0.75-1.1."""
    import numpy as np
    scene = load_scene(os.path.join(HERE, "scenes", "scan_room.glb"))
    bvh, surf = build_scene_bvh(scene), pack(scene)
    sol = solve(scene, solver_config("preview"), bvh=bvh, surfaces=surf)
    v = sol.voxels
    base = np.nonzero((v.normal[:, 1] > 0.999) & (np.abs(v.centroid[:, 1]) < 1e-6) & (v.cut_sign != 0) &
                      (np.abs(v.centroid[:, [0, 2]]).max(axis=1) < 0.9))[0]  # not at the room's walls
    assert len(base) >= 50
    discrete, continuous = gathers(sol, bvh, surf, base)
    a = v.area[base]
    ratio = (discrete * a).sum() / (continuous * a).sum()
    assert 0.75 < ratio < 1.1, ratio


def test_lamp_pixels_are_the_emitters_in_view(cornell):
    """The lamp mask comes from the camera's rays, not from brightness: the
    Cornell box's light is in it (and its brightest pixels), a view of the
    floor has no lamp pixel at all (the brightness rule left out the
    brightest half of such a view: scan_room's scan was left out of its own
    test)."""
    import numpy as np
    from baker.scene.model import make_camera
    bvh, surf = build_scene_bvh(cornell), pack(cornell)
    cam = camera_for(cornell, None, bvh)
    lamp = lamp_pixels(bvh, surf, cam, 32, 32)
    img = render(cornell, cam, 32, 32, "pathtrace", spp=16, seed=1, bvh=bvh, surfaces=surf)
    lum = img @ np.array([0.2126, 0.7152, 0.0722])
    assert 0 < lamp.sum() < 40
    assert np.all(lamp[lum > 0.5 * lum.max()])
    assert not lamp[16:].any()  # the light is in the ceiling, the top half of the view
    down = make_camera("down", cam.position, (0, -1, 0.3), (0, 0, 1), cam.yfov)
    assert not lamp_pixels(bvh, surf, down, 32, 32).any()


def test_lamp_pixels_take_the_sky_seen_through_glass(tmp_path):
    """Under a sky, the pixels whose rays escape are light sources too (a
    window shows the sky, the lightmap holds no light for it): directly
    and through thin glass the voxels leave out; without a sky they are
    not the lamp's."""
    import numpy as np
    from baker.scene import Sky, load_scene
    from baker.scene.model import make_camera
    from scenes.generate import GltfBuilder, quad
    b = GltfBuilder()
    b.mesh("floor", *quad((-2, 0, -2), (2, 0, -2), (2, 0, 2), (-2, 0, 2), facing=(0, 1, 0)),
           b.material("floor", (0.5,) * 3))
    b.mesh("pane", *quad((-2, 0, 1), (2, 0, 1), (2, 4, 1), (-2, 4, 1), facing=(0, 0, -1)),
           b.material("glass", (0.9,) * 3, transmission=0.9))
    b.save(tmp_path / "pane.glb")
    cam = make_camera("c", (0.0, 1.0, -1.5), (0.0, 0.0, 1.0), (0.0, 1.0, 0.0), np.radians(60))
    for sky in (None, Sky(np.ones(3))):
        scene = load_scene(tmp_path / "pane.glb", sky=sky)
        lamp = lamp_pixels(build_scene_bvh(scene), pack(scene), cam, 32, 32)
        # the top rows look through the pane at the sky, the bottom rows at the floor
        assert lamp[:4].all() == (sky is not None) and not lamp[-4:].any()
