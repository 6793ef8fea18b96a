"""`voxbake`: the baker's command line, a thin layer over the library.

Every subcommand prints `error: <file>: <problem>` and exits 2 on bad
input, never a traceback from inside numba; outputs are written atomically
so Ctrl-C or an error leaves nothing half-written.
"""
from __future__ import annotations

import argparse
import os
import sys
import warnings

import numpy as np

from .errors import VoxgiError, VoxgiWarning

EPILOG = """examples:
  voxbake info scenes/cornell_box.glb
  voxbake render scenes/cornell_box.glb --method pathtrace --spp 256 -o cornell.exr
  voxbake render scenes/cornell_box.glb --method voxels --preset preview -o voxels.png --stats s.json
"""


def _progress(total, desc):
    from tqdm import tqdm
    return tqdm(total=total, desc=desc, unit="row", leave=False, file=sys.stderr, disable=None)


def _threads(n):
    import numba
    if n:
        numba.set_num_threads(max(1, min(int(n), numba.config.NUMBA_NUM_THREADS)))


def cmd_info(args):
    from .scene import load_scene
    scene = load_scene(args.scene, one_sided=args.one_sided)
    lo, hi = scene.bounds()
    area = scene.triangle_areas()
    power = scene.emitted_power()
    print(f"scene      {scene.path}")
    print(f"triangles  {len(scene.triangles)}  (vertices {len(scene.vertices)}, surface area {area.sum():.6g})")
    print(f"bounds     min {np.array2string(lo, precision=4)}  max {np.array2string(hi, precision=4)}"
          f"  size {np.array2string(hi - lo, precision=4)}")
    print(f"materials  {len(scene.materials)}")
    for i, m in enumerate(scene.materials):
        n = int((scene.material_ids == i).sum())
        em = f"  emits L_e {np.array2string(m.emission, precision=4)}" if m.emission.max() > 0 else ""
        tex = "  textured" if m.texture is not None else ""
        print(f"  [{i}] {m.name:<20} albedo {np.array2string(m.albedo, precision=3)}"
              f"  {'double' if m.double_sided else 'one'}-sided  {n} triangles{em}{tex}")
    ne = len(scene.emitter_triangles())
    print(f"emitters   {ne} triangles, total emitted power {np.array2string(power, precision=5)} W"
          f" (sum {power.sum():.6g} W)")
    print(f"lights     {len(scene.lights)} punctual")
    for l in scene.lights:
        unit = "W/m^2" if l.kind == "directional" else "W/sr"
        print(f"  {l.name:<20} {l.kind:<12} {np.array2string(l.intensity, precision=4)} {unit}")
    print(f"cameras    {len(scene.cameras)}")
    for i, c in enumerate(scene.cameras):
        print(f"  [{i}] {c.name:<20} at {np.array2string(c.position, precision=4)} looking "
              f"{np.array2string(c.forward, precision=3)}  yfov {np.degrees(c.yfov):.1f} deg")
    for w in scene.warnings:
        print(f"warning: {w}")
    return 0


