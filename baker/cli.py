"""`voxbake`: the baker's command line, a thin layer over the library.

Every subcommand checks its arguments and output paths before any work,
prints `error: <file>: <problem>` and exits 2 on bad input (never a
traceback from inside numba), writes outputs atomically, and on Ctrl-C
prints `interrupted: nothing was written` and exits 130.
"""
from __future__ import annotations

import argparse
import os
import sys
import warnings

import numpy as np

from .cli_args import EXPOSURE, IMAGE_SIDE, SEED, THREADS, OneLineParser, colour, integer, number, sun, triple
from .errors import VoxgiError, VoxgiWarning

SPP_CAP = 1 << 20  # pathtrace: the most samples per pixel --noise or --time-limit take unless --spp says

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


def load_limits(args):
    """What the scene file may make us read and hold (scene/refs.py)."""
    from .scene.refs import LoadLimits
    return LoadLimits(allow_outside_refs=args.allow_outside_refs, max_texture=args.max_texture,
                      memory_budget_mb=args.memory_budget if args.memory_budget is not None else
                      LoadLimits.memory_budget_mb)


def _load(args):
    """The scene with the lights the command line adds."""
    from .scene import Sky, load_scene, sun as make_sun
    lights = [make_sun(*args.sun)] if getattr(args, "sun", None) is not None else []
    sky = Sky(args.sky, args.sky_mode == "hemisphere") if getattr(args, "sky", None) is not None else None
    return load_scene(args.scene, one_sided=args.one_sided, lights=lights, sky=sky, limits=load_limits(args))


def _camera(args, scene, bvh):
    from .scene import adjust_camera
    cam = scene.camera(args.camera, bvh)
    return adjust_camera(cam, args.look_from, args.look_at, args.up, args.fov)


def _inputs(args) -> list:
    """The files a command reads: outputs must never be one of them."""
    from .scene.load import resolve
    return [resolve(args.scene)] if getattr(args, "scene", None) else []


def _check_common(args, extensions=None):
    """Argument checks that need no scene, before any work: the output
    (`-o`, with `extensions`) and the stats file are writable, are neither
    an input nor each other, and are regular files or new paths."""
    from .config import check_threads
    from .fileio import check_output_path
    check_threads(args.threads)
    inputs = _inputs(args)
    if getattr(args, "output", None):
        check_output_path(args.output, extensions, inputs)
    if getattr(args, "stats", None):
        check_output_path(args.stats, (".json",), inputs + [args.output] if getattr(args, "output", None)
                          else inputs)
        if getattr(args, "output", None) and os.path.abspath(args.stats) == os.path.abspath(args.output):
            raise VoxgiError("--stats names the output file itself: choose another file", args.stats)


def write_stats(args, stats):
    """Writes --stats after the main output; a failure says that the main
    output was written."""
    if not args.stats:
        return
    try:
        stats.write(args.stats)
    except VoxgiError as e:
        raise VoxgiError(f"{e} (the main output {args.output} was written)", e.path) from None


def cmd_scenes(args):
    from .scene import builtin_scenes
    from .scene.load import resolve
    for name in builtin_scenes():
        print(f"{name:<26} {resolve(name)}")
    return 0


def cmd_info(args):
    scene = _load(args)
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
    for light in scene.lights:
        unit = "W/m^2" if light.kind == "directional" else "W/sr"
        print(f"  {light.name:<20} {light.kind:<12} {np.array2string(light.intensity, precision=4)} {unit}")
    if scene.sky is not None:
        where = "upper hemisphere" if scene.sky.hemisphere else "whole sphere"
        print(f"sky        radiance {np.array2string(scene.sky.radiance, precision=4)} W m^-2 sr^-1 ({where})")
    print(f"cameras    {len(scene.cameras)}")
    for i, c in enumerate(scene.cameras):
        print(f"  [{i}] {c.name:<20} at {np.array2string(c.position, precision=4)} looking "
              f"{np.array2string(c.forward, precision=3)}  yfov {np.degrees(c.yfov):.1f} deg")
    return 0


