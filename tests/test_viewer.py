"""The viewer: shaders, the camera's maths, headless snapshots against the
CPU render of the same bake, golden images of every view, bad input, and a
real window under Xvfb with scripted input.

Goldens: tests/golden/cornell_preview.glb is a committed bake (so the
goldens test the viewer, not the solver); the linear EXR snapshots beside
it are compared per pixel. VOXGI_UPDATE_GOLDEN=1 rewrites them; a failure
writes actual, expected and difference images to the test's folder."""
import json
import os
import subprocess
import sys

import numpy as np
import pytest

from baker.bake import read_bake, render_bake
from baker.render import read_exr, write_image
from viewer.camera import Controls, FlyCamera, look_at, perspective
from viewer.renderer import MODES

from .conftest import need_xvfb

HERE = os.path.dirname(os.path.abspath(__file__))
GOLDEN = os.path.join(HERE, "golden")
BAKE = os.path.join(GOLDEN, "cornell_preview.glb")


@pytest.fixture(scope="module")
def ctx():
    from viewer.context import headless_context
    c = headless_context()
    yield c
    c.release()


@pytest.fixture(scope="module")
def bake():
    return read_bake(BAKE)


def test_every_shader_builds(ctx):
    import shaders
    from viewer.context import build_program
    pairs = sorted({n.rsplit(".", 1)[0] for n in shaders.names() if n.endswith(".vert")})
    assert {"lightmap", "overlay"} <= set(pairs)
    for name in pairs:
        build_program(ctx, name + ".vert", name + ".frag").release()


def test_the_shaders_tone_curve_is_the_images_within_an_8bit_level(ctx):
    """tone.glsl (exposure, ACES, the sRGB curve by square roots) against
    baker.render.images' exact curves, over radiances from 1e-5 to 100
    into an 8-bit target: every value within one level, 97% on it. An
    error of 1% in the curve (or pow(x, 1 / 2.2) for it) fails."""
    import moderngl

    import shaders
    from baker.render.images import aces_filmic, linear_to_srgb
    n = 4096
    values = np.geomspace(1e-5, 100.0, n).astype(np.float32)
    frag = ("#version 330 core\nuniform sampler2D u_in;\nout vec4 f_color;\n" + shaders.source("tone.glsl")
            + "void main() { f_color = vec4(tone(vec3(texelFetch(u_in, ivec2(gl_FragCoord.xy), 0).r), 0.7), 1.0); }\n")
    prog = ctx.program(vertex_shader="#version 330 core\nvoid main() { vec2 p = vec2((gl_VertexID << 1) & 2, "
                                     "gl_VertexID & 2); gl_Position = vec4(2.0 * p - 1.0, 0.0, 1.0); }\n",
                       fragment_shader=frag)
    src = ctx.texture((n, 1), 1, values.tobytes(), dtype="f4")
    src.filter = (moderngl.NEAREST, moderngl.NEAREST)
    out = ctx.texture((n, 1), 4)
    fbo = ctx.framebuffer([out])
    try:
        fbo.use()
        ctx.viewport = (0, 0, n, 1)
        src.use(0)
        prog["u_in"].value = 0
        ctx.vertex_array(prog, []).render(moderngl.TRIANGLES, vertices=3)
        got = np.frombuffer(fbo.read(components=4), np.uint8).reshape(n, 4)[:, 0].astype(int)
    finally:
        for obj in (fbo, out, src, prog):
            obj.release()
    want = linear_to_srgb(aces_filmic(values.astype(np.float64) * 0.7)) * 255
    assert np.abs(got - want).max() <= 1.0
    assert np.mean(got == np.rint(want)) > 0.97


