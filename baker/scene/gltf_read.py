"""Reading glTF 2.0 (.gltf/.glb) through pygltflib: meshes with node
transforms, materials (baseColorFactor/Texture, emissiveFactor times
KHR_materials_emissive_strength, doubleSided), every camera, and
KHR_lights_punctual lights.

trimesh loses the primitive -> material index and quantises base colours to
8 bits, so the file's own JSON (pygltflib's schema objects) is read here and
only the accessor bytes are decoded by hand.
"""
from __future__ import annotations

import os

import numpy as np

from ..errors import SceneError
from .model import PunctualLight, make_camera, make_material
from .refs import LoadLimits, read_file, resolve_reference
from .textures import decode_texture

_COMPONENT = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16, 5125: np.uint32, 5126: np.float32}
_WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
_INDEX_TYPES = (5121, 5123, 5125)  # glTF 3.7.2.1: indices are unsigned integers
LOAD_BYTES_PER_TRIANGLE = 600  # what a triangle costs through loading and clean-up (corners, normals, cuts)
MAX_NODE_INSTANCES = 1_000_000  # a node graph sharing children can instance a mesh exponentially often
MAX_DYNAMIC = 4096   # dynamic mesh instances (--dynamic) a scene, and so a bake file, may hold


def _int(value, what, path, lo=0, hi=1 << 62):
    """An integer field of the file in lo..hi; SceneError naming it otherwise."""
    if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
        raise SceneError(f"{what} is {value!r}, expected an integer in {lo}..{hi}", path)
    return value


def _item(items, index, what, path):
    """items[index] for an index read from the file, checked."""
    items = items or []
    _int(index, f"{what} index", path, 0, max(len(items) - 1, 0))
    if not items:
        raise SceneError(f"{what} {index} does not exist (the file has none)", path)
    return items[index]


def _buffers(doc, path, limits: LoadLimits, file_size: int):
    """The bytes of every buffer, each checked against its stated byteLength
    before it is read (at most byteLength bytes of a file are read)."""
    out = []
    for i, buf in enumerate(doc.buffers or []):
        n = _int(buf.byteLength, f"buffer {i} byteLength", path, 1)
        if buf.uri is None:
            blob = doc.binary_blob() if i == 0 else None
            if blob is None:
                raise SceneError(f"buffer {i} has no uri and no GLB binary chunk (truncated file?)", path)
            data = blob
        elif not isinstance(buf.uri, str):
            raise SceneError(f"buffer {i} uri is not a string", path)
        elif buf.uri.startswith("data:"):
            import base64
            import binascii
            head, _, body = buf.uri.partition(",")
            if not head.endswith(";base64") or len(body) * 3 // 4 + 3 < n:
                raise SceneError(f"buffer {i}: a data URI of fewer bytes than its byteLength {n}", path)
            try:
                data = base64.b64decode(body, validate=True)
            except (binascii.Error, ValueError):
                raise SceneError(f"buffer {i}: damaged base64 data URI", path) from None
        else:
            target = resolve_reference(buf.uri, path, f"buffer {i} uri", limits, encoded=True)
            size = os.path.getsize(target)
            if size < n:
                raise SceneError(f"buffer {i} file {buf.uri!r} holds {size} bytes, the file says {n} (truncated?)",
                                 path)
            limits.check_bytes(n, f"buffer {i}", path)
            data = read_file(target, n, path, f"buffer {i} uri {buf.uri!r}")
        if len(data) < n:
            raise SceneError(f"buffer {i} holds {len(data)} bytes, the file says {n} (truncated?)", path)
        out.append(memoryview(data)[:n])
    limits.check_bytes(sum(len(b) for b in out) + file_size, "the scene's buffers", path)
    return out