def _solver_config(args, **knobs):
    from .config import solver_config
    from .errors import ConfigError
    try:
        return solver_config(args.preset, resolution=args.resolution, cell_size=args.cell_size,
                             surface_cells=getattr(args, "surface_cells", None),
                             photons_per_voxel=getattr(args, "photons_per_voxel", None),
                             photon_smoothing=getattr(args, "photon_smoothing", None), **knobs)
    except ConfigError as e:
        raise ConfigError(f"invalid solver setting: {e}") from None


def _render_config(args):
    return _solver_config(args, radius=args.radius, photons=args.photons, seed=args.seed, threads=args.threads,
                          memory_budget_mb=args.memory_budget, schedule=args.schedule, tolerance=args.tolerance,
                          max_bounces=args.max_bounces)


def _lightcuts_config(args):
    from .errors import ConfigError
    from .lights import lightcuts_config
    try:
        return lightcuts_config(args.preset, epsilon=getattr(args, "epsilon", None),
                                direct_vpls=getattr(args, "direct_vpls", None), seed=getattr(args, "seed", None))
    except ConfigError as e:
        raise ConfigError(f"invalid lightcuts setting: {e}") from None


def cmd_render(args):
    from .config import threads
    from .progress import bar
    from .render import camera_array, write_image
    from .scene import build_scene_bvh, pack
    from .startup import checkpoint
    from .stats import Stats
    _check_common(args, (".exr", ".png"))
    if args.width * args.height > 64_000_000:
        raise VoxgiError(f"image size {args.width}x{args.height} out of range")
    adaptive = args.time_limit is not None or args.noise is not None
    if args.spp is None:
        args.spp = SPP_CAP if adaptive else 64
    if args.spp < 1:
        raise VoxgiError(f"--spp must be at least 1 (got {args.spp})")
    if args.time_limit is not None and not args.time_limit > 0:
        raise VoxgiError(f"--time-limit must be a positive number of seconds (got {args.time_limit})")
    if args.noise is not None and not args.noise > 0:
        raise VoxgiError(f"--noise must be a positive fraction, e.g. 0.02 for 2% (got {args.noise})")
    if adaptive and args.method != "pathtrace":
        raise VoxgiError("--time-limit and --noise apply to --method pathtrace")
    config = _render_config(args) if args.method in ("voxels", "lightcuts", "instant-radiosity") else None
    stats = Stats("render " + args.method)
    with threads(args.threads):
        with stats.stage("load"):
            if args.method == "lightmap":
                from .bake import read_bake
                bake = read_bake(args.scene)
                scene = bake.scene
            else:
                scene = _load(args)
        with stats.stage("bvh"):
            tree = build_scene_bvh(scene)
            surf = pack(scene)
        camera = _camera(args, scene, tree)
        cam = camera_array(camera, args.width, args.height)
        stats.count(triangles=len(scene.triangles), bvh_nodes=tree.node_count, width=args.width,
                    height=args.height, camera=camera.name)
        if args.method == "lightmap":
            from .bake.shade import render_bake
            with stats.stage("lightmap_view"), bar(args.height, "lightmap view", "row") as b:
                image = render_bake(bake, camera, args.width, args.height, b.update, tree)
        elif args.method == "lightcuts":
            from .lights import build_lights
            from .render.lightcuts_frame import render_lightcuts
            from .solve import solve
            solution = solve(scene, config, stats=stats, bvh=tree, surfaces=surf, progress=True)
            lc = _lightcuts_config(args)
            with stats.stage("lights"):
                lights = build_lights(scene, solution, surf, lc, tree)
            stats.count(**lights.vpls.counts())
            n_pts = args.width * args.height
            with stats.stage("lightcuts_frame"), bar(n_pts, "lightcuts", "point") as b:
                image, fstats = render_lightcuts(tree, surf, lights, cam, args.width, args.height, lc.epsilon,
                                                 lc.cap, b.update, grow=b.grow)
            stats.count(**fstats, epsilon=lc.epsilon, cut_cap=lc.cap)
            print(f"{solution.summary()}\nVPLs {len(lights.vpls)} ({lights.vpls.counts()['vpls_direct']} direct, "
                  f"{lights.vpls.counts()['vpls_indirect']} indirect, {lights.vpls.counts()['vpls_sky']} sky)  "
                  f"cut mean {fstats['cut_mean']:.0f} max {fstats['cut_max']}  shadow rays/pixel "
                  f"{fstats['shadow_rays_per_pixel']:.0f}", file=sys.stderr)
        elif args.method == "instant-radiosity":
            from .lights import build_lights, ordered_vpls
            from .render.instant_radiosity import render_instant_radiosity
            from .solve import solve
            if args.vpls_per_frame < 1 or args.frames < 1:
                raise VoxgiError("--vpls-per-frame and --frames must be at least 1")
            solution = solve(scene, config, stats=stats, bvh=tree, surfaces=surf, progress=True)
            lc = _lightcuts_config(args)
            with stats.stage("lights"):
                lights = build_lights(scene, solution, surf, lc, tree)
                lo, hi = scene.bounds()
                order = ordered_vpls(lights.vpls, args.vpls_per_frame * args.frames,
                                     0.5 * float(np.linalg.norm(hi - lo)), lc.seed)
            stats.count(**lights.vpls.counts())
            with stats.stage("instant_radiosity"), bar(args.frames, "instant radiosity", "frame") as b:
                image, irs = render_instant_radiosity(tree, surf, order, cam, args.width, args.height,
                                                      args.vpls_per_frame, args.frames, args.ir_tolerance, b.update)
            stats.count(ir_frames=irs["frames"], ir_vpls_used=irs["vpls_used"], ir_last_change=irs["change"])
            print(f"{irs['frames']} frames of {args.vpls_per_frame} VPLs (last change {irs['change']:.2e})",
                  file=sys.stderr)
        elif args.method == "pathtrace":
            from .render.pathtrace import pathtrace
            total = None if adaptive else args.width * args.height * args.spp
            what = f"{args.spp} spp" if not adaptive else "until " + " or ".join(
                ([f"{args.noise:.2%} noise"] if args.noise else []) + ([f"{args.time_limit:g} s"] if args.time_limit
                                                                      else []))
            with stats.stage("pathtrace"), bar(total, f"path tracing {what}", "sample") as b:
                pt = pathtrace(tree, surf, cam, args.width, args.height, args.spp, args.seed, args.time_limit,
                               args.noise, b.update)
            image = pt.image
            stats.count(spp=pt.spp, camera_paths=args.width * args.height * pt.spp, noise_estimate=pt.noise,
                        stopped_by=pt.stopped, samples_per_second=args.width * args.height * pt.spp / pt.seconds)
            print(f"{pt.spp} spp, estimated noise {pt.noise:.2%} (relative RMSE), stopped by "
                  f"{dict(spp='--spp', noise='--noise', time='--time-limit')[pt.stopped]}", file=sys.stderr)
        else:
            from .render.voxelview import render_voxels
            from .solve import solve
            solution = solve(scene, config, stats=stats, bvh=tree, surfaces=surf, progress=True)
            with stats.stage("voxel_view"), bar(args.height, "voxel view", "row") as b:
                image = render_voxels(tree, surf, solution, cam, args.width, args.height, b.update)
            print(solution.summary(), file=sys.stderr)
    if not np.isfinite(image).all() or image.min() < 0:
        raise VoxgiError("internal error: non-finite or negative pixels (please report)", args.scene)
    checkpoint()  # a Ctrl-C from the last stretch: stop before writing
    with stats.stage("write"):
        write_image(args.output, image, args.exposure)
    write_stats(args, stats)
    print(f"wrote {args.output}  ({args.width}x{args.height}, {stats.as_dict()['total_seconds']:.2f} s)")
    return 0


