"""The bake file: glTF 2.0 binary (docs/bake-file.md).

- Geometry: the baked triangles (bake/mesh.py) grouped into one primitive
  per (material, lightmap page), with POSITION, NORMAL, TEXCOORD_0 (the
  scene's texture coordinates, zeros where it had none: glTF wants
  TEXCOORD_0 wherever TEXCOORD_1 is) and TEXCOORD_1 (the lightmap UVs).
- Materials: one per (material, page), Lambertian (metallic 0, roughness
  1), with `MOZ_lightmap` {"index": page texture, "texCoord": 1,
  "intensity": page scale} (Hubs' and UnityGLTF's convention) and
  `VOXGI_lightmap` {"page": p}.
- Pages: an 8-bit linear PNG per page (texel = round(255 H / scale),
  scale = the brightest non-emitter texel of the page, so lamps may clip
  but the 8 bits go to the scene) for other viewers; the full-precision
  page (half-float EXR, `image/x-exr`, H in W/m^2 times `exrScale`) in the
  root `VOXGI_lightmap` extension for ours, with the ordered VPL list of
  the viewer's progressive preview (`vpls`: float32 rows of VPL_FIELDS)
  and the irradiance probe grid (`probes`: _probe_entry).
- Cameras, KHR_lights_punctual lights, and in root `extras.voxgi`: format
  version, voxgi version, settings, counts, and `fileSha256`, the SHA-256
  of the whole file with those 64 digits written as zeros (JSON and binary
  chunk alike), which the reader checks: a damaged or altered file is
  refused with one line, never half read. Nothing in the file depends on
  the machine or the thread count: the same bake is the same bytes.
"""
from __future__ import annotations

import io
import json
import os
import struct

import numpy as np

from ..errors import BakeFileError
from .mesh import Bake

FORMAT_VERSION = 2  # 2: the checksum covers the whole file
EXTENSION = "VOXGI_lightmap"
VPL_FIELDS = ("px", "py", "pz", "nx", "ny", "nz", "r", "g", "b", "area", "kind", "indirect")  # float32 per VPL
HALF_MAX = 60000.0


def _png(page, scale):
    from PIL import Image
    q = np.clip(np.rint(page / max(float(scale), 1e-30) * 255.0), 0, 255).astype(np.uint8)
    buf = io.BytesIO()
    Image.fromarray(q, "RGB").save(buf, format="PNG")
    return buf.getvalue()


def _exr(page):
    import OpenEXR
    buf = io.BytesIO()
    OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage},
                 {"RGB": np.ascontiguousarray(page, np.float16)}).write(buf)
    return buf.getvalue()


def _texture_png(tex, opacity=None):
    """An albedo texture as an sRGB PNG; with its mask's alpha (h, w), RGBA
    (alpha is stored linearly, as glTF reads it)."""
    from PIL import Image

    from ..render.images import linear_to_srgb
    q = np.clip(np.rint(linear_to_srgb(tex) * 255.0), 0, 255).astype(np.uint8)
    if opacity is not None and opacity.shape == tex.shape[:2]:
        a = np.clip(np.rint(opacity * 255.0), 0, 255).astype(np.uint8)
        q = np.concatenate([q, a[..., None]], axis=2)
    buf = io.BytesIO()
    # zlib level 3: a third of the default level's time for 6-12% more bytes (the modern hall's three textures:
    # 0.88 s -> 0.28 s, 3.06 -> 3.35 MB)
    Image.fromarray(q, "RGBA" if q.shape[2] == 4 else "RGB").save(buf, format="PNG", compress_level=3)
    return buf.getvalue()


