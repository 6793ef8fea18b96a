"""Command-line argument types with their valid ranges, and a parser whose
own rejections are one line in our format (`error: ...`, exit 2).

Every numeric flag states its range here, in its type, so that a value
outside it (10^30 photons, a cell size of 1e-300, NaN, inf) is refused
while the arguments are parsed, before any work.
"""
from __future__ import annotations

import argparse
import math
import sys

import numpy as np

SEED_MAX = 2 ** 31 - 1


class OneLineParser(argparse.ArgumentParser):
    """argparse's rejections as one line, `error: <problem> (see --help)`,
    exit status 2, in place of the usage block."""

    def error(self, message):
        print(f"error: {message} (see '{self.prog} --help')", file=sys.stderr)
        raise SystemExit(2)


def integer(lo: int, hi: int):
    """An argparse type: an integer in lo..hi."""
    def parse(text):
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected an integer in {lo}..{hi:,}, got {text!r}") from None
        if not lo <= v <= hi:
            raise argparse.ArgumentTypeError(f"must lie in {lo}..{hi:,}, got {text}")
        return v
    parse.__name__ = "integer"
    return parse


def number(lo: float, hi: float, lo_open=False):
    """An argparse type: a finite number in lo..hi (lo excluded when
    lo_open)."""
    def parse(text):
        try:
            v = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
        if not math.isfinite(v) or v > hi or v < lo or (lo_open and v == lo):
            span = f"above {lo:g} and at most {hi:g}" if lo_open else f"in {lo:g}..{hi:g}"
            raise argparse.ArgumentTypeError(f"must be a finite number {span}, got {text}")
        return v
    parse.__name__ = "number"
    return parse


def triple(text, what="X,Y,Z", bound=1e18):
    """Three finite numbers of magnitude at most `bound`, as X,Y,Z."""
    try:
        v = [float(t) for t in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}") from None
    if len(v) != 3 or not np.all(np.isfinite(v)) or max(abs(x) for x in v) > bound:
        raise argparse.ArgumentTypeError(f"expected {what} (three finite numbers within +-{bound:g}), got {text!r}")
    return np.array(v)


RADIANCE_MAX = 1e9  # W m^-2 sr^-1 (or W/m^2 for the sun): far above the sun's disc, far below float32's range


def colour(text):
    """R,G,B radiance, each in 0..RADIANCE_MAX."""
    v = triple(text, "R,G,B", RADIANCE_MAX)
    if (v < 0).any():
        raise argparse.ArgumentTypeError(f"radiance must not be negative, got {text!r}")
    return v


def sun(text):
    """AZIMUTH,ELEVATION,IRRADIANCE of a sun."""
    az, el, e = triple(text, "AZIMUTH,ELEVATION,IRRADIANCE", 1e9)
    if not -90 <= el <= 90 or not 0 <= e <= RADIANCE_MAX or not -360 <= az <= 360:
        raise argparse.ArgumentTypeError(f"azimuth must lie in -360..360, elevation in -90..90 and irradiance in "
                                         f"0..{RADIANCE_MAX:g}, got {text!r}")
    return az, el, e


# the ranges of the flags both commands share
THREADS = integer(0, 4096)
EXPOSURE = number(-64, 64)
IMAGE_SIDE = integer(1, 16384)
SEED = integer(0, SEED_MAX)


# ---- voxbake's parser: the flags, their ranges and their help, generated from the presets and the methods ----

EPILOG = """examples:
  voxbake scenes
  voxbake info cornell_box
  voxbake render cornell_box --method pathtrace --spp 256 -o cornell.exr
  voxbake render cornell_box --method voxels --preset preview -o voxels.png --stats s.json
  voxbake bake cornell_box -o cornell.glb --preset preview
  voxbake render bunny.ply --sky 1,1,1 --sun 30,45,3 --look-from 0,0.2,0.5 --look-at 0,0.1,0 -o bunny.png

Scenes: a .glb/.gltf/.obj/.ply file, or a built-in scene by name (`voxbake scenes`).
The first run of a method compiles its kernels (10-30 s); later runs reuse them.
"""


def per_preset(value) -> str:
    """A setting's value in each preset, as 'preview/default/high' shows it."""
    from .presets import PRESETS
    return "/".join(f"{value(p):g}" if isinstance(value(p), float) else f"{value(p)}" for p in PRESETS.values())


