"""What other tools make of a bake file: the Khronos glTF-Validator finds no
error in any bake, and three.js (GLTFLoader with a MOZ_lightmap plugin of a
few lines, in headless Chromium on SwiftShader) shows the same image as our
own CPU render of the bake.

Needs node, the npm packages of tests/web (`npm ci` there) and Chromium:
scripts/setup.sh installs them. Skipped where they are missing, unless
VOXGI_REQUIRE_WEB=1 (CI sets it: there a missing tool is a failure)."""
import json
import os
import shutil
import subprocess
from dataclasses import replace

import numpy as np
import pytest
from PIL import Image
from scipy.ndimage import binary_erosion

from baker.bake import bake_config, bake_scene, read_bake, render_bake, write_bake
from baker.scene import load_scene
from baker.scene.model import make_camera
from baker.scene.textures import srgb_to_linear
from scenes.generate import thin_wall, two_rooms

WEB = os.path.join(os.path.dirname(os.path.abspath(__file__)), "web")
CHROMIUM = os.environ.get("CHROMIUM", "/usr/bin/chromium")


def _missing():
    if not shutil.which("node"):
        return "node is not installed"
    if not os.path.isdir(os.path.join(WEB, "node_modules", "three")):
        return "tests/web has no node_modules (run `npm ci` there)"
    if not os.path.exists(CHROMIUM):
        return f"no Chromium at {CHROMIUM}"
    return None


@pytest.fixture(scope="module")
def web():
    why = _missing()
    if why:
        if os.environ.get("VOXGI_REQUIRE_WEB") == "1":
            pytest.fail(why)
        pytest.skip(why)


def textured_obj(folder):
    """A floor with a checker texture (OBJ + MTL + PNG) under a lamp."""
    tex = np.kron((np.indices((8, 8)).sum(axis=0) % 2), np.ones((8, 8)))
    img = (np.stack([tex * 0.6 + 0.2, tex * 0.3 + 0.2, 0.5 - tex * 0.3], axis=-1) * 255).astype(np.uint8)
    Image.fromarray(img, "RGB").save(folder / "checker.png")
    (folder / "floor.mtl").write_text("newmtl checker\nKd 1 1 1\nmap_Kd checker.png\n"
                                      "newmtl lamp\nKd 0 0 0\nKe 5 5 5\n")
    (folder / "floor.obj").write_text(
        "mtllib floor.mtl\n"
        "v -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\nv -0.2 1 -0.2\nv 0.2 1 -0.2\nv 0.2 1 0.2\nv -0.2 1 0.2\n"
        "vt 0 0\nvt 2 0\nvt 2 2\nvt 0 2\n"
        "usemtl checker\nf 1/1 4/4 3/3\nf 1/1 3/3 2/2\nusemtl lamp\nf 5 6 7\nf 5 7 8\n")
    return folder / "floor.obj"


@pytest.fixture(scope="module")
def bakes(tmp_path_factory):
    """A bake of each kind of scene: the Cornell box, two-sided walls, a
    room with a dark half, a textured OBJ, a room with a dynamic mesh."""
    out = tmp_path_factory.mktemp("web")
    scenes = {"cornell": load_scene("cornell_box")}
    thin_wall().save(out / "thin.glb")
    two_rooms().save(out / "rooms.glb")
    scenes["thin_wall"] = load_scene(out / "thin.glb")
    scenes["two_rooms"] = load_scene(out / "rooms.glb")
    from tests.test_dynamic import add_ball
    b = two_rooms()
    add_ball(b, centre=(0.5, 0.3, 0.5), radius=0.1, cap=True)
    b.save(out / "dynamic.glb")
    scenes["dynamic"] = load_scene(out / "dynamic.glb", dynamic=("ball",))
    floor = load_scene(textured_obj(out))
    scenes["textured"] = replace(floor, cameras=(make_camera("above", (0, 1.6, -2.2), (0, -0.6, 1), (0, 1, 0),
                                                             np.radians(50)),))
    paths = {}
    for name, scene in scenes.items():
        bake = bake_scene(scene, bake_config("preview", resolution=24, photons=100_000)).bake
        paths[name] = out / f"{name}.glb"
        write_bake(paths[name], bake)
    return paths