def write_bake(path, bake: Bake, inputs=()):
    """Writes `bake` to `path` (.glb) atomically, never over one of `inputs`."""
    from .. import __version__
    from ..scene.gltf_write import GltfBuilder
    b = GltfBuilder()
    scene = bake.scene
    peak = float(bake.pages.max()) if bake.pages.size else 0.0
    exr_scale = 1.0 if peak <= HALF_MAX else 2.0 ** -np.ceil(np.log2(peak / HALF_MAX))
    page_tex, page_entries = [], []
    for p in range(len(bake.pages)):
        page_tex.append(b.texture(b.image(_png(bake.pages[p], bake.page_scale[p]))))
        page_entries.append({"bufferView": b.buffer_view(_exr(bake.pages[p] * exr_scale)), "mimeType": "image/x-exr",
                             "size": int(bake.pages.shape[1]), "scale": float(bake.page_scale[p])})
    albedo_tex, emit_tex = {}, {}
    with_uvs = scene.uvs is not None or any(d.uvs is not None for d in scene.dynamic)
    for i, m in enumerate(scene.materials):
        if m.texture is not None and with_uvs:
            albedo_tex[i] = b.texture(b.image(_texture_png(m.texture, m.opacity)), clamp=False)
        if m.emission_texture is not None and with_uvs and float(np.max(m.emission)) > 0:
            emit_tex[i] = b.texture(b.image(_texture_png(m.emission_texture, None)), clamp=False)
    corners = scene.vertices.reshape(-1, 3, 3)
    normals = scene.normals.reshape(-1, 3, 3)
    uv0 = scene.uvs.reshape(-1, 3, 2) if scene.uvs is not None else np.zeros((len(corners), 3, 2), np.float32)
    groups = {}
    for k, key in enumerate(zip(scene.material_ids.tolist(), bake.page.tolist())):
        groups.setdefault(key, []).append(k)
    parts = []
    for (mi, p), tris in sorted(groups.items()):
        m = scene.materials[mi]
        ext = {"MOZ_lightmap": {"index": page_tex[p], "texCoord": 1, "intensity": float(bake.page_scale[p])},
               EXTENSION: {"page": int(p), "material": int(mi)}}
        mat = b.material(f"{m.name}@page{p}", list(m.albedo) + [m.alpha], m.emission, False, albedo_tex.get(mi), ext,
                         m.alpha_cutoff, m.transmission, emit_tex.get(mi))
        t = np.asarray(tris)
        parts.append({"positions": corners[t], "normals": normals[t], "uv0": uv0[t], "uv1": bake.uv1[t],
                      "material": mat})
    b.primitives("baked", parts)
    moving = [{"node": _dynamic_node(b, d, scene.materials, albedo_tex, emit_tex), "name": d.name}
              for d in scene.dynamic]
    for cam in scene.cameras:
        b.camera(cam.name, cam.position, cam.forward, cam.up, float(np.degrees(cam.yfov)), cam.aspect or 1.0)
    for light in scene.lights:
        inten = np.asarray(light.intensity, float)
        peak_i = float(inten.max()) or 1.0
        b.light(light.name, light.kind, inten / peak_i, peak_i, light.position, light.direction,
                float(np.degrees(light.inner_cone)), float(np.degrees(light.outer_cone)))
    root = {"version": FORMAT_VERSION, "pages": page_entries, "exrScale": float(exr_scale)}
    if bake.vpls is not None and len(bake.vpls):
        v = bake.vpls
        rows = np.concatenate([v.position, v.normal, v.power, v.area[:, None], v.kind[:, None],
                               v.indirect[:, None]], axis=1).astype(np.float32)
        root["vpls"] = {"bufferView": b.buffer_view(rows.tobytes()), "count": int(len(rows)),
                        "fields": list(VPL_FIELDS)}
    if scene.sky is not None:
        root["sky"] = {"radiance": [float(v) for v in scene.sky.radiance], "hemisphere": bool(scene.sky.hemisphere)}
    if bake.probes is not None:
        root["probes"] = _probe_entry(b, bake.probes)
    if moving:
        root["dynamic"] = moving
    extras = {"voxgi": {"formatVersion": FORMAT_VERSION, "version": __version__, **_jsonable(bake.meta)}}
    b.save(path, extensions={EXTENSION: root}, extras=extras, checksum_key="voxgi", inputs=inputs)
    return path


def _dynamic_node(b, d, materials, albedo_tex, emit_tex) -> int:
    """A dynamic mesh (scene.DynamicMesh) as a plain glTF node at its pivot,
    one primitive per material, no lightmap: the node's index."""
    parts = []
    for mi in np.unique(d.material_ids).tolist():
        m = materials[mi]
        used, local = np.unique(d.triangles[d.material_ids == mi], return_inverse=True)
        textured = d.uvs is not None
        mat = b.material(m.name, list(m.albedo) + [m.alpha], m.emission, True,
                         albedo_tex.get(mi) if textured else None, None, m.alpha_cutoff, m.transmission,
                         emit_tex.get(mi) if textured else None)
        parts.append({"positions": d.vertices[used].astype(np.float64) - d.pivot, "normals": d.normals[used],
                      "uv0": d.uvs[used] if textured else None, "triangles": local.reshape(-1, 3), "material": mat})
    return b.primitives(d.name, parts, translation=d.pivot)


