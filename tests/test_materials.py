"""Alpha-masked surfaces and thin glass: read from glTF and MTL, passed by
every ray query, the photons and the voxels, against the analytic shadow
and the path tracer."""
import io

import numpy as np
import pytest

from baker import load_scene
from baker.lights import Lights, VPLs, build_lights, irradiance
from baker.presets import lightcuts_config, solver_config
from baker.render.frame import RenderSettings, render_frame
from baker.scene import Sky, camera_for, prepare
from baker.solve import solve
from scenes.generate import GltfBuilder, quad

N_CHECK = 8        # the leaf's alpha texture: N_CHECK x N_CHECK texels, alternately cut out
SUN = 3.0          # W/m^2 on a surface facing it
TINT = (0.8, 0.7, 0.6)


def _png(rgba):
    from PIL import Image
    buf = io.BytesIO()
    Image.fromarray(rgba, "RGBA").save(buf, format="PNG")
    return buf.getvalue()


def _checker(clear=False):
    a = ((np.arange(N_CHECK)[:, None] + np.arange(N_CHECK)[None, :]) % 2 * 255).astype(np.uint8)
    if clear:
        a[:] = 0
    rgba = np.full((N_CHECK, N_CHECK, 4), 200, np.uint8)
    rgba[..., 3] = a
    return rgba


def leaf_card(clear=False):
    """A grey floor, a 1 x 1 leaf card 1 m above it with a checkerboard alpha
    mask (or an all-clear one), a sun straight overhead."""
    b = GltfBuilder()
    b.mesh("floor", *quad((-2, 0, -2), (2, 0, -2), (2, 0, 2), (-2, 0, 2), facing=(0, 1, 0)),
           b.material("floor", (0.5, 0.5, 0.5)))
    tex = b.texture(b.image(_png(_checker(clear))), linear_filter=False, clamp=False)
    card = b.material("leaf", (1, 1, 1), double_sided=True, texture=tex, alpha_cutoff=0.5)
    pos = np.array([(-0.5, 1, -0.5), (0.5, 1, -0.5), (0.5, 1, 0.5), (-0.5, 1, 0.5)])
    # texel (i, j) of the mask over x = -0.5 + (i + 0.5) / N, z = -0.5 + (j + 0.5) / N
    b.mesh("card", pos, np.array([[0, 2, 1], [0, 3, 2]]), card, uvs=(pos[:, [0, 2]] + 0.5).astype(np.float32))
    b.light("sun", "directional", intensity=SUN, direction=(0, -1, 0))
    b.camera("down", (0.3, 2.5, 1.6), (-0.2, -1, -0.8), up=(0, 1, 0), yfov_deg=60)
    return b


def glass_room(glass=True, transmission=1.0):
    """A closed 4 x 2 x 4 room whose ceiling has a 1 x 1 opening, glazed
    with thin glass (or open), under a sun and a sky."""
    b = GltfBuilder()
    wall = b.material("wall", (0.6, 0.6, 0.6))
    h = 2.0
    b.mesh("floor", *quad((-2, 0, -2), (2, 0, -2), (2, 0, 2), (-2, 0, 2), facing=(0, 1, 0)), wall)
    for name, q in [("north", ((-2, 0, -2), (2, 0, -2), (2, h, -2), (-2, h, -2))),
                    ("south", ((-2, 0, 2), (2, 0, 2), (2, h, 2), (-2, h, 2))),
                    ("west", ((-2, 0, -2), (-2, 0, 2), (-2, h, 2), (-2, h, -2))),
                    ("east", ((2, 0, -2), (2, 0, 2), (2, h, 2), (2, h, -2)))]:
        inward = -np.mean(q, axis=0)
        inward[1] = 0
        b.mesh(name, *quad(*q, facing=inward), wall)
    for q in [((-2, h, -2), (2, h, -2), (2, h, -0.5), (-2, h, -0.5)),
              ((-2, h, 0.5), (2, h, 0.5), (2, h, 2), (-2, h, 2)),
              ((-2, h, -0.5), (-0.5, h, -0.5), (-0.5, h, 0.5), (-2, h, 0.5)),
              ((0.5, h, -0.5), (2, h, -0.5), (2, h, 0.5), (0.5, h, 0.5))]:
        b.mesh("ceiling", *quad(*q, facing=(0, -1, 0)), wall)
    if glass:
        pane = b.material("glass", TINT, double_sided=True, transmission=transmission)
        b.mesh("pane", *quad((-0.5, h, -0.5), (0.5, h, -0.5), (0.5, h, 0.5), (-0.5, h, 0.5), facing=(0, -1, 0)), pane)
    b.light("sun", "directional", intensity=5.0, direction=(0.3, -1, 0.2))
    b.camera("view", (1.8, 1.6, 1.8), (-1, -0.6, -1), yfov_deg=70)
    return b


