"""A standalone (windowless) moderngl context through EGL: Mesa llvmpipe on
machines without a GPU. Never imports glfw (docs/design.md section 9)."""
from __future__ import annotations

from baker.errors import GLError


def headless_context(require: int = 330):
    """moderngl.Context on standalone EGL. Where EGL is missing and an X
    display is there (Xvfb), a standalone GLX context on it instead, said
    on stderr. GLError with the reasons if neither."""
    import os
    import sys

    import moderngl
    try:
        if os.environ.get("VOXGI_NO_EGL") == "1":  # as if EGL were missing (tests the fallback)
            raise RuntimeError("EGL disabled by VOXGI_NO_EGL=1")
        return moderngl.create_context(standalone=True, backend="egl", require=require)
    except Exception as e:  # moderngl raises plain Exceptions with EGL codes
        why = str(e).splitlines()[0] if str(e) else type(e).__name__
    if os.environ.get("DISPLAY"):
        try:
            ctx = moderngl.create_context(standalone=True, require=require)
            print(f"note: no EGL ({why}); rendering through the X display {os.environ['DISPLAY']} instead",
                  file=sys.stderr)
            return ctx
        except Exception as e:
            why += f"; X display {os.environ['DISPLAY']}: {str(e).splitlines()[0] if str(e) else type(e).__name__}"
    raise GLError(f"no headless OpenGL {require // 100}.{require % 100 // 10} context: EGL: {why}; install "
                  f"libegl1 libgl1 libgl1-mesa-dri (scripts/setup.sh does), or run under Xvfb")


def _with_defines(src: str, defines) -> str:
    if not defines:
        return src
    head, rest = src.split("\n", 1)  # the #version line stays first
    return head + "\n" + "".join(f"#define {k} {int(v)}\n" for k, v in defines.items()) + rest


def build_program(ctx, vert: str, frag: str, defines=None):
    """Compiles one shader pair from the shipped `shaders` package, with
    `defines` {NAME: int} put after the #version line of both, with the
    light kinds' codes (KIND_AREA, ...: baker.scene.model.LightKind)."""
    import shaders
    from baker.scene.model import LightKind
    defines = {**LightKind.defines(), **(defines or {})}
    try:
        return ctx.program(vertex_shader=_with_defines(shaders.source(vert), defines),
                           fragment_shader=_with_defines(shaders.source(frag), defines))
    except Exception as e:
        raise GLError(f"shader {vert}/{frag} failed to build: {str(e).strip().splitlines()[-1]}") from e
