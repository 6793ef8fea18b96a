"""GLSL sources shipped with the package; `source(name)` reads one, with
each line `#include "other.glsl"` replaced by that file of the package
(once per source: a second include of the same file is dropped)."""
import re
from importlib.resources import files

_INCLUDE = re.compile(r'^\s*#include\s+"([A-Za-z0-9_]+\.glsl)"\s*$')


def _read(name: str) -> str:
    return files(__name__).joinpath(name).read_text(encoding="utf-8")


def source(name: str) -> str:
    seen = set()

    def expand(text, depth):
        out = []
        for line in text.splitlines():
            m = _INCLUDE.match(line)
            if not m:
                out.append(line)
                continue
            inc = m.group(1)
            if depth > 8:
                raise ValueError(f"shader {name}: includes nested deeper than 8")
            if inc not in seen:
                seen.add(inc)
                out.append(expand(_read(inc), depth + 1))
        return "\n".join(out)

    return expand(_read(name), 0) + "\n"


def names() -> list:
    return sorted(p.name for p in files(__name__).iterdir() if p.name.endswith((".vert", ".frag", ".glsl")))
