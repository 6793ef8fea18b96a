"""What a scene file may make voxgi read, and how much.

Every file is untrusted. A scene's external references (glTF buffer and
image `uri`s, OBJ `mtllib`, MTL `map_Kd`) resolve only to regular files
inside the scene file's own folder or below it, after symbolic links are
followed; absolute paths, `..` escapes, URLs and anything that is not a
regular file (a device, a FIFO, a folder) are refused in one line that
names the reference. `LoadLimits.allow_outside_refs` (the command line's
`--allow-outside-refs`) lifts the folder rule for a user who means it,
never the regular-file rule: `/dev/zero` has no end and a FIFO may never
answer.

Every size a file states is checked against the bytes present before
anything is allocated (gltf_read.py, ply.py); what the load as a whole
would hold is checked against `LoadLimits.memory_budget_mb`.
"""
from __future__ import annotations

import os
import re
import stat
from dataclasses import dataclass
from urllib.parse import unquote

from ..errors import BudgetError, ConfigError, SceneError

_SCHEME = re.compile(r"^[A-Za-z][A-Za-z0-9+.\-]*:")


@dataclass(frozen=True)
class LoadLimits:
    """What a scene file may make the loader read and hold.

    allow_outside_refs: external references may name files outside the
        scene's folder (still regular files only).
    max_texture: textures larger than this many pixels along a side are
        scaled down to it (with a warning); the baker averages albedo over
        surface pieces and texels, far coarser than this.
    memory_budget_mb: refuse a load whose arrays would exceed this.
    """
    allow_outside_refs: bool = False
    max_texture: int = 4096
    memory_budget_mb: float = 8192.0

    def __post_init__(self):
        if not 16 <= self.max_texture <= 65536:
            raise ConfigError(f"max texture size must lie in 16..65536 pixels (got {self.max_texture})")
        if not 0 < self.memory_budget_mb <= 1 << 30:
            raise ConfigError(f"memory budget must be positive MiB (got {self.memory_budget_mb})")

    def check_bytes(self, nbytes: float, what: str, path):
        """BudgetError if holding `nbytes` for `what` would exceed the budget."""
        if nbytes > self.memory_budget_mb * 2 ** 20:
            raise BudgetError(f"{what} would need {nbytes / 2 ** 20:.0f} MiB, over the memory budget of "
                              f"{self.memory_budget_mb:g} MiB (--memory-budget)", path)


def check_regular(path, what="the scene") -> os.stat_result:
    """The stat of `path` if it is a regular file; SceneError otherwise."""
    try:
        st = os.stat(path)
    except FileNotFoundError:
        raise SceneError(f"{what}: file not found", path) from None
    except OSError as e:
        raise SceneError(f"{what}: cannot read ({e.strerror})", path) from None
    if stat.S_ISDIR(st.st_mode):
        raise SceneError(f"{what}: is a folder, not a file", path)
    if not stat.S_ISREG(st.st_mode):
        raise SceneError(f"{what}: not a regular file (a device, FIFO or socket is never read)", path)
    return st


def resolve_reference(ref: str, scene_path, what: str, limits: LoadLimits, encoded=False) -> str:
    """The path of the file an external reference `ref` names, relative to
    the scene file `scene_path`; SceneError if the rules above refuse it.
    `encoded`: `ref` is a URI reference (glTF), so %XX escapes are decoded."""
    shown = ref if len(ref) <= 80 else ref[:77] + "..."
    if "\x00" in ref:
        raise SceneError(f"{what} {shown!r}: a name with a NUL byte", scene_path)
    if _SCHEME.match(ref):
        raise SceneError(f"{what} {shown!r}: URLs are not read (only files beside the scene)", scene_path)
    name = unquote(ref) if encoded else ref
    folder = os.path.realpath(os.path.dirname(os.path.abspath(os.fspath(scene_path))))
    if os.path.isabs(name) and not limits.allow_outside_refs:
        raise SceneError(f"{what} {shown!r}: an absolute path; references are read only inside the scene's "
                         f"folder (--allow-outside-refs to read it anyway)", scene_path)
    target = os.path.realpath(os.path.join(folder, name))
    if not limits.allow_outside_refs and os.path.commonpath([folder, target]) != folder:
        raise SceneError(f"{what} {shown!r}: outside the scene's folder; references are read only inside it "
                         f"(--allow-outside-refs to read it anyway)", scene_path)
    if not os.path.exists(target):
        raise SceneError(f"{what} {shown!r}: file not found", scene_path)
    try:
        st = os.stat(target)
    except OSError as e:
        raise SceneError(f"{what} {shown!r}: cannot read ({e.strerror})", scene_path) from None
    if not stat.S_ISREG(st.st_mode):
        raise SceneError(f"{what} {shown!r}: not a regular file (a device, FIFO or folder is never read)",
                         scene_path)
    return target


def read_file(path, limit: int | None = None, scene_path=None, what="file") -> bytes:
    """The bytes of a regular file, at most `limit` of them. Opened without
    blocking and checked again once open, so a file swapped for a FIFO or a
    device between the check and the read is refused, not waited on."""
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0))
    except OSError as e:
        raise SceneError(f"{what}: cannot read ({e.strerror})", scene_path or path) from None
    with os.fdopen(fd, "rb") as f:
        st = os.fstat(f.fileno())
        if not stat.S_ISREG(st.st_mode):
            raise SceneError(f"{what}: not a regular file", scene_path or path)
        return f.read(st.st_size if limit is None else min(limit, st.st_size))
