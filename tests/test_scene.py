import os

import numpy as np
import pygltflib
import pytest

from baker.errors import SceneError
from baker.scene import load_scene
from scenes.generate import GltfBuilder, box, cornell_box, quad

from .conftest import skip_without_shared
from baker.scene import camera_for

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def test_cornell_box_loads_with_published_data(cornell):
    assert len(cornell.triangles) == 32
    names = [m.name for m in cornell.materials]
    assert names == ["white", "red", "green", "light"]
    lo, hi = cornell.bounds()
    np.testing.assert_allclose(hi, [0.556, 0.5488, 0.5592], atol=1e-6)  # metres from the mm data
    cam = camera_for(cornell)
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


def test_box_helper_is_closed_and_oriented():
    pos, tri = box((0, 0, 0), (1, 2, 3), inward=True)
    c = pos[tri]
    n = np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0])
    centre_dir = np.array([0.5, 1, 1.5]) - c.mean(axis=1)
    assert (np.einsum("ij,ij->i", n, centre_dir) > 0).all()
    assert 0.5 * np.linalg.norm(n, axis=1).sum() == pytest.approx(2 * (2 + 6 + 3))


CORNELL_STYLE_OBJ = """# each object a quad given with negative (relative) indices under o/g/usemtl
mtllib {lib}
o floor
usemtl white
v 1.0 0.0 0.0
v 0.0 0.0 0.0
v 0.0 0.0 1.0
v 1.0 0.0 1.0
f -4 -3 -2 -1
o back_wall
g walls
usemtl red
v 1.0 0.0 1.0
v 0.0 0.0 1.0
v 0.0 1.0 1.0
v 1.0 1.0 1.0
f -4 -3 -2 -1
o light
usemtl light
v 0.6 0.99 0.4
v 0.6 0.99 0.6
v 0.4 0.99 0.6
v 0.4 0.99 0.4
f -4 -3 -2 -1
"""


def test_obj_negative_indices_under_groups(tmp_path):
    """The classic public Cornell box OBJ files give each object as a quad
    with negative indices under o/g/usemtl: every quad keeps its area (a
    grouped import once made half of them degenerate and indexed the wrong
    vertices), and the MTL named with a space in it is read."""
    (tmp_path / "box materials.mtl").write_text(
        "newmtl white\nKd 0.7 0.7 0.7\nnewmtl red\nKd 0.6 0.05 0.05\nnewmtl light\nKd 0.8 0.8 0.8\nKe 10 9 8\n")
    (tmp_path / "box.obj").write_text(CORNELL_STYLE_OBJ.format(lib="box materials.mtl"))
    s = load_scene(tmp_path / "box.obj")
    assert len(s.triangles) == 6
    np.testing.assert_allclose(s.triangle_areas().sum(), 1 + 1 + 0.04, rtol=1e-6)
    mats = {m.name: m for m in s.materials}
    np.testing.assert_allclose(mats["light"].emission, [10, 9, 8])
    np.testing.assert_allclose(mats["red"].albedo, [0.6, 0.05, 0.05])
    floor = s.material_ids == [m.name for m in s.materials].index("white")
    assert s.vertices[s.triangles[floor]][:, :, 1].max() == 0  # the floor's own vertices, not another quad's


def test_obj_polygons_materials_and_errors(tmp_path):
    """n-gons (convex: a fan; concave: ear clipping keeps the area), faces
    before the first usemtl (a default grey), a usemtl no MTL defines, a
    missing MTL (a warning, not an error), texture coordinates, and an
    index out of range reported as the file counts (from 1, with its line)."""
    (tmp_path / "p.obj").write_text(
        "mtllib nowhere.mtl\n"
        "v 0 0 0\nv 2 0 0\nv 2 2 0\nv 1 0.5 0\nv 0 2 0\n"      # a concave pentagon (a dart), area 2.5
        "vt 0 0\nvt 1 0\nvt 1 1\nvt 0.5 0.5\nvt 0 1\n"
        "f 1/1 2/2 3/3 4/4 5/5\n"
        "g roof\nusemtl undefined\n"
        "v 0 0 1\nv 1 0 1\nv 1 1 1\nv 0.5 1.5 1\nv 0 1 1\n"   # a convex pentagon, area 1.25
        "f -5 -4 -3 -2 -1\n")
    with pytest.warns(UserWarning) as rec:
        s = load_scene(tmp_path / "p.obj")
    text = " ".join(str(r.message) for r in rec)
    assert "nowhere.mtl" in text and "not found" in text
    assert len(s.triangles) == 3 + 3
    areas = s.triangle_areas()
    z = s.vertices[s.triangles][:, 0, 2]
    assert areas[z == 0].sum() == pytest.approx(2.5) and areas[z == 1].sum() == pytest.approx(1.25)
    assert s.uvs is not None and [m.name for m in s.materials] == ["default", "undefined"]
    (tmp_path / "bad.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 4\n")
    with pytest.raises(SceneError, match=r"line 5: vertex index 4 out of range \(3 defined so far"):
        load_scene(tmp_path / "bad.obj")
    (tmp_path / "zero.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n")
    with pytest.raises(SceneError, match="line 4: vertex index 0 out of range"):
        load_scene(tmp_path / "zero.obj")


