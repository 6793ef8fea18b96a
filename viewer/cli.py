"""`voxview`: walk through a bake (`voxbake bake`) in a window, or take
headless snapshots of it."""
from __future__ import annotations

import argparse
import sys

from baker.startup import run
from baker.cli_args import EXPOSURE, IMAGE_SIDE, command_parser, integer, number
from baker.errors import VoxgiError

from .renderer import MODES

EPILOG = """examples:
  voxbake bake cornell_box -o cornell.glb --preset preview
  voxview cornell.glb
  voxview snapshot cornell.glb --width 640 --height 480 -o shot.png
  voxview snapshot cornell.glb --mode checker -o texels.png
  voxview snapshot cornell.glb --mode preview --frames 256 -o ir.png
  voxview glinfo

Keys in the window: W A S D (Q E down/up) move, Shift faster, drag to look, wheel zooms, 1-9 cameras,
+/- exposure (0 automatic), F1-F5 or M views, P the progressive preview, B bicubic, O a sphere lit by the
probes, N the next object to move (the sphere, the bake's dynamic meshes; arrow keys, Page Up/Down move
it), G the probes, F12 screenshot, Esc.
"""
COMMANDS = ("walk", "snapshot", "glinfo")


def _read(path):
    from baker.bake import read_bake
    return read_bake(path)


def _camera(bake, which):
    from baker.scene import camera_for
    return camera_for(bake.scene, which)


def cmd_walk(args):
    from .window import Walkthrough, load_script
    script = load_script(args.script) if args.script else None
    if args.screenshot:
        from baker.fileio import check_output_path
        check_output_path(args.screenshot, (".png",), inputs=[args.bake])
    bake = _read(args.bake)
    cam = _camera(bake, args.camera)
    _check_probes(args, bake)
    result = Walkthrough(bake, args.width, args.height, cam, args.exposure, args.mode, script, args.frames,
                         args.screenshot, title=f"voxview {args.bake}", show_probes=args.probes).run()
    secs = result["seconds"]
    print(f"{result['frames']} frames in {secs:.2f} s ({result['frames'] / max(secs, 1e-9):.1f} fps)")
    return 0


def cmd_snapshot(args):
    from baker.fileio import check_output_path
    from baker.render import write_image
    from baker.startup import checkpoint
    from .snapshot import snapshot
    check_output_path(args.output, (".png", ".exr"), inputs=[args.bake])
    if args.width * args.height > 64_000_000:
        raise VoxgiError(f"image size {args.width}x{args.height} out of range")
    objects = _objects(args)   # the flags checked before the bake is read
    bake = _read(args.bake)
    objects = _objects(args, bake)
    if objects and bake.probes is None:
        raise VoxgiError("the bake holds no irradiance probes for --object: bake it again without --no-probes",
                         args.bake)
    _check_probes(args, bake)
    cam = _camera(bake, args.camera)
    from baker.progress import bar
    with bar(args.frames if args.mode == "preview" else 0, "preview", "frame", args.mode == "preview") as b:
        img = snapshot(bake, cam, args.width, args.height, args.mode, args.samples, args.bicubic,
                       frames=args.frames, per_frame=args.vpls_per_frame, progress=b.update, objects=objects,
                       probes=args.probes)
    checkpoint()
    write_image(args.output, img, args.exposure)
    print(f"wrote {args.output}  ({args.width}x{args.height}, {args.mode})")
    return 0


def _check_probes(args, bake):
    if args.probes and bake.probes is None:
        raise VoxgiError("the bake holds no irradiance probes for --probes: bake it again without --no-probes",
                         args.bake)
    if args.probes and args.mode != "lightmap":
        raise VoxgiError("--probes are drawn in the lightmap view (--mode lightmap)")


def _objects(args, bake=None):
    """The --object asked for, checked (one line, before any work): a
    sphere, or one of the bake's dynamic meshes by name (resolved once
    `bake` is read: () before)."""
    from .objects import Sphere, placed_at
    if not args.object:
        if args.at is not None or args.radius is not None or args.object_albedo is not None:
            raise VoxgiError("--at, --radius and --object-albedo place an --object: add --object sphere (or a "
                             "dynamic mesh's name)")
        return ()
    if args.mode != "lightmap":
        raise VoxgiError("--object is drawn in the lightmap view (--mode lightmap)")
    if args.object == "sphere":
        if args.at is None or args.radius is None:
            raise VoxgiError("--object sphere needs --at X,Y,Z and --radius R")
        albedo = args.object_albedo if args.object_albedo is not None else 0.8
        return (Sphere(tuple(args.at), float(args.radius), (albedo,) * 3),)
    if args.at is None:
        raise VoxgiError(f"--object {args.object} needs --at X,Y,Z (where the centre of its bounds goes)")
    if args.radius is not None or args.object_albedo is not None:
        raise VoxgiError("--radius and --object-albedo are the sphere's: a dynamic mesh keeps its own size and "
                         "materials")
    if bake is None:
        return ()
    names = [d.name for d in bake.scene.dynamic]
    if args.object not in names:
        held = f"its dynamic meshes: {', '.join(repr(n) for n in names)}" if names else \
            "it has none: bake with --dynamic NODE"
        raise VoxgiError(f"--object {args.object!r}: neither 'sphere' nor a dynamic mesh of the bake ({held})",
                         args.bake)
    i = names.index(args.object)
    return (placed_at(bake.scene.dynamic[i], i, args.at),)