def test_the_window_view_is_the_snapshot_tone_mapped(ctx, bake):
    """The tone-mapped lightmap view (as the window draws it, 8 bits) is
    the linear one (as snapshots read it) through the images' display
    transform, within one level: the view's variants (tone curve, glass,
    emission) agree."""
    from baker.render.images import aces_filmic, linear_to_srgb
    from baker.scene import camera_for
    from viewer.renderer import Renderer
    r = Renderer(ctx, bake)
    cam = camera_for(bake.scene, None)
    w, h, exposure = 96, 96, 1.7
    shots = {}
    for tonemap, dtype in ((True, "f1"), (False, "f4")):
        color = ctx.renderbuffer((w, h), 4, dtype=dtype)
        depth = ctx.depth_renderbuffer((w, h))
        fbo = ctx.framebuffer([color], depth)
        fbo.use()
        fbo.clear(0.0, 0.0, 0.0, 1.0, depth=1.0)
        r.render(cam, w, h, exposure=exposure, tonemap=tonemap)
        raw = fbo.read(components=3, dtype=dtype)
        shots[tonemap] = np.frombuffer(raw, np.uint8 if tonemap else np.float32).reshape(h, w, 3)
        for obj in (fbo, color, depth):
            obj.release()
    r.release()
    want = linear_to_srgb(aces_filmic(np.maximum(shots[False].astype(np.float64), 0.0) * exposure)) * 255
    assert np.ptp(want) > 100   # a lit view, not a black one
    assert np.abs(shots[True] - want).max() <= 1.0


def test_camera_and_renderer_need_no_window():
    """The camera is pure maths (no GL at all); the renderer and snapshots
    take a context and never import glfw."""
    code = ("import sys, viewer.camera; assert 'moderngl' not in sys.modules and 'glfw' not in sys.modules; "
            "import viewer.renderer, viewer.snapshot, viewer.cli; assert 'glfw' not in sys.modules")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=os.path.dirname(HERE))
    assert r.returncode == 0, r.stderr


def test_camera_moves_by_speed_times_dt():
    from baker.scene.model import make_camera
    cam = FlyCamera.from_camera(make_camera("c", (1, 2, 3), (0.3, -0.2, -1), (0, 1, 0), 0.8), speed=2.0)
    assert np.allclose(cam.forward, np.array([0.3, -0.2, -1]) / np.linalg.norm([0.3, -0.2, -1]))
    moved = cam.step(0.5, Controls(move=(1, 0, 0)))
    assert np.allclose(np.subtract(moved.position, cam.position), cam.forward * 1.0)
    fast = cam.step(0.5, Controls(move=(0, 1, 0), fast=True))
    assert np.allclose(np.subtract(fast.position, cam.position), cam.right * 4.0)
    # the same motion in ten steps of a tenth: frame-rate independent
    c = cam
    for _ in range(10):
        c = c.step(0.05, Controls(move=(1, -1, 1)))
    once = cam.step(0.5, Controls(move=(1, -1, 1)))
    assert np.allclose(c.position, once.position)
    # looking: yaw by dx * sensitivity, pitch clamped short of the pole; zoom by the wheel
    turned = cam.step(0.0, Controls(look=(100, 0)))
    assert turned.yaw == pytest.approx(cam.yaw + 100 * cam.sensitivity) and turned.position == cam.position
    up = cam.step(0.0, Controls(look=(0, -1e6)))
    assert np.degrees(up.pitch) == pytest.approx(89.0)
    assert cam.step(0.0, Controls(scroll=2)).yfov == pytest.approx(cam.yfov / 1.21)
    # the frame stays orthonormal and the view matrix maps the camera to the origin looking down -Z
    v = look_at(cam.position, cam.forward, cam.up)
    assert np.allclose(v[:3, :3] @ v[:3, :3].T, np.eye(3))
    assert np.allclose(v @ np.append(cam.position, 1), [0, 0, 0, 1])
    assert np.allclose((v @ np.append(np.add(cam.position, cam.forward), 1))[:3], [0, 0, -1])
    p = perspective(cam.yfov, 1.5, 0.1, 10)
    for z in (0.1, 10):  # near and far planes map to -1 and 1
        q = p @ [0, 0, -z, 1]
        assert q[2] / q[3] == pytest.approx(-1 if z == 0.1 else 1)


def test_snapshot_matches_the_cpu_render(ctx, bake):
    """The GPU's lightmap view and the CPU render of the same bake and
    camera, 4 x 4 samples per pixel at the same points: mean within 0.1%,
    99% of the pixels within 0.1% (measured: mean 1.00002, 99th percentile
    8e-6; the rest are pixels where rasterizer and rays split an edge)."""
    from viewer.snapshot import snapshot
    gpu = snapshot(bake, 0, 96, 96, ctx=ctx)
    cpu = render_bake(bake, 0, 96, 96)
    assert gpu.shape == cpu.shape and np.isfinite(gpu).all() and gpu.min() >= 0
    assert abs(gpu.mean() / cpu.mean() - 1) < 1e-3
    rel = np.abs(gpu - cpu) / np.maximum(cpu, 1e-3)
    assert np.percentile(rel, 99) < 1e-3


