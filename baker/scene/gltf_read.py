"""Reading glTF 2.0 (.gltf/.glb) through pygltflib: meshes with node
transforms, materials (baseColorFactor/Texture, emissiveFactor times
KHR_materials_emissive_strength, doubleSided), every camera, and
KHR_lights_punctual lights.

trimesh loses the primitive -> material index and quantises base colours to
8 bits, so the file's own JSON (pygltflib's schema objects) is read here and
only the accessor bytes are decoded by hand.
"""
from __future__ import annotations

import io
import os

import numpy as np

from ..errors import SceneError
from .model import PunctualLight, make_camera, make_material
from .textures import image_to_albedo

_COMPONENT = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16, 5125: np.uint32, 5126: np.float32}
_WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}


def _buffers(doc, path):
    out = []
    for i, buf in enumerate(doc.buffers):
        if buf.uri is None:
            blob = doc.binary_blob()
            if blob is None:
                raise SceneError("buffer 0 has no GLB binary chunk (truncated file?)", path)
            out.append(blob)
        elif buf.uri.startswith("data:"):
            import base64
            out.append(base64.b64decode(buf.uri.split(",", 1)[1]))
        else:
            p = os.path.join(os.path.dirname(path), buf.uri)
            if not os.path.exists(p):
                raise SceneError(f"buffer {i} file {buf.uri!r} not found", path)
            with open(p, "rb") as f:
                out.append(f.read())
        if len(out[-1]) < (buf.byteLength or 0):
            raise SceneError(f"buffer {i} holds {len(out[-1])} bytes, the file says {buf.byteLength} (truncated?)",
                             path)
    return out


def _accessor(doc, bufs, index, path):
    acc = doc.accessors[index]
    if acc.sparse is not None:
        raise SceneError(f"accessor {index}: sparse accessors are not supported", path)
    dtype = np.dtype(_COMPONENT[acc.componentType])
    width = _WIDTH[acc.type]
    if acc.bufferView is None:
        return np.zeros((acc.count, width), dtype)
    view = doc.bufferViews[acc.bufferView]
    data = bufs[view.buffer]
    start = (view.byteOffset or 0) + (acc.byteOffset or 0)
    stride = view.byteStride or dtype.itemsize * width
    end = start + stride * (acc.count - 1) + dtype.itemsize * width if acc.count else start
    if end > len(data):
        raise SceneError(f"accessor {index} reads past the end of its buffer (truncated file?)", path)
    raw = np.frombuffer(data, np.uint8, count=end - start, offset=start) if acc.count else np.zeros(0, np.uint8)
    if stride == dtype.itemsize * width:
        arr = raw.view(dtype).reshape(acc.count, width)
    else:
        rows = np.lib.stride_tricks.as_strided(raw, (acc.count, dtype.itemsize * width), (stride, 1))
        arr = np.ascontiguousarray(rows).view(dtype).reshape(acc.count, width)
    if acc.normalized and dtype.kind in "iu":
        arr = arr.astype(np.float32) / np.iinfo(dtype).max
    return arr


def _node_matrix(node):
    if node.matrix is not None:
        return np.array(node.matrix, float).reshape(4, 4).T  # glTF is column-major
    m = np.eye(4)
    if node.rotation is not None:
        x, y, z, w = node.rotation
        m[:3, :3] = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
    if node.scale is not None:
        m[:3, :3] = m[:3, :3] * np.asarray(node.scale, float)[None, :]
    if node.translation is not None:
        m[:3, 3] = node.translation
    return m


def _world_nodes(doc):
    """Yields (node index, world matrix) over the default scene's hierarchy."""
    if doc.scenes:
        roots = doc.scenes[doc.scene or 0].nodes or []
    else:
        children = {c for n in doc.nodes for c in (n.children or [])}
        roots = [i for i in range(len(doc.nodes)) if i not in children]
    stack = [(i, np.eye(4), 0) for i in reversed(roots)]  # depth-first, document order
    while stack:
        i, parent, depth = stack.pop()
        if depth > 256:
            raise SceneError("node hierarchy deeper than 256 (a cycle?)")
        world = parent @ _node_matrix(doc.nodes[i])
        yield i, world
        stack.extend((c, world, depth + 1) for c in reversed(doc.nodes[i].children or []))