def node(*args, timeout=300):
    r = subprocess.run(["node", *map(str, args)], capture_output=True, text=True, timeout=timeout, cwd=WEB)
    assert r.returncode == 0, r.stderr
    return [json.loads(line) for line in r.stdout.splitlines() if line.startswith("{")]


def test_validator_finds_no_error(web, bakes):
    reports = node("validate.mjs", *bakes.values())
    assert len(reports) == len(bakes)
    for rep in reports:
        assert rep["errors"] == 0, rep
        assert rep["warnings"] == 0, rep  # nothing the validator frowns on either


def three_image(path, width, height, exposure, material, tmp_path):
    """three.js's canvas at 4x the size, box-filtered to (width, height)
    (4 x 4 samples per pixel at the same points as our CPU render), linear."""
    png = tmp_path / f"three_{material}.png"
    node("render.mjs", path, png, 4 * width, 4 * height, exposure, material)
    img = srgb_to_linear(np.asarray(Image.open(png).convert("RGB"), np.float32) / 255)
    return img.reshape(height, 4, width, 4, 3).mean(axis=(1, 3))


@pytest.mark.parametrize("name", ["cornell", "textured"])
def test_three_js_shows_what_we_render(web, bakes, tmp_path, name):
    """Lambertian materials (the model the bake assumes): per pixel within
    0.01 (linear, on a 0..1 range after exposure) for 99% of the pixels
    and the mean within 1%, away from the outline of the lit area (where
    the rasterizer's coverage and the rays' differ): what is left is 8-bit
    rounding of the PNG pages and of the output (measured on the Cornell
    box: 99th percentile 0.002, mean ratio 1.0001). three.js's own
    PBR material (metallic 0, roughness 1) is within 5% in the mean: it
    takes the dielectric Fresnel reflection off the diffuse (measured 0.974)."""
    bake = read_bake(bakes[name])
    w = h = 96
    ours = render_bake(bake, 0, w, h)
    exposure = 0.5 / float(np.percentile(ours, 90))  # most of the image in range, the lamp clipped
    ours = np.clip(ours * exposure, 0, 1)
    visible = (ours.max(axis=2) < 0.95) & (ours.mean(axis=2) > 0.005)  # not clipped, not background
    visible = binary_erosion(visible, np.ones((3, 3), bool))  # outline pixels: rasterizer vs ray coverage
    assert visible.mean() > 0.2
    lam = three_image(bakes[name], w, h, exposure, "lambert", tmp_path)
    diff = np.abs(lam - ours)[visible]
    assert np.percentile(diff, 99) < 0.01, np.percentile(diff, [50, 99])
    assert abs(lam[visible].mean() / ours[visible].mean() - 1) < 0.01
    std = three_image(bakes[name], w, h, exposure, "standard", tmp_path)
    assert abs(std[visible].mean() / ours[visible].mean() - 1) < 0.05


def test_three_js_lights_a_sphere_with_the_probes(web, tmp_path, make_scene):
    """examples/three: a sphere lit only by THREE.LightProbe from the
    bake's probe SH, in a furnace (irradiance 2 everywhere): its pixels
    read albedo x 2 / pi, as voxview's sphere does."""
    from scenes.generate import furnace_box
    scene = make_scene(furnace_box(albedo=0.5, emission=1.0), "web_probe_furnace")
    path = tmp_path / "f.glb"
    write_bake(str(path), bake_scene(scene, bake_config("preview", resolution=16, photons=50_000,
                                                        probe_spacing=0.25)).bake)
    png = tmp_path / "sphere.png"
    node("probes.mjs", path, png, 64, 64, "0.5,0.5,0.6", 0.15, 0.6)
    img = np.asarray(Image.open(png).convert("RGB"), float) / 255
    c = img[26:38, 26:38].reshape(-1, 3)   # the sphere's middle (the camera looks at it from z = 0.1)
    linear = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    assert np.abs(linear / (0.6 * 2 / np.pi) - 1).max() < 0.04, linear.mean(axis=0)