def cmd_render(args):
    from . import bvh as bvh_mod
    from . import surfaces
    from .images import write_image
    from .render import camera_array
    from .scene import load_scene
    from .stats import Stats
    ext = os.path.splitext(args.output)[1].lower()
    if ext not in (".exr", ".png"):
        raise VoxgiError(f"unsupported image format {ext or '(none)'!r}; use .exr or .png", args.output)
    if not os.path.isdir(os.path.dirname(os.path.abspath(args.output))):
        raise VoxgiError("output folder does not exist", args.output)
    if args.width < 1 or args.height < 1 or args.width * args.height > 64_000_000:
        raise VoxgiError(f"image size {args.width}x{args.height} out of range")
    if args.spp < 1:
        raise VoxgiError(f"--spp must be at least 1 (got {args.spp})")
    _threads(args.threads)
    stats = Stats("render " + args.method)
    with stats.stage("load"):
        scene = load_scene(args.scene, one_sided=args.one_sided)
    camera = scene.camera(args.camera)
    cam = camera_array(camera, args.width, args.height)
    with stats.stage("bvh"):
        tree = bvh_mod.build_scene_bvh(scene)
        surf = surfaces.pack(scene)
    stats.count(triangles=len(scene.triangles), bvh_nodes=tree.node_count, width=args.width,
                height=args.height, camera=camera.name)
    if args.method == "pathtrace":
        from .pathtrace import render_pathtrace
        with stats.stage("pathtrace"), _progress(args.height, f"path tracing {args.spp} spp") as bar:
            image = render_pathtrace(tree, surf, cam, args.width, args.height, args.spp, args.seed, bar.update)
        stats.count(spp=args.spp, camera_paths=args.width * args.height * args.spp)
    else:
        from .config import solver_config
        from .solver import solve
        from .voxelview import render_voxels
        try:
            config = solver_config(args.preset, resolution=args.resolution, cell_size=args.cell_size,
                                   radius=args.radius, photons=args.photons, seed=args.seed, threads=args.threads,
                                   memory_budget_mb=args.memory_budget, schedule=args.schedule,
                                   tolerance=args.tolerance, max_bounces=args.max_bounces)
        except ValueError as e:
            raise VoxgiError(f"invalid solver setting: {e}") from e
        solution = solve(scene, config, stats=stats, bvh=tree, surfaces=surf, progress=True)
        with stats.stage("voxel_view"), _progress(args.height, "voxel view") as bar:
            image = render_voxels(tree, surf, solution, cam, args.width, args.height, bar.update)
        print(solution.summary(), file=sys.stderr)
    if not np.isfinite(image).all() or image.min() < 0:
        raise VoxgiError("internal error: non-finite or negative pixels (please report)", args.scene)
    with stats.stage("write"):
        write_image(args.output, image, args.exposure)
    if args.stats:
        stats.write(args.stats)
    print(f"wrote {args.output}  ({args.width}x{args.height}, {stats.as_dict()['total_seconds']:.2f} s)")
    return 0


def cmd_audit(args):
    from . import bvh as bvh_mod
    from . import surfaces
    from .audit import audit
    from .config import solver_config
    from .scene import load_scene
    from .voxels import voxelize
    scene = load_scene(args.scene, one_sided=args.one_sided)
    try:
        config = solver_config(args.preset, resolution=args.resolution, cell_size=args.cell_size)
    except ValueError as e:
        raise VoxgiError(f"invalid solver setting: {e}") from e
    if args.families < 1 or args.samples < 1 or args.radius < 1:
        raise VoxgiError("--families, --samples and --radius must be at least 1")
    tree = bvh_mod.build_scene_bvh(scene)
    surf = surfaces.pack(scene)
    vox = voxelize(scene, config.resolution, config.cell_size, config.memory_budget_mb, surf)
    report = audit(scene, vox, tree, surf, radius=args.radius, families=args.families, samples=args.samples,
                   seed=args.seed)
    print(f"{len(vox)} voxels, cell {vox.cell_size:.4g}")
    print(report.summary())
    for centroid, direction, kind in report.worst:
        print(f"  {kind:14s} voxel at {centroid} looking along {direction}")
    return 0