def test_the_view_shows_the_sky_the_bake_was_lit_by(ctx, make_scene, tmp_path):
    """A floor and a glass pane under a sky over the upper hemisphere, seen
    across the horizon: read back, the bake keeps its sky; the CPU view
    shows exactly the sky's radiance where a ray meets nothing above the
    horizon, nothing below it, the sky times the pane's tint through the
    pane (as the path tracer); the GPU snapshot draws the same (mean within
    0.1%, 99% of the pixels within 0.1%)."""
    from dataclasses import replace
    from baker.bake import bake_config, bake_scene, write_bake
    from baker.scene import Sky
    from scenes.generate import GltfBuilder, quad
    from viewer.snapshot import snapshot
    b = GltfBuilder()
    b.mesh("floor", *quad((-2, 0, -2), (2, 0, -2), (2, 0, 2), (-2, 0, 2), facing=(0, 1, 0)),
           b.material("white", (0.6,) * 3))
    glass = b.material("glass", (0.5, 0.8, 1.0), transmission=1.0)
    b.mesh("pane", *quad((0.2, 0.3, -1), (1.5, 0.3, -1), (1.5, 2.0, -1), (0.2, 2.0, -1), facing=(0, 0, 1)), glass)
    b.camera("view", (0, 0.4, 1.5), (0, -0.02, -1), yfov_deg=90)
    sky = Sky(np.array([0.8, 1.0, 1.3]), True)
    scene = replace(make_scene(b, "sky_view"), sky=sky)
    write_bake(tmp_path / "s.glb", bake_scene(scene, bake_config("preview", resolution=16, photons=20_000)).bake)
    back = read_bake(tmp_path / "s.glb")
    assert np.array_equal(back.scene.sky.radiance, sky.radiance) and back.scene.sky.hemisphere
    s = 64
    cpu = render_bake(back, 0, s, s)
    assert np.allclose(cpu[s // 3, s // 4], sky.radiance, rtol=1e-6)          # above the horizon, beside the pane
    assert np.allclose(cpu[s // 3, 3 * s // 4], sky.radiance * [0.5, 0.8, 1.0], rtol=1e-6)   # through the pane
    below = cpu[s // 2 + 1:, 0]   # below the horizon, past the floor's far corner: nothing
    assert (below == 0).all(axis=1).any() and cpu.min() >= 0
    gpu = snapshot(back, 0, s, s, ctx=ctx)
    assert abs(gpu.mean() / cpu.mean() - 1) < 1e-3
    rel = np.abs(gpu - cpu) / np.maximum(cpu, 1e-3)
    assert np.percentile(rel, 99) < 1e-3


@pytest.mark.parametrize("mode", MODES)
def test_golden_snapshots(ctx, bake, mode, tmp_path):
    """Each view of the committed Cornell bake against its golden EXR:
    per pixel within 1e-3 relative (+1e-5 absolute): llvmpipe renders the
    same bits run after run; the margin is for another Mesa build's
    rounding."""
    from viewer.snapshot import snapshot
    img = snapshot(bake, 0, 64, 64, mode=mode, ctx=ctx)
    path = os.path.join(GOLDEN, f"cornell_{mode}.exr")
    if os.environ.get("VOXGI_UPDATE_GOLDEN") == "1" or not os.path.exists(path):
        write_image(path, img)
        if os.environ.get("VOXGI_UPDATE_GOLDEN") != "1":
            pytest.fail(f"no golden image {path}: written now, check it and commit it")
    expected = read_exr(path)
    bad = np.abs(img - expected) > 1e-3 * np.abs(expected) + 1e-5
    if bad.any():
        for name, im in (("actual", img), ("expected", expected), ("difference", np.abs(img - expected))):
            write_image(tmp_path / f"{mode}_{name}.exr", im)
        pytest.fail(f"{int(bad.any(axis=2).sum())} pixels differ from {path}; images in {tmp_path}")


def voxview(*args, env=None, timeout=300):
    return subprocess.run([sys.executable, "-m", "viewer", *map(str, args)], capture_output=True, text=True,
                          timeout=timeout, env=env)


def test_bad_bake_files_are_one_line_errors(tmp_path):
    data = open(BAKE, "rb").read()
    (tmp_path / "truncated.glb").write_bytes(data[:len(data) // 3])
    altered = bytearray(data)
    altered[-50] ^= 1
    (tmp_path / "altered.glb").write_bytes(bytes(altered))
    cases = [(tmp_path / "missing.glb", "file not found"), (tmp_path / "truncated.glb", "truncated"),
             (tmp_path / "altered.glb", "checksum"),
             (os.path.join(os.path.dirname(HERE), "scenes", "cornell_box.glb"), "not a voxgi bake")]
    for path, message in cases:
        for args in (["snapshot", path, "-o", tmp_path / "x.png"], [path, "--frames", "1"]):
            r = voxview(*args)
            assert r.returncode == 2 and message in r.stderr, (args, r.stderr)
            assert "Traceback" not in r.stderr and len(r.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "x.png").exists()


def test_snapshot_command_writes_png_and_exr(tmp_path):
    for name in ("shot.png", "shot.exr"):
        r = voxview("snapshot", BAKE, "-o", tmp_path / name, "--width", 48, "--height", 32, "--mode", "checker")
        assert r.returncode == 0, r.stderr
    img = read_exr(tmp_path / "shot.exr")
    assert img.shape == (32, 48, 3) and img.max() > 0
    r = voxview("snapshot", BAKE, "-o", tmp_path / "p.png", "--mode", "preview", "--frames", "4", "--width", "32",
                "--height", "32")
    assert r.returncode == 0 and (tmp_path / "p.png").exists(), r.stderr


def test_real_window_under_xvfb(tmp_path, bake):
    """A glfw window on a virtual X display takes scripted key, drag and
    wheel events (through the same handlers as glfw's callbacks), renders
    frames and saves the last one: walking forward changes the picture
    (the view is nearer the back wall: brighter in the middle)."""
    need_xvfb()
    script = [{"frame": 1, "key": "W", "action": "press"}, {"frame": 8, "key": "W", "action": "release"},
              {"frame": 9, "drag": [30, 0]}, {"frame": 10, "scroll": 1}, {"frame": 11, "key": "F2"},
              {"frame": 12, "key": "F1"}]
    (tmp_path / "walk.json").write_text(json.dumps(script))
    (tmp_path / "still.json").write_text("[]")
    shots = {}
    for name in ("walk", "still"):
        out = tmp_path / f"{name}.png"
        r = subprocess.run(["xvfb-run", "-a", "-s", "-screen 0 800x600x24", sys.executable, "-m", "viewer", BAKE,
                            "--script", tmp_path / f"{name}.json", "--frames", "16", "--screenshot", out,
                            "--width", "320", "--height", "240", "--exposure", "1"],
                           capture_output=True, text=True, timeout=300)
        assert r.returncode == 0, r.stderr
        assert "16 frames" in r.stdout
        from PIL import Image
        shots[name] = np.asarray(Image.open(out).convert("RGB"), float)
        assert shots[name].shape == (240, 320, 3) and shots[name].mean() > 20
    assert np.abs(shots["walk"] - shots["still"]).mean() > 5


def test_gpu_preview_converges_to_the_cpu_instant_radiosity(ctx, bake):
    """The viewer's progressive preview (cube shadow maps per VPL) against
    the CPU's instant radiosity over the same ordered list, 64 frames of 16
    VPLs, at the pixels' centres: mean within 2%, relative RMSE below 5%
    (measured 0.993 and 1.8% at 64 x 64; what differs is the shadow maps'
    resolution and bias against exact shadow rays)."""
    from baker.render import camera_array
    from baker.render.instant_radiosity import render_instant_radiosity
    from baker.scene import build_scene_bvh, load_scene, pack
    from viewer.snapshot import snapshot
    assert bake.vpls is not None and len(bake.vpls) >= 1024
    s = 48
    gpu = snapshot(bake, 0, s, s, mode="preview", frames=64, ctx=ctx)
    scene = load_scene("cornell_box")
    bvh, surf = build_scene_bvh(scene), pack(scene)
    cpu, st = render_instant_radiosity(bvh, surf, bake.vpls, camera_array(bake.scene.cameras[0], s, s), s, s, 16, 64)
    lum = np.array([0.2126, 0.7152, 0.0722])
    a, c = gpu @ lum, cpu @ lum
    lit = (c > 0) & (c < 0.5 * c.max())
    assert abs(a[lit].mean() / c[lit].mean() - 1) < 0.02
    assert np.sqrt(np.mean((a[lit] - c[lit]) ** 2)) / c[lit].mean() < 0.05


def test_gpu_preview_punctual_lights_and_sky(ctx, make_scene, tmp_path):
    """A floor with a box under a point light, a spot, a sun and a sky: the
    GPU preview (cube maps for the point and spot, orthographic maps for the
    sun and the sky's directions) against the CPU's instant radiosity over
    the same list: mean within 3%, relative RMSE below 10% (shadow maps at
    their edges against exact rays; measured 0.999 and 0.6%)."""
    from baker.bake import bake_config, bake_scene, write_bake
    from baker.render import camera_array
    from baker.render.instant_radiosity import render_instant_radiosity
    from baker.scene import Sky, build_scene_bvh, pack
    from dataclasses import replace
    from scenes.generate import GltfBuilder, box, quad
    from viewer.snapshot import snapshot
    b = GltfBuilder()
    w = b.material("white", (0.6,) * 3)
    b.mesh("floor", *quad((-2, 0, -2), (2, 0, -2), (2, 0, 2), (-2, 0, 2), facing=(0, 1, 0)), w)
    b.mesh("box", *box((-0.4, 0, -0.4), (0.4, 0.6, 0.4)), w)
    b.light("bulb", "point", intensity=3.0, position=(0.8, 1.5, 0.6))
    b.light("spot", "spot", intensity=6.0, position=(-1.0, 1.8, 0.8), direction=(0.3, -1, -0.2), outer_deg=35)
    b.light("sun", "directional", intensity=2.0, direction=(-0.4, -1, -0.3))
    b.camera("view", (0, 2.2, 3.2), (0, -0.6, -1))
    scene = replace(make_scene(b, "preview_punctual"), sky=Sky(np.array([0.3, 0.35, 0.4]), True))
    bake = bake_scene(scene, bake_config("preview", resolution=16, photons=50_000, preview_vpls=2048)).bake
    write_bake(tmp_path / "p.glb", bake)
    back = read_bake(tmp_path / "p.glb")
    s = 48
    gpu = snapshot(back, 0, s, s, mode="preview", frames=64, ctx=ctx)
    bvh, surf = build_scene_bvh(scene), pack(scene)
    cpu, _ = render_instant_radiosity(bvh, surf, back.vpls, camera_array(back.scene.cameras[0], s, s), s, s, 16, 64)
    lum = np.array([0.2126, 0.7152, 0.0722])
    a, c = gpu @ lum, cpu @ lum
    lit = c > 0
    assert lit.mean() > 0.5
    assert abs(a[lit].mean() / c[lit].mean() - 1) < 0.03, a[lit].mean() / c[lit].mean()
    assert np.sqrt(np.mean((a[lit] - c[lit]) ** 2)) / c[lit].mean() < 0.10


def test_snapshot_falls_back_to_an_x_display_without_egl(tmp_path):
    """Where EGL is missing (simulated: VOXGI_NO_EGL=1), a snapshot renders
    through the X display (Xvfb here) and says so; with neither, one line
    naming both."""
    need_xvfb()
    import os as _os
    env = dict(_os.environ, VOXGI_NO_EGL="1")
    out = tmp_path / "x.exr"
    r = subprocess.run(["xvfb-run", "-a", sys.executable, "-m", "viewer", "snapshot", BAKE, "-o", str(out),
                        "--width", "32", "--height", "32"], capture_output=True, text=True, timeout=300, env=env)
    assert r.returncode == 0, r.stderr
    assert "no EGL" in r.stderr and "X display" in r.stderr
    expected = read_exr(os.path.join(GOLDEN, "cornell_lightmap.exr"))
    assert read_exr(out).shape == (32, 32, 3) and expected.shape == (64, 64, 3)
    env.pop("DISPLAY", None)
    r = voxview("snapshot", BAKE, "-o", tmp_path / "y.png", env=env)
    assert r.returncode == 2 and "EGL" in r.stderr and "Traceback" not in r.stderr
