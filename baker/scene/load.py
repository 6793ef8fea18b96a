"""Loading a scene file (glTF 2.0, OBJ/MTL, PLY) or a built-in scene by name
into a validated `Scene`."""
from __future__ import annotations

import os
import warnings
from dataclasses import replace
from importlib.resources import files

import numpy as np

from ..errors import SceneError, VoxgiError, VoxgiWarning
from .model import DynamicMesh, Scene, Sky, make_material
from .overlaps import MAX_PIECES, cut_overlaps
from .refs import LoadLimits, check_regular, read_file

FORMATS = (".glb", ".gltf", ".obj", ".ply")


BUILTIN_FORMATS = (".glb", ".obj")


def _builtin_files() -> dict:
    """name -> file name of the scenes shipped with the package (`scenes/*.glb`, `scenes/*.obj`)."""
    try:
        return {os.path.splitext(p.name)[0]: p.name for p in files("scenes").iterdir()
                if os.path.splitext(p.name)[1] in BUILTIN_FORMATS}
    except (ModuleNotFoundError, FileNotFoundError):
        return {}


def builtin_scenes() -> list:
    """Names of the scenes shipped with the package."""
    return sorted(_builtin_files())


def resolve(path) -> str:
    """A file path, or the path of a built-in scene given by name
    (`cornell_box`), so that commands work from any folder and install."""
    path = os.fspath(path)
    if os.path.exists(path) or os.path.splitext(path)[1].lower() in FORMATS or os.sep in path:
        return path
    builtin = _builtin_files()
    if path in builtin:
        return str(files("scenes").joinpath(builtin[path]))
    return path


def load_scene(path, one_sided=False, lights=(), sky: Sky | None = None,
               limits: LoadLimits = LoadLimits(), dynamic=()) -> Scene:
    """Loads a .gltf/.glb, .obj or .ply file (or a built-in scene by name)
    into a validated `Scene`, with extra punctual `lights` and a `sky` (a
    scanned model has no lamp of its own).

    OBJ and PLY carry no sidedness: they are double-sided unless `one_sided`.
    `limits` (scene/refs.py): which files the scene may make us read (its
    own folder only, regular files only) and how much memory the load may
    take. Raises SceneError naming the file and the problem; what the file
    holds that the baker ignores or repairs becomes a VoxgiWarning (and is
    kept in `Scene.warnings`). `dynamic`: glTF node names whose meshes
    move at run time (Scene.dynamic): not baked, lit by the probes.
    """
    path = resolve(path)
    if not os.path.lexists(path):
        known = builtin_scenes()
        hint = f" (built-in scenes: {', '.join(known)})" if known and os.sep not in path else ""
        raise SceneError(f"file not found{hint}", path)
    try:
        check_regular(path)
    except SceneError as e:
        raise SceneError(str(e).replace("the scene: ", ""), path) from None
    ext = os.path.splitext(path)[1].lower()
    if dynamic and ext not in (".gltf", ".glb"):
        raise SceneError(f"--dynamic names glTF nodes; a {ext or 'file without extension'} file has none", path)
    try:
        if ext in (".gltf", ".glb"):
            from .gltf_read import read_gltf
            parts = read_gltf(path, limits, tuple(dynamic))
        elif ext == ".obj":
            from .obj import read_obj
            parts = read_obj(path, not one_sided, limits)
        elif ext == ".ply":
            parts = _read_ply(path, not one_sided, limits)
        else:
            raise SceneError(f"unsupported format {ext or '(no extension)'!r}; use {', '.join(FORMATS)}", path)
    except SceneError as e:
        if e.path is None:
            e.path = path
        raise
    except (KeyboardInterrupt, MemoryError, VoxgiError):
        raise
    except Exception as e:  # a parser's own exception: say which file, in one line (never the bytes it read)
        raise SceneError(f"cannot read ({type(e).__name__})", path) from e
    parts["lights"] = tuple(parts.get("lights", ())) + tuple(lights)
    parts.pop("uvs1", None)  # a bake file's lightmap UVs and material extensions: the bake reader's business
    parts.pop("material_extensions", None)
    return scene_from_parts(path, sky=sky, **parts)


