"""Wavefront OBJ and MTL, read as the format says.

OBJ: `v` positions, `vt` texture coordinates, `f` polygons whose vertex
references `v`, `v/vt`, `v//vn` or `v/vt/vn` count from 1, or from the end
of the list read so far when negative (-1 is the latest vertex); `usemtl`
names the material of the faces after it (faces before any `usemtl` get a
default grey), `mtllib` names MTL files (a name may hold spaces), `g`, `o`,
`s`, lines and points carry no area and are skipped. Polygons of more than
three vertices are split into triangles: a fan when convex, ear clipping
in the polygon's plane when not.

MTL: `Kd` (albedo), `Ke` (emitted radiance), `map_Kd` (albedo texture,
options before the file name skipped). The baker treats every surface as
diffuse: specular, transparent and reflective terms are named once in a
warning (`ignored_terms`).

trimesh's grouped OBJ import was tried first and mis-reads negative
indices under groups (half the Cornell box's quads degenerate); tinyobjloader
splits an `mtllib` name at its spaces. Both left too much to work around.
"""
from __future__ import annotations

import os

import numpy as np

from ..errors import SceneError
from .model import make_material
from .refs import LoadLimits, read_file, resolve_reference
from .textures import decode_texture

DEFAULT = "default"  # the material of faces before any usemtl, and of names no MTL defines


def parse_mtl(path) -> dict:
    """name -> {key: values} of an MTL file (keys as written: Kd, Ke, Ks,
    map_Kd, ...; numbers as float lists, map_ values as a file name)."""
    out, cur = {}, None
    text = read_file(path, None, path, "material library").decode("utf-8", errors="replace")
    for line in text.splitlines():
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        key, rest = (line.split(None, 1) + [""])[:2]
        rest = rest.strip()
        if key == "newmtl":
            cur = out.setdefault(rest, {})
        elif cur is None:
            continue
        elif key.startswith("map_") or key in ("bump", "disp", "decal", "refl"):
            cur[key] = _map_file(rest)
        else:
            try:
                cur[key] = [float(v) for v in rest.split()]
            except ValueError:
                cur[key] = rest
    return out


def _map_file(rest: str) -> str:
    """The file name of a map statement: options (-name and their numbers)
    skipped, the remainder kept whole (names may hold spaces)."""
    tok = rest.split()
    i = 0
    while i < len(tok) and tok[i].startswith("-"):
        i += 1
        while i < len(tok) and _is_number(tok[i]):
            i += 1
        if i < len(tok) and tok[i - 1] in ("-clamp", "-blendu", "-blendv", "-cc", "-imfchan", "-type"):
            i += 1  # an option with a word argument (on/off, r/g/b/m/l/z, sphere/cube_*)
    return " ".join(tok[i:])


def _is_number(s: str) -> bool:
    try:
        float(s)
        return True
    except ValueError:
        return False


def ignored_terms(mtl: dict) -> dict:
    """Terms of MTL materials the diffuse baker ignores, with a non-default
    value: {term description: [material names]}."""
    out = {}

    def note(what, name):
        out.setdefault(what, []).append(name)
    for name, d in mtl.items():
        ks = d.get("Ks", [0.0])
        if isinstance(ks, list) and max(ks, default=0.0) > 0:
            note("specular (Ks, Ns)", name)
        illum = d.get("illum", [2])
        if isinstance(illum, list) and illum and illum[0] >= 3:
            note("reflection/refraction (illum 3-10)", name)
        pm = d.get("Pm", [0.0])
        if isinstance(pm, list) and pm and pm[0] > 0:
            note("metallic (Pm)", name)
    return out


def mtl_transmission(d: dict) -> float:
    """The thin-glass transmission factor of an MTL material: 1 - d (the
    dissolve), else Tr (the transparency some exporters write instead),
    clamped to [0, 1]; its tint is the diffuse colour (as glTF's base
    colour tints transmitted light)."""
    for key, flip in (("d", True), ("Tr", False)):
        v = d.get(key)
        if isinstance(v, list) and v and np.isfinite(v[0]):
            return float(min(max(1.0 - v[0] if flip else v[0], 0.0), 1.0))
    return 0.0