def build_parser():
    ap = argparse.ArgumentParser(
        prog="voxbake", formatter_class=argparse.RawDescriptionHelpFormatter, epilog=EPILOG,
        description="voxgi baker: global illumination by the linear voxel method, with a reference path tracer.")
    ap.add_argument("--version", action="version", version="voxgi 0.1.0")
    sub = ap.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True

    p = sub.add_parser("info", help="print what a scene holds (triangles, materials, emitters, cameras, bounds)",
                       description="Load a scene (.glb/.gltf/.obj/.ply) and print its triangles, materials, "
                                   "emitters with total emitted power, punctual lights, cameras and bounds.")
    p.add_argument("scene", help="scene file: .glb, .gltf, .obj or .ply")
    p.add_argument("--one-sided", action="store_true", help="treat OBJ/PLY triangles as one-sided (default: double)")
    p.set_defaults(func=cmd_info)

    p = sub.add_parser("render", help="render an image: reference path tracer or the direct voxel view",
                       formatter_class=argparse.RawDescriptionHelpFormatter,
                       description="Render one camera of a scene.\n\n"
                                   "  pathtrace  reference path tracer (NEE + MIS, Russian roulette): unbiased,\n"
                                   "             the yardstick for the other methods\n"
                                   "  voxels     the voxel GI solution shown directly: each visible point takes\n"
                                   "             its voxel's outgoing radiance (thesis's 'direct voxel view')\n\n"
                                   "EXR output is linear radiance (W m^-2 sr^-1); PNG is exposure-adjusted,\n"
                                   "ACES-filmic tone-mapped sRGB.")
    p.add_argument("scene", help="scene file: .glb, .gltf, .obj or .ply")
    p.add_argument("-o", "--output", required=True, help="output image, .exr (linear) or .png (tone-mapped)")
    p.add_argument("--method", choices=("pathtrace", "voxels"), default="pathtrace", help="default: pathtrace")
    p.add_argument("--camera", default=None, help="camera name or index (default: the first camera)")
    p.add_argument("--width", type=int, default=512, help="image width in pixels (default 512)")
    p.add_argument("--height", type=int, default=512, help="image height in pixels (default 512)")
    p.add_argument("--spp", type=int, default=64, help="pathtrace: samples per pixel (default 64)")
    p.add_argument("--seed", type=int, default=0, help="random seed (same seed, same image, any thread count)")
    p.add_argument("--threads", type=int, default=0, help="worker threads (default: all cores)")
    p.add_argument("--exposure", type=float, default=None, help="PNG exposure in EV (default: automatic)")
    p.add_argument("--stats", metavar="FILE.json", help="write timings, counters and peak memory as JSON")
    p.add_argument("--one-sided", action="store_true", help="treat OBJ/PLY triangles as one-sided")
    g = p.add_argument_group("voxel solver (--method voxels)")
    g.add_argument("--preset", choices=("preview", "default", "high"), default="default",
                   help="solver preset (default: default)")
    g.add_argument("--resolution", type=int, help="voxel cells along the scene's longest axis")
    g.add_argument("--cell-size", type=float, help="voxel cell size in scene units (instead of --resolution)")
    g.add_argument("--radius", type=int, help="direction radius r of the first propagated bounce")
    g.add_argument("--schedule", choices=("halving", "constant"), help="directions per bounce")
    g.add_argument("--photons", type=int, help="photons for the first bounce")
    g.add_argument("--tolerance", type=float, help="stop when new light < tolerance x first bounce")
    g.add_argument("--max-bounces", type=int, help="bounce cap")
    g.add_argument("--memory-budget", type=float, help="refuse voxelizations above this many MiB")
    p.set_defaults(func=cmd_render)

    p = sub.add_parser("audit", help="compare the voxel lines' visibility with continuous rays (METHOD.md 4)",
                       description="Visibility audit: for sampled (voxel, direction) pairs, compare the first voxel "
                                   "the digital line meets with the first surface a continuous ray hits. 'sees "
                                   "through' (the line passes an occluder) is the leak-like figure; 'misses' is an "
                                   "upper bound (it also counts grazing within a cell).")
    p.add_argument("scene", help="scene file: .glb, .gltf, .obj or .ply")
    p.add_argument("--preset", choices=("preview", "default", "high"), default="default")
    p.add_argument("--resolution", type=int, help="voxel cells along the scene's longest axis")
    p.add_argument("--cell-size", type=float, help="voxel cell size in scene units")
    p.add_argument("--radius", type=int, default=4, help="direction radius r to sample families from (default 4)")
    p.add_argument("--families", type=int, default=16, help="families sampled (default 16)")
    p.add_argument("--samples", type=int, default=2000, help="voxels per family (default 2000)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--one-sided", action="store_true", help="treat OBJ/PLY triangles as one-sided")
    p.set_defaults(func=cmd_audit)
    return ap


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)

    def show_warning(message, category, filename, lineno, file=None, line=None):
        if issubclass(category, VoxgiWarning):
            print(f"warning: {message}", file=sys.stderr)
    warnings.showwarning = show_warning
    try:
        return args.func(args)
    except VoxgiError as e:
        print(f"error: {e.one_line()}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted: nothing was written", file=sys.stderr)
        return 130
    except MemoryError:
        print("error: out of memory (lower --resolution or --memory-budget)", file=sys.stderr)
        return 2
