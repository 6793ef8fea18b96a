"""Keeps numba's on-disk kernel cache in step with the sources.

numba checks a cached kernel against the time stamp and size of the file
that defines it, not of the files it calls into: the propagation sweep
(solve/sweep.py) inlines the visibility rule (solve/visibility.py), so a
changed rule with an unchanged sweep.py would keep running the old rule
from the cache (after an upgrade, or an edit). So on import the package
hashes its own sources; when the hash differs from the one the cache was
built with, it drops its cached kernels (they compile again, once).
Only the cache next to the sources is handled; numba's user-wide cache
(used when the package folder is read-only) is keyed the same way by
numba and is left alone.
"""
import hashlib
import os

_STAMP = "voxgi-sources.sha256"


def _sources(root):
    for folder, dirs, files in os.walk(root):
        dirs[:] = sorted(d for d in dirs if d != "__pycache__")
        for name in sorted(files):
            if name.endswith(".py"):
                yield os.path.join(folder, name)


def sync(root=None) -> bool:
    """Drops the package's cached numba kernels if its sources changed
    since they were compiled. Returns True when it dropped any."""
    root = root or os.path.dirname(os.path.abspath(__file__))
    digest = hashlib.sha256()
    try:
        for path in _sources(root):
            digest.update(os.path.relpath(path, root).encode())
            with open(path, "rb") as f:
                digest.update(f.read())
    except OSError:
        return False
    stamp = os.path.join(root, "__pycache__", _STAMP)
    try:
        with open(stamp) as f:
            if f.read().strip() == digest.hexdigest():
                return False
    except OSError:
        pass
    dropped = False
    for folder, dirs, files in os.walk(root):
        if os.path.basename(folder) != "__pycache__":
            continue
        for name in files:
            if name.endswith((".nbi", ".nbc")):
                try:
                    os.remove(os.path.join(folder, name))
                    dropped = True
                except OSError:
                    pass
    try:
        os.makedirs(os.path.dirname(stamp), exist_ok=True)
        tmp = stamp + f".{os.getpid()}.tmp"
        with open(tmp, "w") as f:
            f.write(digest.hexdigest() + "\n")
        os.replace(tmp, stamp)
    except OSError:
        pass
    return dropped
