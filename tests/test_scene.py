import subprocess
import sys

import numpy as np
import pygltflib
import pytest

from baker.errors import SceneError
from baker.scene import load_scene
from scenes.generate import GltfBuilder, box, cornell_box, quad


def test_cornell_box_loads_with_published_data(cornell):
    assert len(cornell.triangles) == 32
    names = [m.name for m in cornell.materials]
    assert names == ["white", "red", "green", "light"]
    lo, hi = cornell.bounds()
    np.testing.assert_allclose(hi, [0.556, 0.5488, 0.5592], atol=1e-6)  # metres from the mm data
    cam = cornell.camera()
    np.testing.assert_allclose(cam.position, [0.278, 0.273, -0.8], atol=1e-6)
    np.testing.assert_allclose(cam.forward, [0, 0, 1], atol=1e-6)
    assert np.degrees(cam.yfov) == pytest.approx(39.31, abs=0.01)  # 35 mm lens, 25 mm film
    red, green = cornell.materials[1].albedo, cornell.materials[2].albedo
    assert red[0] > 5 * red[1] and green[1] > 3 * green[0]
    light = cornell.materials[3].emission
    assert light[0] > light[1] > light[2] > 0  # the measured lamp is reddish
    # the light is one-sided and faces down into the box
    tri = cornell.emitter_triangles()
    c = cornell.triangle_corners()[tri]
    n = np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0])
    assert (n[:, 1] < 0).all()
    assert c[:, :, 1].max() < 0.5488


def test_gltf_materials_cameras_lights_roundtrip(tmp_path):
    b = GltfBuilder()
    m0 = b.material("a", (0.2, 0.4, 0.6), emission=(30.0, 15.0, 0.0), double_sided=True)
    m1 = b.material("b", (0.9, 0.8, 0.7))
    b.mesh("q0", *quad((0, 0, 0), (1, 0, 0), (1, 0, 1), (0, 0, 1), facing=(0, 1, 0)), m0)
    b.mesh("q1", *quad((0, 1, 0), (1, 1, 0), (1, 1, 1), (0, 1, 1), facing=(0, -1, 0)), m1)
    b.camera("c0", (0, 0.5, -2), (0, 0, 1), yfov_deg=50)
    b.camera("c1", (3, 0.5, 0.5), (-1, 0, 0), yfov_deg=30)
    b.light("p", "point", color=(1, 0.5, 0.25), intensity=4.0, position=(0.5, 0.9, 0.5))
    b.light("s", "spot", intensity=2.0, position=(0, 2, 0), direction=(0, -1, 0), inner_deg=10, outer_deg=20)
    b.light("d", "directional", intensity=3.0, direction=(0, -1, 0))
    path = tmp_path / "t.glb"
    b.save(path)
    s = load_scene(path)
    np.testing.assert_allclose(s.materials[0].emission, [30, 15, 0], rtol=1e-6)  # factor x strength
    np.testing.assert_allclose(s.materials[0].albedo, [0.2, 0.4, 0.6], rtol=1e-6)  # not quantised to 8 bits
    assert s.materials[0].double_sided and not s.materials[1].double_sided
    assert [c.name for c in s.cameras] == ["c0", "c1"]
    np.testing.assert_allclose(s.cameras[1].forward, [-1, 0, 0], atol=1e-6)
    np.testing.assert_allclose(s.cameras[1].up, [0, 1, 0], atol=1e-6)
    assert [l.kind for l in s.lights] == ["point", "spot", "directional"]
    np.testing.assert_allclose(s.lights[0].intensity, [4, 2, 1])
    np.testing.assert_allclose(s.lights[0].position, [0.5, 0.9, 0.5])
    np.testing.assert_allclose(s.lights[1].direction, [0, -1, 0], atol=1e-6)
    assert s.lights[1].outer_cone == pytest.approx(np.radians(20))
    np.testing.assert_allclose(s.emitted_power(), np.pi * np.array([30, 15, 0]) * 1.0 * 2, rtol=1e-6)


def test_gltf_node_transforms_are_applied(tmp_path):
    b = GltfBuilder()
    m = b.material("m", (0.5, 0.5, 0.5))
    node = b.mesh("q", *quad((0, 0, 0), (1, 0, 0), (1, 0, 1), (0, 0, 1), facing=(0, 1, 0)), m)
    # parent node: translate (10, 0, 0), scale 2, rotate 90 degrees about y
    b.doc.nodes[node].translation = [0, 5, 0]
    parent = pygltflib.Node(name="parent", children=[node], translation=[10, 0, 0], scale=[2, 2, 2],
                            rotation=[0, np.sin(np.pi / 4), 0, np.cos(np.pi / 4)])
    b.doc.nodes.append(parent)
    b.doc.scenes[0].nodes = [len(b.doc.nodes) - 1]
    b.save(tmp_path / "t.glb")
    s = load_scene(tmp_path / "t.glb")
    # x' = 10 + 2 * R_y(90) (x, y + 5, z): (1, 0, 0) -> (10, 10, -2)
    v = s.vertices.astype(float)
    assert v[:, 1].min() == pytest.approx(10.0) and v[:, 1].max() == pytest.approx(10.0)
    np.testing.assert_allclose(sorted(set(np.round(v[:, 0], 5))), [10, 12])
    np.testing.assert_allclose(sorted(set(np.round(v[:, 2], 5))), [-2, 0])


