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
  the viewer's progressive preview (`vpls`: float32 rows of VPL_FIELDS).
- Cameras, KHR_lights_punctual lights, and in root `extras.voxgi`: format
  version, voxgi version, settings, counts, timings, and the SHA-256 of the
  binary chunk, which the reader checks: a damaged or altered file is
  refused with one line, never half read.
"""
from __future__ import annotations

import hashlib
import io
import json
import os
import struct

import numpy as np

from ..errors import BakeFileError
from .mesh import Bake

FORMAT_VERSION = 1
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


def _texture_png(tex):
    from PIL import Image

    from ..render.images import linear_to_srgb
    q = np.clip(np.rint(linear_to_srgb(tex) * 255.0), 0, 255).astype(np.uint8)
    buf = io.BytesIO()
    Image.fromarray(q, "RGB").save(buf, format="PNG")
    return buf.getvalue()


def write_bake(path, bake: Bake):
    """Writes `bake` to `path` (.glb) atomically."""
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
    albedo_tex = {}
    for i, m in enumerate(scene.materials):
        if m.texture is not None and scene.uvs is not None:
            albedo_tex[i] = b.texture(b.image(_texture_png(m.texture)), clamp=False)
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
        mat = b.material(f"{m.name}@page{p}", m.albedo, m.emission, False, albedo_tex.get(mi), ext)
        t = np.asarray(tris)
        parts.append({"positions": corners[t], "normals": normals[t], "uv0": uv0[t], "uv1": bake.uv1[t],
                      "material": mat})
    b.primitives("baked", parts)
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
    extras = {"voxgi": {"formatVersion": FORMAT_VERSION, "version": __version__, **_jsonable(bake.meta)}}
    b.save(path, extensions={EXTENSION: root}, extras=extras, checksum_key="voxgi")
    return path


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


def read_bake(path) -> Bake:
    """Reads and validates a bake file; BakeFileError (one line) if it is
    missing, damaged, altered, not a voxgi bake or of another format
    version."""
    path = str(path)
    if not os.path.isfile(path):
        raise BakeFileError("file not found" if not os.path.exists(path) else "not a file", path)
    with open(path, "rb") as f:
        data = f.read()
    doc, blob = _chunks(data, path)
    info = (doc.get("extras") or {}).get("voxgi")
    root = (doc.get("extensions") or {}).get(EXTENSION)
    if not isinstance(info, dict) or not isinstance(root, dict):
        raise BakeFileError("a glTF file, but not a voxgi bake (no VOXGI_lightmap data): bake it with "
                            "`voxbake bake`", path)
    if info.get("formatVersion") != FORMAT_VERSION or root.get("version") != FORMAT_VERSION:
        raise BakeFileError(f"bake format version {info.get('formatVersion')!r}, this voxgi reads version "
                            f"{FORMAT_VERSION}: bake the scene again", path)
    if hashlib.sha256(blob).hexdigest() != info.get("binSha256"):
        raise BakeFileError("damaged or altered (the binary data's checksum does not match)", path)
    from ..scene.load import _validate
    from ..scene.gltf_read import read_gltf
    from ..errors import SceneError
    try:
        parts = read_gltf(path)
    except SceneError as e:
        raise BakeFileError(f"damaged bake file ({e})", path) from None
    uv1 = parts.pop("uvs1")
    exts = parts.pop("material_extensions")
    if uv1 is None:
        raise BakeFileError("a primitive has no lightmap UVs (TEXCOORD_1)", path)
    try:
        mat_page = np.array([e[EXTENSION]["page"] for e in exts], np.int32)
        pages = [_read_exr_page(blob, doc, entry) for entry in root["pages"]]
        scale = np.array([float(e["scale"]) for e in root["pages"]], np.float32)
        exr_scale = float(root.get("exrScale", 1.0))
    except (KeyError, TypeError, ValueError, IndexError) as e:
        raise BakeFileError(f"damaged lightmap data ({type(e).__name__}: {e})", path) from None
    if not pages:
        raise BakeFileError("the bake holds no lightmap pages", path)
    pages = np.stack(pages) / exr_scale
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        scene = _validate(path, **{k: v for k, v in parts.items() if k != "notes"})
    if len(scene.triangles) * 3 != len(uv1):
        raise BakeFileError("triangles and lightmap UVs disagree (the file drops or merges triangles)", path)
    page = mat_page[scene.material_ids]
    if page.size and (page.min() < 0 or page.max() >= len(pages)):
        raise BakeFileError("a material names a lightmap page the file does not hold", path)
    if not np.isfinite(pages).all() or pages.min() < 0:
        raise BakeFileError("lightmap pages hold negative or non-finite values", path)
    meta = {k: v for k, v in info.items() if k not in ("binSha256",)}
    try:
        vpls = _read_vpls(blob, doc, root.get("vpls"))
    except (KeyError, TypeError, ValueError, IndexError) as e:
        raise BakeFileError(f"damaged VPL list ({type(e).__name__}: {e})", path) from None
    return Bake(scene, uv1.reshape(-1, 3, 2), page, pages.astype(np.float32), scale, meta, vpls)


def _read_vpls(blob, doc, entry):
    if entry is None:
        return None
    from ..lights.vpl import VPLs
    if list(entry["fields"]) != list(VPL_FIELDS):
        raise ValueError(f"fields {entry['fields']}")
    view = doc["bufferViews"][entry["bufferView"]]
    start = view.get("byteOffset", 0)
    n = int(entry["count"])
    rows = np.frombuffer(blob, np.float32, count=n * len(VPL_FIELDS), offset=start).reshape(n, len(VPL_FIELDS))
    rows = rows.astype(np.float64)
    if not np.isfinite(rows).all():
        raise ValueError("non-finite values")
    return VPLs(rows[:, 10].astype(np.int8), rows[:, 0:3].copy(), rows[:, 3:6].copy(), rows[:, 6:9].copy(),
                rows[:, 9].copy(), rows[:, 11] > 0.5)


def _read_exr_page(blob, doc, entry):
    import OpenEXR
    view = doc["bufferViews"][entry["bufferView"]]
    start = view.get("byteOffset", 0)
    data = blob[start:start + view["byteLength"]]
    with OpenEXR.File(io.BytesIO(data)) as f:
        ch = f.channels()
        rgb = ch["RGB"].pixels if "RGB" in ch else np.stack([ch[c].pixels for c in "RGB"], axis=-1)
    rgb = np.asarray(rgb, np.float32)
    n = int(entry["size"])
    if rgb.shape != (n, n, 3):
        raise ValueError(f"page of shape {rgb.shape}, expected {(n, n, 3)}")
    return rgb