# -- reading -------------------------------------------------------------------------------------------------------

def test_gltf_mask_and_transmission_are_read(make_scene):
    scene = make_scene(leaf_card(), "mat_leaf")
    leaf = scene.materials[1]
    assert leaf.masked and leaf.alpha_cutoff == 0.5 and leaf.alpha == 1.0
    assert leaf.opacity.shape == (N_CHECK, N_CHECK)
    assert np.allclose(leaf.opacity, _checker()[..., 3] / 255.0)
    assert scene.uvs is not None   # the floor has none; the card's are kept (zeros for the floor)
    room = make_scene(glass_room(transmission=0.75), "mat_room_075")
    glass = [m for m in room.materials if m.name == "glass"][0]
    assert glass.transmission == 0.75 and not glass.masked
    assert not any("transmission" in w or "alpha" in w for w in room.warnings + scene.warnings)


def test_mtl_dissolve_is_transmission(tmp_path):
    (tmp_path / "m.mtl").write_text("newmtl glass\nKd 0.9 0.9 0.9\nd 0.25\nnewmtl tr\nKd 1 1 1\nTr 0.4\n"
                                    "newmtl wall\nKd 0.5 0.5 0.5\n")
    (tmp_path / "s.obj").write_text("mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nusemtl glass\nf 1 2 3\n"
                                    "usemtl tr\nf 1 3 4\nusemtl wall\nf 1 2 4\n")
    scene = load_scene(str(tmp_path / "s.obj"))
    t = {m.name: m.transmission for m in scene.materials}
    assert t == {"glass": 0.75, "tr": 0.4, "wall": 0.0}


# -- ray queries ---------------------------------------------------------------------------------------------------

def test_rays_pass_cut_out_texels_and_glass_tints_shadow_rays(make_scene):
    scene = make_scene(leaf_card(), "mat_leaf")
    bvh = prepare(scene).bvh
    xs = -0.5 + (np.arange(N_CHECK) + 0.5) / N_CHECK
    o = np.array([[x, 2.0, z] for z in xs for x in xs])
    d = np.tile([0.0, -1.0, 0.0], (len(o), 1))
    t, tri, u, v = bvh.closest(o, d)
    on_card = np.isclose(t, 1.0)
    assert on_card.sum() == N_CHECK * N_CHECK // 2 and np.isclose(t[~on_card], 2.0).all()
    ij = np.floor((o[:, [0, 2]] + 0.5) * N_CHECK).sum(axis=1) % 2
    assert np.array_equal(on_card, ij == 1)
    blocked = bvh.occluded(o, d, 0.0, 1.5)
    assert np.array_equal(blocked, on_card)
    assert np.array_equal(bvh.transmitted(o, d, 0.0, 1.5)[:, 0], (~on_card).astype(float))
    clear = prepare(make_scene(leaf_card(clear=True), "mat_leaf_clear")).bvh
    assert not clear.occluded(o, d, 0.0, 1.5).any()

    room = prepare(make_scene(glass_room(transmission=0.75), "mat_room_075")).bvh
    o = np.array([[0.0, 1.0, 0.0], [0.0, 1.0, 1.0]])
    up = np.tile([0.0, 1.0, 0.0], (2, 1))
    tr = room.transmitted(o, up)
    assert np.allclose(tr[0], 0.75 * np.asarray(TINT, np.float32)) and np.array_equal(tr[1], np.zeros(3))
    assert room.occluded(o, up).all()   # any hit: glass is a surface (the caller decides)


# -- against the analytic shadow and the path tracer -------------------------------------------------------------

