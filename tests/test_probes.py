"""Irradiance probes (baker/probes/): the ray set's exact order-2
quadrature, the grid's placement and refusals, a furnace's probes, the
Cornell box's against the path tracer, no light through a one-sided wall,
and the probe block of the bake file (round trip, damage refused)."""
import json
import math

import numpy as np
import pytest

from baker.bake import bake_config, bake_scene, read_bake, write_bake
from baker.config import ProbeConfig
from baker.errors import BakeFileError, ConfigError
from baker.probes import grid_for, interpolate
from baker.probes.gather import MAP_FRAME, MAX_PROBES, SH_BAND, ray_set, sh_basis_np
from baker.probes.sample import irradiance_map_at, probe_irradiance_sh
from baker.render.irradiance import path_traced_irradiance
from scenes.generate import closed_box, furnace_box, thin_wall, two_rooms
from tests.conftest import cli, need_xvfb
from tests.hostile import resign_bake, split_glb

CUBE_NORMALS = np.array([v for a in range(3) for v in (np.eye(3)[a], -np.eye(3)[a])]
                        + [np.array([x, y, z]) / 3 ** 0.5 for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])


def small(**kw):
    return bake_config("default", resolution=24, photons=100_000, direct_vpls=2048, texel_density=12, **kw)


def test_the_ray_set_integrates_smooth_light_and_the_cosine_closely():
    """The probes' rays (a spherical Fibonacci set): the projection of any
    order-2 radiance is its coefficients within 5e-4 at 768 rays (3e-3 at
    192), and a constant radiance L gives the irradiance pi L for every
    normal within 0.1% (0.5% at 192): the clamped cosine's kink, which
    random directions integrate to a per cent at 768 (1.0% here for 64
    randomly turned icosahedra)."""
    rng = np.random.default_rng(0)
    normals = rng.normal(size=(4000, 3))
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    for count, sh_tol, cos_tol in ((768, 5e-4, 1e-3), (192, 3e-3, 5e-3)):
        d = ray_set(count)
        assert d.shape == (count, 3) and np.allclose(np.linalg.norm(d, axis=1), 1)
        y = sh_basis_np(d)
        coeffs = rng.normal(size=9)
        projected = 4 * np.pi / len(d) * (y * (y @ coeffs)[:, None]).sum(axis=0)
        assert np.abs(projected - coeffs).max() < sh_tol * np.abs(coeffs).max()
        e = 4 * np.pi / len(d) * np.maximum(normals @ d.T, 0).sum(axis=1) * 0.7
        assert np.abs(e / (np.pi * 0.7) - 1).max() < cos_tol
        const = 4 * np.pi / len(d) * y.sum(axis=0) * 0.7   # radiance 0.7 everywhere, through the SH
        e = probe_irradiance_sh(np.repeat(np.stack([const] * 3, axis=1)[None], len(CUBE_NORMALS), 0), CUBE_NORMALS)
        assert np.allclose(e, np.pi * 0.7, rtol=sh_tol * 10)
    assert SH_BAND[0] == math.pi


def test_the_irradiance_map_reads_a_cosine_lobe_smoothly():
    """A map of E(n) = max(0, n.z) read between its texels (and across
    its folded edges) is within a few per cent of exact near the pole and
    continuous everywhere."""
    from baker.probes.gather import IRR, texel_directions
    dirs = texel_directions(IRR)
    maps = np.maximum(dirs[:, 2], 0.0).reshape(1, IRR, IRR, 1).repeat(3, axis=3)
    rng = np.random.default_rng(1)
    n = rng.normal(size=(2000, 3))
    n /= np.linalg.norm(n, axis=1)[:, None]
    got = irradiance_map_at(np.repeat(maps, len(n), 0), n)[:, 0]
    want = np.maximum(n[:, 2], 0)
    # bilinear in the octahedral parameterization, which is not linear in the normal: a few per cent
    assert np.abs(got - want).max() < 0.08
    up = n[:, 2] > 0.5
    assert np.abs(got[up] - want[up]).max() < 0.06
    assert np.abs(got - want).mean() < 0.01


def test_the_grid_lies_inside_the_bounds():
    origin, spacing, dims = grid_for((0, 0, 0), (1, 0.5, 2), budget=4096)
    last = origin + (dims - 1) * spacing
    assert (origin >= spacing / 4 - 1e-12).all() and (last <= np.array([1, 0.5, 2]) - spacing / 4 + 1e-12).all()
    assert 2000 < np.prod(dims) < 8000 and (dims >= 4).all()
    origin, spacing, dims = grid_for((0, 0, 0), (1, 1, 1), spacing=0.3)
    assert spacing == 0.3 and tuple(dims) == (3, 3, 3)
    for bad in (0.0, -1.0, float("nan")):
        with pytest.raises(ConfigError):
            ProbeConfig(spacing=bad)
    with pytest.raises(ConfigError, match="probes over the scene's bounds") as e:
        grid_for((0, 0, 0), (10, 10, 10), spacing=10 / 200)
    assert "\n" not in str(e.value) and f"{MAX_PROBES:,}" in str(e.value)


def test_the_presets_space_the_probes_from_the_scene(cornell):
    """The Cornell box gets at least 4 probes per axis; the walkthrough
    about half a metre between probes at default."""
    from baker.scene.load import load_scene
    lo, hi = cornell.bounds()
    _, _, dims = grid_for(lo, hi, budget=bake_config("preview").probes.budget)
    assert (dims >= 4).all()
    lo, hi = load_scene("walkthrough").bounds()
    _, spacing, _ = grid_for(lo, hi, budget=bake_config("default").probes.budget)
    assert 0.3 <= spacing <= 0.7, spacing


@pytest.mark.parametrize("value", ["0", "-1", "nan", "1e-9"])
def test_bad_probe_spacings_are_refused_before_any_work(tmp_path, value):
    out = tmp_path / "b.glb"
    status, stdout, stderr = cli("bake", "cornell_box", "-o", out, f"--probe-spacing={value}")
    assert status == 2 and "Traceback" not in stderr and len(stderr.strip().splitlines()) == 1, stderr
    assert "probe" in stderr and not out.exists()


@pytest.fixture(scope="module")
def furnace_bake(make_scene):
    scene = make_scene(furnace_box(albedo=0.5, emission=1.0), "probe_furnace")
    return bake_scene(scene, small(probe_spacing=0.2))


