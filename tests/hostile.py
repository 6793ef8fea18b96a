"""Crafted scene and bake files for the hostile-input tests: a one-triangle
glTF whose every field a test may change, a GLB of it, an OBJ, and the
edit-and-re-sign helper for bake files (the checksum is no signature: an
attacker can recompute it, so what lies behind it is validated too)."""
import base64
import copy
import json
import struct

import numpy as np

SECRET = b"TOP-SECRET-7f3a9c-token"

TRIANGLE = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32)


def triangle_doc(uri=None):
    """A valid glTF dict: one lit triangle, its 36 bytes in a data URI (or
    in the buffer file `uri`, written by `write_gltf`)."""
    data = TRIANGLE.tobytes()
    return {
        "asset": {"version": "2.0"},
        "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "material": 0}]}],
        "materials": [{"pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 1]}, "emissiveFactor": [1, 1, 1],
                       "doubleSided": True}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                       "min": [0, 0, 0], "max": [1, 1, 0]}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36}],
        "buffers": [{"byteLength": 36, "uri": uri or "data:application/octet-stream;base64," +
                     base64.b64encode(data).decode()}],
    }


def write_gltf(path, doc):
    path.write_text(json.dumps(doc))
    return path


def glb_bytes(doc, blob: bytes) -> bytes:
    """A GLB of `doc` (its buffer 0 the binary chunk `blob`)."""
    doc = copy.deepcopy(doc)
    doc["buffers"][0].pop("uri", None)
    j = json.dumps(doc).encode()
    j += b" " * (-len(j) % 4)
    blob = blob + b"\0" * (-len(blob) % 4)
    return (struct.pack("<4sII", b"glTF", 2, 12 + 8 + len(j) + 8 + len(blob)) + struct.pack("<I4s", len(j), b"JSON")
            + j + struct.pack("<I4s", len(blob), b"BIN\0") + blob)


def split_glb(data: bytes):
    """(json dict, bin bytes) of a GLB."""
    jlen = struct.unpack_from("<I", data, 12)[0]
    doc = json.loads(data[20:20 + jlen])
    blen = struct.unpack_from("<I", data, 20 + jlen)[0]
    return doc, data[28 + jlen:28 + jlen + blen]


def resign_bake(data: bytes, edit) -> bytes:
    """A bake file's bytes with its JSON changed by edit(doc) and the
    checksum computed again as the writer does (scene/gltf_write.py)."""
    import hashlib
    doc, blob = split_glb(data)
    edit(doc)
    doc["extras"]["voxgi"]["fileSha256"] = "0" * 64
    whole = glb_bytes(doc, blob)
    digest = hashlib.sha256(whole).hexdigest().encode()
    return whole.replace(b"0" * 64, digest, 1)


def tiny_png_header(width, height) -> bytes:
    """A PNG whose header claims width x height pixels, with almost no data."""
    import zlib

    def chunk(kind, body):
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body) & 0xFFFFFFFF)
    ihdr = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(b"\0" * 16))
            + chunk(b"IEND", b""))


OBJ = """mtllib {mtl}
v 0 0 0
v 1 0 0
v 0 1 0
usemtl lamp
f 1 2 3
"""


def write_obj(folder, mtl_name="box.mtl", mtl_text="newmtl lamp\nKd 0.5 0.5 0.5\nKe 1 1 1\n", name="s.obj"):
    (folder / name).write_text(OBJ.format(mtl=mtl_name))
    if mtl_text is not None and "/" not in mtl_name and ".." not in mtl_name:
        (folder / mtl_name).write_text(mtl_text)
    return folder / name