def test_masked_card_casts_its_checkerboard_shadow(make_scene):
    """Direct sun straight down through the card: the floor's irradiance
    under each texel is SUN where the texel is cut out and only the
    (small) indirect light where it is not; with an all-clear mask, SUN
    everywhere (no shadow at all)."""
    scene = make_scene(leaf_card(), "mat_leaf")
    prepared = prepare(scene)
    sol = solve(prepared, solver_config("preview", resolution=24, photons=50_000))
    lights = build_lights(prepared, sol, lightcuts_config("preview"))
    # four points inside each texel's shadow, away from its edges
    q = (np.arange(N_CHECK)[:, None] + np.array([0.3, 0.7])[None, :]).ravel() / N_CHECK - 0.5
    pts = np.array([[x, 0.0, z] for z in q for x in q])
    nrm = np.tile([0.0, 1.0, 0.0], (len(pts), 1))
    h, _, _ = irradiance(lights, prepared.bvh, prepared.surfaces, pts, nrm, offset=1e-4)
    lit = ~prepared.bvh.occluded(pts + [0, 1e-4, 0], np.tile([0.0, 1.0, 0.0], (len(pts), 1)))
    assert lit.sum() == len(pts) // 2
    v = lights.vpls
    sun_only = Lights(VPLs(*(getattr(v, k)[:0] for k in ("kind", "position", "normal", "power", "area", "indirect"))),
                      None)
    direct, _, _ = irradiance(sun_only, prepared.bvh, prepared.surfaces, pts, nrm, offset=1e-4)
    assert np.array_equal(direct[:, 0], np.where(lit, SUN, 0.0))
    bounced = h[:, 0] - direct[:, 0]                            # light off the card's underside and back
    assert (bounced > 0).all() and (bounced < 0.1 * SUN).all()
    # the lit points are those under the mask's cut-out texels (alpha 0 where i + j is even)
    cell = (np.floor((pts[:, 0] + 0.5) * N_CHECK) + np.floor((pts[:, 2] + 0.5) * N_CHECK)) % 2
    assert np.array_equal(lit, cell == 0)
    clear = prepare(make_scene(leaf_card(clear=True), "mat_leaf_clear"))
    sol_c = solve(clear, solver_config("preview", resolution=24, photons=50_000))
    hc, _, _ = irradiance(build_lights(clear, sol_c, lightcuts_config("preview")), clear.bvh, clear.surfaces, pts,
                          nrm, offset=1e-4)
    assert np.allclose(hc, SUN, rtol=1e-9)


def _frame(scene, method, spp=64, size=48):
    p = prepare(scene)
    return render_frame(p, camera_for(scene, None, p.bvh),
                        RenderSettings(method=method, width=size, height=size, spp=spp,
                                       solver=solver_config("preview", resolution=24, photons=100_000),
                                       lightcuts=lightcuts_config("preview"))).image


def test_masked_card_frame_matches_the_path_tracer(make_scene):
    scene = make_scene(leaf_card(), "mat_leaf")
    pt, lc = _frame(scene, "pathtrace", 256), _frame(scene, "lightcuts")
    assert abs(lc.mean() / pt.mean() - 1) < 0.02


def test_glass_room_matches_the_path_tracer_and_scales_by_its_tint(make_scene):
    """Light enters the closed room only through the glazed opening: the
    room's mean and its sun patch as the path tracer shows them within 3%;
    glass that transmits everything tinted by TINT makes the room exactly
    TINT times the open room (it reflects nothing, and everything that
    enters passes it once)."""
    sky = Sky(np.full(3, 0.3))
    glazed = make_scene(glass_room(), "mat_room").with_lights(sky=sky)
    open_ = make_scene(glass_room(glass=False), "mat_room_open").with_lights(sky=sky)
    pt, lc = _frame(glazed, "pathtrace", 512), _frame(glazed, "lightcuts")
    assert abs(lc.mean() / pt.mean() - 1) < 0.03
    patch = pt.mean(axis=2) > 0.5 * pt.mean(axis=2).max()
    assert patch.sum() > 20
    assert abs(lc[patch].mean() / pt[patch].mean() - 1) < 0.03
    lo = _frame(open_, "lightcuts")
    ratio = lc.reshape(-1, 3).sum(axis=0) / lo.reshape(-1, 3).sum(axis=0)
    assert np.allclose(ratio, np.asarray(TINT, np.float32), rtol=0.01)


