"""A frozen dataclass of arrays and plain values (the voxel Solution, its
Voxels) to one .npz file and back, exactly: no pickle, so a damaged or
crafted checkpoint can only be refused, never run.

The record's plain values (numbers, strings, lists, dicts) go into one
JSON document stored as an array; every array (at any depth) is an entry
of the .npz named by its place; a nested record names its class, which
must be one of the kinds the reader allows.
"""
from __future__ import annotations

import io
import json
import zipfile
from dataclasses import fields, is_dataclass

import numpy as np

from ..errors import VoxgiError


def _encode(v, arrays):
    if is_dataclass(v):
        return {"__record__": type(v).__name__, "fields": {f.name: _encode(getattr(v, f.name), arrays)
                                                           for f in fields(v)}}
    if isinstance(v, np.ndarray):
        name = f"a{len(arrays)}"
        arrays[name] = v
        return {"__array__": name}
    if isinstance(v, dict):
        if not all(isinstance(k, str) for k in v):
            raise TypeError("a record's dict keys must be strings")
        return {"__dict__": {k: _encode(x, arrays) for k, x in v.items()}}
    if isinstance(v, (list, tuple)):
        return {"__list__": [_encode(x, arrays) for x in v], "tuple": isinstance(v, tuple)}
    if isinstance(v, np.generic):
        return v.item()
    if v is None or isinstance(v, (bool, int, float, str)):
        return v
    raise TypeError(f"a record cannot hold {type(v).__name__}")


def record_bytes(record) -> bytes:
    """The .npz bytes of a dataclass record."""
    arrays = {}
    doc = json.dumps(_encode(record, arrays), allow_nan=True)
    buf = io.BytesIO()
    np.savez(buf, __json__=np.frombuffer(doc.encode(), np.uint8), **arrays)
    return buf.getvalue()


def _decode(v, z, kinds, path):
    if isinstance(v, dict):
        if "__array__" in v:
            name = v["__array__"]
            if not isinstance(name, str) or name not in z.files or name == "__json__":
                raise VoxgiError("damaged checkpoint record (a missing array)", path)
            return z[name]
        if "__record__" in v:
            cls = kinds.get(v["__record__"])
            if cls is None or not isinstance(v.get("fields"), dict):
                raise VoxgiError(f"damaged checkpoint record (an unknown kind {str(v['__record__'])[:40]!r})", path)
            got = {k: _decode(x, z, kinds, path) for k, x in v["fields"].items()}
            want = {f.name for f in fields(cls)}
            if set(got) != want:
                raise VoxgiError(f"damaged checkpoint record (the fields of {cls.__name__} differ)", path)
            return cls(**got)
        if "__dict__" in v and isinstance(v["__dict__"], dict):
            return {k: _decode(x, z, kinds, path) for k, x in v["__dict__"].items()}
        if "__list__" in v and isinstance(v["__list__"], list):
            out = [_decode(x, z, kinds, path) for x in v["__list__"]]
            return tuple(out) if v.get("tuple") else out
        raise VoxgiError("damaged checkpoint record", path)
    if isinstance(v, list):
        raise VoxgiError("damaged checkpoint record", path)
    return v


def read_record(path, cls, kinds=None):
    """The record of class `cls` stored at path; nested records may be of
    the classes in kinds (name -> class) besides the dataclasses among
    cls's own field values' kinds given there. Raises VoxgiError naming
    the file when it is damaged."""
    kinds = dict(kinds or {})
    kinds[cls.__name__] = cls
    try:
        with np.load(path, allow_pickle=False) as z:
            doc = json.loads(z["__json__"].tobytes().decode())
            out = _decode(doc, z, kinds, path)
    except VoxgiError:
        raise
    except (OSError, ValueError, KeyError, UnicodeDecodeError, TypeError, EOFError, zipfile.BadZipFile,
            RecursionError):
        raise VoxgiError("damaged checkpoint record: remove the checkpoint folder", path) from None
    if not isinstance(out, cls):
        raise VoxgiError("damaged checkpoint record (not the record expected)", path)
    return out
