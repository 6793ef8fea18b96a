"""`voxview`: the viewer's command line.

Today: `glinfo` opens a headless EGL context, builds every shipped shader
program and reports the GL renderer: the check that this machine can run
the viewer's snapshots.
"""
from __future__ import annotations

import argparse

from baker.cli import run


def cmd_glinfo(args):
    import shaders
    from .context import build_program, headless_context
    ctx = headless_context()
    info = ctx.info
    print(f"renderer  {info['GL_RENDERER']}")
    print(f"version   {info['GL_VERSION']}")
    print(f"vendor    {info['GL_VENDOR']}")
    pairs = sorted({n.rsplit(".", 1)[0] for n in shaders.names() if n.endswith(".vert")})
    for name in pairs:
        build_program(ctx, name + ".vert", name + ".frag")
        print(f"shader    {name}: ok")
    ctx.release()
    return 0


def build_parser():
    ap = argparse.ArgumentParser(prog="voxview", description="voxgi viewer.")
    sub = ap.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    p = sub.add_parser("glinfo", help="check headless OpenGL (EGL) and build every shipped shader",
                       description="Open a standalone EGL context (no window, no display), print the GL renderer "
                                   "and version, and compile every shader program shipped in `shaders`.")
    p.set_defaults(func=cmd_glinfo)
    return ap


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    return run(args.func, args)