@pytest.mark.parametrize("name", ["leaf", "room"])
def test_bake_keeps_masks_and_glass(make_scene, tmp_path, name):
    from baker.bake import read_bake, write_bake
    from baker.bake.pipeline import bake_scene
    from baker.presets import bake_config
    scene = make_scene(leaf_card(), "mat_leaf") if name == "leaf" else make_scene(glass_room(), "mat_room")
    result = bake_scene(scene, bake_config("preview", resolution=16, photons=20_000))
    write_bake(tmp_path / "b.glb", result.bake)
    back = read_bake(tmp_path / "b.glb").scene
    if name == "leaf":
        leaf = [m for m in back.materials if m.name.startswith("leaf")][0]
        assert leaf.masked and leaf.alpha_cutoff == 0.5
        assert np.array_equal(np.rint(leaf.opacity * 255), _checker()[..., 3])
    else:
        glass = [m for m in back.materials if m.name.startswith("glass")][0]
        assert glass.transmission == 1.0
    # our viewer shows it as the CPU view of the bake does: cut-out texels and glass see through
    from baker.bake import render_bake
    from viewer.context import headless_context
    from viewer.snapshot import snapshot
    bake = read_bake(tmp_path / "b.glb")
    ctx = headless_context()
    try:
        gpu = snapshot(bake, 0, 64, 64, ctx=ctx)
    finally:
        ctx.release()
    cpu = render_bake(bake, 0, 64, 64)
    assert abs(gpu.mean() / cpu.mean() - 1) < 0.01
    assert np.percentile(np.abs(gpu - cpu) / np.maximum(cpu, 1e-3), 95) < 0.01


LAMP_L = 2.0   # the lamp's emissive factor: its texture is white (1) on x < 0, black (0) on x > 0


def half_lit_lamp():
    """A 1 x 1 lamp 1 m over a grey floor, facing down, black (it reflects
    nothing back), its emissive texture 16 x 2 texels, white over x < 0 and
    black over x > 0 (each of its two triangles spans both halves); a
    camera below it, looking along +z, that sees the lamp (x < 0 on the
    right of the image) and the floor."""
    b = GltfBuilder()
    b.mesh("floor", *quad((-3, 0, -3), (3, 0, -3), (3, 0, 3), (-3, 0, 3), facing=(0, 1, 0)),
           b.material("floor", (0.5, 0.5, 0.5)))
    rgba = np.zeros((2, 16, 4), np.uint8)
    rgba[..., 3] = 255
    rgba[:, :8, :3] = 255
    tex = b.texture(b.image(_png(rgba)), linear_filter=False, clamp=False)
    pos, tris = quad((-0.5, 1, -0.5), (0.5, 1, -0.5), (0.5, 1, 0.5), (-0.5, 1, 0.5), facing=(0, -1, 0))
    uvs = np.stack([pos[:, 0] + 0.5, pos[:, 2] + 0.5], axis=1).astype(np.float32)
    b.mesh("lamp", pos, tris, b.material("lamp", (0.0,) * 3, emission=(LAMP_L,) * 3, emissive_texture=tex), uvs=uvs)
    b.camera("below", (0.0, 0.1, -2.0), (0.0, 0.45, 1.0), (0.0, 1.0, 0.0), 60.0, 1.0)
    return b


