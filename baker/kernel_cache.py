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

Several processes may start at once (a bake's workers, tests, benchmark
runs): the check, the drop and the new stamp happen under an exclusive
file lock, so a process that finds the sources changed drops the kernels
once and every later one sees the new stamp; none deletes kernels another
compiled after its own check.
"""
import hashlib
import os

try:
    import fcntl
except ImportError:   # not on POSIX: no lock (one process at a time is the user's to keep)
    fcntl = None

_STAMP = "voxgi-sources.sha256"


def _sources(root):
    for folder, dirs, files in os.walk(root):
        dirs[:] = sorted(d for d in dirs if d != "__pycache__")
        for name in sorted(files):
            if name.endswith(".py"):
                yield os.path.join(folder, name)


def source_digest(root=None) -> str | None:
    """sha256 (hex) of the package's Python sources (None: unreadable):
    what the kernel cache is stamped with, and what a bake's workers must
    share with its coordinator (bake/cluster.py)."""
    root = root or os.path.dirname(os.path.abspath(__file__))
    digest = hashlib.sha256()
    try:
        for path in _sources(root):
            digest.update(os.path.relpath(path, root).encode())
            with open(path, "rb") as f:
                digest.update(f.read())
    except OSError:
        return None
    return digest.hexdigest()


def sync(root=None) -> bool:
    """Drops the package's cached numba kernels if its sources changed
    since they were compiled. Returns True when it dropped any."""
    root = root or os.path.dirname(os.path.abspath(__file__))
    hexdigest = source_digest(root)
    if hexdigest is None:
        return False
    stamp = os.path.join(root, "__pycache__", _STAMP)
    try:
        os.makedirs(os.path.dirname(stamp), exist_ok=True)
        lock = open(stamp + ".lock", "a")
    except OSError:
        lock = None   # a read-only package: numba uses its user-wide cache, nothing here to drop
    try:
        if lock is not None and fcntl is not None:
            fcntl.flock(lock, fcntl.LOCK_EX)
        return _drop_unless_stamped(root, stamp, hexdigest)
    finally:
        if lock is not None:
            lock.close()   # (releases the lock)


def _drop_unless_stamped(root, stamp, hexdigest) -> bool:
    try:
        with open(stamp) as f:
            if f.read().strip() == hexdigest:
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
        tmp = stamp + f".{os.getpid()}.tmp"
        with open(tmp, "w") as f:
            f.write(hexdigest + "\n")
        os.replace(tmp, stamp)
    except OSError:
        pass
    return dropped
