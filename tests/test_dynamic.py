"""Dynamic meshes (`voxbake bake --dynamic NODE`): a named glTF node's
meshes, with its children's, leave the bake (no lightmap, no shadow, no
bounced light), travel in the bake file as plain meshes listed in our
extension, and voxview lights them from the probes wherever they are moved;
every rule of the reader with a crafted file."""
import json

import numpy as np
import pytest

from baker.bake import bake_scene, read_bake, write_bake
from baker.errors import BakeFileError, SceneError
from baker.scene import load_scene
from scenes.generate import cornell_box, furnace_box, icosphere, two_rooms
from tests.conftest import cli, need_xvfb
from tests.hostile import resign_bake, split_glb
from tests.test_probes import _sphere_pixels, assert_dark_beside_the_wall_and_lit, small

CENTRE, RADIUS = (0.5, 0.5, 0.6), 0.15


def add_ball(b, name="ball", centre=CENTRE, radius=RADIUS, albedo=0.6, subdiv=3, cap=False):
    """A diffuse icosphere node `name` at `centre` (its vertices local to
    the node), with a child node 'cap' (a small sphere on its top) if
    asked; the node's index."""
    m = b.material(f"{name}_paint", (albedo,) * 3)
    pos, tri = icosphere(subdiv, radius)
    node = b.primitives(name, [{"positions": pos, "normals": pos / radius, "triangles": tri, "material": m}],
                        translation=centre)
    if cap:
        p2, t2 = icosphere(1, 0.3 * radius)
        child = b.primitives("cap", [{"positions": p2, "triangles": t2, "material": m}],
                             translation=(0.0, radius, 0.0))
        b.doc.scenes[0].nodes.remove(child)
        b.doc.nodes[node].children = [child]
    return node


@pytest.fixture(scope="module")
def furnace(tmp_path_factory):
    """A furnace (albedo 0.5, emitted radiosity 1 everywhere) with a ball
    and its cap marked dynamic: (source path, bake path)."""
    folder = tmp_path_factory.mktemp("dynamic")
    b = furnace_box(albedo=0.5, emission=1.0)
    add_ball(b, cap=True)
    src = folder / "furnace_ball.glb"
    b.save(str(src))
    scene = load_scene(src, dynamic=("ball",))
    out = folder / "furnace_ball_bake.glb"
    write_bake(str(out), bake_scene(scene, small(probe_spacing=0.2)).bake)
    return src, out


@pytest.fixture(scope="module")
def gl():
    from viewer.context import headless_context
    c = headless_context()
    yield c
    c.release()


def test_a_dynamic_node_and_its_children_leave_the_scene(furnace):
    src, _ = furnace
    whole = load_scene(src)
    scene = load_scene(src, dynamic=("ball",))
    (d,) = scene.dynamic
    ball, cap = 20 * 4 ** 3, 20 * 4
    assert len(whole.triangles) - len(scene.triangles) == ball + cap
    assert d.name == "ball" and len(d.triangles) == ball + cap
    assert np.allclose(d.pivot, CENTRE)
    r = np.linalg.norm(d.vertices - np.array(CENTRE), axis=1)
    assert np.isclose(r.max(), RADIUS * 1.3, rtol=1e-5)   # the cap (its child, moved by both nodes) on its top
    assert np.allclose(np.linalg.norm(d.normals, axis=1), 1, atol=1e-5)
    assert (d.material_ids == [m.name for m in scene.materials].index("ball_paint")).all()
    # the cap has no normals in the file: made from its faces, pointing out of it
    top = d.vertices[:, 1] > CENTRE[1] + RADIUS * 1.25
    assert (d.normals[top, 1] > 0.5).all()


def test_the_furnace_with_a_dynamic_ball_is_still_exact(furnace):
    """The ball is not in the bake: every probe of the furnace reads
    exactly 2 (pi times the radiance 2 / pi) for every normal, the ball's
    place included, and every texel 2 / (1 - 0.5) x ... = the furnace's."""
    from baker.probes.sample import irradiance_map_at
    from tests.test_probes import CUBE_NORMALS
    bake = read_bake(str(furnace[1]))
    g = bake.probes
    assert g.valid.all()
    for i in range(g.count):
        e = irradiance_map_at(np.repeat(g.irradiance[i][None], len(CUBE_NORMALS), 0), CUBE_NORMALS)
        assert np.abs(e / 2.0 - 1).max() < 0.03
    assert bake.triangle_count == len(load_scene(furnace[0], dynamic=("ball",)).triangles)