def scene_from_parts(path, vertices, triangles, material_ids, materials, normals=None, uvs=None, cameras=(),
                     lights=(), sky=None, notes=(), clean=True, dynamic=()) -> Scene:
    """A validated Scene from a reader's arrays: finite vertices, indices
    in range, sane materials; with `clean`, degenerate and duplicate
    triangles dropped and coplanar overlaps cut (a bake file's geometry
    is read as written: clean=False). dynamic: dicts of DynamicMesh's
    fields, checked alike (never cleaned: they are drawn, not baked)."""
    vertices = np.asarray(vertices, np.float64).reshape(-1, 3)
    triangles = np.asarray(triangles, np.int64).reshape(-1, 3)
    material_ids = np.asarray(material_ids, np.int64).reshape(-1)
    notes = list(notes)
    if len(triangles) == 0:
        raise SceneError("no triangles", path)
    if not np.isfinite(vertices).all():
        bad = int((~np.isfinite(vertices)).any(axis=1).sum())
        raise SceneError(f"{bad} vertices are NaN or infinite", path)
    if triangles.min() < 0 or triangles.max() >= len(vertices):
        raise SceneError(f"triangle indices out of range (0..{len(vertices) - 1}, found "
                         f"{triangles.min()}..{triangles.max()})", path)
    if np.abs(vertices).max() > 1e18:
        raise SceneError("vertex coordinates beyond 1e18", path)
    for what, arr, width in (("normals", normals, 3), ("texture coordinates", uvs, 2)):
        if arr is not None and (np.shape(arr) != (len(vertices), width) or not np.isfinite(arr).all()):
            raise SceneError(f"{what}: not one finite {width}-vector per vertex", path)
    if len(material_ids) != len(triangles) or material_ids.min() < 0 or material_ids.max() >= len(materials):
        raise SceneError("material indices out of range", path)
    materials = _checked_materials(path, materials, notes)
    moving = tuple(_dynamic_mesh(path, d, len(materials)) for d in dynamic)
    if not clean:
        return Scene(vertices=vertices.astype(np.float32), triangles=triangles.astype(np.int32),
                     material_ids=material_ids.astype(np.int32), materials=tuple(materials),
                     normals=None if normals is None else np.asarray(normals, np.float32),
                     uvs=None if uvs is None else np.asarray(uvs, np.float32),
                     cameras=tuple(cameras), lights=tuple(lights), sky=sky, path=path, dynamic=moving)
    c = vertices[triangles]
    area2 = np.linalg.norm(np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0]), axis=1)
    scale = float(np.abs(vertices).max()) or 1.0
    # Below float32's resolution at this scale a triangle has no usable area.
    degenerate = area2 <= 1e-14 * scale * scale
    if degenerate.any():
        n = int(degenerate.sum())
        notes.append(f"{path}: dropped {n} degenerate (zero-area) triangle{'s' * (n != 1)}")
        triangles, material_ids = triangles[~degenerate], material_ids[~degenerate]
        if len(triangles) == 0:
            raise SceneError("every triangle is degenerate", path)
    duplicate = duplicate_triangles(vertices.astype(np.float32)[triangles])
    if duplicate.any():
        n = int(duplicate.sum())
        notes.append(f"{path}: dropped {n} duplicate triangle{'s' * (n != 1)} (the same corners, in the same "
                     f"order, as another: one surface counts once)")
        triangles, material_ids = triangles[~duplicate], material_ids[~duplicate]
    emits = np.array([max(m.emission) > 0 for m in materials], bool)
    two_sided = np.array([m.double_sided for m in materials], bool)
    vertices, triangles, material_ids, normals, uvs, (n_cut, cut_area, n_whole) = cut_overlaps(
        vertices, triangles, material_ids, emits, two_sided,
        None if normals is None else np.asarray(normals, np.float64),
        None if uvs is None else np.asarray(uvs, np.float64))
    if n_whole:
        notes.append(f"{path}: left {n_whole} coplanar triangle{'s' * (n_whole != 1)} whole although others "
                     f"overlap {'them' if n_whole != 1 else 'it'}: cutting would need more than "
                     f"{MAX_PIECES} pieces each (the overlap is lit twice there)")
    if n_cut:
        notes.append(f"{path}: cut the overlapping part out of {n_cut} coplanar triangle{'s' * (n_cut != 1)} "
                     f"({cut_area:.4g} scene units^2, covered by another facing the same way: one surface counts "
                     f"once)")
    scene = Scene(vertices=vertices.astype(np.float32), triangles=triangles.astype(np.int32),
                  material_ids=material_ids.astype(np.int32), materials=tuple(materials),
                  normals=None if normals is None else np.asarray(normals, np.float32),
                  uvs=None if uvs is None else np.asarray(uvs, np.float32),
                  cameras=tuple(cameras), lights=tuple(lights), sky=sky, path=path, dynamic=moving)
    if not scene.has_light():
        notes.append(f"{path}: the scene has no emitter (no emissive material, no punctual light): it will bake "
                     f"black unless lit with --sky or --sun")
    for note in notes:
        warnings.warn(note, VoxgiWarning, stacklevel=3)
    return replace(scene, warnings=tuple(notes))


