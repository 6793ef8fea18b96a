"""Hostile input and faults (one test per rule): no file outside the scene's
folder is read, sizes are checked against the bytes present, outputs never
replace an input, every bad flag is one line before any work, the bake file
is protected and validated whole, signals leave nothing behind, and the
bake's bytes do not depend on the thread count. Then a fuzz test: mutated
glTF, GLB and OBJ files load or fail in one line, never a traceback."""
import contextlib
import io
import json
import os
import random
import signal
import stat
import subprocess
import sys
import time

import pytest

from baker.errors import BakeFileError, SceneError, VoxgiError
from baker.scene import load_scene
from baker.scene.refs import LoadLimits

from .conftest import cli
from .hostile import (SECRET, TRIANGLE, glb_bytes, resign_bake, split_glb, tiny_png_header, triangle_doc,
                      write_gltf, write_obj)


def voxbake(*args, timeout=120, **kw):
    return subprocess.run([sys.executable, "-m", "baker", *map(str, args)], capture_output=True, timeout=timeout,
                          **kw)


def one_line_error(code, err, *words):
    """The refusal users should see: exit 2, one line `error: ...`, naming what."""
    lines = err.strip().splitlines()
    assert code == 2, err
    assert len(lines) == 1 and lines[0].startswith("error: ") and "Traceback" not in err, err
    for w in words:
        assert w in err, (w, err)
    assert SECRET.decode() not in err


@pytest.fixture
def room(tmp_path):
    """A scene folder with a secret file beside it (outside the folder)."""
    (tmp_path / "secret").mkdir()
    (tmp_path / "secret" / "token.txt").write_bytes(SECRET + b"\0" * 64)
    scene = tmp_path / "scene"
    scene.mkdir()
    return scene


# 1. Security: references resolve only to regular files inside the scene's folder

@pytest.mark.parametrize("uri,words", [
    ("../secret/token.txt", ["outside the scene's folder"]),
    ("%2E%2E/secret/token.txt", ["outside the scene's folder"]),   # escaped dots are still dots
    ("ABSOLUTE", ["an absolute path"]),
    ("/dev/zero", ["an absolute path"]),
    ("file:///etc/passwd", ["URLs are not read"]),
    ("http://127.0.0.1:9/x.bin", ["URLs are not read"]),
    ("link.bin", ["outside the scene's folder"]),                  # a symlink inside pointing out
    ("fifo.bin", ["not a regular file"]),
    ("sub", ["not a regular file"]),
])
def test_buffer_references_outside_the_folder_are_refused(room, uri, words):
    secret = room.parent / "secret" / "token.txt"
    if uri == "ABSOLUTE":
        uri = str(secret)
    os.symlink(secret, room / "link.bin")
    os.mkfifo(room / "fifo.bin")
    (room / "sub").mkdir()
    path = write_gltf(room / "s.gltf", triangle_doc(uri))
    t = time.perf_counter()
    code, out, err = cli("info", path)
    assert time.perf_counter() - t < 30  # a FIFO or /dev/zero is never opened
    one_line_error(code, err, "buffer 0 uri", *words)
    assert SECRET.decode() not in out


def test_outside_references_are_read_when_the_user_allows_them(room):
    secret = room.parent / "secret" / "token.txt"
    secret.write_bytes(TRIANGLE.tobytes())
    path = write_gltf(room / "s.gltf", triangle_doc("../secret/token.txt"))
    assert len(load_scene(path, limits=LoadLimits(allow_outside_refs=True)).triangles) == 1
    code, out, err = cli("info", path, "--allow-outside-refs")
    assert code == 0, err
    os.mkfifo(room / "f.bin")  # never a FIFO, even then
    with pytest.raises(SceneError, match="not a regular file"):
        load_scene(write_gltf(room / "g.gltf", triangle_doc("f.bin")), limits=LoadLimits(allow_outside_refs=True))


def test_image_references_outside_the_folder_are_refused(room, tmp_path):
    from PIL import Image
    Image.new("RGB", (4, 4), (255, 0, 0)).save(room.parent / "secret" / "tex.png")
    doc = triangle_doc()
    doc["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"] = {"index": 0}
    doc["textures"] = [{"source": 0}]
    doc["images"] = [{"uri": "../secret/tex.png"}]
    code, _, err = cli("bake", write_gltf(room / "s.gltf", doc), "-o", tmp_path / "out.glb", "--preset", "preview")
    one_line_error(code, err, "image 0 uri", "outside the scene's folder")
    assert not (tmp_path / "out.glb").exists()