def test_the_bake_file_holds_the_dynamic_mesh_as_a_plain_node(furnace):
    src, out = furnace
    want = load_scene(src, dynamic=("ball",)).dynamic[0]
    bake = read_bake(str(out))
    (d,) = bake.scene.dynamic
    assert d.name == "ball" and np.allclose(d.pivot, CENTRE)
    assert len(d.triangles) == len(want.triangles)
    assert np.allclose(np.sort(d.vertices, axis=0), np.sort(want.vertices, axis=0), atol=1e-6)
    doc, _ = split_glb(out.read_bytes())
    entry = doc["extensions"]["VOXGI_lightmap"]["dynamic"]
    assert [e["name"] for e in entry] == ["ball"]
    node = doc["nodes"][entry[0]["node"]]
    assert node["translation"] == pytest.approx(list(CENTRE))
    for prim in doc["meshes"][node["mesh"]]["primitives"]:
        assert "TEXCOORD_1" not in prim["attributes"]   # no lightmap
        assert "MOZ_lightmap" not in (doc["materials"][prim["material"]].get("extensions") or {})


@pytest.mark.parametrize("names, message", [(("nosuch",), "'nosuch': no node has that name"),
                                            (("inside",), "'inside': the node holds no triangles"),
                                            (("ball", "box"), "nothing is left to bake")])
def test_bad_dynamic_names_are_refused_in_one_line(furnace, names, message):
    with pytest.raises(SceneError, match=message) as e:
        load_scene(furnace[0], dynamic=names)
    assert "\n" not in e.value.one_line() and "furnace_ball.glb" in e.value.one_line()


def test_a_dynamic_node_instanced_too_often_is_refused(tmp_path):
    """A node graph that shares its children instances a dynamic node
    2^13 times: refused in one line before the meshes are gathered (a bake
    holds at most MAX_DYNAMIC)."""
    from baker.scene.gltf_read import MAX_DYNAMIC
    from tests.hostile import triangle_doc, write_gltf
    doc = triangle_doc()
    doc["nodes"] = [{"mesh": 0, "name": "leaf"}] + [{"children": [k, k]} for k in range(13)]
    doc["scenes"] = [{"nodes": [13, 0]}]
    path = write_gltf(tmp_path / "shared.gltf", doc)
    assert 2 ** 13 > MAX_DYNAMIC
    with pytest.raises(SceneError, match=f"more than {MAX_DYNAMIC} instances") as e:
        load_scene(path, dynamic=("leaf",))
    assert "\n" not in e.value.one_line()


def test_the_bake_command_refuses_bad_dynamic_flags(furnace, tmp_path):
    from tests.hostile import write_obj
    out = tmp_path / "o.glb"
    obj = write_obj(tmp_path)
    for args, said in (((furnace[0], "--dynamic", "nosuch"), "nosuch"),
                       ((furnace[0], "--dynamic", "ball", "--no-probes"), "--no-probes"),
                       ((obj, "--dynamic", "ball"), "glTF")):
        status, _, stderr = cli("bake", *args, "-o", out, "--preset", "preview")
        assert status == 2 and "Traceback" not in stderr and len(stderr.strip().splitlines()) == 1, stderr
        assert said in stderr and not out.exists()


def _edit_dynamic(edit):
    def f(doc):
        edit(doc["extensions"]["VOXGI_lightmap"], doc)
    return f


CRAFTED = {
    "node out of range": lambda root, doc: root["dynamic"][0].update(node=len(doc["nodes"])),
    "node not a number": lambda root, doc: root["dynamic"][0].update(node="1"),
    "listed twice": lambda root, doc: root["dynamic"].append(dict(root["dynamic"][0])),
    "not a list": lambda root, doc: root.update(dynamic={"node": 1}),
    "empty list": lambda root, doc: root.update(dynamic=[]),
    "a node without a mesh": lambda root, doc: root["dynamic"][0].update(
        node=next(i for i, n in enumerate(doc["nodes"]) if "camera" in n)),
    "a meshless node beside it": lambda root, doc: root["dynamic"].append(
        {"node": next(i for i, n in enumerate(doc["nodes"]) if "camera" in n), "name": "inside"}),
    "the baked node": lambda root, doc: root["dynamic"][0].update(
        node=next(i for i, n in enumerate(doc["nodes"]) if n.get("name") == "baked")),
    "no probes": lambda root, doc: root.pop("probes"),
    "unlisted": lambda root, doc: root.pop("dynamic"),
}