def bake_summary(stats, bake) -> str:
    """The closing table of `voxbake bake`: counts, then time and peak
    memory per stage."""
    c = stats.counters
    rows = [("voxels", f"{c.get('voxels', 0):,} (cell {c.get('cell_size', 0):.4g})"),
            ("directions per bounce", " ".join(str(d) for d in c.get("directions_per_bounce", [])) or "-"),
            ("photons", f"{c.get('photons', 0):,} ({c.get('photons_landed', 0):,} landed)"),
            ("bounces", f"{c.get('bounces', 0)} ({c.get('stop_reason', '')})"),
            ("VPLs / average cut", f"{c['vpls']:,} ({c['vpls_direct']:,} direct, {c['vpls_indirect']:,} indirect, "
                                   f"{c['vpls_sky']:,} sky) / cut mean {c['cut_mean']:.0f}, max {c['cut_max']}, "
                                   f"{c['shadow_rays']:,} shadow rays" if "vpls" in c else
             "- (preview: texel values from the voxel solution)"),
            ("texels", f"{c.get('texels', 0):,} in {c.get('charts', 0):,} maps ({c.get('texels_covered', 0):,} "
                       f"sampled, {c.get('texels_inside', 0):,} inside geometry)"),
            ("points shaded", f"{c['points_shaded']:,} ({c['texels_shaded']:,} texels, "
                              f"{c.get('texels_interpolated', 0):,} interpolated; {c['subtexel_triangles']:,} "
                              f"small-triangle sides at their corners; {c['texels_antialiased']:,} edge texels "
                              f"at {c['texel_samples']}x{c['texel_samples']})" if "points_shaded" in c else
             "- (preview)"),
            ("maps stored", f"{c.get('unique', 0):,} ({c.get('constant', 0):,} single-colour, dedup ratio "
                            f"{c.get('dedup_ratio', 1):.2f})"),
            ("pages", f"{c.get('pages', 0)} x 512^2 ({c.get('texels_stored', 0) / max(1, c.get('pages', 0)) / 512 ** 2:.0%} "
                      f"used)"),
            ("triangles", f"{bake.triangle_count:,} baked")]
    w = max(len(k) for k, _ in rows)
    out = [f"  {k:<{w}}  {v}" for k, v in rows]
    out.append(f"  {'stage':<{w}}  {'seconds':>8}  {'peak MiB':>9}")
    for name, e in stats.stages.items():
        out.append(f"  {name:<{w}}  {e['seconds']:8.2f}  {e.get('peak_rss_mb', 0):9.0f}")
    return "\n".join(out)