@pytest.mark.parametrize("statement", ["mtllib ../secret/token.txt", "mtllib ABSOLUTE", "map_Kd ../secret/tex.png"])
def test_obj_references_outside_the_folder_are_refused(room, statement):
    from PIL import Image
    Image.new("RGB", (4, 4)).save(room.parent / "secret" / "tex.png")
    secret = room.parent / "secret" / "token.txt"
    if statement.startswith("mtllib"):
        path = write_obj(room, statement.split()[1].replace("ABSOLUTE", str(secret)), None)
    else:
        path = write_obj(room, "m.mtl", f"newmtl lamp\nKd 1 1 1\nKe 1 1 1\n{statement}\n")
    code, out, err = cli("info", path)
    one_line_error(code, err, "outside the scene's folder" if "ABSOLUTE" not in statement else "absolute path")


def test_a_fifo_scene_is_refused_at_once(tmp_path):
    os.mkfifo(tmp_path / "s.glb")
    code, _, err = cli("info", tmp_path / "s.glb")
    one_line_error(code, err, "not a regular file")


def test_error_messages_never_print_bytes_of_other_files(room):
    (room / "b.bin").write_bytes(SECRET)
    doc = triangle_doc("b.bin")
    doc["buffers"][0]["byteLength"] = len(SECRET)
    doc["bufferViews"][0]["byteLength"] = len(SECRET)
    doc["accessors"][0]["componentType"] = 5125
    doc["accessors"][0]["type"] = "SCALAR"
    code, _, err = cli("info", write_gltf(room / "s.gltf", doc))
    one_line_error(code, err, "componentType")


# 2. Memory: every size is checked against the bytes present

def peak_rss_of(cmd, timeout=120):
    """(exit status, stderr, peak resident MiB) of a command in a child
    process, under a 4 GiB limit on its data segment (an unbounded
    allocation fails there rather than taking the machine). The peak is
    the child's own high-water mark (VmHWM, read every 50 ms while it
    runs): its rusage would also count this test process's memory, which
    the forked child held until its exec."""
    import resource
    import tempfile

    def limit():
        resource.setrlimit(resource.RLIMIT_DATA, (4 << 30, 4 << 30))
    with tempfile.TemporaryFile() as err:
        p = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=err, preexec_fn=limit)
        deadline = time.monotonic() + timeout
        hwm = 0.0
        while True:
            try:
                with open(f"/proc/{p.pid}/status") as f:
                    hwm = max([hwm] + [int(line.split()[1]) / 1024 for line in f if line.startswith("VmHWM:")])
            except (OSError, ValueError):
                pass
            pid, status, usage = os.wait4(p.pid, os.WNOHANG)
            if pid:
                break
            if time.monotonic() > deadline:
                p.kill()
                raise TimeoutError(cmd)
            time.sleep(0.05)
        p.returncode = os.waitstatus_to_exitcode(status)
        err.seek(0)
        return p.returncode, err.read().decode(), hwm if hwm > 0 else usage.ru_maxrss / 1024


@pytest.mark.parametrize("edit,words", [
    (lambda d: d["accessors"][0].update(count=50_000_000, bufferView=None), "no bufferView"),
    (lambda d: d["accessors"][0].update(count=50_000_000), "need 600000000 bytes"),
    (lambda d: d["bufferViews"][0].update(byteLength=10 ** 12), "spans bytes"),
    (lambda d: d["buffers"][0].update(byteLength=10 ** 12), "fewer bytes than its byteLength"),
])
def test_sizes_beyond_the_bytes_present_are_refused_before_allocating(tmp_path, edit, words):
    doc = triangle_doc()
    edit(doc)
    path = write_gltf(tmp_path / "s.gltf", doc)
    code, err, peak = peak_rss_of([sys.executable, "-m", "baker", "info", str(path)])
    one_line_error(code, err, words)
    assert peak < 1500, peak  # the whole interpreter with numba loaded: a few hundred MiB