def test_obj_mtl_and_ply(tmp_path):
    (tmp_path / "m.mtl").write_text("newmtl lamp\nKd 0.1 0.2 0.3\nKe 5 4 3\nnewmtl wall\nKd 0.7 0.7 0.7\n")
    (tmp_path / "s.obj").write_text(
        "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 1 0 1\nv 0 1 0\nv 1 1 0\nv 1 1 1\n"
        "usemtl lamp\nf 1 2 3\nusemtl wall\nf 4 5 6\n")
    s = load_scene(tmp_path / "s.obj")
    mats = {m.name: m for m in s.materials}
    np.testing.assert_allclose(mats["lamp"].emission, [5, 4, 3])
    np.testing.assert_allclose(mats["lamp"].albedo, [0.1, 0.2, 0.3])
    assert all(m.double_sided for m in s.materials)  # OBJ carries no sidedness
    assert not any(m.double_sided for m in load_scene(tmp_path / "s.obj", one_sided=True).materials)
    assert len(s.triangles) == 2
    import trimesh
    trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]]).export(tmp_path / "s.ply")
    p = load_scene(tmp_path / "s.ply")
    assert len(p.triangles) == 1 and p.materials[0].emission.max() == 0


def test_errors_name_the_file_and_problem(tmp_path):
    with pytest.raises(SceneError, match="file not found") as e:
        load_scene(tmp_path / "missing.glb")
    assert "missing.glb" in e.value.one_line()
    (tmp_path / "junk.glb").write_bytes(b"\x00garbage" * 10)
    with pytest.raises(SceneError) as e:
        load_scene(tmp_path / "junk.glb")
    assert "junk.glb" in e.value.one_line()
    (tmp_path / "x.stl2").write_text("solid")
    with pytest.raises(SceneError, match="unsupported format"):
        load_scene(tmp_path / "x.stl2")
    (tmp_path / "nan.obj").write_text("v 0 0 0\nv 1 0 nan\nv 0 1 0\nf 1 2 3\n")
    with pytest.raises(SceneError, match="NaN or infinite"):
        load_scene(tmp_path / "nan.obj")
    # out-of-range index in a glb
    b = GltfBuilder()
    m = b.material("m", (0.5,) * 3)
    pos, tri = quad((0, 0, 0), (1, 0, 0), (1, 0, 1), (0, 0, 1))
    tri = tri.copy()
    tri[0, 0] = 99
    b.mesh("bad", pos, tri, m)
    b.save(tmp_path / "bad.glb")
    with pytest.raises(SceneError, match="out of range"):
        load_scene(tmp_path / "bad.glb")
    # truncated glb
    cornell_box().save(tmp_path / "c.glb")
    data = (tmp_path / "c.glb").read_bytes()
    (tmp_path / "trunc.glb").write_bytes(data[: len(data) // 2])
    with pytest.raises(SceneError) as e:
        load_scene(tmp_path / "trunc.glb")
    assert "trunc.glb" in e.value.one_line()


def test_degenerate_triangles_dropped_and_no_emitter_warned(tmp_path):
    (tmp_path / "d.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\nf 1 2 3\nf 1 2 4\nf 1 1 3\n")
    with pytest.warns(UserWarning) as rec:
        s = load_scene(tmp_path / "d.obj")
    assert len(s.triangles) == 1
    text = " ".join(str(r.message) for r in rec)
    assert "dropped 2 degenerate" in text and "no emitter" in text


def test_info_command(tmp_path):
    out = subprocess.run([sys.executable, "-m", "baker", "info", "scenes/cornell_box.glb"], capture_output=True,
                         text=True, check=True).stdout
    assert "triangles  32" in out and "published" in out and "total emitted power" in out
    bad = subprocess.run([sys.executable, "-m", "baker", "info", str(tmp_path / "nope.obj")], capture_output=True,
                         text=True)
    assert bad.returncode == 2
    assert bad.stderr.strip() == f"error: {tmp_path / 'nope.obj'}: file not found"
    for cmd in ([], ["info"], ["render"]):
        h = subprocess.run([sys.executable, "-m", "baker", *cmd, "--help"], capture_output=True, text=True)
        assert h.returncode == 0 and "usage: voxbake" in h.stdout


def test_box_helper_is_closed_and_oriented():
    pos, tri = box((0, 0, 0), (1, 2, 3), inward=True)
    c = pos[tri]
    n = np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0])
    centre_dir = np.array([0.5, 1, 1.5]) - c.mean(axis=1)
    assert (np.einsum("ij,ij->i", n, centre_dir) > 0).all()
    assert 0.5 * np.linalg.norm(n, axis=1).sum() == pytest.approx(2 * (2 + 6 + 3))


def test_render_refuses_bad_settings_before_work(tmp_path):
    cases = [
        (["--camera", "nope"], "no camera named 'nope'"),
        (["--spp", "0"], "--spp must be at least 1"),
        (["--method", "voxels", "--radius", "0"], "invalid solver setting"),
        (["--width", "0"], "out of range"),
    ]
    for extra, message in cases:
        r = subprocess.run([sys.executable, "-m", "baker", "render", "scenes/cornell_box.glb", "-o",
                            str(tmp_path / "x.png"), *extra], capture_output=True, text=True)
        assert r.returncode == 2 and message in r.stderr and "Traceback" not in r.stderr, (extra, r.stderr)
        assert len(r.stderr.strip().splitlines()) == 1
    r = subprocess.run([sys.executable, "-m", "baker", "render", "scenes/cornell_box.glb", "-o",
                        str(tmp_path / "no" / "x.png")], capture_output=True, text=True)
    assert r.returncode == 2 and "output folder does not exist" in r.stderr
    assert not list(tmp_path.iterdir())  # nothing half-written