def cmd_bake(args):
    from .bake import bake_config, bake_scene, write_bake
    from .config import threads
    from .errors import ConfigError
    from .startup import checkpoint
    from .stats import Stats
    _check_common(args, (".glb",))
    try:
        config = bake_config(args.preset, args.uv, args.texel_density, args.texels, args.epsilon, args.direct_vpls,
                             preview_vpls=args.preview_vpls, texel_samples=args.texel_samples,
                             texel_interpolate=args.texel_interpolate, resolution=args.resolution,
                             cell_size=args.cell_size, surface_cells=args.surface_cells,
                             photons_per_voxel=args.photons_per_voxel, photon_smoothing=args.photon_smoothing,
                             radius=args.radius, photons=args.photons,
                             seed=args.seed,
                             threads=args.threads, memory_budget_mb=args.memory_budget, schedule=args.schedule,
                             tolerance=args.tolerance, max_bounces=args.max_bounces)
    except ConfigError as e:
        raise ConfigError(f"invalid bake setting: {e}") from None
    stats = Stats("bake")
    with threads(args.threads):
        with stats.stage("load"):
            scene = _load(args)
        bake, _, _, _ = bake_scene(scene, config, stats, progress=True)
    if not np.isfinite(bake.pages).all() or bake.pages.min() < 0:
        raise VoxgiError("internal error: non-finite or negative texels (please report)", args.scene)
    checkpoint()
    with stats.stage("write"):
        write_bake(args.output, bake, inputs=_inputs(args))
    write_stats(args, stats)
    print(bake_summary(stats, bake))
    size = os.path.getsize(args.output)
    print(f"wrote {args.output}  ({size / 2 ** 20:.1f} MiB, {stats.as_dict()['total_seconds']:.2f} s)")
    return 0


def cmd_audit(args):
    from .config import threads
    from .scene import build_scene_bvh, pack
    from .scene.inspect import geometry_report
    from .solve.audit import audit
    from .voxels import voxelize
    _check_common(args)
    config = _solver_config(args)
    if args.families < 1 or args.samples < 1 or args.radius < 1:
        raise VoxgiError("--families, --samples and --radius must be at least 1")
    with threads(args.threads):
        scene = _load(args)
        print(geometry_report(scene).summary())
        tree = build_scene_bvh(scene)
        surf = pack(scene)
        vox = voxelize(scene, config.resolution_for(scene), config.cell_size, config.memory_budget_mb, surf)
        report = audit(scene, vox, tree, surf, radius=args.radius, families=args.families, samples=args.samples,
                       seed=args.seed)
    print(f"{len(vox)} voxels, cell {vox.cell_size:.4g}")
    print(report.summary())
    for centroid, direction, kind in report.worst:
        print(f"  {kind:14s} voxel at {centroid} looking along {direction}")
    return 0