@pytest.mark.parametrize("case", list(CRAFTED))
def test_a_crafted_dynamic_list_is_refused_in_one_line(furnace, tmp_path, case):
    """Every way the list can lie: refused with one line naming the file
    (an unlisted dynamic mesh: its primitives have no lightmap UVs)."""
    bad = tmp_path / f"{case.replace(' ', '_')}.glb"
    bad.write_bytes(resign_bake(furnace[1].read_bytes(), _edit_dynamic(CRAFTED[case])))
    with pytest.raises(BakeFileError) as e:
        read_bake(str(bad))
    assert "\n" not in e.value.one_line() and bad.name in e.value.one_line(), e.value.one_line()


def test_a_dynamic_mesh_in_the_furnace_reads_albedo_times_radiance(furnace, gl):
    """voxview's dynamic ball, where the file has it and moved: every pixel
    of it reads albedo x radiance, 0.6 x 2 / pi."""
    from baker.scene import camera_for
    from viewer.objects import Placed
    from viewer.snapshot import snapshot
    bake = read_bake(str(furnace[1]))
    cam = camera_for(bake.scene, None)
    want = 0.6 * 2 / np.pi
    for offset in ((0.0, 0.0, 0.0), (-0.2, 0.1, 0.1)):
        img = snapshot(bake, cam, 64, 64, ctx=gl, objects=(Placed(0, offset),))
        c = np.add(CENTRE, offset)
        mask = _sphere_pixels(cam, 64, 64, c, 0.97 * RADIUS)
        assert mask.sum() > 200
        assert np.abs(img[mask] / want - 1).max() < 0.02
        # the walls around it read the furnace's own radiance 2 / pi
        assert abs(np.median(img[~_sphere_pixels(cam, 64, 64, c, 1.4 * RADIUS)]) / (2 / np.pi) - 1) < 0.03


@pytest.fixture(scope="module")
def cornell_ball(tmp_path_factory):
    """The Cornell box with a white ball (radius 5 cm) marked dynamic:
    its bake read back."""
    folder = tmp_path_factory.mktemp("dynamic_cornell")
    b = cornell_box()
    add_ball(b, centre=(0.28, 0.42, 0.28), radius=0.05, albedo=0.8, subdiv=4)
    src = folder / "cornell_ball.glb"
    b.save(str(src))
    out = folder / "cornell_ball_bake.glb"
    write_bake(str(out), bake_scene(load_scene(src, dynamic=("ball",)), small()).bake)
    return read_bake(str(out))


def test_a_dynamic_mesh_is_lit_as_the_sphere_object_is(cornell_ball, gl):
    """The dynamic ball (per-vertex irradiance from the probes,
    interpolated) and voxview's sphere object (a map over its normals) at
    the same place in the Cornell box: the same light, the mean over the
    ball's pixels within 1% and 95% of its pixels within 4% (0.3% and 3.1%
    at worst here, beside the lamp, where the light bends fastest)."""
    from baker.scene import camera_for
    from viewer.objects import Placed, Sphere
    from viewer.snapshot import snapshot
    bake = cornell_ball
    cam = camera_for(bake.scene, None)
    w = h = 96
    away = (0.0, 0.0, -5.0)   # behind the camera
    for centre in ((0.28, 0.42, 0.28), (0.12, 0.30, 0.40), (0.44, 0.42, 0.30)):
        offset = tuple(np.subtract(centre, (0.28, 0.42, 0.28)))
        mesh = snapshot(bake, cam, w, h, samples=1, ctx=gl, objects=(Placed(0, offset),))
        sphere = snapshot(bake, cam, w, h, samples=1, ctx=gl, objects=(Placed(0, away),
                                                                       Sphere(centre, 0.05, (0.8, 0.8, 0.8))))
        mask = _sphere_pixels(cam, w, h, centre, 0.97 * 0.05)
        assert mask.sum() > 60
        a, b = mesh[mask].sum(axis=1), sphere[mask].sum(axis=1)
        assert abs(a.mean() / b.mean() - 1) < 0.01, (centre, a.mean() / b.mean())
        assert np.quantile(np.abs(a / b - 1), 0.95) < 0.04, (centre, np.quantile(np.abs(a / b - 1), 0.95))