def _vector(text):
    import math
    try:
        v = tuple(float(x) for x in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected X,Y,Z, got {text!r}") from None
    if len(v) != 3 or not all(math.isfinite(x) for x in v):
        raise argparse.ArgumentTypeError(f"expected three finite numbers X,Y,Z, got {text!r}")
    return v


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
    ap, sub = command_parser(
        "voxview", "voxgi viewer: walk through a baked scene (a .glb written by `voxbake bake`) in a window, or take "
                   "snapshots of it without a display. `voxview BAKE.glb` is `voxview walk BAKE.glb`.", EPILOG)

    p = sub.add_parser("walk", help="open a window and walk through the bake",
                       formatter_class=argparse.RawDescriptionHelpFormatter,
                       description="Open a window on a bake: albedo x lightmap / pi + emission, filmic tone map, "
                                   "sRGB.\n\n" + EPILOG.split("\n\n", 1)[1])
    p.add_argument("bake", help="bake file (.glb from `voxbake bake`)")
    p.add_argument("--camera", default=None, help="start at this camera (name or index; default: the first)")
    p.add_argument("--width", type=integer(64, 16384), default=1280, help="window width (default 1280)")
    p.add_argument("--height", type=integer(64, 16384), default=720, help="window height (default 720)")
    p.add_argument("--exposure", type=EXPOSURE, default=None, help="exposure in EV (default: automatic)")
    p.add_argument("--mode", choices=MODES + ("preview",), default="lightmap",
                   help="view to start in (default: lightmap; preview: progressive instant radiosity)")
    p.add_argument("--script", metavar="FILE.json", help="scripted input events (see viewer/window.py)")
    p.add_argument("--frames", type=integer(1, 1 << 24), help="close after this many frames")
    p.add_argument("--screenshot", metavar="FILE.png", help="with --frames: save the last frame here")
    p.add_argument("--probes", action="store_true",
                   help="show the irradiance probes as small spheres lit by their SH, invalid ones red (key G)")
    p.set_defaults(func=cmd_walk)

    p = sub.add_parser("snapshot", help="render a bake headless (EGL, no display) to an image",
                       description="Render one camera of a bake offscreen through standalone EGL (Mesa llvmpipe "
                                   "without a GPU) with 4 x 4 samples per pixel. EXR: linear radiance; PNG: "
                                   "exposure, filmic tone map, sRGB.")
    p.add_argument("bake", help="bake file (.glb from `voxbake bake`)")
    p.add_argument("-o", "--output", required=True, help="output image (.png or .exr)")
    p.add_argument("--camera", default=None, help="camera name or index (default: the first)")
    p.add_argument("--width", type=IMAGE_SIDE, default=512)
    p.add_argument("--height", type=IMAGE_SIDE, default=512)
    p.add_argument("--mode", choices=MODES + ("preview",), default="lightmap",
                   help="lightmap (default), a debug view, or preview (progressive instant radiosity over the "
                        "bake's VPL list, at the pixels' centres)")
    p.add_argument("--frames", type=integer(1, 1 << 20), default=64,
                   help="preview mode: frames to accumulate (default 64)")
    p.add_argument("--vpls-per-frame", type=integer(1, 1 << 20), default=16,
                   help="preview mode: VPLs a frame (default 16)")
    p.add_argument("--samples", type=integer(1, 16), default=4, help="samples per pixel along each axis (default 4)")
    p.add_argument("--bicubic", action="store_true", help="bicubic lightmap filtering")
    p.add_argument("--exposure", type=EXPOSURE, default=None, help="PNG exposure in EV (default: automatic)")
    p.add_argument("--object", metavar="sphere|NAME",
                   help="draw a moving object lit by the bake's irradiance probes (it does not shadow the room): "
                        "a diffuse sphere, or the dynamic mesh NAME (baked with --dynamic NAME; without --object "
                        "the dynamic meshes stand where the file has them)")
    p.add_argument("--at", type=_vector, metavar="X,Y,Z", help="the object's centre (a mesh: its bounds' centre)")
    p.add_argument("--radius", type=number(0, 1e9, lo_open=True), metavar="R", help="the sphere's radius")
    p.add_argument("--object-albedo", type=number(0, 1), metavar="A", help="the object's albedo (default 0.8)")
    p.add_argument("--probes", action="store_true",
                   help="draw the irradiance probes as small spheres lit by their SH (a white diffuse sphere's "
                        "light), invalid ones (inside walls, outside a closed building) red")
    p.set_defaults(func=cmd_snapshot)

    p = sub.add_parser("glinfo", help="check headless OpenGL (EGL) and build every shipped shader",
                       description="Open a standalone EGL context (no window, no display), print the GL renderer "
                                   "and version, and compile every shader program shipped in `shaders`.")
    p.set_defaults(func=cmd_glinfo)
    return ap


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv and argv[0] not in COMMANDS and not argv[0].startswith("-"):
        argv.insert(0, "walk")  # `voxview BAKE.glb`
    args = build_parser().parse_args(argv)
    return run(args.func, args)