def _view(doc, bufs, index, path):
    """The bytes of bufferView `index` and its stride (None: packed),
    checked against its buffer."""
    view = _item(doc.bufferViews, index, "bufferView", path)
    buf = _int(view.buffer, f"bufferView {index} buffer", path, 0, max(len(bufs) - 1, 0))
    if not bufs:
        raise SceneError(f"bufferView {index} names buffer {buf}, the file has none", path)
    off = _int(view.byteOffset or 0, f"bufferView {index} byteOffset", path)
    n = _int(view.byteLength, f"bufferView {index} byteLength", path, 1)
    if off + n > len(bufs[buf]):
        raise SceneError(f"bufferView {index} spans bytes {off}..{off + n} of buffer {buf}, which holds "
                         f"{len(bufs[buf])}", path)
    stride = None if view.byteStride is None else _int(view.byteStride, f"bufferView {index} byteStride", path,
                                                       4, 252)
    return bufs[buf][off:off + n], stride


def _accessor(doc, bufs, index, path, what, components=tuple(_COMPONENT), types=tuple(_WIDTH), zeros_limit=0):
    """(count, width) array of accessor `index`, read as `what`: its
    component type and type must be among those given, and count x stride
    must lie within its bufferView. An accessor without a bufferView is
    zeros (glTF 3.6.2.3), allowed only up to `zeros_limit` bytes."""
    acc = _item(doc.accessors, index, f"{what} accessor", path)
    name = f"accessor {index} ({what})"
    if acc.sparse is not None:
        raise SceneError(f"{name}: sparse accessors are not supported", path)
    if acc.componentType not in components:
        raise SceneError(f"{name}: componentType {acc.componentType!r} is not allowed here (allowed: "
                         f"{', '.join(map(str, components))})", path)
    if acc.type not in types:
        raise SceneError(f"{name}: type {acc.type!r} is not allowed here (allowed: {', '.join(types)})", path)
    count = _int(acc.count, f"{name} count", path, 1)
    dtype = np.dtype(_COMPONENT[acc.componentType])
    width = _WIDTH[acc.type]
    elem = dtype.itemsize * width
    if acc.bufferView is None:
        if count * elem > zeros_limit:
            raise SceneError(f"{name}: {count} elements with no bufferView (all zeros), more than the file's "
                             f"bytes", path)
        return np.zeros((count, width), dtype)
    data, stride = _view(doc, bufs, acc.bufferView, path)
    stride = stride or elem
    if stride < elem:
        raise SceneError(f"{name}: byteStride {stride} is smaller than an element ({elem} bytes)", path)
    start = _int(acc.byteOffset or 0, f"{name} byteOffset", path)
    end = start + stride * (count - 1) + elem
    if end > len(data):
        raise SceneError(f"{name}: {count} elements need {end} bytes of bufferView {acc.bufferView}, which "
                         f"holds {len(data)} (truncated file?)", path)
    raw = np.frombuffer(data, np.uint8, count=end - start, offset=start)
    if stride == elem:
        arr = raw.view(dtype).reshape(count, width)
    else:
        rows = np.lib.stride_tricks.as_strided(raw, (count, elem), (stride, 1))
        arr = np.ascontiguousarray(rows).view(dtype).reshape(count, width)
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


