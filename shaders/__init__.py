"""GLSL sources shipped with the package; `source(name)` reads one."""
from importlib.resources import files


def source(name: str) -> str:
    return files(__name__).joinpath(name).read_text(encoding="utf-8")


def names() -> list:
    return sorted(p.name for p in files(__name__).iterdir() if p.name.endswith((".vert", ".frag", ".glsl")))