def test_a_buffer_file_shorter_than_its_byte_length_is_refused(tmp_path):
    (tmp_path / "b.bin").write_bytes(TRIANGLE.tobytes())
    doc = triangle_doc("b.bin")
    doc["buffers"][0]["byteLength"] = 10 ** 12
    code, _, err = cli("info", write_gltf(tmp_path / "s.gltf", doc))
    one_line_error(code, err, "holds 36 bytes, the file says 1000000000000")


def textured(tmp_path, png: bytes):
    (tmp_path / "t.png").write_bytes(png)
    doc = triangle_doc()
    doc["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"] = {"index": 0}
    doc["textures"] = [{"source": 0}]
    doc["images"] = [{"uri": "t.png"}]
    return write_gltf(tmp_path / "s.gltf", doc)


def test_a_huge_texture_header_is_refused(tmp_path):
    code, err, peak = peak_rss_of([sys.executable, "-m", "baker", "info",
                                   str(textured(tmp_path, tiny_png_header(100_000, 100_000)))])
    one_line_error(code, err, "image 0")
    assert peak < 1500, peak


def test_large_textures_are_scaled_down_with_a_warning(tmp_path):
    from PIL import Image
    buf = io.BytesIO()
    Image.new("RGB", (3000, 1000), (200, 100, 50)).save(buf, "PNG")
    path = textured(tmp_path, buf.getvalue())
    with pytest.warns(Warning, match="scaled down to 512x171"):
        scene = load_scene(path, limits=LoadLimits(max_texture=512))
    assert scene.materials[0].texture.shape == (171, 512, 3)
    with pytest.raises(VoxgiError, match="over the memory budget"):
        load_scene(path, limits=LoadLimits(memory_budget_mb=4))


# 3. Data loss: outputs never equal an input, and are regular files

def test_outputs_never_replace_an_input(tmp_path):
    scene = tmp_path / "s.glb"
    from baker.scene.load import resolve
    scene.write_bytes(open(resolve("cornell_box"), "rb").read())
    before = scene.read_bytes()
    os.link(scene, tmp_path / "hard.glb")
    os.symlink(scene, tmp_path / "soft.glb")
    for out in (scene, tmp_path / "." / "s.glb", tmp_path / "hard.glb", tmp_path / "soft.glb"):
        code, _, err = cli("bake", scene, "-o", out, "--preset", "preview")
        one_line_error(code, err, "the output is an input")
        code, _, err = cli("bake", scene, "-o", tmp_path / "o.glb", "--stats", out, "--preset", "preview")
        one_line_error(code, err)
    code, _, err = cli("render", scene, "-o", tmp_path / "o.png", "--stats", tmp_path / "o.png")
    one_line_error(code, err)
    assert scene.read_bytes() == before and not (tmp_path / "o.glb").exists()


def test_outputs_onto_devices_fifos_and_folders_are_refused(tmp_path):
    os.mkfifo(tmp_path / "fifo.json")
    (tmp_path / "dir.glb").mkdir()
    code, _, err = cli("bake", "cornell_box", "-o", tmp_path / "o.glb", "--stats", tmp_path / "fifo.json")
    one_line_error(code, err, "not a regular file")
    assert stat.S_ISFIFO(os.stat(tmp_path / "fifo.json").st_mode)
    code, _, err = cli("bake", "cornell_box", "-o", tmp_path / "dir.glb")
    one_line_error(code, err, "is a folder")
    code, _, err = cli("render", "cornell_box", "-o", tmp_path / "x.png", "--stats", os.devnull)
    one_line_error(code, err)
    assert stat.S_ISCHR(os.stat(os.devnull).st_mode)


# 4. The sun at the preview preset

def test_sun_at_preview_bakes_and_renders(tmp_path):
    code, _, err = cli("bake", "cornell_box", "-o", tmp_path / "o.glb", "--preset", "preview", "--sun", "30,45,3",
                       "--resolution", "16", "--preview-vpls", "0")
    assert code == 0, err
    code, _, err = cli("render", "cornell_box", "-o", tmp_path / "o.png", "--method", "voxels", "--preset",
                       "preview", "--sun", "30,45,3", "--resolution", "16", "--width", "16", "--height", "16")
    assert code == 0, err


# 5. Output problems found before the work, write errors in one line