def _dynamic_mesh(path, d: dict, n_materials: int) -> DynamicMesh:
    """A DynamicMesh from a reader's dict, every array checked."""
    name = str(d["name"])
    v = np.asarray(d["vertices"], np.float64).reshape(-1, 3)
    t = np.asarray(d["triangles"], np.int64).reshape(-1, 3)
    m = np.asarray(d["material_ids"], np.int64).reshape(-1)
    n = np.asarray(d["normals"], np.float64).reshape(-1, 3)
    pivot = np.asarray(d["pivot"], np.float64).reshape(-1)
    what = f"dynamic mesh {name!r}"
    if len(t) == 0:
        raise SceneError(f"{what}: no triangles", path)
    if pivot.shape != (3,) or not np.isfinite(pivot).all() or not np.isfinite(v).all() or np.abs(v).max() > 1e18:
        raise SceneError(f"{what}: vertices or position not finite (or beyond 1e18)", path)
    if t.min() < 0 or t.max() >= len(v):
        raise SceneError(f"{what}: triangle indices out of range (0..{len(v) - 1})", path)
    if len(m) != len(t) or m.min() < 0 or m.max() >= n_materials:
        raise SceneError(f"{what}: material indices out of range", path)
    if n.shape != v.shape or not np.isfinite(n).all():
        raise SceneError(f"{what}: not one finite normal per vertex", path)
    uv = d.get("uvs")
    if uv is not None:
        uv = np.asarray(uv, np.float64).reshape(-1, 2)
        if len(uv) != len(v) or not np.isfinite(uv).all():
            raise SceneError(f"{what}: not one finite texture coordinate per vertex", path)
    n = n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)
    return DynamicMesh(name, pivot, v.astype(np.float32), t.astype(np.int32), m.astype(np.int32),
                       n.astype(np.float32), None if uv is None else uv.astype(np.float32))


def _checked_materials(path, materials, notes) -> list:
    """Materials with finite, non-negative colours; albedo above 1 (which
    would create energy at every bounce) is clamped to 1 with a note."""
    out, clamped = [], []
    for i, m in enumerate(materials):
        for what, v in (("albedo", m.albedo), ("emission", m.emission)):
            if len(v) != 3 or not np.isfinite(v).all() or (v < 0).any() or (v > 1e30).any():
                raise SceneError(f"material {i} ({m.name!r}): {what} must be 3 finite numbers in 0..1e30", path)
        if (m.albedo > 1).any():
            clamped.append(m.name)
            m = replace(m, albedo=np.minimum(m.albedo, 1).astype(np.float32))
        out.append(m)
    if clamped:
        notes.append(f"{path}: albedo above 1 clamped to 1 in {', '.join(repr(n) for n in clamped)}")
    return out


