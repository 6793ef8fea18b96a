"""Writing outputs so that an error or Ctrl-C leaves nothing half-written:
a temporary file in the same folder, renamed over the target when done."""
from __future__ import annotations

import os
import tempfile

from .errors import VoxgiError


def check_output_path(path, extensions=None):
    """Refuses, before any work, an output whose folder does not exist or
    whose extension is not one of `extensions` (e.g. ('.exr', '.png'))."""
    folder = os.path.dirname(os.path.abspath(path)) or "."
    if extensions is not None:
        ext = os.path.splitext(path)[1].lower()
        if ext not in extensions:
            raise VoxgiError(f"unsupported output format {ext or '(none)'!r}; use {' or '.join(extensions)}", path)
    if not os.path.isdir(folder):
        raise VoxgiError("output folder does not exist", path)


def atomic_write(path, writer):
    """Calls writer(tmp) on a temporary file beside `path`, then renames it
    to `path`; the temporary file is removed on any error or interrupt."""
    check_output_path(path)
    folder = os.path.dirname(os.path.abspath(path)) or "."
    suffix = os.path.splitext(path)[1]
    fd, tmp = tempfile.mkstemp(prefix=".voxgi-", suffix=suffix, dir=folder)
    os.close(fd)
    try:
        writer(tmp)
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.remove(tmp)
        raise