def test_ignored_material_terms_are_named_once(tmp_path):
    """A mirror comes out diffuse: the loader says which terms it ignores,
    in one warning per file. Glass's dissolve is read (thin glass, 1 - d),
    not ignored."""
    (tmp_path / "m.mtl").write_text("newmtl mirror\nKd 0.1 0.1 0.1\nKs 0.9 0.9 0.9\nNs 900\nillum 3\n"
                                    "newmtl glass\nKd 0.9 0.9 0.9\nd 0.2\nNi 1.5\nnewmtl matte\nKd 0.5 0.5 0.5\n")
    (tmp_path / "m.obj").write_text("mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl mirror\nf 1 2 3\n"
                                    "usemtl glass\nf 1 3 2\nusemtl matte\nf 3 2 1\n")
    with pytest.warns(UserWarning, match="ignores") as rec:
        scene = load_scene(tmp_path / "m.obj")
    notes = [str(r.message) for r in rec if "ignores" in str(r.message)]
    assert len(notes) == 1
    assert "specular" in notes[0] and "'mirror'" in notes[0] and "reflection/refraction" in notes[0]
    assert "'glass'" not in notes[0] and "matte" not in notes[0]
    assert {m.name: round(m.transmission, 6) for m in scene.materials} == {"mirror": 0.0, "glass": 0.8, "matte": 0.0}
    b = GltfBuilder()
    b.material("plain", (0.5,) * 3)
    b.mesh("q", *quad((0, 0, 0), (1, 0, 0), (1, 0, 1), (0, 0, 1)), 0)
    b.doc.materials[0].pbrMetallicRoughness.metallicFactor = 1.0
    b.doc.materials[0].extensions = {"KHR_materials_volume": {"thicknessFactor": 1.0}}
    b.save(tmp_path / "metal.glb")
    with pytest.warns(UserWarning, match=r"ignores metallic.*'plain'.*volume"):
        load_scene(tmp_path / "metal.glb")


def test_builtin_scenes_by_name():
    """Commands take a built-in scene by name, from any folder."""
    from baker.scene import builtin_scenes
    assert "cornell_box" in builtin_scenes() and "walkthrough" in builtin_scenes()
    assert len(load_scene("cornell_box").triangles) == 32
    with pytest.raises(SceneError, match="built-in scenes: .*cornell_box"):
        load_scene("cornel_box")


def test_automatic_camera_sees_the_inside(tmp_path):
    """A scene without a camera: an open box (the Cornell box OBJ has no front
    wall) is seen through its open side, a closed room from inside, an
    object from outside; each way the image shows lit surfaces."""
    from baker.render import render
    from baker.scene import auto_camera
    (tmp_path / "open.obj").write_text(
        "v 0 0 0\nv 1 0 0\nv 1 0 1\nv 0 0 1\nv 0 1 0\nv 1 1 0\nv 1 1 1\nv 0 1 1\n"
        "f 1 4 3 2\nf 5 6 7 8\nf 1 5 8 4\nf 2 3 7 6\nf 4 8 7 3\n")  # floor, ceiling, two walls, back (z = 1)
    s = load_scene(tmp_path / "open.obj", lights=[], sky=None)
    cam = auto_camera(s)
    assert cam.position[2] < 0 and cam.forward[2] > 0.99  # outside the open side (z = 0), looking in
    b = GltfBuilder()
    b.mesh("room", *box((0, 0, 0), (4, 2, 3), inward=True), b.material("m", (0.5,) * 3, emission=(1, 1, 1)))
    b.save(tmp_path / "room.glb")
    room = load_scene(tmp_path / "room.glb")
    cam = camera_for(room)
    assert np.all(cam.position > [0, 0, 0]) and np.all(cam.position < [4, 2, 3])  # inside
    img = render(room, width=16, height=16, spp=1)
    assert img.min() > 0  # every pixel sees the lit inside, none the outside of a one-sided wall


SHARED = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "..", "shared", "realscenes")
BUNNY = os.path.join(SHARED, "stanford_bun_zipper_res2.ply")


def closed_scene(tmp_path, kind, two_sided):
    """A closed surface with no camera: a sphere, a box (outward normals: an
    object), a room (inward normals), or the Stanford bunny scan."""
    from scenes.generate import icosphere
    if kind == "bunny":
        skip_without_shared(BUNNY, "the public Stanford bunny")
        return load_scene(BUNNY, one_sided=not two_sided)
    b = GltfBuilder()
    part = {"sphere": lambda: icosphere(2, 0.5, (1, 2, 3)), "box": lambda: box((0, 0, 0), (2, 1, 1.5)),
            "room": lambda: box((0, 0, 0), (4, 2, 3), inward=True)}[kind]()
    b.mesh(kind, *part, b.material("m", (0.5,) * 3, emission=(1, 1, 1), double_sided=two_sided))
    b.save(tmp_path / f"{kind}.glb")
    return load_scene(tmp_path / f"{kind}.glb")