def _world_nodes(doc, path, dynamic=frozenset()):
    """Yields (node index, world matrix, object) over the default scene's
    hierarchy: object -1 for a static node, else a number per visit of the
    outermost node in `dynamic` (node indices) above it or itself: each
    instance of a dynamic node is an object of its own."""
    nodes = doc.nodes or []
    if doc.scenes:
        roots = _item(doc.scenes, doc.scene or 0, "scene", path).nodes or []
    else:
        children = {c for n in nodes for c in (n.children or []) if isinstance(c, int)}
        roots = [i for i in range(len(nodes)) if i not in children]
    for i in roots:
        _item(nodes, i, "scene root node", path)
    stack = [(i, np.eye(4), 0, -1) for i in reversed(roots)]  # depth-first, document order
    seen = objects = 0
    while stack:
        i, parent, depth, obj = stack.pop()
        seen += 1
        if depth > 256:
            raise SceneError("node hierarchy deeper than 256 (a cycle?)", path)
        if seen > MAX_NODE_INSTANCES:
            raise SceneError(f"more than {MAX_NODE_INSTANCES} node instances (shared children repeated?)", path)
        world = parent @ _node_matrix(nodes[i])
        if not np.isfinite(world).all():
            raise SceneError(f"node {i}: its transform is not finite", path)
        if obj < 0 and i in dynamic:
            obj, objects = objects, objects + 1
            if objects > MAX_DYNAMIC:
                raise SceneError(f"more than {MAX_DYNAMIC} instances of --dynamic nodes (shared children "
                                 f"repeated?)", path)
        yield i, world, obj
        children = nodes[i].children or []
        for c in children:
            _item(nodes, c, f"node {i} child", path)
        stack.extend((c, world, depth + 1, obj) for c in reversed(children))


def dynamic_nodes(doc, names, path) -> frozenset:
    """The indices of the nodes named in `names` (--dynamic): SceneError
    for a name no node has."""
    nodes = doc.nodes or []
    found = set()
    for name in names:
        hits = [i for i, n in enumerate(nodes) if n.name == name]
        if not hits:
            named = sorted({n.name for n in nodes if isinstance(n.name, str) and n.name})
            listed = ", ".join(repr(n) for n in named[:12]) + (", ..." if len(named) > 12 else "")
            raise SceneError(f"--dynamic {name!r}: no node has that name (nodes: {listed or 'none named'})", path)
        found.update(hits)
    return frozenset(found)


def _texture(doc, bufs, tex_index, path, limits, alpha=False):
    """(albedo array or None, note or None) of texture `tex_index`; with
    alpha, (albedo, alpha (h, w) or None, note)."""
    tex = _item(doc.textures, tex_index, "texture", path)
    none = (None, None, None) if alpha else (None, None)
    if tex.source is None:
        return none
    img = _item(doc.images, tex.source, "image", path)
    what = f"image {tex.source}"
    if img.bufferView is not None:
        data = bytes(_view(doc, bufs, img.bufferView, path)[0])
    elif isinstance(img.uri, str) and img.uri.startswith("data:"):
        import base64
        import binascii
        try:
            data = base64.b64decode(img.uri.split(",", 1)[1], validate=True)
        except (binascii.Error, ValueError, IndexError):
            raise SceneError(f"{what}: damaged base64 data URI", path) from None
    elif isinstance(img.uri, str) and img.uri:
        target = resolve_reference(img.uri, path, f"{what} uri", limits, encoded=True)
        data = read_file(target, None, path, f"{what} uri {img.uri!r}")
    else:
        return none
    return decode_texture(data, what, path, limits, alpha)


# material extensions whose effect a diffuse baker drops
_IGNORED_EXTENSIONS = {"KHR_materials_volume": "volume",
                       "KHR_materials_clearcoat": "clearcoat", "KHR_materials_sheen": "sheen",
                       "KHR_materials_specular": "specular", "KHR_materials_iridescence": "iridescence"}


def ignored_terms(m) -> list:
    """What of glTF material m the diffuse baker ignores: metallic (the
    factor, 1 when unset, as the specification says), blended or masked
    alpha, a transmission texture (the factor is read) and the extensions
    above."""
    out = []
    pbr = m.pbrMetallicRoughness
    metallic = 1.0 if pbr is None or pbr.metallicFactor is None else float(pbr.metallicFactor)
    if metallic > 0:
        out.append("metallic")
    if m.alphaMode == "BLEND":
        out.append("alpha BLEND")
    if ((m.extensions or {}).get("KHR_materials_transmission") or {}).get("transmissionTexture") is not None:
        out.append("transmission texture")
    for ext, what in _IGNORED_EXTENSIONS.items():
        if ext in (m.extensions or {}):
            out.append(what)
    return out