def scene_args(p):
    p.add_argument("scene", help="scene file (.glb, .gltf, .obj, .ply) or a built-in scene's name")
    p.add_argument("--one-sided", action="store_true", help="treat OBJ/PLY triangles as one-sided (default: double)")
    g = p.add_argument_group("input limits (every scene file is untrusted)")
    g.add_argument("--allow-outside-refs", action="store_true",
                   help="let the scene's buffers, images and material libraries name files outside the scene "
                        "file's folder (by default they are refused; devices and FIFOs always are)")
    g.add_argument("--max-texture", type=integer(16, 65536), default=4096, metavar="PIXELS",
                   help="textures longer than this on a side are scaled down to it (default 4096)")
    g.add_argument("--memory-budget", type=number(1, 1 << 30), metavar="MIB",
                   help="refuse a load or a voxelization estimated above this many MiB (default 8192)")
    g = p.add_argument_group("extra light (for a model with no lamp of its own)")
    g.add_argument("--sky", type=colour, metavar="R,G,B",
                   help="a uniform sky of this radiance (W m^-2 sr^-1) around the scene")
    g.add_argument("--sky-mode", choices=("hemisphere", "sphere"), default="hemisphere",
                   help="the sky lights from the upper hemisphere (+Y up, the default) or from every direction")
    g.add_argument("--sun", type=sun, metavar="AZIMUTH,ELEVATION,IRRADIANCE",
                   help="a sun: azimuth in degrees from +Z towards +X, elevation above the horizon (+Y up), "
                        "irradiance in W/m^2 on a surface facing it")


def camera_args(p):
    g = p.add_argument_group("camera")
    g.add_argument("--camera", default=None,
                   help="camera name or index in the file (default: its first; none: an automatic camera that "
                        "sees the scene, inside a closed room or through the open side of a box)")
    g.add_argument("--look-from", type=triple, metavar="X,Y,Z", help="camera position (scene units)")
    g.add_argument("--look-at", type=triple, metavar="X,Y,Z", help="point the camera looks at")
    g.add_argument("--up", type=triple, metavar="X,Y,Z", help="camera up direction (default: the camera's, +Y)")
    g.add_argument("--fov", type=number(0, 180, lo_open=True), metavar="DEG", help="vertical field of view in degrees")


def run_args(p):
    p.add_argument("--seed", type=SEED, default=0, help="random seed (same seed, same result, any thread count)")
    p.add_argument("--threads", type=THREADS, default=0, help="worker threads (default 0: all cores)")


def preset_arg(p):
    from .presets import PRESETS
    p.add_argument("--preset", choices=tuple(PRESETS), default="default",
                   help="settings preset (default: default; their values are listed at the end)")


def grid_args(g):
    g.add_argument("--resolution", type=integer(1, 1 << 16),
                   help="voxel cells along the scene's longest axis (instead of --surface-cells)")
    g.add_argument("--cell-size", type=number(0, 1e18, lo_open=True),
                   help="voxel cell size in scene units (instead of either)")


def solver_args(p):
    from .config import MAX_GATHER
    g = p.add_argument_group("voxel solver")
    preset_arg(g)
    g.add_argument("--surface-cells", type=integer(1, 10 ** 8),
                   help="cells the scene's surfaces should cover, about the voxel count; the cell size follows "
                        f"the surface area (preset: {per_preset(lambda p: p.solver.surface_cells)})")
    grid_args(g)
    g.add_argument("--gather-rays", type=integer(0, MAX_GATHER), metavar="K",
                   help="the bounces after the photons: gathered by K rays per voxel at the first, halving bounce "
                        "by bounce down to 64; 0: propagated along digital lines with --radius "
                        f"(preset: {per_preset(lambda p: p.solver.gather_rays)})")
    g.add_argument("--radius", type=integer(1, 64), help="direction radius r of the first propagated bounce, "
                                                         "with --gather-rays 0 "
                                                         f"(preset: {per_preset(lambda p: p.solver.radius)})")
    g.add_argument("--schedule", choices=("halving", "constant"), help="directions per bounce (default: halving)")
    g.add_argument("--photons", type=integer(1, 10 ** 10),
                   help="photons for the first bounce (instead of --photons-per-voxel)")
    g.add_argument("--photons-per-voxel", type=number(0, 1e6, lo_open=True),
                   help=f"photons per voxel for the first bounce (preset: "
                        f"{per_preset(lambda p: p.solver.photons_per_voxel)})")
    g.add_argument("--photon-smoothing", type=number(0, 100), metavar="K",
                   help="pool a voxel's photons with same-surface neighbours that agree within K standard "
                        f"deviations of the photon noise (preset: {per_preset(lambda p: p.solver.photon_smoothing)};"
                        " 0: off)")
    g.add_argument("--tolerance", type=number(0, 1), help="stop when new light < tolerance x first bounce "
                                                          f"(preset: {per_preset(lambda p: p.solver.tolerance)})")
    g.add_argument("--max-bounces", type=integer(1, 10000),
                   help=f"bounce cap (preset: {per_preset(lambda p: p.solver.max_bounces)})")
    g = p.add_argument_group("lightcuts (render --method lightcuts; bake's texels at default and high)")
    g.add_argument("--epsilon", type=number(0, 1, lo_open=True),
                   help=f"lightcuts' relative error bound per cut (frames' preset: "
                        f"{per_preset(lambda p: p.lightcuts.epsilon)}; a bake's texels: "
                        f"{per_preset(lambda p: p.texel_epsilon)})")
    g.add_argument("--direct-vpls", type=integer(1, 1 << 24),
                   help=f"VPLs sampled on the area emitters (preset: {per_preset(lambda p: p.lightcuts.direct_vpls)})")