def test_a_dynamic_mesh_against_the_wall_of_the_dark_room_is_black(tmp_path, gl):
    """Moved into the dark room, touching the one-sided wall: every pixel
    exactly black; moved into the lit room beside it: lit."""
    from viewer.objects import placed_at
    b = two_rooms(wall_x=1.0)
    r = 0.1
    add_ball(b, centre=(0.5, 0.3, 0.5), radius=r, albedo=0.8, subdiv=3)
    src = tmp_path / "rooms_ball.glb"
    b.save(str(src))
    scene = load_scene(src, dynamic=("ball",))
    out = tmp_path / "rooms_ball_bake.glb"
    write_bake(str(out), bake_scene(scene, small(probe_spacing=0.125)).bake)
    bake = read_bake(str(out))
    assert_dark_beside_the_wall_and_lit(bake, gl, r, 0.97 * r,
                                        lambda centre: (placed_at(bake.scene.dynamic[0], 0, centre),))


def test_voxview_places_a_dynamic_mesh_by_name(furnace, tmp_path):
    from viewer.cli import main as viewer_main
    out = tmp_path / "s.exr"
    status, _, stderr = cli("snapshot", furnace[1], "-o", out, "--width", "48", "--height", "48", "--object", "ball",
                            "--at", "0.3,0.5,0.6", main=viewer_main)
    assert status == 0, stderr
    for args, said in ((("--object", "nosuch", "--at", "0.3,0.5,0.6"), "'ball'"),
                       (("--object", "ball"), "--at"),
                       (("--object", "ball", "--at", "0.3,0.5,0.6", "--radius", "0.1"), "--radius")):
        bad = tmp_path / "bad.png"
        status, _, stderr = cli("snapshot", furnace[1], "-o", bad, *args, main=viewer_main)
        assert status == 2 and "Traceback" not in stderr and len(stderr.strip().splitlines()) == 1, stderr
        assert said in stderr and not bad.exists()


def test_the_window_moves_a_dynamic_mesh(furnace, tmp_path):
    """voxview's window under Xvfb: the arrow keys move the bake's dynamic
    mesh (the one chosen first); the last frame differs from the same walk
    without a key, right of where it stood."""
    import subprocess
    import sys
    need_xvfb()
    from PIL import Image
    scripts = {"moved": [{"frame": 1, "key": "RIGHT", "action": "press"},
                         {"frame": 7, "key": "RIGHT", "action": "release"}], "still": []}
    shots = {}
    for name, script in scripts.items():
        (tmp_path / f"{name}.json").write_text(json.dumps(script))
        out = tmp_path / f"{name}.png"
        r = subprocess.run(["xvfb-run", "-a", "-s", "-screen 0 800x600x24", sys.executable, "-m", "viewer",
                            str(furnace[1]), "--script", str(tmp_path / f"{name}.json"), "--frames", "8",
                            "--screenshot", str(out), "--width", "160", "--height", "120", "--exposure", "0"],
                           capture_output=True, text=True, timeout=300)
        assert r.returncode == 0, r.stderr
        shots[name] = np.asarray(Image.open(out).convert("RGB"), float)
    diff = np.abs(shots["moved"] - shots["still"]).sum(axis=2) > 10
    assert 50 < diff.sum() < diff.size // 2
    rows, cols = np.nonzero(diff)
    # the ball leaves its place and shows right of it: the changed pixels' columns span both sides of where it was
    assert cols.max() > 80 + 20


def test_a_dynamic_mesh_with_a_nan_vertex_is_refused(tmp_path):
    """A dynamic node's own geometry is checked as the scene's is: a NaN
    corner is refused in one line naming the mesh."""
    import base64
    from tests.hostile import triangle_doc, write_gltf
    doc = triangle_doc()
    bad = np.array([[0, 0, 0], [1, 0, 0], [np.nan, 1, 0]], np.float32).tobytes()
    doc["buffers"].append({"byteLength": 36, "uri": "data:application/octet-stream;base64,"
                           + base64.b64encode(bad).decode()})
    doc["bufferViews"].append({"buffer": 1, "byteOffset": 0, "byteLength": 36})
    doc["accessors"].append({"bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC3",
                             "min": [0, 0, 0], "max": [1, 1, 0]})
    doc["meshes"].append({"primitives": [{"attributes": {"POSITION": 1}, "material": 0}]})
    doc["nodes"].append({"mesh": 1, "name": "prop"})
    doc["scenes"][0]["nodes"].append(1)
    path = write_gltf(tmp_path / "nan_prop.gltf", doc)
    with pytest.raises(SceneError, match="dynamic mesh 'prop': vertices or position not finite") as e:
        load_scene(path, dynamic=("prop",))
    assert "\n" not in e.value.one_line() and "nan_prop.gltf" in e.value.one_line()