@pytest.mark.parametrize("two_sided", [False, True])
@pytest.mark.parametrize("kind", ["sphere", "box", "room", "bunny"])
def test_automatic_camera_tells_a_closed_object_from_a_closed_room(tmp_path, kind, two_sided):
    """The centre of a closed object's bounds lies inside it: its rays meet
    back faces, where a room's meet front faces. Objects are framed from
    outside, rooms from inside; either way most pixels see the surface."""
    from baker.render import camera_array
    from baker.scene import build_scene_bvh
    scene = closed_scene(tmp_path, kind, two_sided)
    bvh = build_scene_bvh(scene)
    cam = camera_for(scene, None, bvh)
    lo, hi = scene.bounds()
    inside = bool(np.all(cam.position > lo) and np.all(cam.position < hi))
    assert inside == (kind == "room"), (kind, cam.position, lo, hi)
    n = 32
    c = camera_array(cam, n, n)
    a, b_ = np.meshgrid(2 * (np.arange(n) + 0.5) / n - 1, 1 - 2 * (np.arange(n) + 0.5) / n)
    d = c[1] + a.reshape(-1, 1) * c[2] + b_.reshape(-1, 1) * c[3]
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    _, tri, _, _ = bvh.closest(np.broadcast_to(c[0], d.shape), d)
    assert np.mean(tri >= 0) > 0.3, np.mean(tri >= 0)


def test_the_bunny_under_a_sky_renders_lit():
    """The issue as a user met it: the scan without a camera, under a sky."""
    from baker.render import render
    from baker.scene import Sky
    skip_without_shared(BUNNY, "the public Stanford bunny")
    scene = load_scene(BUNNY, sky=Sky(np.ones(3)))
    img = render(scene, width=32, height=32, spp=8)
    assert img.mean() > 0.1, img.mean()


@pytest.mark.parametrize("what", ["cornell_box", "OBJ"])
def test_a_scene_where_a_bake_is_expected_says_how_to_bake_it(tmp_path, capsys, what):
    from viewer.cli import main as voxview
    if what == "OBJ":
        what = str(tmp_path / "s.obj")
        (tmp_path / "s.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    assert voxview(["snapshot", what, "-o", str(tmp_path / "x.png")]) == 2
    err = capsys.readouterr().err
    assert "not a bake file" in err and "voxbake bake" in err and "not found" not in err, err
    assert len(err.strip().splitlines()) == 1


def test_command_line_camera():
    from baker.scene import adjust_camera, make_camera
    cam = make_camera("c", (0, 0, 0), (0, 0, 1), (0, 1, 0), np.radians(40))
    c = adjust_camera(cam, look_from=np.array([1.0, 2.0, 3.0]), look_at=np.array([1.0, 2.0, 10.0]), fov_deg=60)
    np.testing.assert_allclose(c.position, [1, 2, 3])
    np.testing.assert_allclose(c.forward, [0, 0, 1])
    assert c.yfov == pytest.approx(np.radians(60))


def test_duplicate_faces_count_once(tmp_path):
    """The classic Cornell box OBJ gives a box's front face twice (again as
    its "bottom", with the same corners): the repeat is dropped, with a
    warning, so that its area counts once. The same corners in the opposite
    winding are a sheet's two faces and stay."""
    (tmp_path / "d.obj").write_text(
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
        "f 1 2 3 4\n"      # the front face
        "f -4 -3 -2 -1\n"  # the same quad again, as the file gives it
        "f 4 3 2 1\n")     # the other winding: the back face
    with pytest.warns(UserWarning, match="dropped 2 duplicate triangles"):
        s = load_scene(tmp_path / "d.obj", one_sided=True)
    c = s.vertices[s.triangles].astype(float)
    normal_z = np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0])[:, 2]
    assert (normal_z > 0).sum() == 2 and (normal_z < 0).sum() == 2
    assert s.triangle_areas().sum() == pytest.approx(2.0)


def test_row_labels_are_numpys_unique_row_inverse():
    """scene.topology.row_labels (a lexsort) labels rows as np.unique(axis=0,
    return_inverse=True) does: integer keys with negatives, float positions
    where -0.0 and 0.0 are one corner."""
    from baker.scene.topology import row_labels
    rng = np.random.default_rng(3)
    for a in (rng.integers(-5, 5, (2000, 2)), rng.integers(0, 3, (3000, 5)), rng.integers(-(1 << 40), 1 << 40, (500, 3))):
        _, want = np.unique(a, axis=0, return_inverse=True)
        assert np.array_equal(row_labels(a), want.ravel())
    v = rng.integers(-2, 3, (4000, 3)).astype(np.float64)
    v[::5] *= -1.0   # -0.0 where 0.0 was
    _, want = np.unique(v, axis=0, return_inverse=True)
    got = row_labels(v)
    assert np.array_equal(got, want.ravel())
    assert len(np.unique(got)) == len(np.unique(v + 0.0, axis=0))
    assert len(row_labels(np.zeros((0, 3)))) == 0