def test_a_furnace_probe_reads_pi_times_the_radiance_for_every_normal(furnace_bake):
    """Albedo 0.5 and emitted radiosity 1 everywhere: the radiance is 2 /
    pi in every direction, so every probe's irradiance is pi times that, 2,
    for every normal, by its map, its SH and interpolated anywhere inside."""
    g = furnace_bake.bake.probes
    assert g.valid.all() and g.count == 125 and g.rays == 768
    exact = np.pi * (2.0 / np.pi)
    n = len(CUBE_NORMALS)
    for i in range(g.count):
        by_map = irradiance_map_at(np.repeat(g.irradiance[i][None], n, 0), CUBE_NORMALS)
        by_sh = probe_irradiance_sh(np.repeat(g.sh[i][None].astype(np.float64), n, 0), CUBE_NORMALS)
        assert np.abs(by_map / exact - 1).max() < 0.03, (i, by_map.min(), by_map.max())
        assert np.abs(by_sh / exact - 1).max() < 0.03, (i, by_sh.min(), by_sh.max())
    rng = np.random.default_rng(2)
    pts = rng.uniform(0.05, 0.95, size=(300, 3))
    nrm = rng.normal(size=(300, 3))
    nrm /= np.linalg.norm(nrm, axis=1)[:, None]
    e = interpolate(g, pts, nrm)
    assert np.abs(e / exact - 1).max() < 0.03


def test_the_probe_block_round_trips_and_damage_is_refused(furnace_bake, tmp_path):
    path = tmp_path / "f.glb"
    write_bake(str(path), furnace_bake.bake)
    back = read_bake(str(path)).probes
    g = furnace_bake.bake.probes
    for name in ("origin", "dims", "sh", "irradiance", "depth", "valid"):
        assert np.array_equal(getattr(back, name), getattr(g, name)), name
    assert back.spacing == g.spacing and back.rays == g.rays
    data = path.read_bytes()

    def edited(edit):
        bad = tmp_path / "bad.glb"
        bad.write_bytes(resign_bake(data, edit))
        with pytest.raises(BakeFileError) as e:
            read_bake(str(bad))
        assert "\n" not in str(e.value)
        return str(e.value)

    def probes(doc):
        return doc["extensions"]["VOXGI_lightmap"]["probes"]
    assert "probe" in edited(lambda d: probes(d).__setitem__("dims", [5, 5, 6]))
    assert "probe" in edited(lambda d: probes(d).__setitem__("dims", [1 << 20, 1 << 20, 1 << 20]))
    assert "probe" in edited(lambda d: probes(d).__setitem__("spacing", -1.0))
    assert "probe" in edited(lambda d: probes(d).__setitem__("version", 99))
    assert "probe" in edited(lambda d: probes(d).__setitem__("frame", np.eye(3).tolist()))   # another layout
    assert "probe" in edited(lambda d: probes(d).pop("frame"))
    assert "probe" in edited(lambda d: probes(d).__setitem__("frame", [[float("nan")] * 3] * 3))
    assert "probe" in edited(lambda d: probes(d)["sh"].__setitem__("bufferView", 10 ** 6))
    doc, _ = split_glb(data)
    assert json.dumps(probes(doc)["dims"]) == "[5, 5, 5]"


@pytest.fixture(scope="module")
def rooms_bake(make_scene):
    scene = make_scene(two_rooms(wall_x=1.0), "probe_rooms")
    return scene, bake_scene(scene, small(probe_spacing=0.125))


def test_no_probe_light_goes_through_a_one_sided_wall(rooms_bake):
    """Two rooms split by a one-sided wall, the lamp in one: every probe
    of the dark room holds no light, and a sphere anywhere in the dark
    room, touching the wall included, reads exactly 0 at every point of
    its surface (its centre sees which probes are on its side); one in the
    lit room is lit."""
    from baker.scene.prepared import prepare
    scene, result = rooms_bake
    g = result.bake.probes
    bvh = prepare(scene).bvh.arrays
    pos = g.positions()
    dark = pos[:, 0] > 1.0
    assert (g.irradiance[dark] == 0).all() and (g.sh[dark] == 0).all()
    lit = (pos[:, 0] < 1.0) & g.valid
    assert (g.irradiance[lit].sum(axis=(1, 2, 3)) > 0).all()
    rng = np.random.default_rng(3)
    r = 0.05
    nrm = rng.normal(size=(200, 3))
    nrm /= np.linalg.norm(nrm, axis=1)[:, None]
    centres = [(1.0 + r + 0.001, 0.5, 0.5), (1.0 + r + 0.001, 0.2, 0.8), (1.5, 0.5, 0.5), (1.9, 0.9, 0.1)]
    for c in centres:
        c = np.array(c)
        e = interpolate(g, c + r * nrm, nrm, np.repeat(c[None], len(nrm), 0), bvh)
        assert (e == 0).all(), (c, e.max())
    c = np.array([0.5, 0.5, 0.5])
    assert (interpolate(g, c + r * nrm, nrm, np.repeat(c[None], len(nrm), 0), bvh).sum(axis=1) > 0).all()


