"""Writing outputs so that an error, Ctrl-C or SIGTERM leaves nothing
half-written, and no output ever replaces an input.

An output goes to a temporary file `.voxgi-<pid>-*` in the target's folder
and is renamed over the target when complete. The pid in the name lets a
later run into that folder remove the temporary files of runs that were
killed (SIGKILL, a power cut) without touching those of a run still going.
"""
from __future__ import annotations

import os
import stat
import tempfile

from .errors import VoxgiError

TEMP_PREFIX = ".voxgi-"


def _same_file(a, b) -> bool:
    """Do paths a and b name one file (any spelling, links, hard links)?"""
    try:
        return os.path.samefile(a, b)
    except OSError:
        return os.path.realpath(a) == os.path.realpath(b)


def check_output_path(path, extensions=None, inputs=(), probe=True):
    """Refuses, before any work, an output that could not be written or
    that would destroy something: an extension not among `extensions`
    (e.g. ('.exr', '.png')), a missing or read-only folder, an existing
    target that is not a regular file (a folder, a device such as
    /dev/null, a FIFO), and a target that is one of `inputs` (compared
    after resolving links, and by inode). `probe` creates and removes a
    temporary file in the folder to prove it writable."""
    path = os.fspath(path)
    folder = os.path.dirname(os.path.abspath(path)) or "."
    if extensions is not None:
        ext = os.path.splitext(path)[1].lower()
        if ext not in extensions:
            raise VoxgiError(f"unsupported output format {ext or '(none)'!r}; use {' or '.join(extensions)}", path)
    if not os.path.isdir(folder):
        raise VoxgiError("output folder does not exist", path)
    for other in inputs:
        if other is not None and os.path.lexists(os.fspath(other)) and _same_file(path, os.fspath(other)):
            raise VoxgiError(f"the output is an input ({os.fspath(other)}): choose another output file", path)
    if os.path.lexists(path):
        try:
            st = os.stat(path)
        except OSError:
            st = None  # a dangling link: replaced by the rename like a new file
        if st is not None and not stat.S_ISREG(st.st_mode):
            what = "a folder" if stat.S_ISDIR(st.st_mode) else "not a regular file (a device, FIFO or socket)"
            raise VoxgiError(f"the output exists and is {what}: outputs are regular files", path)
    if probe:
        remove_stale_temporaries(folder)
        try:
            fd, tmp = tempfile.mkstemp(prefix=f"{TEMP_PREFIX}{os.getpid()}-", suffix=".probe", dir=folder)
        except OSError as e:
            raise VoxgiError(f"cannot write in the output folder ({e.strerror})", path) from None
        os.close(fd)
        os.remove(tmp)


def remove_stale_temporaries(folder):
    """Removes the `.voxgi-<pid>-*` files in `folder` whose process is gone
    (a run killed before it could clean up)."""
    try:
        names = os.listdir(folder)
    except OSError:
        return
    for name in names:
        if not name.startswith(TEMP_PREFIX):
            continue
        pid = name[len(TEMP_PREFIX):].split("-", 1)[0]
        if not pid.isdigit() or _alive(int(pid)):
            continue
        try:
            full = os.path.join(folder, name)
            if stat.S_ISREG(os.lstat(full).st_mode):
                os.remove(full)
        except OSError:
            pass


def _alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def atomic_write(path, writer, inputs=()):
    """Calls writer(tmp) on a temporary file beside `path`, then renames it
    to `path`; the temporary file is removed on any error or interrupt. A
    Ctrl-C or SIGTERM noted while the writer ran stops before the rename:
    the target keeps what it held."""
    from .startup import checkpoint
    check_output_path(path, inputs=inputs, probe=False)
    folder = os.path.dirname(os.path.abspath(path)) or "."
    remove_stale_temporaries(folder)
    suffix = os.path.splitext(path)[1]
    try:
        fd, tmp = tempfile.mkstemp(prefix=f"{TEMP_PREFIX}{os.getpid()}-", suffix=suffix, dir=folder)
    except OSError as e:
        raise VoxgiError(f"cannot write in the output folder ({e.strerror})", path) from None
    os.close(fd)
    try:
        writer(tmp)
        os.chmod(tmp, 0o644)
        checkpoint()
        os.replace(tmp, path)
    except OSError as e:
        _remove(tmp)
        raise VoxgiError(f"cannot write ({e.strerror or e})", path) from None
    except BaseException:
        _remove(tmp)
        raise


def _remove(tmp):
    try:
        os.remove(tmp)
    except OSError:
        pass