PROBES_VERSION = 2   # 2: the octahedral maps in a turned frame (probes/gather.py MAP_FRAME)
SH_ORDER = ("Y00", "Y1-1", "Y10", "Y11", "Y2-2", "Y2-1", "Y20", "Y21", "Y22")


def _probe_entry(b, pr) -> dict:
    """The probe block of the root extension: the grid, then four
    bufferViews (little-endian, probe-major, x fastest, then y, then z):
    sh float32 [probe][9][rgb], the incident radiance's real spherical
    harmonics; irradiance float16 [probe][row][column][rgb] of an
    octahedral map of normals, times `scale` (a power of two); depth float32 [probe][row][column][mean,
    mean square] of an octahedral distance map; valid uint8 [probe]. Both maps encode the direction
    `frame` @ d (row-major 3 x 3) of a scene direction d."""
    from ..probes.gather import MAP_FRAME, half_scale
    k = half_scale(pr.irradiance)
    return {"version": PROBES_VERSION,
            "origin": [float(v) for v in pr.origin], "spacing": float(pr.spacing),
            "dims": [int(v) for v in pr.dims], "rays": int(pr.rays),
            "frame": [[float(v) for v in row] for row in MAP_FRAME],
            "sh": {"bufferView": b.buffer_view(np.ascontiguousarray(pr.sh, "<f4").tobytes()),
                   "coefficients": list(SH_ORDER), "unit": "W m^-2 sr^-1"},
            "irradiance": {"bufferView": b.buffer_view(np.ascontiguousarray(pr.irradiance * k, "<f2").tobytes()),
                           "size": int(pr.irradiance.shape[1]), "mapping": "octahedral", "unit": "W m^-2",
                           "scale": k},
            "depth": {"bufferView": b.buffer_view(np.ascontiguousarray(pr.depth, "<f4").tobytes()),
                      "size": int(pr.depth.shape[1]), "mapping": "octahedral", "fields": ["mean", "meanSquare"]},
            "valid": {"bufferView": b.buffer_view(np.ascontiguousarray(pr.valid, np.uint8).tobytes())}}


def _read_probes(blob, doc, entry):
    """The probe block, checked (sizes against the bytes present before
    anything is made of them); None where the bake has none."""
    if entry is None:
        return None
    from ..probes.gather import DEPTH, IRR, MAP_FRAME, MAX_PROBES, SH, ProbeGrid
    if entry.get("version") != PROBES_VERSION:
        raise ValueError(f"probe block version {entry.get('version')!r}, this voxgi reads {PROBES_VERSION}")
    dims = entry["dims"]
    if not (isinstance(dims, list) and len(dims) == 3 and all(isinstance(d, int) and d >= 1 for d in dims)):
        raise ValueError(f"probe dims {dims!r}")
    n = dims[0] * dims[1] * dims[2]
    if n > MAX_PROBES:
        raise ValueError(f"{n} probes, over the limit of {MAX_PROBES}")
    origin = np.array(entry["origin"], np.float64)
    spacing = float(entry["spacing"])
    rays = entry["rays"]
    if origin.shape != (3,) or not np.isfinite(origin).all() or not (np.isfinite(spacing) and spacing > 0) \
            or not isinstance(rays, int) or rays < 1:
        raise ValueError("probe origin, spacing or ray count")
    for key, size in (("depth", DEPTH), ("irradiance", IRR)):
        if entry[key].get("size") != size or entry[key].get("mapping") != "octahedral":
            raise ValueError(f"probe {key} map size or mapping")
    if list(entry["sh"].get("coefficients", [])) != list(SH_ORDER):
        raise ValueError("probe coefficients")
    if entry.get("frame") != [[float(v) for v in row] for row in MAP_FRAME]:
        raise ValueError("probe map frame (this voxgi reads its own turned frame only)")
    out = []
    scale = float(entry["irradiance"].get("scale", 0))
    if not (np.isfinite(scale) and scale > 0 and np.log2(scale) == np.round(np.log2(scale))):
        raise ValueError("probe irradiance scale")
    for key, dtype, shape in (("sh", "<f4", (n, SH, 3)), ("irradiance", "<f2", (n, IRR, IRR, 3)),
                              ("depth", "<f4", (n, DEPTH, DEPTH, 2)), ("valid", np.uint8, (n,))):
        data = _view_bytes(blob, doc, entry[key]["bufferView"])
        want = int(np.prod(shape)) * np.dtype(dtype).itemsize
        if len(data) != want:
            raise ValueError(f"probe {key}: {len(data)} bytes, {want} expected")
        out.append(np.frombuffer(data, dtype).reshape(shape).copy())
    sh, irr, depth, valid = out
    if not (np.isfinite(sh).all() and np.isfinite(irr).all() and np.isfinite(depth).all()):
        raise ValueError("non-finite probe values")
    if min(irr.min(initial=0), depth.min(initial=0)) < 0:
        raise ValueError("negative probe irradiance or distances")
    if valid.max(initial=0) > 1:
        raise ValueError("probe validity other than 0 or 1")
    irr = (irr.astype(np.float64) / scale).astype(np.float32)
    return ProbeGrid(origin, spacing, np.array(dims, np.int64), sh.astype(np.float32), irr,
                     depth.astype(np.float32), valid.astype(bool), rays)