def _scene_args(p):
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


def _camera_args(p):
    g = p.add_argument_group("camera")
    g.add_argument("--camera", default=None,
                   help="camera name or index in the file (default: its first; none: an automatic camera that "
                        "sees the scene, inside a closed room or through the open side of a box)")
    g.add_argument("--look-from", type=triple, metavar="X,Y,Z", help="camera position (scene units)")
    g.add_argument("--look-at", type=triple, metavar="X,Y,Z", help="point the camera looks at")
    g.add_argument("--up", type=triple, metavar="X,Y,Z", help="camera up direction (default: the camera's, +Y)")
    g.add_argument("--fov", type=number(0, 180, lo_open=True), metavar="DEG", help="vertical field of view in degrees")


def _solver_args(p):
    g = p.add_argument_group("voxel solver")
    g.add_argument("--preset", choices=("preview", "default", "high"), default="default",
                   help="solver preset (default: default)")
    g.add_argument("--surface-cells", type=integer(1, 10 ** 8),
                   help="cells the scene's surfaces should cover, about the voxel count; the cell size follows "
                        "the surface area (preset: 12500/25000/100000)")
    g.add_argument("--resolution", type=integer(1, 1 << 16),
                   help="voxel cells along the scene's longest axis (instead)")
    g.add_argument("--cell-size", type=number(0, 1e18, lo_open=True),
                   help="voxel cell size in scene units (instead of either)")
    g.add_argument("--radius", type=integer(1, 64), help="direction radius r of the first propagated bounce")
    g.add_argument("--schedule", choices=("halving", "constant"), help="directions per bounce")
    g.add_argument("--photons", type=integer(1, 10 ** 10),
                   help="photons for the first bounce (instead of --photons-per-voxel)")
    g.add_argument("--photons-per-voxel", type=number(0, 1e6, lo_open=True),
                   help="photons per voxel for the first bounce (preset: 32/64/128)")
    g.add_argument("--photon-smoothing", type=number(0, 100), metavar="K",
                   help="pool a voxel's photons with same-surface neighbours that agree within K standard "
                        "deviations of the photon noise (preset: 2/0/0; 0: off)")
    g.add_argument("--tolerance", type=number(0, 1), help="stop when new light < tolerance x first bounce")
    g.add_argument("--max-bounces", type=integer(1, 10000), help="bounce cap")
    g = p.add_argument_group("lightcuts (render --method lightcuts; bake --preset default/high)")
    g.add_argument("--epsilon", type=number(0, 1, lo_open=True),
                   help="lightcuts' relative error bound per cut (preset: 0.05/0.02/0.01; "
                                                 "a bake's texels at default: 0.01)")
    g.add_argument("--direct-vpls", type=integer(1, 1 << 24),
                   help="VPLs sampled on the area emitters (preset: 4096/32768/131072)")


