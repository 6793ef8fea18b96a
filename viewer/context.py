"""A standalone (windowless) moderngl context through EGL: Mesa llvmpipe on
machines without a GPU. Never imports glfw (docs/design.md section 9)."""
from __future__ import annotations

from baker.errors import GLError


def headless_context(require: int = 330):
    """moderngl.Context on standalone EGL; GLError with the reason if none."""
    import moderngl
    try:
        return moderngl.create_context(standalone=True, backend="egl", require=require)
    except Exception as e:  # moderngl raises plain Exceptions with EGL codes
        raise GLError(f"no headless OpenGL {require // 100}.{require % 100 // 10} context through EGL "
                      f"({str(e).splitlines()[0] if str(e) else type(e).__name__}); install libegl1 libgl1 "
                      f"libgl1-mesa-dri (scripts/setup.sh does)") from e


def build_program(ctx, vert: str, frag: str):
    """Compiles one shader pair from the shipped `shaders` package."""
    import shaders
    try:
        return ctx.program(vertex_shader=shaders.source(vert), fragment_shader=shaders.source(frag))
    except Exception as e:
        raise GLError(f"shader {vert}/{frag} failed to build: {str(e).strip().splitlines()[-1]}") from e