def duplicate_triangles(corners) -> np.ndarray:
    """(nt,) bool: triangles whose corners (nt, 3, 3) repeat an earlier
    triangle's with the same winding (any first corner). A file that gives
    one face twice (the classic Cornell box OBJ repeats a box's front face
    as its "bottom") would otherwise count its area twice. The same corners
    in the opposite winding are the two faces of a sheet, and stay."""
    c = np.ascontiguousarray(corners, np.float32) + np.float32(0.0)  # -0.0 as 0.0

    def less(a, b):  # corner a before corner b, lexicographically (x, y, z)
        pa, pb = c[:, a], c[:, b]
        return (pa[:, 0] < pb[:, 0]) | ((pa[:, 0] == pb[:, 0]) & ((pa[:, 1] < pb[:, 1]) |
                                                                   ((pa[:, 1] == pb[:, 1]) & (pa[:, 2] < pb[:, 2]))))
    l01, l02, l12 = less(0, 1), less(0, 2), less(1, 2)
    first = np.where(l01 & l02, 0, np.where(~l01 & l12, 1, 2))
    rot = (first[:, None] + np.arange(3)[None, :]) % 3  # the smallest corner first, the winding kept
    canon = np.ascontiguousarray(np.take_along_axis(c, rot[:, :, None], axis=1).reshape(len(c), 9))
    _, index = np.unique(canon.view(np.dtype((np.void, 36))).ravel(), return_index=True)
    repeat = np.ones(len(c), bool)
    repeat[index] = False
    return repeat


def _read_ply(path, double_sided, limits: LoadLimits):
    """A PLY file through trimesh, its header's element counts checked
    against the bytes present first. It is handed over as bytes, so no
    texture named in its comments is opened."""
    import io

    import trimesh
    data = read_file(path, None, path, "the scene")
    _check_ply_header(data, path, limits)
    mesh = trimesh.load(io.BytesIO(data), file_type="ply", force="mesh", process=False)
    if not hasattr(mesh, "faces") or len(mesh.faces) == 0:
        raise SceneError("no triangles (a point cloud?)", path)
    return dict(vertices=np.asarray(mesh.vertices), triangles=np.asarray(mesh.faces),
                material_ids=np.zeros(len(mesh.faces)),
                materials=[make_material("default", double_sided=double_sided)])


_PLY_SIZES = {"char": 1, "uchar": 1, "int8": 1, "uint8": 1, "short": 2, "ushort": 2, "int16": 2, "uint16": 2,
              "int": 4, "uint": 4, "int32": 4, "uint32": 4, "float": 4, "float32": 4, "double": 8, "float64": 8}


def _check_ply_header(data: bytes, path, limits: LoadLimits):
    """SceneError if the header's element counts need more bytes than the
    file holds (a binary element needs its fixed-size properties, a list at
    least its count; an ASCII one at least two characters a property)."""
    end = data.find(b"end_header")
    if not data.startswith(b"ply") or end < 0:
        raise SceneError("not a PLY file (no 'ply' magic or no end_header)", path)
    header = data[:end].decode("ascii", errors="replace").split("\n")
    fmt = next((line.split()[1] for line in header if line.startswith("format ") and len(line.split()) > 1), "")
    need, count, elements = 0, 0, 0
    for line in header:
        w = line.split()
        if not w:
            continue
        if w[0] == "element" and len(w) >= 3:
            try:
                count = int(w[2])
            except ValueError:
                raise SceneError(f"PLY header: element count {w[2]!r} is not a number", path) from None
            if count < 0:
                raise SceneError(f"PLY header: negative element count {count}", path)
            elements += count
        elif w[0] == "property" and len(w) >= 3:
            if fmt == "ascii":
                need += 2 * count
            elif w[1] == "list" and len(w) >= 5:
                need += _PLY_SIZES.get(w[2], 1) * count
            else:
                need += _PLY_SIZES.get(w[1], 1) * count
    present = len(data) - end
    if need > present:
        raise SceneError(f"PLY header promises {elements} elements needing at least {need} bytes; the file holds "
                         f"{present} after its header (truncated?)", path)
    limits.check_bytes(float(elements) * 200, f"{elements} PLY elements", path)