def test_a_moving_mesh_takes_the_lamp_s_shadow_from_its_centre_until_it_stops(tmp_path, gl):
    """A ball under a lamp, half of it in the shadow of a plate whose edge
    lies over its centre. Each vertex's lamp light, with its shadow rays
    from the vertex, is interpolate's (the reference) exactly; in the
    window, while the ball moves, the lamp's shadow rays are traced once
    from its centre (half the lamp seen there: the shadowed side reads
    the lamp half lit), and the first frame it stands still from each
    vertex again. The sphere object's moving map likewise."""
    from baker.probes import interpolate
    from baker.scene.gltf_write import GltfBuilder
    from scenes.generate import box, quad
    from viewer.objects import DynamicMeshes
    b = GltfBuilder()
    grey = b.material("grey", (0.5, 0.5, 0.5))
    b.mesh("floor", *quad((-2, 0, -2), (2, 0, -2), (2, 0, 2), (-2, 0, 2), facing=(0, 1, 0)), grey)
    b.mesh("lamp", *quad((-0.3, 2, -0.3), (0.3, 2, -0.3), (0.3, 2, 0.3), (-0.3, 2, 0.3), facing=(0, -1, 0)),
           b.material("lamp", (0.0, 0.0, 0.0), emission=(10.0, 10.0, 10.0)))
    b.mesh("plate", *box((-2, 1.0, -2), (0.0, 1.02, 2)), grey)
    b.camera("cam", (0, 1.2, 3), (0, -0.3, -1))
    r = 0.3
    add_ball(b, centre=(0.0, 0.4, 0.0), radius=r, albedo=0.8, subdiv=3)
    src = tmp_path / "lamp_ball.glb"
    b.save(str(src))
    out = tmp_path / "lamp_ball_bake.glb"
    write_bake(str(out), bake_scene(load_scene(src, dynamic=("ball",)), small(probe_spacing=0.5)).bake)
    bake = read_bake(str(out))
    meshes = DynamicMeshes(gl, bake, interactive=True)
    e = meshes.meshes[0]
    assert len(meshes.lights.lamps.corners) == 2

    def held():
        return np.frombuffer(e["irr"].read(), np.float32).reshape(-1, 3).astype(np.float64)

    verts = bake.scene.dynamic[0].vertices.astype(np.float64)
    normals = bake.scene.dynamic[0].normals.astype(np.float64)
    off = np.array([0.01, 0.0, 0.0])
    meshes.update(0, (0.0, 0.0, 0.0))
    assert not e["coarse"]
    meshes.update(0, off)
    assert e["coarse"]
    coarse = held()
    meshes.update(0, off)
    assert not e["coarse"]
    exact = held()
    centre = e["center"] + off
    want = interpolate(bake.probes, verts + off, normals, np.repeat(centre[None], len(verts), 0),
                       meshes.bvh, meshes.lights)
    assert np.allclose(exact, want, rtol=1e-4, atol=1e-5)
    shadowed = (verts[:, 0] < -0.5 * r) & (normals[:, 1] > 0.5)   # up-facing, under the plate
    lit = (verts[:, 0] > 0.5 * r) & (normals[:, 1] > 0.5)
    assert shadowed.sum() > 5 and lit.sum() > 5
    assert exact[lit].mean() > 5 * exact[shadowed].mean()
    assert coarse[shadowed].mean() > 2 * exact[shadowed].mean()
    meshes.release()
    # the sphere object the same: its moving map takes the lamp's shadow from its centre
    from baker.probes.gather import texel_directions
    from baker.probes.sample import sphere_map
    from viewer.objects import probe_seen
    seen = probe_seen(bake.probes, centre, r, meshes.bvh)
    full, moving = (sphere_map(bake.probes, centre, r, seen, 16, meshes.lights, coarse=c).reshape(-1, 3)
                    for c in (False, True))
    n = texel_directions(16)
    shadowed, lit = (n[:, 0] < -0.5) & (n[:, 1] > 0.5), (n[:, 0] > 0.5) & (n[:, 1] > 0.5)
    assert full[lit].mean() > 5 * full[shadowed].mean()
    assert moving[shadowed].mean() > 2 * full[shadowed].mean()