def _texture(doc, bufs, tex_index, path, folder):
    from PIL import Image
    tex = doc.textures[tex_index]
    if tex.source is None:
        return None
    img = doc.images[tex.source]
    if img.bufferView is not None:
        view = doc.bufferViews[img.bufferView]
        start = view.byteOffset or 0
        data = bufs[view.buffer][start:start + view.byteLength]
    elif img.uri and img.uri.startswith("data:"):
        import base64
        data = base64.b64decode(img.uri.split(",", 1)[1])
    elif img.uri:
        with open(os.path.join(folder, img.uri), "rb") as f:
            data = f.read()
    else:
        return None
    return image_to_albedo(Image.open(io.BytesIO(data)))


# material extensions whose effect a diffuse baker drops
_IGNORED_EXTENSIONS = {"KHR_materials_transmission": "transmission", "KHR_materials_volume": "volume",
                       "KHR_materials_clearcoat": "clearcoat", "KHR_materials_sheen": "sheen",
                       "KHR_materials_specular": "specular", "KHR_materials_iridescence": "iridescence"}


def ignored_terms(m) -> list:
    """What of glTF material m the diffuse baker ignores: metallic (the
    factor, 1 when unset, as the specification says), blended or masked
    alpha, and the extensions above."""
    out = []
    pbr = m.pbrMetallicRoughness
    metallic = 1.0 if pbr is None or pbr.metallicFactor is None else float(pbr.metallicFactor)
    if metallic > 0:
        out.append("metallic")
    if m.alphaMode in ("BLEND", "MASK"):
        out.append(f"alpha {m.alphaMode}")
    for ext, what in _IGNORED_EXTENSIONS.items():
        if ext in (m.extensions or {}):
            out.append(what)
    return out