def _jsonable(obj):
    return json.loads(json.dumps(obj, default=lambda o: o.tolist() if hasattr(o, "tolist") else str(o)))


def _chunks(data: bytes, path):
    """(json dict, bin bytes) of a GLB, checking its framing."""
    if len(data) < 12:
        raise BakeFileError("not a bake file (too short for a glTF binary header)", path)
    magic, version, length = struct.unpack_from("<4sII", data, 0)
    if magic != b"glTF":
        raise BakeFileError("not a bake file (not glTF binary: no 'glTF' magic)", path)
    if version != 2:
        raise BakeFileError(f"glTF binary version {version}, expected 2", path)
    if length != len(data):
        raise BakeFileError(f"truncated or padded: the header says {length} bytes, the file has {len(data)}", path)
    pos, doc, blob = 12, None, b""
    while pos < len(data):
        if pos + 8 > len(data):
            raise BakeFileError("truncated chunk header", path)
        clen, ctype = struct.unpack_from("<II", data, pos)
        if pos + 8 + clen > len(data):
            raise BakeFileError("truncated chunk", path)
        chunk = data[pos + 8:pos + 8 + clen]
        if ctype == 0x4E4F534A:
            try:
                doc = json.loads(chunk.decode("utf-8"))
            except (UnicodeDecodeError, ValueError) as e:
                raise BakeFileError(f"damaged JSON chunk ({e})", path) from None
        elif ctype == 0x004E4942:
            blob = chunk
        pos += 8 + clen
    if not isinstance(doc, dict):
        raise BakeFileError("no JSON chunk", path)
    return doc, blob


def _index(value, count, what):
    """An index read from the bake file, checked to lie in 0..count-1."""
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value < count:
        raise ValueError(f"{what} {value!r} out of range (0..{count - 1})")
    return value