def build_parser():
    ap = OneLineParser(
        prog="voxbake", formatter_class=argparse.RawDescriptionHelpFormatter, epilog=EPILOG,
        description="voxgi baker: global illumination by the linear voxel method, with a reference path tracer. "
                    "It bakes lightmaps into glTF files (`voxbake bake`) and renders images.")
    ap.add_argument("--version", action="version", version="voxgi 0.1.0")
    sub = ap.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True

    p = sub.add_parser("scenes", help="list the built-in scenes (usable by name wherever a scene file is asked)",
                       description="List the scenes shipped with voxgi; give a name instead of a file path.")
    p.set_defaults(func=cmd_scenes)

    p = sub.add_parser("info", help="print what a scene holds (triangles, materials, emitters, cameras, bounds)",
                       description="Load a scene (.glb/.gltf/.obj/.ply or a built-in name) and print its "
                                   "triangles, materials, emitters with total emitted power, punctual lights, "
                                   "cameras and bounds, and what the baker ignores in it.")
    _scene_args(p)
    p.set_defaults(func=cmd_info)

    p = sub.add_parser("render", help="render an image: reference path tracer or the direct voxel view",
                       formatter_class=argparse.RawDescriptionHelpFormatter,
                       description="Render one camera of a scene.\n\n"
                                   "  pathtrace  reference path tracer (NEE + MIS, Russian roulette, scrambled Sobol\n"
                                   "             samples): unbiased, the yardstick for the other methods;\n"
                                   "             --noise and --time-limit stop it when it is good enough\n"
                                   "  voxels     the voxel GI solution shown directly: each visible point takes\n"
                                   "             its voxel's outgoing radiance (the thesis's 'direct voxel view')\n"
                                   "  lightcuts  the quality frame: the voxel solution as virtual point lights,\n"
                                   "             shaded by lightcuts (edge pixels anti-aliased 4x4)\n"
                                   "  instant-radiosity  the progressive preview on the CPU: the VPLs in a fixed\n"
                                   "             order drawn by power, --vpls-per-frame a frame, running average\n"
                                   "  lightmap   a bake file (`voxbake bake`) as a viewer shows it: albedo x\n"
                                   "             lightmap irradiance / pi + emission (give the .glb as SCENE)\n\n"
                                   "EXR output is linear radiance (W m^-2 sr^-1); PNG is exposure-adjusted,\n"
                                   "ACES-filmic tone-mapped sRGB.")
    _scene_args(p)
    p.add_argument("-o", "--output", required=True, help="output image, .exr (linear) or .png (tone-mapped)")
    p.add_argument("--method", choices=("pathtrace", "voxels", "lightcuts", "instant-radiosity", "lightmap"),
                   default="pathtrace", help="default: pathtrace")
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
    p.add_argument("--seed", type=SEED, default=0, help="random seed (same seed, same image, any thread count)")
    p.add_argument("--threads", type=THREADS, default=0, help="worker threads (default 0: all cores)")
    p.add_argument("--exposure", type=EXPOSURE, default=None, help="PNG exposure in EV (default: automatic)")
    p.add_argument("--stats", metavar="FILE.json", help="write timings, counters and peak memory as JSON")
    _camera_args(p)
    _solver_args(p)
    p.set_defaults(func=cmd_render)

    p = sub.add_parser("bake", help="bake lightmaps into a glTF file a viewer can walk through",
                       formatter_class=argparse.RawDescriptionHelpFormatter,
                       description="Bake a scene's diffuse global illumination into lightmaps and write a glTF\n"
                                   "binary (.glb): the geometry with lightmap UVs (TEXCOORD_1), the lightmap\n"
                                   "pages as 8-bit PNGs (MOZ_lightmap: three.js, Hubs, Unity read them) and as\n"
                                   "half-float EXR (for voxview), cameras, lights and the bake's settings.\n\n"
                                   "Presets: preview (coarse voxels, seconds), default, high (finer voxels, more\n"
                                   "photons and directions). Texels are one voxel cell wide unless\n"
                                   "--texel-density says otherwise. preview reconstructs the voxel solution at\n"
                                   "each texel; default and high shade each texel by lightcuts over virtual\n"
                                   "point lights (direct light with shadow rays, bounced light from the voxels).")
    _scene_args(p)
    p.add_argument("-o", "--output", required=True, help="output bake file (.glb)")
    p.add_argument("--uv", choices=("per-triangle", "xatlas"), default="per-triangle",
                   help="lightmap UVs: one square map per triangle (default, the thesis's method: deduplicated, "
                        "quadtree-packed) or xatlas charts over connected triangles")
    p.add_argument("--texel-density", type=number(0, 1e9, lo_open=True), metavar="D",
                   help="texels per scene unit (default: one texel per voxel cell)")
    p.add_argument("--preview-vpls", type=integer(0, 1 << 24), default=65_536,
                   help="VPLs in the bake's ordered list for the viewer's progressive preview (default 65536; "
                        "0: none)")
    p.add_argument("--texel-samples", type=integer(1, 8), metavar="N",
                   help="anti-aliasing of lightcuts texels: where the light changes sharply across a texel (a "
                        "shadow's edge, a contact) it takes the mean of an N x N grid of points (default: 2 for "
                        "default, 4 for high; 1: one point per texel)")
    p.add_argument("--texel-interpolate", type=number(0, 1), metavar="T",
                   help="adaptive shading of lightcuts texels: every other texel of every other row is shaded, "
                        "and a texel between shaded ones that agree within T (a share of the brightest) takes "
                        "their mean; the others are shaded too (default: 0.2 for default, 0 for high: every "
                        "texel shaded)")
    p.add_argument("--texels", choices=("voxels", "lightcuts"),
                   help="texel values from the voxel solution (preview's) or lightcuts (default and high's)")
    p.add_argument("--seed", type=SEED, default=0, help="random seed (same seed, same bake, any thread count)")
    p.add_argument("--threads", type=THREADS, default=0, help="worker threads (default 0: all cores)")
    p.add_argument("--stats", metavar="FILE.json", help="write timings, counters and peak memory as JSON")
    _solver_args(p)
    p.set_defaults(func=cmd_bake)

    p = sub.add_parser("audit", help="compare the voxel lines' visibility with continuous rays",
                       description="Visibility audit: for sampled (voxel, direction) pairs, compare the first voxel "
                                   "the digital line meets with the first surface a continuous ray hits. 'sees "
                                   "through' (the line passes an occluder) is the leak-like figure; 'misses' is an "
                                   "upper bound (it also counts grazing within a cell).")
    _scene_args(p)
    p.add_argument("--preset", choices=("preview", "default", "high"), default="default")
    p.add_argument("--resolution", type=integer(1, 1 << 16), help="voxel cells along the scene's longest axis")
    p.add_argument("--cell-size", type=number(0, 1e18, lo_open=True), help="voxel cell size in scene units")
    p.add_argument("--radius", type=integer(1, 64), default=4,
                   help="direction radius r to sample families from (default 4)")
    p.add_argument("--families", type=integer(1, 10000), default=16, help="families sampled (default 16)")
    p.add_argument("--samples", type=integer(1, 10 ** 6), default=2000, help="voxels per family (default 2000)")
    p.add_argument("--seed", type=SEED, default=0)
    p.add_argument("--threads", type=THREADS, default=0, help="worker threads (default 0: all cores)")
    p.set_defaults(func=cmd_audit)
    return ap