def _render_parser(sub):
    import textwrap
    from .render.frame import METHODS, SPP_CAP
    from .config import MAX_GATHER, MAX_GATHER_SPACING
    methods = "\n".join(textwrap.fill(m.about, 78, initial_indent=f"  {m.name:<18} ", subsequent_indent=" " * 21)
                        for m in METHODS.values())
    p = sub.add_parser("render", help="render an image: reference path tracer, the voxel view, lightcuts, ...",
                       formatter_class=argparse.RawDescriptionHelpFormatter,
                       description=f"Render one camera of a scene.\n\n{methods}\n\nEXR output is linear radiance "
                                   "(W m^-2 sr^-1); PNG is exposure-adjusted,\nACES-filmic tone-mapped sRGB.")
    scene_args(p)
    p.add_argument("-o", "--output", required=True, help="output image, .exr (linear) or .png (tone-mapped)")
    p.add_argument("--method", choices=tuple(METHODS), default="pathtrace", help="default: pathtrace")
    p.add_argument("--vpls-per-frame", type=integer(1, 1 << 20), default=16,
                   help="instant-radiosity: VPLs added per frame (default 16)")
    p.add_argument("--frames", type=integer(1, 1 << 20), default=256,
                   help="instant-radiosity: frames at most (default 256)")
    p.add_argument("--ir-tolerance", type=number(0, 1), default=0.0,
                   help="instant-radiosity: stop when a frame changes the image by less than this (relative)")
    p.add_argument("--width", type=IMAGE_SIDE, default=512, help="image width in pixels (default 512)")
    p.add_argument("--height", type=IMAGE_SIDE, default=512, help="image height in pixels (default 512)")
    p.add_argument("--spp", type=integer(1, SPP_CAP), default=None,
                   help=f"pathtrace: samples per pixel (default 64; with --noise or --time-limit the most to take, "
                        f"default {SPP_CAP})")
    p.add_argument("--noise", type=number(0, 1, lo_open=True), default=None, metavar="TARGET",
                   help="pathtrace: stop when the estimated relative RMSE of the image falls to TARGET (0.02: 2%%); "
                        "the estimate comes from two halves of each pixel's samples, over the pixels that do "
                        "not see a lamp directly")
    p.add_argument("--time-limit", type=number(0, 1e7, lo_open=True), default=None, metavar="SECONDS",
                   help="pathtrace: stop after about this many seconds (of path tracing)")
    p.add_argument("--path-bounces", type=integer(0, 999), default=None, metavar="K",
                   help="pathtrace: count the light of paths with at most K reflections (1: direct light only, "
                        "0: only the lamps and sky seen; default: all), to split an image's error by bounce")
    p.add_argument("--frame-gather", type=integer(0, MAX_GATHER), default=None, metavar="RAYS",
                   help="lightcuts: the bounced light gathered from the voxel solution by RAYS rays at records "
                        "--frame-gather-spacing cells apart (preset: " + per_preset(lambda q: q.lightcuts.gather) +
                        "; 0: the voxels as VPLs in the cuts)")
    p.add_argument("--frame-gather-spacing", type=number(0, MAX_GATHER_SPACING), default=None, metavar="CELLS",
                   help="lightcuts: voxel cells between the gather's records, interpolated between them (preset: "
                        + per_preset(lambda q: q.lightcuts.gather_spacing) + "; 0: every point gathered)")
    run_args(p)
    p.add_argument("--exposure", type=EXPOSURE, default=None, help="PNG exposure in EV (default: automatic)")
    p.add_argument("--stats", metavar="FILE.json",
                   help="write timings (wall and CPU seconds per stage), counters and peak memory as JSON")
    camera_args(p)
    solver_args(p)
    p.epilog = _presets_epilog()