def read_bake(path) -> Bake:
    """Reads and validates a bake file; BakeFileError (one line) if it is
    missing, damaged, altered, not a voxgi bake or of another format
    version. The geometry is taken as the bake wrote it (no second
    clean-up), every index checked before use."""
    path = str(path)
    _refuse_scene(path)
    if not os.path.isfile(path):
        raise BakeFileError("file not found" if not os.path.exists(path) else "not a regular file", path)
    from ..scene.refs import read_file
    from ..errors import SceneError
    try:
        data = read_file(path, None, path, "the bake")
    except SceneError as e:
        raise BakeFileError(str(e), path) from None
    doc, blob = _chunks(data, path)
    info = (doc.get("extras") or {}).get("voxgi") if isinstance(doc.get("extras"), dict) else None
    root = (doc.get("extensions") or {}).get(EXTENSION) if isinstance(doc.get("extensions"), dict) else None
    if not isinstance(info, dict) or not isinstance(root, dict):
        raise BakeFileError("a glTF file, but not a voxgi bake (no VOXGI_lightmap data): bake it with "
                            "`voxbake bake`", path)
    for version in (info.get("formatVersion"), root.get("version")):
        if version != FORMAT_VERSION:
            raise BakeFileError(f"bake format version {version!r}, this voxgi reads version {FORMAT_VERSION}: "
                                f"bake the scene again", path)
    from ..scene.gltf_write import file_checksum
    if file_checksum(data, info.get("fileSha256")) != info.get("fileSha256"):
        raise BakeFileError("damaged or altered (the file's checksum does not match)", path)
    from ..scene.gltf_read import read_gltf
    from ..scene.load import scene_from_parts
    moving = _dynamic_entries(root.get("dynamic"), doc, path)
    try:
        parts = read_gltf(path, dynamic=moving)
        uv1 = parts.pop("uvs1")
        exts = parts.pop("material_extensions")
        if uv1 is None:
            raise BakeFileError("a primitive has no lightmap UVs (TEXCOORD_1)", path)
        scene = scene_from_parts(path, clean=False, **{k: v for k, v in parts.items() if k != "notes"})
    except SceneError as e:
        raise BakeFileError(f"damaged bake file ({e.args[0]})", path) from None
    if len(scene.dynamic) != len(moving):
        raise BakeFileError(f"damaged bake file ({len(moving)} dynamic nodes listed, {len(scene.dynamic)} hold "
                            f"meshes of their own)", path)
    try:
        entries = root["pages"]
        if not isinstance(entries, list) or not entries:
            raise BakeFileError("the bake holds no lightmap pages", path)
        mat_page = np.array([-1 if (e or {}).get(EXTENSION) is None else   # a dynamic mesh's: no page
                             _index(e[EXTENSION].get("page"), len(entries), "material's page") for e in exts],
                            np.int32)
        pages = [_read_exr_page(blob, doc, entry) for entry in entries]
        scale = np.array([float(e["scale"]) for e in entries], np.float32)
        exr_scale = float(root.get("exrScale", 1.0))
        if not (np.isfinite(scale).all() and (scale > 0).all() and np.isfinite(exr_scale) and exr_scale > 0):
            raise ValueError("page scales must be finite and positive")
        if len({p.shape for p in pages}) != 1:
            raise ValueError("pages of different sizes")
    except (KeyError, TypeError, ValueError, IndexError, AttributeError) as e:
        raise BakeFileError(f"damaged lightmap data ({type(e).__name__}: {e})", path) from None
    pages = np.stack(pages) / exr_scale
    if len(scene.triangles) * 3 != len(uv1):
        raise BakeFileError("triangles and lightmap UVs disagree (the file drops or merges triangles)", path)
    page = mat_page[scene.material_ids]
    if (page < 0).any():
        raise BakeFileError("a baked triangle's material names no lightmap page", path)
    if not np.isfinite(pages).all() or pages.min() < 0:
        raise BakeFileError("lightmap pages hold negative or non-finite values", path)
    if not np.isfinite(uv1).all():
        raise BakeFileError("lightmap UVs are not finite", path)
    meta = {k: v for k, v in info.items() if k not in ("fileSha256",)}
    if root.get("sky") is not None:
        from dataclasses import replace
        scene = replace(scene, sky=_read_sky(root["sky"], path))
    try:
        vpls = _read_vpls(blob, doc, root.get("vpls"))
    except (KeyError, TypeError, ValueError, IndexError, AttributeError) as e:
        raise BakeFileError(f"damaged VPL list ({type(e).__name__}: {e})", path) from None
    try:
        probes = _read_probes(blob, doc, root.get("probes"))
    except (KeyError, TypeError, ValueError, IndexError, AttributeError) as e:
        raise BakeFileError(f"damaged probe block ({type(e).__name__}: {e})", path) from None
    if scene.dynamic and probes is None:
        raise BakeFileError("damaged bake file (dynamic meshes, but no probe block to light them)", path)
    return Bake(scene, uv1.reshape(-1, 3, 2), page, pages.astype(np.float32), scale, meta, vpls, probes)


def _dynamic_entries(entry, doc, path) -> tuple:
    """The node indices of the bake's dynamic meshes (root `dynamic`:
    [{"node": i, "name": s}]), each checked: in range, once."""
    if entry is None:
        return ()
    from ..scene.gltf_read import MAX_DYNAMIC
    n_nodes = len(doc.get("nodes") or [])
    try:
        if not isinstance(entry, list) or not 0 < len(entry) <= MAX_DYNAMIC:
            raise ValueError(f"a list of 1..{MAX_DYNAMIC} entries expected")
        nodes = tuple(_index(e.get("node"), n_nodes, "node") for e in entry)
        if len(set(nodes)) != len(nodes):
            raise ValueError("a node listed twice")
    except (AttributeError, TypeError, ValueError) as e:
        raise BakeFileError(f"damaged dynamic mesh list ({type(e).__name__}: {e})", path) from None
    return nodes