def interrupted(exc: BaseException) -> bool:
    """Was this exception caused by Ctrl-C? numba's dispatcher, interrupted
    while it converts arguments, raises a SystemError whose context is the
    KeyboardInterrupt."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return True
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return False


def run(func, *args):
    """Calls func(*args) the way every voxgi command runs: one-line errors
    with exit 2, Ctrl-C with exit 130, our warnings as one line each (other
    libraries' warnings shown as usual), the process's warning hooks put
    back after."""
    from .startup import checkpoint, release_interrupts
    original = warnings.showwarning

    def show(message, category, filename, lineno, file=None, line=None):
        if issubclass(category, VoxgiWarning):
            print(f"warning: {message}", file=sys.stderr)
        else:
            original(message, category, filename, lineno, file, line)
    with warnings.catch_warnings():
        warnings.showwarning = show
        try:
            checkpoint()  # Ctrl-C while the command was starting
            return func(*args)
        except VoxgiError as e:
            print(f"error: {e.one_line()}", file=sys.stderr)
            return 2
        except MemoryError:
            print("error: out of memory (lower --resolution or --memory-budget)", file=sys.stderr)
            return 2
        except OSError as e:  # an output or input the system refused (a full disk, a permission)
            if isinstance(e, BrokenPipeError):  # the output's reader left (`voxbake scenes | head -1`): quietly
                os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
                return 141
            where = f"{e.filename}: " if e.filename else ""
            print(f"error: {where}{e.strerror or type(e).__name__}", file=sys.stderr)
            return 2
        except BaseException as e:
            if interrupted(e):
                from .startup import exit_status
                print("interrupted: nothing was written", file=sys.stderr)
                return exit_status()
            raise
        finally:
            release_interrupts()


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    return run(args.func, args)