@pytest.mark.slow
def test_cornell_probes_match_the_path_tracer(cornell):
    """Probes that see no surface nearer than four voxel cells (and do not
    look out of the open front), for the 14
    normals of a cube's faces and corners: the irradiance map within 3%
    of the path tracer's irradiance (plus 1% of the probe's brightest, for
    normals that face the open front and see almost nothing), and the
    grid interpolated at the probe itself the same."""
    from baker.scene.prepared import prepare
    result = bake_scene(cornell, small(probe_spacing=0.1))
    g = result.bake.probes
    cell = float(result.solution.voxels.cell_size)
    pos = g.positions()
    lo, hi = cornell.bounds()
    # clear of surfaces, and in the back of the box (the open front at z = 0 lets nearly nothing in: tiny values)
    clear = g.valid & (g.depth[..., 0].reshape(g.count, -1).min(axis=1) > 4 * cell) & \
        (pos[:, 2] > lo[2] + 0.4 * (hi[2] - lo[2]))
    assert clear.sum() >= 8
    prepared = prepare(cornell)
    picked = np.nonzero(clear)[0][::max(1, clear.sum() // 8)][:8]
    n = len(CUBE_NORMALS)
    errors = []
    for i in picked:
        want = path_traced_irradiance(prepared, pos[i], CUBE_NORMALS).sum(axis=1)
        got = irradiance_map_at(np.repeat(g.irradiance[i][None], n, 0), CUBE_NORMALS).sum(axis=1)
        errors.append(np.abs(got - want) / (want + 0.02 * want.max()))
        near = interpolate(g, np.repeat(pos[i][None], n, 0), CUBE_NORMALS).sum(axis=1)
        assert np.allclose(near, got, rtol=1e-6)
    errors = np.concatenate(errors)
    # at this test's coarse solve (24 cells across) the bounced light's own error reaches 10-15% in a few directions
    # (the per-pixel accuracy issue); the map's bilinear read near its kinks adds up to 30% in one or two
    # (test_the_map_reads_the_probe_s_own_irradiance_between_its_texels)
    assert np.median(errors) < 0.03 and np.mean(errors < 0.05) > 0.85 and errors.max() < 0.4, \
        (np.median(errors), np.mean(errors < 0.05), errors.max())


def test_the_map_reads_the_probe_s_own_irradiance_between_its_texels(cornell, monkeypatch):
    """The irradiance map read at the 14 cube normals against the same
    probe's irradiance gathered at those normals themselves (the same rays
    and lamp samples, so no noise between them): the error is the map's
    bilinear read alone. In the turned frame (MAP_FRAME) the scene's axes
    lie off the octahedron's vertices: at least 88% of the readings within
    3% (96% as shipped; at 17 x 17 texels in the scene's own frame, the
    axes on its vertices: 80%), the axes' median under 2%."""
    import baker.probes.gather as gather
    from baker.probes.gather import IRR
    cfg = small(probe_spacing=0.1)
    result = bake_scene(cornell, cfg)
    from baker.scene.prepared import prepare
    prepared = prepare(cornell)
    g = result.bake.probes
    lo, hi = cornell.bounds()
    plain = gather.texel_directions

    def at_the_normals(size, sub=1):
        d = plain(size, sub)
        if size == IRR and sub == 1:
            d = d.copy()
            d[:len(CUBE_NORMALS)] = CUBE_NORMALS
        return d
    monkeypatch.setattr(gather, "texel_directions", at_the_normals)
    exact_grid = gather.bake_probes(prepared, result.solution, grid_for(lo, hi, cfg.probes.spacing, cfg.probes.budget),
                                    cfg.probes.rays, cfg.solver.seed)
    n = len(CUBE_NORMALS)
    exact = exact_grid.irradiance[:, 0, :n].sum(axis=2)
    read = np.stack([irradiance_map_at(np.repeat(g.irradiance[i][None], n, 0), CUBE_NORMALS).sum(axis=1)
                     for i in range(g.count)])
    ok = g.valid & (exact.max(axis=1) > 0)
    assert ok.sum() >= 20
    err = np.abs(read - exact)[ok] / (exact[ok] + 0.02 * exact[ok].max(axis=1, keepdims=True))
    assert np.mean(err < 0.03) >= 0.88 and np.median(err[:, :6]) < 0.02, (np.mean(err < 0.03), np.median(err[:, :6]))


@pytest.mark.slow
def test_walkthrough_probes_match_the_path_tracer():
    """The walkthrough at default (three rooms, four lamps hung under the
    ceiling, a sun through a window): eight probes that see no surface
    nearer than four voxel cells, 14 normals each, against the path
    tracer's irradiance with the sun counted at the point (65,536
    directions: 8,192 x 4 paths are themselves off by up to 4-8% beside
    a lamp). A regression guard at today's figures (median 1.0%, 96% within
    3%, all within 5%, at most 4.6%): the issue's 3% is met for most
    normals, not all."""
    from baker.presets import bake_config
    from baker.probes import bake_probes
    from baker.scene import load_scene
    from baker.scene.prepared import prepare
    from baker.solve import solve
    scene = load_scene("walkthrough")
    prepared = prepare(scene)
    cfg = bake_config("default")
    solution = solve(prepared, cfg.solver)
    lo, hi = scene.bounds()
    g = bake_probes(prepared, solution, grid_for(lo, hi, cfg.probes.spacing, cfg.probes.budget), cfg.probes.rays,
                    cfg.solver.seed)
    cell = float(solution.voxels.cell_size)
    pos = g.positions()
    clear = np.nonzero(g.valid & (g.depth[..., 0].reshape(g.count, -1).min(axis=1) > 4 * cell))[0]
    picked = np.random.default_rng(2).choice(clear, 8, replace=False)
    n = len(CUBE_NORMALS)
    errors = []
    for i in picked:
        want = path_traced_irradiance(prepared, pos[i], CUBE_NORMALS, 65536, 1).sum(axis=1)
        got = irradiance_map_at(np.repeat(g.irradiance[i][None], n, 0), CUBE_NORMALS).sum(axis=1)
        errors.append(np.abs(got - want) / (want + 0.02 * want.max()))
    errors = np.concatenate(errors)
    assert np.median(errors) < 0.015 and np.mean(errors < 0.03) > 0.92 and np.mean(errors < 0.05) > 0.97 \
        and errors.max() < 0.07, (np.median(errors), np.mean(errors < 0.03), np.mean(errors < 0.05), errors.max())


@pytest.fixture(scope="module")
def gl():
    from viewer.context import headless_context
    c = headless_context()
    yield c
    c.release()


def _sphere_pixels(cam, w, h, center, radius):
    """(h, w) bool: pixels whose every corner ray meets the sphere."""
    from baker.render import camera_array
    c = camera_array(cam, w, h)
    ys, xs = np.mgrid[0:h + 1, 0:w + 1]
    a = 2.0 * xs / w - 1.0
    b = 1.0 - 2.0 * ys / h
    d = c[1][None, None] + a[..., None] * c[2][None, None] + b[..., None] * c[3][None, None]
    d /= np.linalg.norm(d, axis=2)[..., None]
    oc = c[0] - np.asarray(center)
    t = np.einsum("ijk,k->ij", d, oc)
    hit = t * t - (oc @ oc - radius ** 2) > 0
    return hit[:-1, :-1] & hit[1:, :-1] & hit[:-1, 1:] & hit[1:, 1:]


def _sphere_normals(cam, w, h, center, radius):
    """(ys, xs, normals): the pixels of _sphere_pixels and the sphere's
    normal where each pixel's central ray first meets it."""
    from baker.render import camera_array
    center = np.asarray(center, np.float64)
    ys, xs = np.nonzero(_sphere_pixels(cam, w, h, center, radius))
    c = camera_array(cam, w, h)
    a, b = 2.0 * (xs + 0.5) / w - 1.0, 1.0 - 2.0 * (ys + 0.5) / h
    d = c[1] + a[:, None] * c[2] + b[:, None] * c[3]
    d /= np.linalg.norm(d, axis=1)[:, None]
    oc = c[0] - center
    t = d @ oc
    return ys, xs, (c[0] + (-t - np.sqrt(t * t - (oc @ oc - radius * radius)))[:, None] * d - center) / radius


def test_a_snapshot_sphere_in_a_furnace_reads_albedo_times_radiance(furnace_bake, gl, tmp_path):
    """voxview's sphere (the shader, not the Python reference) in the
    furnace: every pixel of it reads albedo x radiance, A x 2 / pi."""
    from viewer.objects import Sphere
    from viewer.snapshot import snapshot
    from baker.scene import camera_for
    path = tmp_path / "f.glb"
    write_bake(str(path), furnace_bake.bake)
    bake = read_bake(str(path))
    cam = camera_for(bake.scene, None)
    centre, r = (0.5, 0.5, 0.6), 0.15
    img = snapshot(bake, cam, 64, 64, ctx=gl, objects=(Sphere(centre, r, (0.6, 0.6, 0.6)),))
    mask = _sphere_pixels(cam, 64, 64, centre, r)
    assert mask.sum() > 200
    assert np.abs(img[mask] / (0.6 * 2 / np.pi) - 1).max() < 0.02


@pytest.mark.slow
def test_snapshot_spheres_in_the_cornell_box_match_the_path_tracer(cornell, gl, tmp_path):
    """A sphere at three places in voxview's snapshot (one sample at each
    pixel's centre): the mean over 48 of its pixels within 5% of the path
    tracer's albedo x E / pi at the same surface points and normals in the
    room. The bake's room holds no sphere: the sphere neither shadows the
    room nor lights it, so the path tracer's room has none either (with
    the sphere in the path-traced room its shadow darkens what its
    underside sees: bench/results/probes.md has those figures)."""
    from baker.render import camera_array
    from baker.scene import camera_for
    from baker.scene.prepared import prepare
    from viewer.objects import Sphere
    from viewer.snapshot import snapshot
    path = tmp_path / "c.glb"
    write_bake(str(path), bake_scene(cornell, small()).bake)
    bake = read_bake(str(path))
    prepared = prepare(cornell)
    w = h = 48
    cam = camera_for(bake.scene, None)
    c = camera_array(cam, w, h)
    rng = np.random.default_rng(4)
    # (not by the open front: what faces it sees almost nothing, and a per-cent error there is tens of per cent)
    for centre, r in (((0.28, 0.42, 0.28), 0.05), ((0.12, 0.30, 0.40), 0.06), ((0.44, 0.42, 0.30), 0.05)):
        img = snapshot(bake, cam, w, h, samples=1, ctx=gl, objects=(Sphere(centre, r, (0.8, 0.8, 0.8)),))
        ys, xs = np.nonzero(_sphere_pixels(cam, w, h, centre, r))
        pick = rng.choice(len(ys), size=min(48, len(ys)), replace=False)
        ys, xs = ys[pick], xs[pick]
        a, b = 2.0 * (xs + 0.5) / w - 1.0, 1.0 - 2.0 * (ys + 0.5) / h
        d = c[1] + a[:, None] * c[2] + b[:, None] * c[3]
        d /= np.linalg.norm(d, axis=1)[:, None]
        oc = c[0] - np.asarray(centre)
        t = d @ oc
        hit = -t - np.sqrt(t * t - (oc @ oc - r * r))
        pts = c[0] + hit[:, None] * d
        nrm = (pts - np.asarray(centre)) / r
        want = np.array([path_traced_irradiance(prepared, p, n[None], 4096, 1)[0] for p, n in zip(pts, nrm)])
        want = 0.8 * want / np.pi
        ratio = img[ys, xs].mean() / want.mean()
        assert abs(ratio - 1) < 0.05, (centre, ratio)


def test_a_snapshot_sphere_against_the_wall_of_the_dark_room_is_black(rooms_bake, gl, tmp_path):
    """voxview's sphere touching the one-sided wall on its dark side is
    exactly black in every pixel; in the lit room it is lit."""
    from viewer.objects import Sphere
    path = tmp_path / "rooms.glb"
    write_bake(str(path), rooms_bake[1].bake)
    bake = read_bake(str(path))
    r = 0.1
    assert_dark_beside_the_wall_and_lit(bake, gl, r, r, lambda centre: (Sphere(centre, r),))


def assert_dark_beside_the_wall_and_lit(bake, gl, r, seen, place):
    """In the two-rooms scene (one-sided wall at x = 1), an object of
    radius r touching the wall, placed by place(centre) -> objects: every
    pixel of it (within `seen` of its centre) exactly black on the dark
    side, lit on the lit side."""
    from baker.scene import camera_for
    from viewer.snapshot import snapshot
    for name, centre in (("dark", (1.0 + r + 0.001, 0.5, 0.5)), ("lit", (1.0 - r - 0.001, 0.5, 0.5))):
        cam = camera_for(bake.scene, name)
        img = snapshot(bake, cam, 48, 48, ctx=gl, objects=place(centre))
        mask = _sphere_pixels(cam, 48, 48, centre, seen)
        assert mask.sum() > 30
        if name == "dark":
            assert (img[mask] == 0).all()
        else:
            assert (img[mask].sum(axis=1) > 0).all()


def test_the_window_drops_and_moves_a_sphere(furnace_bake, tmp_path):
    """voxview's window under Xvfb: O drops a sphere in front of the
    camera, the arrow keys move it; the last frame differs from the same
    walk without it."""
    import subprocess
    import sys
    need_xvfb()
    from PIL import Image
    path = tmp_path / "f.glb"
    write_bake(str(path), furnace_bake.bake)
    scripts = {"sphere": [{"frame": 1, "key": "O"}, {"frame": 2, "key": "RIGHT", "action": "press"},
                          {"frame": 7, "key": "RIGHT", "action": "release"}], "none": []}
    shots = {}
    for name, script in scripts.items():
        (tmp_path / f"{name}.json").write_text(json.dumps(script))
        out = tmp_path / f"{name}.png"
        r = subprocess.run(["xvfb-run", "-a", "-s", "-screen 0 800x600x24", sys.executable, "-m", "viewer", str(path),
                            "--script", str(tmp_path / f"{name}.json"), "--frames", "8", "--screenshot", str(out),
                            "--width", "160", "--height", "120", "--exposure", "0"],
                           capture_output=True, text=True, timeout=300)
        assert r.returncode == 0, r.stderr
        shots[name] = np.asarray(Image.open(out).convert("RGB"), float)
    diff = np.abs(shots["sphere"] - shots["none"]).sum(axis=2) > 10
    assert 50 < diff.sum() < diff.size // 2
    cols = np.nonzero(diff.any(axis=0))[0]
    assert cols.mean() > 80   # moved right of the centre


@pytest.mark.parametrize("builder", [thin_wall, closed_box], ids=["thin_wall", "closed_box"])
def test_a_sphere_sees_only_its_own_side(make_scene, builder):
    """Beside a double-sided wall thinner than a cell, a sphere on the
    dark side reads exactly 0 and one on the lit side is lit; the probes
    inside a closed box are invalid or dark, and a sphere in it reads 0."""
    from baker.scene.prepared import prepare
    scene = make_scene(builder(), f"probe_{builder.__name__}")
    g = bake_scene(scene, small(probe_spacing=0.1)).bake.probes
    bvh = prepare(scene).bvh.arrays
    rng = np.random.default_rng(5)
    nrm = rng.normal(size=(200, 3))
    nrm /= np.linalg.norm(nrm, axis=1)[:, None]
    r = 0.05
    if builder is thin_wall:
        dark, lit = (1.0 + r + 0.002, 0.5, 0.5), (1.0 - r - 0.004, 0.5, 0.5)
    else:
        dark, lit = (1.0, 0.55, 1.0), (0.3, 1.0, 0.3)   # in the closed box, over its inner object; in the room
        inside = np.all((g.positions() > [0.6, 0.0, 0.6]) & (g.positions() < [1.4, 0.8, 1.4]), axis=1)
        assert (~g.valid[inside] | (g.irradiance[inside] == 0).all(axis=(1, 2, 3))).all()
    for centre, want_dark in ((dark, True), (lit, False)):
        c = np.array(centre)
        e = interpolate(g, c + r * nrm, nrm, np.repeat(c[None], len(nrm), 0), bvh).sum(axis=1)
        assert (e == 0).all() if want_dark else (e > 0).all(), (centre, e.min(), e.max())


def test_a_small_sphere_is_shaded_by_its_blended_map(cornell, gl, tmp_path):
    """A sphere no larger than a probe cell: voxview reads one map, the
    probes blended at its centre (object_map); every pixel equals the
    Python interpolation at the centre with that pixel's normal (within
    1%; the lamp out of the probes and in at the centre, as the viewer
    has it), and the map read at n is interpolate(centre, n) exactly."""
    from baker.probes.sample import object_map, probe_lights
    from baker.scene import camera_for
    from baker.scene.prepared import prepare
    from viewer.objects import OBJECT_LAMP_RAYS, Sphere
    from viewer.snapshot import snapshot
    path = tmp_path / "c.glb"
    write_bake(str(path), bake_scene(cornell, small(probe_spacing=0.08)).bake)
    bake = read_bake(str(path))
    g = bake.probes
    prepared = prepare(cornell)
    bvh = prepared.bvh.arrays
    centre, r = np.array([0.3, 0.35, 0.3]), 0.07
    n = CUBE_NORMALS
    m = object_map(g, centre, bvh)
    assert np.allclose(irradiance_map_at(np.repeat(m[None], len(n), 0), n),
                       interpolate(g, np.repeat(centre[None], len(n), 0), n, np.repeat(centre[None], len(n), 0), bvh),
                       rtol=1e-5, atol=1e-6)
    m = object_map(g, centre, bvh, probe_lights(g, prepared, OBJECT_LAMP_RAYS))
    w = h = 48
    cam = camera_for(bake.scene, None)
    img = snapshot(bake, cam, w, h, samples=1, ctx=gl, objects=(Sphere(tuple(centre), r, (0.8, 0.8, 0.8)),))
    ys, xs, nrm = _sphere_normals(cam, w, h, centre, r)
    want = 0.8 / np.pi * irradiance_map_at(np.repeat(m[None], len(nrm), 0), nrm)
    assert len(ys) > 30 and np.abs(img[ys, xs] - want).max() <= 0.01 * want.max()


def test_a_large_sphere_is_shaded_by_its_surface_map(cornell, gl, tmp_path):
    """A sphere larger than a probe cell: voxview reads one map over its
    normals (sphere_map), each texel the per-point interpolation at the
    sphere's point with that normal. At the map's texel normals the map is
    interpolate (anchored at the centre) exactly; every pixel of the
    snapshot is interpolate at the pixel's point and normal within 1.5% of
    the sphere's brightest (the map's bilinear read between texels: 1.03%
    at most here, beside the lamp). The lamp out of the probes and in at
    each point, as the viewer has it."""
    from baker.probes.sample import probe_lights, sphere_map
    from baker.scene import camera_for
    from baker.scene.prepared import prepare
    from viewer.objects import OBJECT_LAMP_RAYS, Sphere, probe_seen
    from viewer.snapshot import snapshot
    path = tmp_path / "c.glb"
    write_bake(str(path), bake_scene(cornell, small(probe_spacing=0.06)).bake)
    bake = read_bake(str(path))
    g = bake.probes
    prepared = prepare(cornell)
    bvh = prepared.bvh.arrays
    lights = probe_lights(g, prepared, OBJECT_LAMP_RAYS)
    centre, r = np.array([0.28, 0.40, 0.28]), 0.09
    assert r > g.spacing
    size = 16
    m = sphere_map(g, centre, r, probe_seen(g, centre, r, bvh), size, lights)
    uv = (np.stack(np.meshgrid(np.arange(size), np.arange(size)), -1).reshape(-1, 2) + 0.5) / size * 2 - 1
    n = np.concatenate([uv, (1 - np.abs(uv).sum(axis=1))[:, None]], axis=1)   # the texel centres' normals
    low = n[:, 2] < 0
    n[low, :2] = (1 - np.abs(n[low][:, [1, 0]])) * np.where(n[low, :2] >= 0, 1.0, -1.0)
    n /= np.linalg.norm(n, axis=1)[:, None]
    n = n @ MAP_FRAME   # the maps' frame to the scene's
    anchors = np.repeat(centre[None], len(n), 0)
    want = interpolate(g, centre + r * n, n, anchors, bvh, lights)
    assert np.allclose(m.reshape(-1, 3), want, rtol=1e-4, atol=1e-6)
    assert (want.sum(axis=1) > 0).mean() > 0.9
    w = h = 96
    cam = camera_for(bake.scene, None)
    img = snapshot(bake, cam, w, h, samples=1, ctx=gl, objects=(Sphere(tuple(centre), r, (0.8, 0.8, 0.8)),))
    ys, xs, nrm = _sphere_normals(cam, w, h, centre, r)
    want = 0.8 / np.pi * interpolate(g, centre + r * nrm, nrm, np.repeat(centre[None], len(nrm), 0), bvh, lights)
    assert len(ys) > 200
    assert np.abs(img[ys, xs] - want).max() <= 0.015 * want.max()


def test_the_probe_view_draws_each_probe_lit_by_its_sh(cornell, furnace_bake, gl, tmp_path):
    """voxview's probe view (--probes, key G): in the Cornell box, the pixel
    through the middle of each probe's sphere that nothing hides (no other
    probe, no block) reads a white diffuse sphere's radiance under that
    probe's SH at the pixel's normal, E(n) / pi (within 2%); an invalid
    probe is flat red. In the furnace every probe reads the room's own
    radiance, so the view with the probes is the view without them."""
    from baker.probes.sample import probe_irradiance_sh
    from baker.render import camera_array
    from baker.scene import camera_for
    from baker.scene.prepared import prepare
    from baker.kernels.traverse import any_hit_batch
    from viewer.objects import PROBE_SIZE
    from viewer.snapshot import snapshot
    path = tmp_path / "c.glb"
    write_bake(str(path), bake_scene(cornell, small(probe_spacing=0.1)).bake)
    bake = read_bake(str(path))
    g = bake.probes
    w = h = 384
    cam = camera_for(bake.scene, None)
    img = snapshot(bake, cam, w, h, samples=1, ctx=gl, probes=True)
    c = camera_array(cam, w, h)
    pos = g.positions()
    r = PROBE_SIZE * g.spacing
    v = pos - c[0]
    t = v @ c[1] / (c[1] @ c[1])
    a = (v @ c[2]) / (t * (c[2] @ c[2]))
    b = (v @ c[3]) / (t * (c[3] @ c[3]))
    xs, ys = np.floor((a + 1) / 2 * w).astype(int), np.floor((1 - b) / 2 * h).astype(int)
    dist = np.linalg.norm(v, axis=1)
    u = v / dist[:, None]
    # hidden: another probe's sphere nearer along the ray, or the room's geometry before it
    side = np.linalg.norm(np.cross(u[:, None, :], pos[None, :, :] - c[0]), axis=2)
    nearer = (dist[None, :] < dist[:, None]) & (side < 3 * r)
    np.fill_diagonal(nearer, False)
    blocked = any_hit_batch(prepare(cornell).bvh.arrays, np.repeat(c[0][None], len(pos), 0), u, 0.0, dist - 2 * r)
    shown = (t > 0) & (xs >= 0) & (xs < w) & (ys >= 0) & (ys < h) & ~nearer.any(axis=1) & ~blocked
    assert shown.sum() >= 10 and (shown & g.valid).sum() >= 10
    checked = 0
    for i in np.nonzero(shown)[0]:
        x, y = xs[i], ys[i]
        d = c[1] + (2 * (x + 0.5) / w - 1) * c[2] + (1 - 2 * (y + 0.5) / h) * c[3]
        d /= np.linalg.norm(d)
        oc = c[0] - pos[i]
        tt = d @ oc
        disc = tt * tt - (oc @ oc - r * r)
        if disc < (0.5 * r) ** 2:   # the pixel's ray only grazes the sphere
            continue
        n = (c[0] + (-tt - np.sqrt(disc)) * d - pos[i]) / r
        if not g.valid[i]:
            assert np.allclose(img[y, x], (0.6, 0.0, 0.0)), (i, img[y, x])
            continue
        want = np.maximum(probe_irradiance_sh(g.sh[i][None], n[None])[0], 0) / np.pi
        assert np.abs(img[y, x] - want).max() <= 0.02 * want.max() + 1e-4, (i, img[y, x], want)
        checked += 1
    assert checked >= 10
    furnace = furnace_bake.bake
    fcam = camera_for(furnace.scene, None)
    with_probes = snapshot(furnace, fcam, 64, 64, samples=1, ctx=gl, probes=True)
    without = snapshot(furnace, fcam, 64, 64, samples=1, ctx=gl)
    assert np.abs(with_probes / without - 1).max() < 0.01


def test_the_probe_view_from_the_command_line(cornell, tmp_path):
    """`voxview snapshot --probes` draws the probes (the image differs from
    the one without); on a bake made with --no-probes, or in a debug view,
    one line and exit 2 before any drawing."""
    from PIL import Image
    from viewer.cli import main
    from tests.conftest import cli
    with_probes, without = tmp_path / "c.glb", tmp_path / "none.glb"
    write_bake(str(with_probes), bake_scene(cornell, small(probe_spacing=0.1)).bake)
    write_bake(str(without), bake_scene(cornell, small(probe_rays=0)).bake)
    shots = {}
    for name, extra in (("probes", ["--probes"]), ("plain", [])):
        out = tmp_path / f"{name}.png"
        code, _, err = cli("snapshot", with_probes, "-o", out, "--width", 96, "--height", 96, "--samples", 1,
                           "--exposure", 0, *extra, main=main)
        assert code == 0, err
        shots[name] = np.asarray(Image.open(out).convert("RGB"), float)
    assert (np.abs(shots["probes"] - shots["plain"]).sum(axis=2) > 10).mean() > 0.02
    for bake, extra, message in ((without, [], "no irradiance probes"),
                                 (with_probes, ["--mode", "checker"], "lightmap")):
        out = tmp_path / "x.png"
        code, _, err = cli("snapshot", bake, "-o", out, "--probes", *extra, main=main)
        assert code == 2 and message in err and len(err.strip().splitlines()) == 1, err
        assert not out.exists()


def test_the_path_traced_reference_counts_the_sun_at_the_point(make_scene):
    """path_traced_irradiance (the probes' reference) over a black floor
    under a sun of E = 3 at 60 degrees from the zenith and a 0.5 x 0.5
    blocker: above the floor in the open, E(n) = 3 cos(n, -sun) for each
    normal (no sampled direction meets a delta); in the blocker's shadow
    0; nothing else lights the point."""
    from scenes.generate import GltfBuilder, quad
    from baker.render.irradiance import path_traced_irradiance
    from baker.scene.prepared import prepare
    b = GltfBuilder()
    black = b.material("black", (0.0, 0.0, 0.0))
    b.mesh("floor", *quad((-4, 0, -4), (4, 0, -4), (4, 0, 4), (-4, 0, 4), facing=(0, 1, 0)), black)
    b.mesh("blocker", *quad((-0.25, 1, -0.25), (0.25, 1, -0.25), (0.25, 1, 0.25), (-0.25, 1, 0.25),
                            facing=(0, -1, 0)), b.material("blocker", (0.0, 0.0, 0.0), double_sided=True))
    sun = np.array([np.sin(np.pi / 3), -np.cos(np.pi / 3), 0.0])
    b.light("sun", "directional", intensity=3.0, direction=tuple(sun))
    b.camera("c", (0, 2, 3), (0, -0.5, -1))
    prepared = prepare(make_scene(b, "sun_reference"))
    e = path_traced_irradiance(prepared, (2.0, 0.5, 0.0), CUBE_NORMALS, 256, 1)
    assert np.allclose(e, 3.0 * np.maximum(CUBE_NORMALS @ -sun, 0)[:, None], atol=1e-9)
    shade = (np.tan(np.pi / 3) * 0.5, 0.5, 0.0)   # 0.5 under the blocker's centre along the sun
    assert (path_traced_irradiance(prepared, shade, CUBE_NORMALS, 256, 1) == 0).all()


def test_a_moving_sphere_reads_a_coarser_map_until_it_stops(cornell, gl):
    """In the window (interactive) a large sphere's map is MOVING_MAP wide
    the frames it moves and SURFACE_MAP wide the first frame it stands
    still; a snapshot always reads the full map. The border the GPU's
    bilinear filter reads holds each fold's mirror texels."""
    from viewer.objects import MOVING_MAP, SURFACE_MAP, ProbeObjects, Sphere, bordered
    bake = bake_scene(cornell, small(probe_spacing=0.06)).bake
    r = 0.09
    a, b = Sphere((0.28, 0.40, 0.28), r), Sphere((0.29, 0.40, 0.28), r)
    window = ProbeObjects(gl, bake, interactive=True)
    sizes = [window._object_map(0, s)[0] for s in (a, b, b, a, a)]
    assert sizes == [SURFACE_MAP, MOVING_MAP, SURFACE_MAP, MOVING_MAP, SURFACE_MAP]
    window.release()
    still = ProbeObjects(gl, bake)
    assert [still._object_map(0, s)[0] for s in (a, b, a)] == [SURFACE_MAP] * 3
    still.release()
    m = np.arange(4 * 4 * 3, dtype=np.float32).reshape(4, 4, 3)
    out = bordered(m)
    from baker.probes.sample import _wrap
    for row in range(-1, 5):
        for col in range(-1, 5):
            rr, cc = _wrap(np.array([row]), np.array([col]), 4)
            assert (out[row + 1, col + 1] == m[rr[0], cc[0]]).all(), (row, col)


@pytest.fixture(scope="module")
def sun_scene(make_scene):
    """A floor 4 x 4 with a wall 1 high across it, under a sun 35 degrees
    up from +x: the wall's shadow a 1.43 band beyond it, in the open."""
    from baker.scene.model import sun
    from scenes.generate import box, quad
    from baker.scene.gltf_write import GltfBuilder
    b = GltfBuilder()
    grey = b.material("grey", (0.5, 0.5, 0.5))
    b.mesh("floor", *quad((-2, 0, -2), (2, 0, -2), (2, 0, 2), (-2, 0, 2), facing=(0, 1, 0)), grey)
    b.mesh("wall", *box((-0.1, 0, -1.5), (0.1, 1, 1.5)), grey)
    b.camera("above", (2.5, 1.5, 0), (-1, -0.5, 0), yfov_deg=60)
    scene = make_scene(b, "probe_sun")
    return scene.with_lights([sun(90, 35, 3.0)])


def test_the_sun_is_exact_at_each_point_not_between_probes(sun_scene):
    """The sun comes out of the probes (each holds it as the delta the
    bake added) and in at each point behind its own shadow ray. Points
    half-way up the wall, on both sides of its shadow's edge at that
    height and 0.5 from the nearest probes, against the path tracer for
    the 14 normals: in the sun within 10% (at most 8.6% here: the bounced
    light between probes), in the shadow within 25% (19.5%: the dim
    bounced light there, which the coarse test solve holds a few per cent
    off, against little else), where the probes alone read the sun that
    the probes beside the edge see, two orders of magnitude off."""
    from baker.probes.sample import probe_lights
    from baker.scene.prepared import prepare
    g = bake_scene(sun_scene, small(probe_spacing=0.5)).bake.probes
    prepared = prepare(sun_scene)
    lights = probe_lights(g, prepared)
    assert lights.count == 1 and (lights.irradiance[g.valid].max(axis=2) > 0).mean() > 0.3
    edge = -0.1 - 0.5 / np.tan(np.radians(35))    # the shadow's edge 0.5 over the floor
    n = len(CUBE_NORMALS)
    for x, lit in ((edge - 0.15, True), (edge - 0.05, True), (edge + 0.05, False), (edge + 0.15, False)):
        p = np.array([x, 0.5, 0.3])
        want = path_traced_irradiance(prepared, p, CUBE_NORMALS, 16384, 1).sum(axis=1)
        pts = np.repeat(p[None], n, 0)
        err = {}
        for key, lt in (("exact", lights), ("probes", None)):
            got = interpolate(g, pts, CUBE_NORMALS, pts, prepared.bvh.arrays, lt).sum(axis=1)
            err[key] = np.abs(got - want) / (want + 0.02 * want.max())
        assert err["exact"].max() < (0.10 if lit else 0.25), (x, err["exact"].max())
        if not lit:
            assert err["probes"].max() > 10, (x, err["probes"].max())


def test_the_viewer_s_maps_take_the_sun_as_the_reference_does(sun_scene):
    """sphere_map (a sphere wholly in the sun: its coarse visibility map
    all ones) and points_irradiance (a dynamic mesh's vertices) equal
    interpolate with the same lights at their points."""
    from baker.probes.sample import points_irradiance, probe_lights, sphere_map
    from baker.scene.prepared import prepare
    from viewer.objects import probe_seen
    g = bake_scene(sun_scene, small(probe_spacing=0.5)).bake.probes
    prepared = prepare(sun_scene)
    bvh = prepared.bvh.arrays
    lights = probe_lights(g, prepared)
    centre, r = np.array([1.2, 0.6, 0.3]), 0.3
    seen = probe_seen(g, centre, r, bvh)
    size = 16
    m = sphere_map(g, centre, r, seen, size, lights)
    uv = (np.stack(np.meshgrid(np.arange(size), np.arange(size)), -1).reshape(-1, 2) + 0.5) / size * 2 - 1
    nrm = np.concatenate([uv, (1 - np.abs(uv).sum(axis=1))[:, None]], axis=1)
    low = nrm[:, 2] < 0
    nrm[low, :2] = (1 - np.abs(nrm[low][:, [1, 0]])) * np.where(nrm[low, :2] >= 0, 1.0, -1.0)
    nrm /= np.linalg.norm(nrm, axis=1)[:, None]
    nrm = nrm @ MAP_FRAME
    anchors = np.repeat(centre[None], len(nrm), 0)
    want = interpolate(g, centre + r * nrm, nrm, anchors, bvh, lights)
    assert np.allclose(m.reshape(-1, 3), want, rtol=1e-4, atol=1e-5)
    assert m.max() > 2.0   # the sun (3 W/m^2 facing it) is in it
    got = points_irradiance(g, centre + r * nrm, nrm, seen, lights)
    assert np.allclose(got, want, rtol=1e-4, atol=1e-5)


def test_lambert_s_formula_matches_the_lamp_s_integral():
    """lamp_factor (E / L of one lamp triangle, unshadowed) against the
    integral of cos_e cos_n / d^2 over the triangle (a fine midpoint rule):
    above it, beside it, clipped by the point's horizon, behind a one-sided
    lamp (0) and a double-sided one, and farther off (its quarters' and
    its own centroid as points)."""
    from baker.probes.lamps import lamp_factor, lamps_of
    tri = np.array([[[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]])   # its front +z

    def lamps(double):
        return lamps_of(tri, np.ones((1, 3)), np.array([double]))

    u = (np.arange(1500) + 0.5) / 1500
    a, b = np.meshgrid(u, u)
    inside = a + b < 1
    pts = np.stack([a[inside], b[inside], np.zeros(inside.sum())], axis=1)

    def integral(x, n):
        d = pts - x
        r = np.linalg.norm(d, axis=1)
        w = d / r[:, None]
        return float((np.abs(w[:, 2]) * np.maximum(w @ n, 0) / r ** 2).sum() * 0.5 / len(pts))

    rng = np.random.default_rng(3)
    cases = [(np.array([0.3, 0.3, 0.05]), np.array([0.0, 0, 1])), (np.array([1.2, 0.2, 0.1]), np.array([-1.0, 0, 0])),
             (np.array([0.3, 0.2, 0.2]), np.array([1.0, 0, 0]))]
    for _ in range(12):
        n = rng.normal(size=3)
        cases.append((np.array([rng.uniform(-0.5, 1.5), rng.uniform(-0.5, 1.5), rng.uniform(0.05, 2)]),
                      n / np.linalg.norm(n)))
    clipped = 0
    for x, n in cases:
        want = integral(x, n)
        got = lamp_factor(lamps(False), 0, *x, *n)
        assert abs(got - want) <= 0.005 * want + 1e-6, (x, n, got, want)
        h = (tri[0] - x) @ n
        clipped += bool((h > 0).any() and (h < 0).any())
    assert clipped >= 3, clipped   # the horizon cut the triangle in several of the cases
    behind = np.array([0.2, 0.2, -1.0])
    assert lamp_factor(lamps(False), 0, *behind, 0.0, 0.0, 1.0) == 0.0
    want = integral(behind, np.array([0.0, 0, 1]))
    assert abs(lamp_factor(lamps(True), 0, *behind, 0.0, 0.0, 1.0) - want) <= 0.005 * want
    # on the lamp's corner, edge, plane and centre, a sliver of a triangle: finite, never negative
    sliver = lamps_of(np.array([[[0.0, 0, 0], [1, 0, 0], [0.5, 1e-12, 0]]]), np.ones((1, 3)), np.array([0.0]))
    for lamp in (lamps(False), lamps(True), sliver):
        for x in ((0.0, 0, 0), (0.5, 0, 0), (0.3, 0.3, 0), (2.0, 2.0, 0), (0.25, 0.25, 1e-15)):
            for n in ((0.0, 0, 1), (0.0, 0, -1), (1.0, 0, 0)):
                f = lamp_factor(lamp, 0, *x, *n)
                assert np.isfinite(f) and f >= 0, (x, n, f)
    # farther off, four points (from MID longest edges) and one (from FAR): within 1% of the lamp's peak there,
    # A cos_e / d^2, whatever the normal (near its horizon the value itself is small)
    from baker.probes.lamps import FAR, MID
    edge, centre = np.sqrt(2.0), tri[0].mean(axis=0)
    for q in (MID * 1.05, 0.5 * (MID + FAR), FAR * 1.05, 3 * FAR):
        for _ in range(40):
            d = rng.normal(size=3)
            d[2] = abs(d[2])
            d /= np.linalg.norm(d)
            n = rng.normal(size=3)
            n /= np.linalg.norm(n)
            x = centre + q * edge * d
            peak = 0.5 * d[2] / (q * edge) ** 2
            assert abs(lamp_factor(lamps(False), 0, *x, *n) - integral(x, n)) <= 0.01 * peak, (q, d, n)


@pytest.mark.slow
def test_the_lamp_is_exact_beside_it_not_between_probes(cornell):
    """The Cornell lamp comes out of the probes and in at each point
    (Lambert's formula behind its shadow rays). The box black, so that all
    the light is the lamp's: points 1.5 cm under the ceiling, inside,
    beside and past the lamp's edge (x = 0.343), between probes 0.1 apart,
    against the path tracer for the 14 normals: within 8% (plus 2% of the
    point's brightest: the normals that see no lamp read 0; all but one
    within 2%, the one 6%: a normal that sees the lamp's edge from far out,
    where the probes' residue, their sampled lamp less Lambert's formula,
    about 1% of the lamp's light at a probe, stands out), where the probes
    alone, which cannot hold the lamp's near field, are off by more than
    half; and with the box's own colours the same points within 15%
    (the bounced light, which this test's coarse solve holds up to 17%
    bright under the ceiling: the per-pixel accuracy issue's)."""
    from dataclasses import replace
    from baker.probes.sample import probe_lights
    from baker.scene.prepared import prepare
    black = replace(cornell, materials=tuple(replace(m, albedo=np.zeros(3, np.float32)) for m in cornell.materials))
    n = len(CUBE_NORMALS)
    for scene, bound in ((black, 0.08), (cornell, 0.15)):
        g = bake_scene(scene, small(probe_spacing=0.1)).bake.probes
        prepared = prepare(scene)
        lights = probe_lights(g, prepared)
        assert lights.count == 2 and len(lights.lamps.corners) == 2
        worst = {"exact": 0.0, "probes": 0.0}
        for x in (0.30, 0.335, 0.35, 0.37):
            p = np.array([x, 0.5328, 0.28])
            want = path_traced_irradiance(prepared, p, CUBE_NORMALS, 16384, 1).sum(axis=1)
            pts = np.repeat(p[None], n, 0)
            for key, lt in (("exact", lights), ("probes", None)):
                got = interpolate(g, pts, CUBE_NORMALS, pts, prepared.bvh.arrays, lt).sum(axis=1)
                worst[key] = max(worst[key], float((np.abs(got - want) / (want + 0.02 * want.max())).max()))
        assert worst["exact"] < bound and worst["probes"] > 0.5, (bound, worst)