def _read_sky(entry, path):
    """The Sky the bake was lit by (shown where a view sees no surface)."""
    from ..scene import Sky
    try:
        radiance = np.array(entry["radiance"], dtype=np.float64)
        hemisphere = entry.get("hemisphere", True)
    except (KeyError, TypeError, ValueError, AttributeError) as e:
        raise BakeFileError(f"damaged sky ({type(e).__name__}: {e})", path) from None
    if radiance.shape != (3,) or not np.isfinite(radiance).all() or radiance.min() < 0 \
            or not isinstance(hemisphere, bool):
        raise BakeFileError("damaged sky (its radiance must be 3 finite non-negative numbers, hemisphere true or "
                            "false)", path)
    return Sky(radiance, hemisphere)


def _view_bytes(blob, doc, index):
    """The bytes of bufferView `index` of the bake's binary chunk, checked."""
    views = doc.get("bufferViews") or []
    view = views[_index(index, len(views), "bufferView")]
    start, n = view.get("byteOffset", 0), view["byteLength"]
    if not all(isinstance(v, int) and v >= 0 for v in (start, n)) or start + n > len(blob):
        raise ValueError(f"bufferView {index} lies outside the binary chunk")
    return blob[start:start + n]


def _refuse_scene(path):
    """A scene (a built-in name, an OBJ, PLY or .gltf file) where a bake is
    expected: say what is needed and how to make it."""
    from ..scene.load import builtin_scenes
    stem, ext = os.path.splitext(os.path.basename(path))
    named = not os.path.exists(path) and path in builtin_scenes()
    if named or (os.path.isfile(path) and ext.lower() in (".obj", ".ply", ".gltf")):
        what = "a built-in scene" if named else "a scene file"
        raise BakeFileError(f"{what}, not a bake file: a bake file (.glb) is needed; make one with "
                            f"`voxbake bake {path} -o {stem}.glb`", path)


def _read_vpls(blob, doc, entry):
    if entry is None:
        return None
    from ..lights.vpl import VPLs
    if list(entry["fields"]) != list(VPL_FIELDS):
        raise ValueError(f"fields {entry['fields']}")
    data = _view_bytes(blob, doc, entry["bufferView"])
    n = entry["count"]
    if not isinstance(n, int) or n < 0 or n * len(VPL_FIELDS) * 4 > len(data):
        raise ValueError(f"count {n!r} does not fit its bufferView")
    rows = np.frombuffer(data, np.float32, count=n * len(VPL_FIELDS)).reshape(n, len(VPL_FIELDS))
    rows = rows.astype(np.float64)
    if not np.isfinite(rows).all():
        raise ValueError("non-finite values")
    col = {name: i for i, name in enumerate(VPL_FIELDS)}

    def span(first, last):
        return rows[:, col[first]:col[last] + 1].copy()
    field = {name: rows[:, i] for name, i in col.items()}
    kind = field["kind"]
    if (kind != np.rint(kind)).any() or kind.min(initial=0) < 0 or kind.max(initial=0) > 127:
        raise ValueError("VPL kinds out of range")
    power = span("r", "b")
    if min(field["area"].min(initial=0), power.min(initial=0)) < 0:
        raise ValueError("negative VPL power or area")
    return VPLs(kind.astype(np.int8), span("px", "pz"), span("nx", "nz"), power, field["area"].copy(),
                field["indirect"] > 0.5)


MAX_PAGE = 16384  # texels on a page's side: far above what the packer writes (512)


def _read_exr_page(blob, doc, entry):
    import OpenEXR
    n = entry["size"]
    if not isinstance(n, int) or not 1 <= n <= MAX_PAGE:
        raise ValueError(f"page size {n!r} out of range (1..{MAX_PAGE})")
    data = _view_bytes(blob, doc, entry["bufferView"])
    with OpenEXR.File(io.BytesIO(data), header_only=True) as f:
        (x0, y0), (x1, y1) = f.header()["dataWindow"]
    if (x1 - x0 + 1, y1 - y0 + 1) != (n, n):
        raise ValueError(f"page of {x1 - x0 + 1}x{y1 - y0 + 1} texels, expected {n}x{n}")
    with OpenEXR.File(io.BytesIO(data)) as f:
        ch = f.channels()
        rgb = ch["RGB"].pixels if "RGB" in ch else np.stack([ch[c].pixels for c in "RGB"], axis=-1)
    rgb = np.asarray(rgb, np.float32)
    if rgb.shape != (n, n, 3):
        raise ValueError(f"page of shape {rgb.shape}, expected {(n, n, 3)}")
    return rgb
