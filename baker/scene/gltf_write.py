"""Writing glTF 2.0 binary files through pygltflib (no hand-written schema).

Used by the scene generator (`scenes/generate.py`) and, later, by the bake
file writer. Geometry goes in as flat numpy arrays; every primitive has one
material; cameras and KHR_lights_punctual lights are nodes.
"""
from __future__ import annotations

import re

import numpy as np
import pygltflib as g

from ..fileio import atomic_write


def _look_rotation(forward, up):
    """Quaternion (x, y, z, w) turning glTF's camera frame (-Z forward, +Y up)
    onto `forward` and `up`."""
    f = np.asarray(forward, float)
    f = f / np.linalg.norm(f)
    u = np.asarray(up, float)
    r = np.cross(f, u)
    r /= np.linalg.norm(r)
    u = np.cross(r, f)
    m = np.stack([r, u, -f], axis=1)  # columns: local x, y, z in world
    # Shepperd's method: divide by the largest of the four candidates
    tr = m[0, 0] + m[1, 1] + m[2, 2]
    if tr > 0:
        s = 2.0 * np.sqrt(1.0 + tr)
        w, x, y, z = s / 4, (m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = 2.0 * np.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
        w, x, y, z = (m[2, 1] - m[1, 2]) / s, s / 4, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s
    elif m[1, 1] > m[2, 2]:
        s = 2.0 * np.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2])
        w, x, y, z = (m[0, 2] - m[2, 0]) / s, (m[0, 1] + m[1, 0]) / s, s / 4, (m[1, 2] + m[2, 1]) / s
    else:
        s = 2.0 * np.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1])
        w, x, y, z = (m[1, 0] - m[0, 1]) / s, (m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, s / 4
    return [float(x), float(y), float(z), float(w)]


class GltfBuilder:
    """Accumulates meshes, materials, cameras and lights; `save` writes a .glb."""

    def __init__(self):
        self.doc = g.GLTF2(asset=g.Asset(generator="voxgi", version="2.0"))
        self.doc.scenes = [g.Scene(nodes=[])]
        self.doc.scene = 0
        self.blob = bytearray()
        self.lights = []
        self.extensions_used = set()

    # -- low level ---------------------------------------------------------
    def _view(self, data: bytes, target=None) -> int:
        while len(self.blob) % 4:
            self.blob.append(0)
        self.doc.bufferViews.append(
            g.BufferView(buffer=0, byteOffset=len(self.blob), byteLength=len(data), target=target))
        self.blob.extend(data)
        return len(self.doc.bufferViews) - 1

    def _accessor(self, arr: np.ndarray, kind: str, target, with_bounds=False) -> int:
        arr = np.ascontiguousarray(arr)
        ctype = {np.dtype(np.float32): g.FLOAT, np.dtype(np.uint32): g.UNSIGNED_INT}[arr.dtype]
        view = self._view(arr.tobytes(), target)
        acc = g.Accessor(bufferView=view, componentType=ctype, count=len(arr) if arr.ndim > 1 else arr.size,
                         type=kind)
        if with_bounds:
            acc.min = arr.min(axis=0).tolist()
            acc.max = arr.max(axis=0).tolist()
        self.doc.accessors.append(acc)
        return len(self.doc.accessors) - 1

    def _add_node(self, node: g.Node) -> int:
        self.doc.nodes.append(node)
        idx = len(self.doc.nodes) - 1
        self.doc.scenes[0].nodes.append(idx)
        return idx

    # -- public ------------------------------------------------------------
    def buffer_view(self, data: bytes) -> int:
        """Raw bytes in the binary chunk (for an extension's data)."""
        return self._view(bytes(data))

    def image(self, data: bytes, mime="image/png") -> int:
        self.doc.images.append(g.Image(bufferView=self._view(bytes(data)), mimeType=mime))
        return len(self.doc.images) - 1

    def texture(self, image: int, linear_filter=True, clamp=True) -> int:
        """A texture of `image` with its own sampler (bilinear, no mipmaps,
        clamped to the edge: what a lightmap page wants)."""
        f = g.LINEAR if linear_filter else g.NEAREST
        w = g.CLAMP_TO_EDGE if clamp else g.REPEAT
        self.doc.samplers.append(g.Sampler(magFilter=f, minFilter=f, wrapS=w, wrapT=w))
        self.doc.textures.append(g.Texture(source=image, sampler=len(self.doc.samplers) - 1))
        return len(self.doc.textures) - 1

    def material(self, name, albedo, emission=(0.0, 0.0, 0.0), double_sided=False, texture=None,
                 extensions=None, alpha_cutoff=None, transmission=0.0, emissive_texture=None) -> int:
        """Lambertian material; `emission` is radiance (W m^-2 sr^-1), split
        into emissiveFactor (max 1) times KHR_materials_emissive_strength;
        `texture` a base colour texture index (TEXCOORD_0; its alpha is the
        mask's when `alpha_cutoff` is given: alphaMode MASK); albedo's
        fourth value, if any, the base colour's alpha; `transmission` thin
        glass (KHR_materials_transmission); `emissive_texture` a texture
        index; `extensions` more material extensions {name: data} (each
        listed as used)."""
        albedo = [float(a) for a in albedo]
        alpha = albedo[3] if len(albedo) > 3 else 1.0
        emission = np.asarray(emission, float)
        strength = float(emission.max())
        mat = g.Material(
            name=name,
            pbrMetallicRoughness=g.PbrMetallicRoughness(
                baseColorFactor=albedo[:3] + [alpha], metallicFactor=0.0, roughnessFactor=1.0),
            doubleSided=bool(double_sided))
        if texture is not None:
            mat.pbrMetallicRoughness.baseColorTexture = g.TextureInfo(index=int(texture))
        if alpha_cutoff is not None:
            mat.alphaMode, mat.alphaCutoff = "MASK", float(alpha_cutoff)
        if emissive_texture is not None:
            mat.emissiveTexture = g.TextureInfo(index=int(emissive_texture))
        ext = dict(extensions or {})
        if transmission > 0:
            ext["KHR_materials_transmission"] = {"transmissionFactor": float(transmission)}
        if strength > 0:
            mat.emissiveFactor = (emission / strength).tolist()
            if strength != 1.0:
                ext["KHR_materials_emissive_strength"] = {"emissiveStrength": strength}
        if ext:
            mat.extensions = ext
            self.extensions_used.update(ext)
        self.doc.materials.append(mat)
        return len(self.doc.materials) - 1

    def mesh(self, name, positions, triangles, material: int, normals=None, uvs=None) -> int:
        """Adds one primitive. positions (n, 3), triangles (m, 3)."""
        positions = np.asarray(positions, np.float32).reshape(-1, 3)
        attrs = g.Attributes(POSITION=self._accessor(positions, "VEC3", g.ARRAY_BUFFER, True))
        if normals is not None:
            attrs.NORMAL = self._accessor(np.asarray(normals, np.float32).reshape(-1, 3), "VEC3", g.ARRAY_BUFFER)
        if uvs is not None:
            attrs.TEXCOORD_0 = self._accessor(np.asarray(uvs, np.float32).reshape(-1, 2), "VEC2", g.ARRAY_BUFFER)
        idx = self._accessor(np.asarray(triangles, np.uint32).reshape(-1), "SCALAR", g.ELEMENT_ARRAY_BUFFER)
        self.doc.meshes.append(g.Mesh(name=name, primitives=[
            g.Primitive(attributes=attrs, indices=idx, material=material)]))
        return self._add_node(g.Node(name=name, mesh=len(self.doc.meshes) - 1))

    def primitives(self, name, parts, translation=None) -> int:
        """One mesh of several primitives in a node (moved by `translation`
        (3,) if given); each part a dict with positions (n, 3), material,
        and optional normals (n, 3), uv0, uv1 (n, 2), triangles (m, 3)
        (default: consecutive corners)."""
        prims = []
        for part in parts:
            pos = np.asarray(part["positions"], np.float32).reshape(-1, 3)
            attrs = g.Attributes(POSITION=self._accessor(pos, "VEC3", g.ARRAY_BUFFER, True))
            if part.get("normals") is not None:
                attrs.NORMAL = self._accessor(np.asarray(part["normals"], np.float32).reshape(-1, 3), "VEC3",
                                              g.ARRAY_BUFFER)
            for key, attr in (("uv0", "TEXCOORD_0"), ("uv1", "TEXCOORD_1")):
                if part.get(key) is not None:
                    setattr(attrs, attr, self._accessor(np.asarray(part[key], np.float32).reshape(-1, 2), "VEC2",
                                                        g.ARRAY_BUFFER))
            tris = part.get("triangles")
            tris = np.arange(len(pos), dtype=np.uint32) if tris is None else np.asarray(tris, np.uint32)
            idx = self._accessor(tris.reshape(-1), "SCALAR", g.ELEMENT_ARRAY_BUFFER)
            prims.append(g.Primitive(attributes=attrs, indices=idx, material=int(part["material"])))
        self.doc.meshes.append(g.Mesh(name=name, primitives=prims))
        node = g.Node(name=name, mesh=len(self.doc.meshes) - 1)
        if translation is not None:
            node.translation = [float(v) for v in translation]
        return self._add_node(node)

    def camera(self, name, position, forward, up=(0, 1, 0), yfov_deg=45.0, aspect=1.0) -> int:
        self.doc.cameras.append(g.Camera(name=name, type="perspective", perspective=g.Perspective(
            yfov=float(np.radians(yfov_deg)), aspectRatio=float(aspect), znear=0.01)))
        return self._add_node(g.Node(name=name, camera=len(self.doc.cameras) - 1,
                                     translation=[float(v) for v in position],
                                     rotation=_look_rotation(forward, up)))

    def light(self, name, kind, color=(1, 1, 1), intensity=1.0, position=(0, 0, 0),
              direction=(0, -1, 0), inner_deg=0.0, outer_deg=45.0) -> int:
        """KHR_lights_punctual light; point and spot intensity in W/sr,
        directional in W/m^2 (docs/design.md section 1)."""
        light = {"name": name, "type": kind, "color": [float(c) for c in color], "intensity": float(intensity)}
        if kind == "spot":
            light["spot"] = {"innerConeAngle": float(np.radians(inner_deg)),
                             "outerConeAngle": float(np.radians(outer_deg))}
        self.lights.append(light)
        self.extensions_used.add("KHR_lights_punctual")
        up = (0, 0, 1) if abs(direction[1]) > 0.9 else (0, 1, 0)
        node = g.Node(name=name, translation=[float(v) for v in position],
                      rotation=_look_rotation(direction, up),
                      extensions={"KHR_lights_punctual": {"light": len(self.lights) - 1}})
        return self._add_node(node)

    def save(self, path, extensions=None, extras=None, checksum_key=None, inputs=()):
        """Writes the .glb atomically (temporary file in the same folder, then
        rename; never over one of `inputs`). `extensions`: more root
        extensions {name: data}; `extras`: the root's extras; `checksum_key`:
        if given, extras[checksum_key]["fileSha256"] holds the SHA-256 of the
        whole file as written with those 64 hex digits as zeros
        (`file_checksum`): the JSON and the binary chunk are both covered,
        and the file stays plain glTF for every other reader."""
        import hashlib
        ext = {"KHR_lights_punctual": {"lights": self.lights}} if self.lights else {}
        ext.update(extensions or {})
        if ext:
            self.doc.extensions = ext
            self.extensions_used.update(ext)
        self.doc.extensionsUsed = sorted(self.extensions_used)
        while len(self.blob) % 4:
            self.blob.append(0)
        if extras is not None or checksum_key:
            extras = dict(extras or {})
            if checksum_key:
                extras[checksum_key] = dict(extras.get(checksum_key, {}), fileSha256=CHECKSUM_PLACEHOLDER)
            self.doc.extras = extras
        self.doc.buffers = [g.Buffer(byteLength=len(self.blob))]
        self.doc.set_binary_blob(bytes(self.blob))
        data = b"".join(self.doc.save_to_bytes())
        if checksum_key:
            at = _digest_at(data)
            if at is None or data[at:at + 64] != CHECKSUM_PLACEHOLDER.encode():
                raise RuntimeError("the bake's JSON names fileSha256 more than once")  # our own writer's bug
            data = data[:at] + hashlib.sha256(data).hexdigest().encode() + data[at + 64:]

        def write(tmp):
            with open(tmp, "wb") as f:
                f.write(data)
        atomic_write(path, write, inputs)
        return path


CHECKSUM_PLACEHOLDER = "0" * 64


_DIGEST_KEY = re.compile(rb'"fileSha256"[ \t\r\n]*:[ \t\r\n]*"([0-9a-f]{64})"')


def _digest_at(data: bytes):
    """Offset of the 64 digits of the one `"fileSha256": "..."` key in a
    .glb's JSON chunk (None: not a .glb, or no such key, or more than one).
    Only the JSON chunk is searched: the binary chunk (floats, PNG bytes)
    may hold any 64 bytes, the placeholder's or the digest's among them,
    and a quote inside a JSON string is escaped, so the key with its quotes
    can only be a key."""
    if len(data) < 20 or data[:4] != b"glTF" or data[16:20] != b"JSON":
        return None
    end = min(len(data), 20 + int.from_bytes(data[12:16], "little"))
    found = list(_DIGEST_KEY.finditer(data, 20, end))
    return found[0].start(1) if len(found) == 1 else None


def file_checksum(data: bytes, stated: str):
    """The SHA-256 of a .glb written by `save`, with the digest it states
    (`stated`, 64 hex digits, at the JSON's one fileSha256 key) as zeros;
    None if the stated digest is malformed or not at that key."""
    import hashlib
    if not isinstance(stated, str) or not re.fullmatch(r"[0-9a-f]{64}", stated):
        return None
    at = _digest_at(data)
    if at is None or data[at:at + 64] != stated.encode():
        return None
    return hashlib.sha256(data[:at] + CHECKSUM_PLACEHOLDER.encode() + data[at + 64:]).hexdigest()