def test_write_errors_are_one_line_and_leave_nothing(tmp_path, monkeypatch):
    import errno

    from baker.fileio import atomic_write

    def full(tmp):
        with open(tmp, "wb") as f:
            f.write(b"half")
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
    with pytest.raises(VoxgiError, match="No space left on device"):
        atomic_write(tmp_path / "x.glb", full)
    assert os.listdir(tmp_path) == []


def test_an_unwritable_folder_is_found_before_the_work(tmp_path, monkeypatch):
    import tempfile

    def refuse(*a, **k):
        raise PermissionError(13, "Permission denied")
    monkeypatch.setattr(tempfile, "mkstemp", refuse)
    t = time.perf_counter()
    code, _, err = cli("bake", "cornell_box", "-o", tmp_path / "o.glb")
    one_line_error(code, err, "cannot write in the output folder")
    assert time.perf_counter() - t < 5


def test_a_failed_stats_file_says_the_main_output_was_written(tmp_path, monkeypatch):
    from baker import stats
    monkeypatch.setattr(stats.Stats, "write", lambda self, p: (_ for _ in ()).throw(VoxgiError("disk full", p)))
    code, _, err = cli("render", "cornell_box", "-o", tmp_path / "o.png", "--stats", tmp_path / "s.json",
                       "--method", "pathtrace", "--spp", "1", "--width", "8", "--height", "8")
    last = err.strip().splitlines()[-1]  # after the work's own report
    assert code == 2 and last.startswith("error: ") and "the main output" in last and "was written" in last, err
    assert err.count("error: ") == 1 and "Traceback" not in err and (tmp_path / "o.png").exists()


# 6. Numeric flags: a stated range, checked while parsing

@pytest.mark.parametrize("flags", [
    ["--photons", "1" + "0" * 30], ["--seed", "1" + "0" * 30], ["--cell-size", "1e-300x"], ["--cell-size", "nan"],
    ["--cell-size", "inf"], ["--cell-size", "0"], ["--photons-per-voxel", "inf"], ["--max-bounces", "1000000000"],
    ["--memory-budget", "nan"], ["--tolerance", "nan"], ["--exposure", "1e308"], ["--exposure", "nan"],
    ["--epsilon", "-1"], ["--epsilon", "nan"], ["--epsilon", "inf"], ["--sky", "1e308,1,1"], ["--sky", "nan,1,1"],
    ["--sun", "30,45,1e300"], ["--width", "0"], ["--spp", "-1"], ["--threads", "-3"], ["--fov", "200"],
    ["--radius", "1000"], ["--surface-cells", "0"], ["--max-texture", "1"], ["--noise", "0"],
    ["--time-limit", "-1"], ["--frames", "0"], ["--resolution", "99999999"], ["--bogus"],
])
def test_numeric_flags_out_of_range_are_one_line(tmp_path, flags):
    t = time.perf_counter()
    code, _, err = cli("render", "cornell_box", "-o", tmp_path / "x.png", *flags)
    one_line_error(code, err, flags[0])
    assert time.perf_counter() - t < 2 and not (tmp_path / "x.png").exists()


@pytest.mark.parametrize("flags", [["--preview-vpls", "1" + "0" * 30], ["--texel-density", "nan"],
                                   ["--texel-density", "0"], ["--texel-samples", "0"], ["--preset", "ultra"]])
def test_bake_flags_out_of_range_are_one_line(tmp_path, flags):
    code, _, err = cli("bake", "cornell_box", "-o", tmp_path / "x.glb", *flags)
    one_line_error(code, err, flags[0])


def test_viewer_flags_are_one_line(tmp_path):
    from viewer.cli import main as voxview
    for flags in (["--width", "0"], ["--exposure", "nan"], ["--samples", "1000"], ["--frames", "-1"]):
        err = io.StringIO()
        with contextlib.redirect_stderr(err):
            try:
                code = voxview(["snapshot", "x.glb", "-o", str(tmp_path / "x.png"), *flags])
            except SystemExit as e:
                code = e.code
        one_line_error(code, err.getvalue(), flags[0])


# 7. glTF validation