def _bake_parser(sub):
    from .config import MAX_GATHER, MAX_GATHER_SPACING, MAX_INDIRECT_STRIDE, MAX_TEXEL_SAMPLES, TEXEL_SOURCES, UV_MODES
    p = sub.add_parser("bake", help="bake lightmaps into a glTF file a viewer can walk through",
                       formatter_class=argparse.RawDescriptionHelpFormatter,
                       description="Bake a scene's diffuse global illumination into lightmaps and write a glTF\n"
                                   "binary (.glb): the geometry with lightmap UVs (TEXCOORD_1), the lightmap\n"
                                   "pages as 8-bit PNGs (MOZ_lightmap: three.js, Hubs, Unity read them) and as\n"
                                   "half-float EXR (for voxview), cameras, lights and the bake's settings.\n\n"
                                   "Texels are one voxel cell wide, or finer where the preset asks for a number of\n"
                                   "texels across the scene's thinnest extent (a room's height), within the memory\n"
                                   "budget, unless --texel-density says otherwise; the summary prints the size. Texel\n"
                                   "values come from the voxel solution reconstructed at each texel, or from\n"
                                   "lightcuts over virtual point lights (direct light with shadow rays, bounced\n"
                                   "light from the voxels); the presets below say which.")
    scene_args(p)
    p.add_argument("-o", "--output", required=True, help="output bake file (.glb)")
    p.add_argument("--uv", choices=UV_MODES,
                   help="lightmap UVs: per-triangle, one square map per triangle (deduplicated, quadtree-packed); "
                        "xatlas, charts over connected triangles; auto, per-triangle unless its maps would shade "
                        "over twice the points of charts (triangles under a texel, slivers) (preset: "
                        f"{per_preset(lambda p: p.uv)})")
    p.add_argument("--texel-density", type=number(0, 1e9, lo_open=True), metavar="D",
                   help="texels per scene unit (default: one per voxel cell, or "
                        f"{per_preset(lambda p: p.texels_across)} across the scene's thinnest extent where finer)")
    p.add_argument("--preview-vpls", type=integer(0, 1 << 24), default=65_536,
                   help="VPLs in the bake's ordered list for the viewer's progressive preview (default 65536; "
                        "0: none)")
    p.add_argument("--texel-samples", type=integer(1, MAX_TEXEL_SAMPLES), metavar="N",
                   help="anti-aliasing of lightcuts texels: where the light changes sharply across a texel (a "
                        "shadow's edge, a contact) it takes the mean of an N x N grid of points (preset: "
                        f"{per_preset(lambda p: p.texel_samples)}; 1: one point per texel)")
    p.add_argument("--texel-interpolate", type=number(0, 1), metavar="T",
                   help="adaptive shading of lightcuts texels: every other texel of every other row is shaded, "
                        "and a texel between shaded ones that agree within T (a share of the brightest) takes "
                        f"their mean; the others are shaded too (preset: {per_preset(lambda p: p.texel_interpolate)}"
                        "; 0: every texel shaded)")
    p.add_argument("--texel-indirect-stride", type=integer(1, MAX_INDIRECT_STRIDE), metavar="S",
                   help="lightcuts texels' bounced light and sky light, which vary slowly, are shaded on every "
                        "S-th texel of every S-th row and interpolated between them where they agree; the lamps' "
                        "and punctual lights' at every texel "
                        f"(preset: {per_preset(lambda p: p.texel_indirect_stride)}; 1: everything at every texel)")
    p.add_argument("--texel-gather", type=integer(0, MAX_GATHER), metavar="RAYS",
                   help="rays per point of the bounced light's sparse lattice (--texel-indirect-stride) that gather it from the voxel "
                        "solution (preset: " + per_preset(lambda p: p.texel_gather) + "; 0: a lightcut over the "
                        "voxels' lights instead, slower)")
    p.add_argument("--texel-gather-spacing", type=number(0, MAX_GATHER_SPACING), metavar="CELLS",
                   help="the gathered bounced light is gathered at records this many voxel cells apart over the "
                        "surfaces and interpolated between those in sight that agree; elsewhere at the texel itself "
                        f"(preset: {per_preset(lambda p: p.texel_gather_spacing)}; 0: on each map's lattice)")
    p.add_argument("--texels", choices=TEXEL_SOURCES,
                   help=f"where texel values come from (preset: {per_preset(lambda p: p.texels)})")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--probe-spacing", type=number(0, 1e9, lo_open=True), metavar="S",
                   help="scene units between the irradiance probes that light moving objects (default: about "
                        f"{per_preset(lambda p: p.probes.budget)} probes over the scene's bounds)")
    g.add_argument("--no-probes", action="store_true", help="bake no irradiance probes")
    p.add_argument("--dynamic", action="append", default=[], metavar="NODE",
                   help="a glTF node (by name; again for more) whose meshes, with its children's, move at run time: "
                        "they are left out of the bake (no lightmap, no shadow, no bounced light) and written as "
                        "plain meshes that voxview lights from the probes and moves (needs the probes)")
    run_args(p)
    p.add_argument("--stats", metavar="FILE.json",
                   help="write timings (wall and CPU seconds per stage), counters and peak memory as JSON")
    cluster_args(p)
    solver_args(p)
    p.epilog = _presets_epilog()