def test_emissive_texture_emits_its_pattern(make_scene, tmp_path):
    """The lamp emits only its white half: the exact irradiance under it is
    that of the rectangle [-0.5, 0] x [-0.5, 0.5] of radiance L, and the
    photons, the direct VPLs and the path tracer all give it (no pattern:
    the whole lamp at L / 2 would light x = +0.25 as much as x = -0.25).
    The bake file carries the texture, and our viewer shows it as the CPU
    view of the bake does."""
    from baker.lights.vpl import direct_vpls
    from baker.scene import build_scene_bvh, pack
    from tests.naive import irradiance_under_rectangle
    from tests.test_pathtrace import point_radiance
    scene = make_scene(half_lit_lamp(), "mat_lamp")
    lamp = [m for m in scene.materials if m.name == "lamp"][0]
    assert lamp.emission_texture is not None
    exact = lambda x, z: irradiance_under_rectangle(LAMP_L, -0.5, 0.0, -0.5, 0.5, 1.0, x, z)  # noqa: E731
    surf = pack(scene)
    assert np.allclose(surf.emitted_power, np.pi * LAMP_L * 0.5, rtol=0.02)  # pi L x the lit half's area
    # direct VPLs: only on the white half, their power the lit half's
    v = direct_vpls(surf, 8192, seed=1)
    lit = v.power[:, 0] > 0
    assert np.all(v.position[lit, 0] <= 1e-9) and np.all(v.position[~lit, 0] >= -1e-9)
    assert v.power[:, 0].sum() == pytest.approx(np.pi * LAMP_L * 0.5, rel=0.01)
    bvh = build_scene_bvh(scene)
    pts = np.array([[-0.25, 0.0, 0.0], [0.25, 0.0, 0.0], [1.0, 0.0, 0.3], [-1.2, 0.0, -0.6]])
    ref = np.array([exact(x, z) for x, _, z in pts])
    H, _, _ = irradiance(Lights(v, None), bvh, surf, pts, np.tile([0.0, 1.0, 0.0], (len(pts), 1)), brute=True)
    np.testing.assert_allclose(H[:, 0], ref, rtol=0.02)
    # photons: the floor's voxels within 1.5 m of the lamp against the exact irradiance at their centroids
    sol = solve(scene, solver_config("default", resolution=32, photons=2_000_000, max_bounces=1))
    vox = sol.voxels
    floor = (np.abs(vox.normal[:, 1] - 1) < 1e-6) & (np.abs(vox.centroid[:, 0]) < 1.5) & \
        (np.abs(vox.centroid[:, 2]) < 1.5) & (vox.area > 0.99 * vox.cell_size ** 2)
    want = np.array([exact(x, z) for x, _, z in vox.centroid[floor]])
    got = sol.irradiance[floor, 0]
    assert abs(got.sum() / want.sum() - 1) < 0.02
    for side in (vox.centroid[floor, 0] < -0.1, vox.centroid[floor, 0] > 0.1):
        assert abs(got[side].sum() / want[side].sum() - 1) < 0.03
    # the path tracer: the floor's radiance rho / pi x H
    for p, e in zip(pts, ref):
        est = point_radiance(scene, p, 20000, seed=4)[:, 0]
        assert abs(est.mean() - 0.5 / np.pi * e) < 4 * est.std(ddof=1) / np.sqrt(est.size) + 1e-9, (p, est.mean())
    # the bake file keeps the texture; the viewer and the CPU view of the bake agree, the lamp half lit
    from baker.bake import read_bake, render_bake, write_bake
    from baker.bake.pipeline import bake_scene
    from baker.presets import bake_config
    from viewer.context import headless_context
    from viewer.snapshot import snapshot
    result = bake_scene(scene, bake_config("preview", resolution=16, photons=50_000))
    write_bake(tmp_path / "lamp.glb", result.bake)
    bake = read_bake(tmp_path / "lamp.glb")
    back = [m for m in bake.scene.materials if m.name.startswith("lamp")][0]
    assert back.emission_texture is not None and np.allclose(back.emission_texture, lamp.emission_texture, atol=1e-3)
    cpu = render_bake(bake, 0, 64, 64)
    ctx = headless_context()
    try:
        gpu = snapshot(bake, 0, 64, 64, ctx=ctx)
    finally:
        ctx.release()
    assert abs(gpu.mean() / cpu.mean() - 1) < 0.01
    assert np.percentile(np.abs(gpu - cpu) / np.maximum(cpu, 1e-3), 95) < 0.01
    # the lamp's white half: right of the image's centre (the texture repeats: bilinear lookups within half a
    # texel of the lamp's far edge blend in the first column, up to half white)
    bright = cpu[..., 0] > 0.75 * LAMP_L
    assert cpu.max() == pytest.approx(LAMP_L, rel=1e-3) and bright.sum() > 50
    assert np.nonzero(bright)[1].min() >= 31


@pytest.mark.parametrize("edit, message", [
    (lambda m: m.extensions.update({"KHR_materials_transmission": {"transmissionFactor": 2.0}}), "above 1"),
    (lambda m: m.extensions.update({"KHR_materials_transmission": {"transmissionFactor": "x"}}), "transmissionFactor"),
    (lambda m: setattr(m, "alphaCutoff", -1.0), "alphaCutoff"),
    (lambda m: setattr(m.pbrMetallicRoughness, "baseColorFactor", [1, 1, 1, -0.5]), "alpha"),
])
def test_crafted_glass_and_mask_values_are_refused_in_one_line(tmp_path, edit, message):
    from baker.errors import SceneError
    b = leaf_card()
    leaf = b.doc.materials[1]
    leaf.extensions = leaf.extensions or {}
    edit(leaf)
    path = tmp_path / "bad.glb"
    b.save(path)
    with pytest.raises(SceneError, match=message) as e:
        load_scene(str(path))
    assert "\n" not in str(e.value)