def _find_libs(rest: str, path, limits: LoadLimits):
    """Files an `mtllib` statement names: the whole remainder if such a file
    exists (a name with spaces), else each word. Returns (found, missing);
    a name the reference rules refuse (refs.py) raises SceneError."""
    folder = os.path.dirname(os.path.abspath(path))
    if rest and os.path.isfile(os.path.join(folder, rest)):
        return [resolve_reference(rest, path, "material library", limits)], []
    found, missing = [], []
    for name in rest.split():
        if os.path.lexists(os.path.join(folder, name)) or os.path.isabs(name):
            found.append(resolve_reference(name, path, "material library", limits))
        else:
            missing.append(name)
    return found, missing


def _triangulate(poly, p):
    """Triangles of a simple polygon: poly its vertex indices, p (n, 3) their
    positions. A fan when convex, else ear clipping in the plane of its
    Newell normal."""
    n = len(poly)
    if n == 3:
        return [tuple(poly)]
    p = np.asarray(p, np.float64)
    normal = np.zeros(3)
    for i in range(n):
        a, b = p[i], p[(i + 1) % n]
        normal += [(a[1] - b[1]) * (a[2] + b[2]), (a[2] - b[2]) * (a[0] + b[0]), (a[0] - b[0]) * (a[1] + b[1])]
    k = int(np.argmax(np.abs(normal)))
    if normal[k] == 0.0:
        return [(poly[0], poly[i], poly[i + 1]) for i in range(1, n - 1)]
    ia, ja = (k + 1) % 3, (k + 2) % 3
    xy = p[:, [ia, ja]] * (1.0 if normal[k] > 0 else -1.0, 1.0)  # counter-clockwise in 2D

    def cross(o, a, b):
        return (xy[a, 0] - xy[o, 0]) * (xy[b, 1] - xy[o, 1]) - (xy[a, 1] - xy[o, 1]) * (xy[b, 0] - xy[o, 0])
    if all(cross(i, (i + 1) % n, (i + 2) % n) >= 0 for i in range(n)):
        return [(poly[0], poly[i], poly[i + 1]) for i in range(1, n - 1)]
    rest = list(range(n))
    out = []
    guard = 0
    while len(rest) > 3 and guard < n * n:
        guard += 1
        m = len(rest)
        for j in range(m):
            a, b, c = rest[j - 1], rest[j], rest[(j + 1) % m]
            if cross(a, b, c) <= 0:
                continue  # a reflex corner: not an ear
            if any(cross(a, b, q) >= 0 and cross(b, c, q) >= 0 and cross(c, a, q) >= 0
                   for q in rest if q not in (a, b, c)):
                continue  # another vertex inside: not an ear
            out.append((poly[a], poly[b], poly[c]))
            rest.pop(j)
            break
        else:
            break  # no ear (a self-intersecting polygon): fan what is left
    out += [(poly[rest[0]], poly[rest[i]], poly[rest[i + 1]]) for i in range(1, len(rest) - 1)]
    return out