def read_gltf(path):
    import pygltflib
    try:
        doc = pygltflib.GLTF2().load(path)
    except Exception as e:
        raise SceneError(f"not a valid glTF file ({type(e).__name__}: {str(e)[:120]})", path) from e
    if doc is None:
        raise SceneError("not a valid glTF file", path)
    bufs = _buffers(doc, path)
    folder = os.path.dirname(path)
    materials, ignored = [], {}
    for i, m in enumerate(doc.materials or []):
        pbr = m.pbrMetallicRoughness
        albedo = (pbr.baseColorFactor if pbr and pbr.baseColorFactor else [1, 1, 1, 1])[:3]
        strength = 1.0
        ext = (m.extensions or {}).get("KHR_materials_emissive_strength")
        if ext:
            strength = float(ext.get("emissiveStrength", 1.0))
        emission = np.asarray(m.emissiveFactor or [0, 0, 0], float) * strength
        tex = None
        if pbr and pbr.baseColorTexture is not None:
            tex = _texture(doc, bufs, pbr.baseColorTexture.index, path, folder)
        name = m.name or f"material_{i}"
        materials.append(make_material(name, albedo, emission, bool(m.doubleSided), tex))
        for what in ignored_terms(m):
            ignored.setdefault(what, []).append(name)
    default_index = None
    verts, tris, mids, norms, uvs, uvs1 = [], [], [], [], [], []
    has_normals = has_uvs = has_uvs1 = True
    offset = 0
    cameras, lights = [], []
    light_defs = ((doc.extensions or {}).get("KHR_lights_punctual") or {}).get("lights", [])
    for ni, world in _world_nodes(doc):
        node = doc.nodes[ni]
        if node.camera is not None:
            cam = doc.cameras[node.camera]
            if cam.type == "perspective" and cam.perspective is not None:
                r = world[:3, :3]
                cameras.append(make_camera(node.name or cam.name or f"camera_{len(cameras)}", world[:3, 3],
                                           -r[:, 2], r[:, 1], cam.perspective.yfov, cam.perspective.aspectRatio))
        lext = (node.extensions or {}).get("KHR_lights_punctual")
        if lext is not None:
            d = light_defs[lext["light"]]
            color = np.asarray(d.get("color", [1, 1, 1]), float) * float(d.get("intensity", 1.0))
            r = world[:3, :3]
            direction = -r[:, 2] / np.linalg.norm(r[:, 2])
            spot = d.get("spot", {})
            lights.append(PunctualLight(d.get("name") or node.name or f"light_{len(lights)}", d["type"], color,
                                        world[:3, 3].copy(), direction, float(spot.get("innerConeAngle", 0.0)),
                                        float(spot.get("outerConeAngle", np.pi / 4))))
        if node.mesh is None:
            continue
        normal_matrix = np.linalg.inv(world[:3, :3]).T
        flip = np.linalg.det(world[:3, :3]) < 0  # mirrored nodes reverse the winding (glTF spec 3.7.4)
        for prim in doc.meshes[node.mesh].primitives:
            mode = 4 if prim.mode is None else prim.mode
            if mode not in (4, 5, 6):
                continue  # points and lines have no area
            pos = _accessor(doc, bufs, prim.attributes.POSITION, path).astype(np.float64)
            if prim.indices is not None:
                idx = _accessor(doc, bufs, prim.indices, path).reshape(-1).astype(np.int64)
            else:
                idx = np.arange(len(pos))
            if mode == 5:
                k = np.arange(len(idx) - 2)
                t = np.stack([idx[k], idx[k + 1 + (k % 2)], idx[k + 2 - (k % 2)]], axis=1)
            elif mode == 6:
                k = np.arange(1, len(idx) - 1)
                t = np.stack([np.full(len(k), idx[0]), idx[k], idx[k + 1]], axis=1)
            else:
                if len(idx) % 3:
                    raise SceneError(f"mesh {node.mesh}: index count {len(idx)} is not a multiple of 3", path)
                t = idx.reshape(-1, 3)
            if len(t) and (t.min() < 0 or t.max() >= len(pos)):
                raise SceneError(f"mesh {node.mesh}: triangle indices out of range (0..{len(pos) - 1}, "
                                 f"found up to {t.max()})", path)
            if flip:
                t = t[:, ::-1]
            verts.append(pos @ world[:3, :3].T + world[:3, 3])
            if prim.attributes.NORMAL is not None:
                n = _accessor(doc, bufs, prim.attributes.NORMAL, path).astype(np.float64) @ normal_matrix.T
                n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)
                norms.append(n)
            else:
                has_normals = False
            if prim.attributes.TEXCOORD_0 is not None:
                uvs.append(_accessor(doc, bufs, prim.attributes.TEXCOORD_0, path).astype(np.float32))
            else:
                has_uvs = False
                uvs.append(np.zeros((len(pos), 2), np.float32))
            if prim.attributes.TEXCOORD_1 is not None:
                uvs1.append(_accessor(doc, bufs, prim.attributes.TEXCOORD_1, path).astype(np.float32))
            else:
                has_uvs1 = False
            if prim.material is None:
                if default_index is None:
                    default_index = len(materials)
                    materials.append(make_material("default", (1, 1, 1)))
                mid = default_index
            else:
                mid = prim.material
            tris.append(t + offset)
            mids.append(np.full(len(t), mid))
            offset += len(pos)
    if not tris:
        raise SceneError("no triangles", path)
    notes = []
    if ignored:
        said = "; ".join(f"{what} in {', '.join(repr(n) for n in names)}" for what, names in ignored.items())
        notes.append(f"{path}: the baker treats every surface as diffuse and ignores {said}")
    return dict(notes=notes, vertices=np.concatenate(verts), triangles=np.concatenate(tris),
                material_ids=np.concatenate(mids),
                materials=materials, normals=np.concatenate(norms) if has_normals and norms else None,
                uvs=np.concatenate(uvs) if has_uvs and uvs else None, cameras=cameras, lights=lights,
                uvs1=np.concatenate(uvs1) if has_uvs1 and uvs1 else None,
                material_extensions=[dict(m.extensions or {}) for m in doc.materials or []])