@pytest.mark.parametrize("edit,words", [
    (lambda d: d["accessors"][0].update(count=-5), "count is -5"),
    (lambda d: d["meshes"][0]["primitives"][0].update(indices=1) or d["accessors"].append(
        {"bufferView": 0, "componentType": 5126, "count": 3, "type": "SCALAR"}), "componentType 5126"),
    (lambda d: d["bufferViews"][0].update(byteLength=37), "spans bytes 0..37"),
    (lambda d: d["meshes"][0]["primitives"][0].update(material=7), "material index"),
    (lambda d: d["nodes"][0].update(mesh=3), "mesh index"),
    (lambda d: d["nodes"][0].update(children=[0]), "deeper than 256"),
    (lambda d: d["asset"].update(version="3.0"), "glTF version '3.0'"),
    (lambda d: d.update(extensionsRequired=["EXT_meshopt_compression"]), "EXT_meshopt_compression"),
    (lambda d: d["bufferViews"][0].update(extensions={"EXT_meshopt_compression": {"buffer": 0}}) or d.update(
        extensionsUsed=["EXT_meshopt_compression"]), "compressed with EXT_meshopt_compression"),
    (lambda d: d["materials"][0].update(emissiveFactor=[float("nan")] * 3), "emissiveFactor"),
    (lambda d: d["accessors"][0].update(type="MAT4"), "type 'MAT4'"),
])
def test_invalid_gltf_fields_are_one_line(tmp_path, edit, words):
    doc = triangle_doc()
    edit(doc)
    with pytest.raises(SceneError, match=words.replace("(", r"\(").replace(".", r"\.")):
        load_scene(write_gltf(tmp_path / "s.gltf", doc))


# 8. The bake file: the whole file is protected, and validated behind the checksum

@pytest.fixture(scope="module")
def small_bake(tmp_path_factory):
    out = tmp_path_factory.mktemp("bake") / "c.glb"
    code, _, err = cli("bake", "cornell_box", "-o", out, "--preset", "preview", "--resolution", "16",
                       "--preview-vpls", "64")
    assert code == 0, err
    return out.read_bytes()


def test_the_checksum_is_found_in_the_json_whatever_the_binary_chunk_holds(tmp_path):
    """The binary chunk may hold the placeholder's 64 ASCII zeros (a float
    0x30303030, PNG bytes) or the digest itself: the writer and the reader
    use the JSON's fileSha256 key alone (a staircase bake once died on an
    assertion here)."""
    import hashlib
    from baker.scene.gltf_write import GltfBuilder, file_checksum
    b = GltfBuilder()
    b._view(b"0" * 64 + b"\x00" * 8 + b"0" * 64)
    path = b.save(tmp_path / "z.glb", extras={}, checksum_key="voxgi")
    data = path.read_bytes()
    doc, blob = split_glb(data)
    stated = doc["extras"]["voxgi"]["fileSha256"]
    assert blob.count(b"0" * 64) == 2 and file_checksum(data, stated) == stated
    # the digest copied into the binary chunk as well: still found at the key, and still the whole file's hash
    twice = glb_bytes(doc, blob + stated.encode())
    at = twice.find(b'"fileSha256": "') + len(b'"fileSha256": "')   # json.dumps puts a space after the colon
    assert file_checksum(twice, stated) == hashlib.sha256(twice[:at] + b"0" * 64 + twice[at + 64:]).hexdigest()
    assert file_checksum(twice, stated) != stated   # the file changed: the stated digest is now wrong
    # the key twice in the JSON: no checksum
    doc["extras"]["other"] = {"fileSha256": stated}
    assert file_checksum(glb_bytes(doc, blob), stated) is None


def test_a_one_byte_json_edit_is_refused(small_bake, tmp_path):
    from baker.bake import read_bake
    data = small_bake.replace(b'"exrScale":1.0', b'"exrScale":9.0', 1)
    assert data != small_bake
    (tmp_path / "e.glb").write_bytes(data)
    with pytest.raises(BakeFileError, match="checksum"):
        read_bake(tmp_path / "e.glb")