_SUPPORTED_REQUIRED = {"KHR_lights_punctual", "KHR_materials_emissive_strength", "KHR_mesh_quantization",
                       "KHR_materials_transmission", "KHR_materials_volume", "KHR_materials_clearcoat",
                       "KHR_materials_sheen", "KHR_materials_specular", "KHR_materials_iridescence",
                       "KHR_materials_ior", "KHR_materials_unlit"}


def _finite(values, what, path, n, lo=-np.inf):
    """n finite numbers >= lo from the file, as float64."""
    try:
        v = np.asarray(values, float).reshape(-1)
    except (TypeError, ValueError):
        raise SceneError(f"{what} is not a list of numbers", path) from None
    if len(v) < n or not np.isfinite(v[:n]).all() or (v[:n] < lo).any():
        raise SceneError(f"{what} needs {n} finite numbers{f' >= {lo:g}' if lo > -np.inf else ''}", path)
    return v[:n]


def _check_glb_header(path):
    """SceneError unless the file starts with a GLB header (magic, version
    2) whose length is the file's."""
    import struct
    with open(path, "rb") as f:
        head = f.read(12)
    size = os.path.getsize(path)
    if len(head) < 12 or head[:4] != b"glTF":
        raise SceneError("not a glTF binary file (no 'glTF' magic)", path)
    version, length = struct.unpack_from("<II", head, 4)
    if version != 2:
        raise SceneError(f"glTF binary container version {version}; voxgi reads version 2", path)
    if length != size:
        raise SceneError(f"the header says {length} bytes, the file has {size} (truncated or padded?)", path)


class _Part:
    """Triangles gathered from primitives: the static scene's, or one
    dynamic object's."""

    def __init__(self, name="", pivot=None):
        self.name, self.pivot = name, pivot
        self.verts, self.tris, self.mids, self.norms, self.uvs, self.uvs1 = [], [], [], [], [], []
        self.offset, self.has_normals, self.has_uvs1 = 0, True, True
        self.names = set()   # the names of the nodes it holds