def cluster_args(p):
    g = p.add_argument_group(
        "workers and checkpoints (the photons, the bounces, the probes and the texels: the same bytes on any number "
        "of workers)")
    w = g.add_mutually_exclusive_group()
    w.add_argument("--workers", type=integer(1, 4096), metavar="N",
                   help="run the bake's heavy work on a local Dask cluster of N worker processes, one numba thread "
                        "each (--threads: more)")
    w.add_argument("--scheduler", metavar="ADDRESS",
                   help="run the bake's heavy work on the workers of an existing Dask cluster (started with `dask "
                        "scheduler` and `dask worker`, the same voxgi, numpy and numba installed): tls://HOST:PORT, "
                        "or tcp://127.0.0.1:PORT on this machine; their numba threads: --threads (0: all)")
    g.add_argument("--insecure", action="store_true",
                   help="allow a tcp:// scheduler beyond this machine (Dask's tcp:// runs pickled code from "
                        "anyone who reaches it: only on a network you trust)")
    g.add_argument("--tls-ca-file", metavar="PEM", help="TLS: the certificate authority's certificate")
    g.add_argument("--tls-cert", metavar="PEM", help="TLS: this client's certificate")
    g.add_argument("--tls-key", metavar="PEM", help="TLS: this client's private key")
    g.add_argument("--checkpoint", metavar="DIR",
                   help="keep the solve's result and every finished texel tile in DIR (each file written whole), "
                        "for --resume after Ctrl-C or a crash")
    g.add_argument("--resume", action="store_true",
                   help="with --checkpoint: take the solve and the finished tiles from DIR (a checkpoint of "
                        "another scene or other settings is refused) and shade the rest")


def _presets_epilog() -> str:
    from .presets import help_table
    return help_table()


def command_parser(prog, description, epilog):
    """A command's parser (one-line errors, --version) and its subcommands."""
    ap = OneLineParser(prog=prog, formatter_class=argparse.RawDescriptionHelpFormatter, epilog=epilog,
                       description=description)
    ap.add_argument("--version", action="version", version="voxgi 0.1.0")
    sub = ap.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    return ap, sub


def build_parser():
    ap, sub = command_parser(
        "voxbake", "voxgi baker: global illumination by the linear voxel method, with a reference path tracer. It "
                   "bakes lightmaps into glTF files (`voxbake bake`) and renders images.", EPILOG)
    sub.add_parser("scenes", help="list the built-in scenes (usable by name wherever a scene file is asked)",
                   description="List the scenes shipped with voxgi; give a name instead of a file path.")
    p = sub.add_parser("info", help="print what a scene holds (triangles, materials, emitters, cameras, bounds)",
                       description="Load a scene (.glb/.gltf/.obj/.ply or a built-in name) and print its "
                                   "triangles, materials, emitters with total emitted power, punctual lights, "
                                   "cameras and bounds, and what the baker ignores in it.")
    scene_args(p)
    _render_parser(sub)
    _bake_parser(sub)
    p = sub.add_parser("audit", help="compare the voxel lines' visibility with continuous rays",
                       description="Visibility audit: for sampled (voxel, direction) pairs, compare the first voxel "
                                   "the digital line meets with the first surface a continuous ray hits. 'sees "
                                   "through' (the line passes an occluder) is the leak-like figure; 'misses' is an "
                                   "upper bound (it also counts grazing within a cell).")
    scene_args(p)
    preset_arg(p)
    grid_args(p)
    p.add_argument("--radius", type=integer(1, 64), default=4,
                   help="direction radius r to sample families from (default 4)")
    p.add_argument("--families", type=integer(1, 10000), default=16, help="families sampled (default 16)")
    p.add_argument("--samples", type=integer(1, 10 ** 6), default=2000, help="voxels per family (default 2000)")
    run_args(p)
    return ap