@pytest.mark.parametrize("edit,words", [
    (lambda d: d["accessors"][0].update(componentType=5121), "componentType"),
    (lambda d: d["meshes"][0]["primitives"][0].update(material=999), "material index"),
    (lambda d: d["asset"].update(version="3.0"), "glTF version"),
    (lambda d: d["extensions"]["VOXGI_lightmap"]["pages"][0].update(bufferView=-1), "bufferView"),
    (lambda d: d["extensions"]["VOXGI_lightmap"]["pages"][0].update(size=10 ** 6), "page size"),
    (lambda d: d["extensions"]["VOXGI_lightmap"]["vpls"].update(count=10 ** 9), "count"),
    (lambda d: d["materials"][0]["extensions"]["VOXGI_lightmap"].update(page=5), "page"),
    (lambda d: d["extensions"]["VOXGI_lightmap"].update(sky={"radiance": [1, -1, 1]}), "damaged sky"),
    (lambda d: d["extensions"]["VOXGI_lightmap"].update(sky={"radiance": [1, 1]}), "damaged sky"),
    (lambda d: d["extensions"]["VOXGI_lightmap"].update(sky={"radiance": [1, 1, 1e400]}), "damaged sky"),
    (lambda d: d["extensions"]["VOXGI_lightmap"].update(sky={"radiance": "x"}), "damaged sky"),
    (lambda d: d["extensions"]["VOXGI_lightmap"].update(sky={"radiance": [1, 1, 1], "hemisphere": 2}),
     "damaged sky"),
    (lambda d: d["extensions"]["VOXGI_lightmap"].update(sky=[1, 1, 1]), "damaged sky"),
    (lambda d: d["images"].append({"uri": "../../etc/passwd"}) or d["textures"].append({"source": len(
        d["images"]) - 1}) or d["materials"][0]["pbrMetallicRoughness"].update(
        baseColorTexture={"index": len(d["textures"]) - 1}), "outside the scene's folder"),
])
def test_re_signed_bake_edits_are_validated(small_bake, tmp_path, edit, words):
    from baker.bake import read_bake
    path = tmp_path / "e.glb"
    path.write_bytes(resign_bake(small_bake, edit))
    with pytest.raises(BakeFileError, match=words):
        read_bake(path)
    code, _, err = cli("render", path, "--method", "lightmap", "-o", tmp_path / "x.png", "--width", "8",
                       "--height", "8")
    one_line_error(code, err)


def test_the_format_version_message_names_the_files_version(small_bake, tmp_path):
    from baker.bake import read_bake
    path = tmp_path / "v.glb"
    path.write_bytes(resign_bake(small_bake, lambda d: d["extensions"]["VOXGI_lightmap"].update(version=7)))
    with pytest.raises(BakeFileError, match="bake format version 7, this voxgi reads version 2"):
        read_bake(path)


# 9. Signals and leftovers