def read_gltf(path, limits: LoadLimits = LoadLimits(), dynamic=()):
    """The parts of a Scene from a .gltf/.glb file, every index and size in
    it checked before use (refs.py: what it may make us read). `dynamic`:
    node names (str) or indices (int) whose meshes, with their children's,
    are moving objects (parts["dynamic"], a list of dicts) rather than
    scene triangles."""
    import warnings

    import pygltflib
    if str(path).lower().endswith(".glb"):
        _check_glb_header(path)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # pygltflib's own notes on odd files: our checks below speak instead
            doc = pygltflib.GLTF2().load(path)
    except Exception as e:
        raise SceneError(f"not a valid glTF file ({type(e).__name__})", path) from None
    if doc is None:
        raise SceneError("not a valid glTF file", path)
    version = str(getattr(doc.asset, "version", "") or "")
    if version.split(".")[0] != "2":
        raise SceneError(f"glTF version {version!r}; voxgi reads glTF 2.x", path)
    unsupported = sorted(set(doc.extensionsRequired or []) - _SUPPORTED_REQUIRED)
    if unsupported:
        raise SceneError(f"the file requires the glTF extension{'s' * (len(unsupported) > 1)} "
                         f"{', '.join(unsupported)}, which voxgi does not read (decompress or re-export the "
                         f"file without it)", path)
    if any("EXT_meshopt_compression" in (v.extensions or {}) for v in doc.bufferViews or []):
        # its uncompressed fallback buffer holds no data: reading it would look like a truncated file
        raise SceneError("the file's buffers are compressed with EXT_meshopt_compression, which voxgi does not "
                         "read (decompress it first, e.g. `gltfpack -noq` or gltf-transform)", path)
    quantized = "KHR_mesh_quantization" in (doc.extensionsUsed or [])
    vector_types = tuple(_COMPONENT) if quantized else (5126,)
    file_size = os.path.getsize(path)
    bufs = _buffers(doc, path, limits, file_size)
    materials, ignored, notes = [], {}, []
    for i, m in enumerate(doc.materials or []):
        pbr = m.pbrMetallicRoughness
        albedo = _finite(pbr.baseColorFactor if pbr and pbr.baseColorFactor else [1, 1, 1, 1],
                         f"material {i} baseColorFactor", path, 3, 0.0)
        strength = 1.0
        ext = (m.extensions or {}).get("KHR_materials_emissive_strength")
        if ext:
            strength = float(_finite([ext.get("emissiveStrength", 1.0)], f"material {i} emissiveStrength", path,
                                     1, 0.0)[0])
        emission = _finite(m.emissiveFactor or [0, 0, 0], f"material {i} emissiveFactor", path, 3, 0.0) * strength
        masked = m.alphaMode == "MASK"
        tex = opacity = emit_tex = None
        if pbr and pbr.baseColorTexture is not None:
            tex, opacity, note = _texture(doc, bufs, pbr.baseColorTexture.index, path, limits, alpha=True)
            if note:
                notes.append(note)
        if m.emissiveTexture is not None and emission.max() > 0:
            emit_tex, note = _texture(doc, bufs, m.emissiveTexture.index, path, limits)
            if note:
                notes.append(note)
        transmission = 0.0
        ext = (m.extensions or {}).get("KHR_materials_transmission")
        if isinstance(ext, dict):
            transmission = float(_finite([ext.get("transmissionFactor", 0.0)], f"material {i} transmissionFactor",
                                         path, 1, 0.0)[0])
            if transmission > 1.0:
                raise SceneError(f"material {i} transmissionFactor {transmission:g} is above 1", path)
        factor = pbr.baseColorFactor if pbr and pbr.baseColorFactor else []
        alpha = float(_finite(factor[3:4], f"material {i} baseColorFactor alpha", path, 1, 0.0)[0]) \
            if isinstance(factor, list) and len(factor) > 3 else 1.0
        cutoff = None
        if masked:
            cutoff = 0.5 if m.alphaCutoff is None else float(_finite([m.alphaCutoff], f"material {i} alphaCutoff",
                                                                     path, 1, 0.0)[0])
        name = m.name if isinstance(m.name, str) and m.name else f"material_{i}"
        materials.append(make_material(name, albedo, emission, bool(m.doubleSided), tex, transmission, cutoff,
                                       alpha, opacity if masked else None, emit_tex))
        for what in ignored_terms(m):
            ignored.setdefault(what, []).append(name)
    n_file_materials = len(materials)
    default_index = None
    names = [d for d in dynamic if isinstance(d, str)]
    chosen = dynamic_nodes(doc, names, path) | {int(d) for d in dynamic if not isinstance(d, str)}
    static, objects = _Part(), {}
    total_tris = 0
    cameras, lights = [], []
    light_defs = ((doc.extensions or {}).get("KHR_lights_punctual") or {}).get("lights", [])
    zeros_limit = file_size
    for ni, world, obj in _world_nodes(doc, path, chosen):
        node = doc.nodes[ni]
        if obj >= 0 and obj not in objects:
            objects[obj] = _Part(node.name if isinstance(node.name, str) and node.name else f"node_{ni}",
                                 world[:3, 3].copy())
        part = static if obj < 0 else objects[obj]
        part.names.add(node.name)
        if node.camera is not None:
            cam = _item(doc.cameras, node.camera, f"node {ni} camera", path)
            if cam.type == "perspective" and cam.perspective is not None:
                yfov = float(_finite([cam.perspective.yfov], f"camera {node.camera} yfov", path, 1, 0.0)[0])
                aspect = cam.perspective.aspectRatio
                if aspect is not None:
                    aspect = float(_finite([aspect], f"camera {node.camera} aspectRatio", path, 1, 0.0)[0])
                if not 0 < yfov < np.pi or aspect == 0:
                    raise SceneError(f"camera {node.camera}: yfov {yfov} or aspect ratio {aspect} out of range",
                                     path)
                r = world[:3, :3]
                cameras.append(make_camera(node.name or cam.name or f"camera_{len(cameras)}", world[:3, 3],
                                           -r[:, 2], r[:, 1], yfov, aspect))
        lext = (node.extensions or {}).get("KHR_lights_punctual")
        if lext is not None:
            d = _item(light_defs, lext.get("light") if isinstance(lext, dict) else None, f"node {ni} light", path)
            kind = d.get("type") if isinstance(d, dict) else None
            if kind not in ("directional", "point", "spot"):
                raise SceneError(f"node {ni}: light type {kind!r} (directional, point or spot)", path)
            color = _finite(d.get("color", [1, 1, 1]), f"light {lext['light']} color", path, 3, 0.0) * \
                _finite([d.get("intensity", 1.0)], f"light {lext['light']} intensity", path, 1, 0.0)[0]
            r = world[:3, :3]
            direction = -r[:, 2] / max(np.linalg.norm(r[:, 2]), 1e-300)
            spot = d.get("spot", {}) if isinstance(d.get("spot", {}), dict) else {}
            cones = _finite([spot.get("innerConeAngle", 0.0), spot.get("outerConeAngle", np.pi / 4)],
                            f"light {lext['light']} spot cone", path, 2, 0.0)
            lights.append(PunctualLight(str(d.get("name") or node.name or f"light_{len(lights)}"), kind, color,
                                        world[:3, 3].copy(), direction, float(cones[0]), float(cones[1])))
        if node.mesh is None:
            continue
        mesh = _item(doc.meshes, node.mesh, f"node {ni} mesh", path)
        normal_matrix = np.linalg.inv(world[:3, :3]).T if np.linalg.det(world[:3, :3]) != 0 else np.eye(3)
        flip = np.linalg.det(world[:3, :3]) < 0  # mirrored nodes reverse the winding (glTF spec 3.7.4)
        for prim in mesh.primitives or []:
            mode = 4 if prim.mode is None else prim.mode
            if mode not in (4, 5, 6):
                continue  # points and lines have no area
            if prim.attributes.POSITION is None:
                raise SceneError(f"mesh {node.mesh}: a primitive without POSITION", path)
            pos = _accessor(doc, bufs, prim.attributes.POSITION, path, "POSITION", vector_types, ("VEC3",),
                            zeros_limit).astype(np.float64)
            if prim.indices is not None:
                idx = _accessor(doc, bufs, prim.indices, path, "indices", _INDEX_TYPES, ("SCALAR",),
                                zeros_limit).reshape(-1).astype(np.int64)
            else:
                idx = np.arange(len(pos))
            if mode == 5:
                k = np.arange(max(len(idx) - 2, 0))
                t = np.stack([idx[k], idx[k + 1 + (k % 2)], idx[k + 2 - (k % 2)]], axis=1)
            elif mode == 6:
                k = np.arange(1, max(len(idx) - 1, 1))
                t = np.stack([np.full(len(k), idx[0]), idx[k], idx[k + 1]], axis=1)
            else:
                if len(idx) % 3:
                    raise SceneError(f"mesh {node.mesh}: index count {len(idx)} is not a multiple of 3", path)
                t = idx.reshape(-1, 3)
            if len(t) and (t.min() < 0 or t.max() >= len(pos)):
                raise SceneError(f"mesh {node.mesh}: triangle indices out of range (0..{len(pos) - 1}, "
                                 f"found up to {t.max()})", path)
            total_tris += len(t)
            limits.check_bytes(float(total_tris) * LOAD_BYTES_PER_TRIANGLE, f"{total_tris} triangles", path)
            if flip:
                t = t[:, ::-1]
            part.verts.append(pos @ world[:3, :3].T + world[:3, 3])
            if prim.attributes.NORMAL is not None:
                n = _accessor(doc, bufs, prim.attributes.NORMAL, path, "NORMAL", vector_types, ("VEC3",),
                              zeros_limit).astype(np.float64)
                if len(n) != len(pos):
                    raise SceneError(f"mesh {node.mesh}: {len(n)} normals for {len(pos)} positions", path)
                n = n @ normal_matrix.T
                n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)
                part.norms.append(n)
            else:
                part.has_normals = False
            for slot, out in (("TEXCOORD_0", part.uvs), ("TEXCOORD_1", part.uvs1)):
                ref = getattr(prim.attributes, slot)
                if ref is not None:
                    uv = _accessor(doc, bufs, ref, path, slot, (5126, 5121, 5123) if not quantized else
                                   tuple(_COMPONENT), ("VEC2",), zeros_limit).astype(np.float32)
                    if len(uv) != len(pos):
                        raise SceneError(f"mesh {node.mesh}: {len(uv)} {slot} for {len(pos)} positions", path)
                    out.append(uv)
                elif slot == "TEXCOORD_0":   # kept when another primitive has them (a textured one needs them)
                    part.uvs.append(np.zeros((len(pos), 2), np.float32))
                else:
                    part.has_uvs1 = False
            if prim.material is None:
                if default_index is None:
                    default_index = len(materials)
                    materials.append(make_material("default", (1, 1, 1)))
                mid = default_index
            else:
                mid = _int(prim.material, f"mesh {node.mesh} material index", path, 0, n_file_materials - 1) \
                    if n_file_materials else _item([], prim.material, f"mesh {node.mesh} material", path)
            part.tris.append(t + part.offset)
            part.mids.append(np.full(len(t), mid))
            part.offset += len(pos)
    held = [objects[k] for k in sorted(objects) if objects[k].tris]
    for d in names:
        if not any(d in o.names for o in held):
            raise SceneError(f"--dynamic {d!r}: the node holds no triangles", path)
    moving = [_dynamic_parts(o) for o in held]
    if not static.tris:
        raise SceneError("no triangles" if not moving else "every triangle is in a --dynamic node: nothing is left "
                         "to bake", path)
    if ignored:
        said = "; ".join(f"{what} in {', '.join(repr(n) for n in names)}" for what, names in ignored.items())
        notes.append(f"{path}: the baker treats every surface as diffuse and ignores {said}")
    any_uv = any(p.attributes.TEXCOORD_0 is not None for me in doc.meshes or [] for p in me.primitives or [])
    out = dict(notes=notes, vertices=np.concatenate(static.verts), triangles=np.concatenate(static.tris),
               material_ids=np.concatenate(static.mids),
               materials=materials, normals=np.concatenate(static.norms) if static.has_normals and static.norms
               else None, uvs=np.concatenate(static.uvs) if any_uv and static.uvs else None, cameras=cameras,
               lights=lights, uvs1=np.concatenate(static.uvs1) if static.has_uvs1 and static.uvs1 else None,
               material_extensions=[dict(m.extensions or {}) for m in doc.materials or []])
    if moving:
        out["dynamic"] = moving
    return out


def _dynamic_parts(part: _Part) -> dict:
    """One dynamic object's arrays (DynamicMesh's fields), normals made
    from its faces where the file gives none."""
    v = np.concatenate(part.verts)
    t = np.concatenate(part.tris)
    if part.has_normals and part.norms:
        n = np.concatenate(part.norms)
    else:   # area-weighted face normals at the vertices
        c = v[t]
        face = np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0])
        n = np.zeros_like(v)
        for k in range(3):
            np.add.at(n, t[:, k], face)
        n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)
    uv = np.concatenate(part.uvs) if part.uvs and len(part.uvs) == len(part.verts) else None
    return dict(name=part.name, pivot=part.pivot, vertices=v, triangles=t, material_ids=np.concatenate(part.mids),
                normals=n, uvs=uv)