def read_obj(path, double_sided=True, limits: LoadLimits = LoadLimits()) -> dict:
    """The parts of a Scene from an OBJ file (and its MTL files), with a
    list of warnings. Raises SceneError naming the line of a bad statement
    (indices as the file counts them, from 1)."""
    pos, tex = [], []
    tri_v, tri_t, tri_m = [], [], []
    mat_index = {}
    mtl, notes = {}, []
    current = DEFAULT
    any_tex = False
    with open(path, encoding="utf-8", errors="replace") as f:
        for lineno, line in enumerate(f, 1):
            words = line.split(None, 1)
            if not words or words[0][0] == "#":
                continue
            key = words[0]
            rest = words[1].strip() if len(words) > 1 else ""
            if key not in ("mtllib", "usemtl"):  # names may hold '#'; elsewhere it starts a comment
                rest = rest.split("#", 1)[0]
            if key == "v":
                xyz = rest.split()
                if len(xyz) < 3:
                    raise SceneError(f"line {lineno}: a vertex needs 3 coordinates", path)
                try:
                    pos.append((float(xyz[0]), float(xyz[1]), float(xyz[2])))
                except ValueError:
                    raise SceneError(f"line {lineno}: vertex coordinates are not numbers", path) from None
            elif key == "vt":
                uv = rest.split()
                try:
                    tex.append((float(uv[0]), float(uv[1]) if len(uv) > 1 else 0.0))
                except (ValueError, IndexError):
                    raise SceneError(f"line {lineno}: texture coordinates are not numbers", path) from None
            elif key == "f":
                refs = rest.split()
                if len(refs) < 3:
                    raise SceneError(f"line {lineno}: a face needs at least 3 vertices", path)
                vi, ti = [], []
                for r in refs:
                    parts = r.split("/")
                    vi.append(_index(parts[0], len(pos), lineno, "vertex", path))
                    if len(parts) > 1 and parts[1]:
                        ti.append(_index(parts[1], len(tex), lineno, "texture coordinate", path))
                        any_tex = True
                    else:
                        ti.append(-1)
                if current not in mat_index:
                    mat_index[current] = len(mat_index)
                corner = {v: t for v, t in zip(vi, ti)}
                for t in _triangulate(vi, [pos[v] for v in vi]) if len(vi) > 3 else [tuple(vi)]:
                    tri_v.append(t)
                    tri_t.append(tuple(corner[v] for v in t))
                    tri_m.append(mat_index[current])
            elif key == "usemtl":
                current = rest or DEFAULT
            elif key == "mtllib":
                found, missing = _find_libs(rest, path, limits)
                for lib in found:
                    mtl.update(parse_mtl(lib))
                for name in missing:
                    notes.append(f"{path}: material library {name!r} not found: its materials are grey")
    if not tri_v:
        raise SceneError("no faces", path)
    materials = []
    for name in mat_index:
        d = mtl.get(name)
        if d is None and name != DEFAULT and mtl:
            notes.append(f"{path}: material {name!r} is not in the material libraries: grey")
        d = d or {}
        texture = None
        tex_name = d.get("map_Kd")
        if tex_name:
            folder = os.path.dirname(os.path.abspath(path))
            if os.path.lexists(os.path.join(folder, tex_name)) or os.path.isabs(tex_name):
                what = f"texture {tex_name!r} of material {name!r}"
                target = resolve_reference(tex_name, path, f"texture of material {name!r}", limits)
                texture, note = decode_texture(read_file(target, None, path, what), what, path, limits)
                if note:
                    notes.append(note)
            else:
                notes.append(f"{path}: texture {tex_name!r} of material {name!r} not found: its Kd alone is used")
        kd = d.get("Kd", [0.8, 0.8, 0.8])
        ke = d.get("Ke", [0.0, 0.0, 0.0])
        materials.append(make_material(name, (kd * 3)[:3] if len(kd) == 1 else kd,
                                       (ke * 3)[:3] if len(ke) == 1 else ke, double_sided, texture,
                                       mtl_transmission(d)))
    used = {n: mtl[n] for n in mat_index if n in mtl}
    terms = ignored_terms(used)
    if terms:
        said = "; ".join(f"{what} in {', '.join(repr(n) for n in names)}" for what, names in terms.items())
        notes.append(f"{path}: the baker treats every surface as diffuse and ignores {said}")
    vertices = np.asarray(pos, np.float64).reshape(-1, 3)
    triangles = np.asarray(tri_v, np.int64).reshape(-1, 3)
    uvs = None
    if any_tex:
        # OBJ indexes positions and texture coordinates apart: one vertex per (position, uv) pair used
        tt = np.asarray(tri_t, np.int64).reshape(-1, 3)
        pairs, inverse = np.unique(np.stack([triangles.ravel(), tt.ravel()], axis=1), axis=0, return_inverse=True)
        texcoords = np.asarray(tex, np.float32).reshape(-1, 2)
        uvs = np.where(pairs[:, 1:2] >= 0, texcoords[np.maximum(pairs[:, 1], 0)], 0.0).astype(np.float32)
        vertices = vertices[pairs[:, 0]]
        triangles = inverse.reshape(-1, 3)
    return dict(vertices=vertices, triangles=triangles, material_ids=np.asarray(tri_m, np.int64),
                materials=materials, uvs=uvs, notes=notes)


def _index(text, count, lineno, what, path) -> int:
    """0-based index of an OBJ reference (1-based, or negative from the end)."""
    try:
        i = int(text)
    except ValueError:
        raise SceneError(f"line {lineno}: {what} reference {text!r} is not a number", path) from None
    j = i - 1 if i > 0 else count + i
    if i == 0 or not 0 <= j < count:
        raise SceneError(f"line {lineno}: {what} index {i} out of range ({count} defined so far, "
                         f"1..{count} or -1..-{count})", path)
    return j