def test_sigterm_is_answered_like_ctrl_c(tmp_path):
    out = tmp_path / "o.glb"
    p = subprocess.Popen([sys.executable, "-m", "baker", "bake", "cornell_box", "-o", str(out), "--preset", "high"],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    time.sleep(4)
    p.send_signal(signal.SIGTERM)
    _, err = p.communicate(timeout=120)
    assert p.returncode == 143 and "interrupted: nothing was written" in err and "Traceback" not in err, err
    assert os.listdir(tmp_path) == []


def test_stray_temporaries_of_dead_runs_are_removed(tmp_path):
    p = subprocess.Popen(["true"])
    p.wait()
    stray = tmp_path / f".voxgi-{p.pid}-abc.glb"
    stray.write_bytes(b"half")
    mine = tmp_path / f".voxgi-{os.getpid()}-live.glb"  # a run still going: kept
    mine.write_bytes(b"busy")
    code, _, err = cli("render", "cornell_box", "-o", tmp_path / "o.png", "--spp", "1", "--width", "8",
                       "--height", "8")
    assert code == 0, err
    assert not stray.exists() and mine.exists()


def test_ctrl_c_during_the_write_keeps_the_old_output(tmp_path):
    from baker import startup
    from baker.fileio import atomic_write
    target = tmp_path / "o.glb"
    target.write_bytes(b"old")

    def writer(tmp):
        with open(tmp, "wb") as f:
            f.write(b"new")
        startup._note(signal.SIGINT, None)  # as the handler does when Ctrl-C comes during the write
    with pytest.raises(KeyboardInterrupt):
        atomic_write(target, writer)
    assert target.read_bytes() == b"old" and os.listdir(tmp_path) == ["o.glb"]


def test_ctrl_c_at_start_up_prints_no_traceback(tmp_path):
    # from the moment our package starts to import: the interpreter's own start (~40 ms, before any of our
    # code runs) is Python's, measured here on this machine as it is loaded now
    starts = []
    for _ in range(3):
        t = time.perf_counter()
        subprocess.run([sys.executable, "-c", "pass"])
        starts.append(time.perf_counter() - t)
    base = 1.5 * max(starts)
    for delay in (base, base + 0.1, base + 0.3, base + 0.6):
        p = subprocess.Popen([sys.executable, "-m", "baker", "info", "cornell_box"], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True)
        time.sleep(delay)
        p.send_signal(signal.SIGINT)
        _, err = p.communicate(timeout=60)
        if p.returncode != 0:
            assert p.returncode == 130 and "Traceback" not in err, (delay, err)



def test_ctrl_c_while_a_finished_command_exits_is_ignored():
    # Python's finalization resets a Python signal handler to SIG_DFL: a Ctrl-C landing there, after the work
    # is done, killed the process by the signal (exit -2). The finished command ignores it instead.
    code = ("import sys, os, signal; sys.argv[0] = 'voxbake'; import baker; from baker.startup import run; "
            "assert signal.getsignal(signal.SIGINT) is not signal.default_int_handler; "
            "rc = run(lambda: 0); "
            "assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN, signal.getsignal(signal.SIGINT); "
            "assert signal.getsignal(signal.SIGTERM) is signal.SIG_IGN; "
            "os.kill(os.getpid(), signal.SIGINT); os.kill(os.getpid(), signal.SIGTERM); raise SystemExit(rc)")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, (p.returncode, p.stderr)


# 10. The file does not depend on the thread count

def test_bake_bytes_do_not_depend_on_the_thread_count(tmp_path):
    outs = []
    for n in (1, 2):
        out = tmp_path / f"t{n}.glb"
        code, _, err = cli("bake", "cornell_box", "-o", out, "--preset", "preview", "--resolution", "16",
                           "--threads", n, "--preview-vpls", "256")
        assert code == 0, err
        outs.append(out.read_bytes())
    assert outs[0] == outs[1]
    doc, _ = split_glb(outs[0])
    assert "threads" not in json.dumps(doc["extras"])


# Fuzz: mutated files load or fail in one line

def mutants(data: bytes, n, seed):
    rng = random.Random(seed)
    for _ in range(n):
        b = bytearray(data)
        for _ in range(rng.choice((1, 1, 1, 2, 4))):
            i = rng.randrange(len(b))
            op = rng.random()
            if op < 0.5:
                b[i] = rng.randrange(256)
            elif op < 0.7:
                b[i:i + rng.randrange(1, 8)] = b""
            elif op < 0.85:
                b[i:i] = bytes(rng.choice(b"0123456789-e.,[]{}\":") for _ in range(rng.randrange(1, 6)))
            else:
                b[i:i] = str(rng.choice((-1, 0, 2 ** 31, 2 ** 63, 10 ** 30))).encode()
        yield bytes(b)


@contextlib.contextmanager
def time_limit(seconds):
    def alarm(signum, frame):
        raise TimeoutError(f"no answer in {seconds} s")
    old = signal.signal(signal.SIGALRM, alarm)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


def test_fuzzed_files_load_or_fail_in_one_line(tmp_path):
    doc = triangle_doc()
    gltf = json.dumps(doc, indent=1).encode()
    glb = glb_bytes(doc, TRIANGLE.tobytes())
    write_obj(tmp_path, "m.mtl")
    obj = (tmp_path / "s.obj").read_bytes() + b"v 0 0 1\nf 1 2 4\nf -1 -2 -3\n"
    (tmp_path / "secret.txt").write_bytes(SECRET)
    limits = LoadLimits(memory_budget_mb=256)
    outcomes = {"ok": 0, "refused": 0}
    for name, data, seed in (("s.gltf", gltf, 1), ("s.glb", glb, 2), ("s.obj", obj, 3)):
        for k, mutant in enumerate(mutants(data, 200, seed)):
            path = tmp_path / name
            path.write_bytes(mutant)
            try:
                with time_limit(10):
                    load_scene(path, limits=limits)
                outcomes["ok"] += 1
            except VoxgiError as e:
                line = f"error: {e.one_line()}"
                assert "\n" not in line and SECRET.decode() not in line and len(line) < 400, line
                outcomes["refused"] += 1
    assert outcomes["ok"] > 10 and outcomes["refused"] > 100, outcomes  # the mutants reach both ends
