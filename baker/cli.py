"""`voxbake`: the baker's command line, a thin layer over the library.

Every subcommand checks its arguments and output paths before any work,
prints `error: <file>: <problem>` and exits 2 on bad input (never a
traceback from inside numba), writes outputs atomically, and on Ctrl-C
prints `interrupted: nothing was written` and exits 130 (startup.run).
The flags are defined in cli_args.py, the pipelines in the library.
"""
from __future__ import annotations

import os
import sys

import numpy as np

from .cli_args import build_parser
from .errors import ConfigError, VoxgiError
from .startup import run


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
    return load_scene(args.scene, one_sided=args.one_sided, lights=lights, sky=sky, limits=load_limits(args),
                      dynamic=tuple(getattr(args, "dynamic", None) or ()))


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
    output = getattr(args, "output", None)
    if output:
        check_output_path(output, extensions, inputs)
    if getattr(args, "stats", None):
        check_output_path(args.stats, (".json",), inputs + [output] if output else inputs)
        if output and os.path.abspath(args.stats) == os.path.abspath(output):
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


SOLVER_FLAGS = ("resolution", "cell_size", "surface_cells", "photons_per_voxel", "photon_smoothing", "radius",
                "gather_rays", "photons", "seed", "threads", "schedule", "tolerance", "max_bounces")


def _solver_overrides(args) -> dict:
    """The solver settings the command line gives (None: the preset's)."""
    out = {k: getattr(args, k, None) for k in SOLVER_FLAGS}
    out["memory_budget_mb"] = args.memory_budget
    return out


def _configs(args, what, make):
    try:
        return make()
    except ConfigError as e:
        raise ConfigError(f"invalid {what} setting: {e}") from None


def cmd_scenes(args):
    from .scene import builtin_scenes
    from .scene.load import resolve
    for name in builtin_scenes():
        print(f"{name:<26} {resolve(name)}")
    return 0


def cmd_info(args):
    from .scene.inspect import describe
    print(describe(_load(args)))
    return 0


def _render_settings(args):
    """What `voxbake render` asks for, checked (render.RenderSettings)."""
    from .presets import lightcuts_config, solver_config
    from .render import RenderSettings
    from .render.frame import SPP_CAP
    adaptive = args.time_limit is not None or args.noise is not None
    solver = _configs(args, "solver", lambda: solver_config(args.preset, **_solver_overrides(args)))
    lc = _configs(args, "lightcuts", lambda: lightcuts_config(args.preset, epsilon=args.epsilon,
                                                              direct_vpls=args.direct_vpls, seed=args.seed,
                                                              gather=args.frame_gather,
                                                              gather_spacing=args.frame_gather_spacing))
    return RenderSettings(args.method, args.width, args.height, args.spp or (SPP_CAP if adaptive else 64), args.seed,
                          args.time_limit, args.noise, solver, lc, args.vpls_per_frame, args.frames,
                          args.ir_tolerance, args.path_bounces)


def cmd_render(args):
    from .config import threads
    from .render import METHODS, render_frame, write_image
    from .scene import adjust_camera, camera_for, prepare
    from .startup import checkpoint
    from .stats import Stats
    _check_common(args, (".exr", ".png"))
    settings = _render_settings(args)
    stats = Stats("render " + args.method)
    with threads(args.threads):
        with stats.stage("load"):
            if METHODS[args.method].bake:
                from .bake import read_bake
                scene = read_bake(args.scene)
                world = scene.scene
            else:
                scene = world = _load(args)
        with stats.stage("bvh"):
            prepared = prepare(world)
        camera = adjust_camera(camera_for(world, args.camera, prepared.bvh), args.look_from, args.look_at, args.up,
                               args.fov)
        stats.count(triangles=len(world.triangles), bvh_nodes=prepared.bvh.node_count, width=args.width,
                    height=args.height, camera=camera.name)
        frame = render_frame(scene if METHODS[args.method].bake else prepared, camera, settings, stats,
                             progress=True, bvh=prepared.bvh, surfaces=prepared.surfaces)
    stats.count(**frame.counts)
    if frame.summary:
        print(frame.summary, file=sys.stderr)
    checkpoint()  # a Ctrl-C from the last stretch: stop before writing
    with stats.stage("write"):
        write_image(args.output, frame.image, args.exposure)
    write_stats(args, stats)
    print(f"wrote {args.output}  ({args.width}x{args.height}, {stats.as_dict()['total_seconds']:.2f} s)")
    return 0


def cmd_bake(args):
    from .bake import bake_scene, write_bake
    from .config import threads
    from .presets import bake_config
    from .startup import checkpoint
    from .stats import Stats
    _check_common(args, (".glb",))
    if args.dynamic and args.no_probes:
        raise VoxgiError("--dynamic meshes are lit by the probes: drop --no-probes")
    config = _configs(args, "bake", lambda: bake_config(
        args.preset, args.uv, args.texel_density, args.texels, args.epsilon, args.direct_vpls,
        preview_vpls=args.preview_vpls, texel_samples=args.texel_samples, texel_interpolate=args.texel_interpolate,
        texel_indirect_stride=args.texel_indirect_stride, texel_gather=args.texel_gather,
        texel_gather_spacing=args.texel_gather_spacing, probe_spacing=args.probe_spacing,
        probe_rays=0 if args.no_probes else None, **_solver_overrides(args)))
    checkpoint_at = _check_cluster(args)
    stats = Stats("bake")
    with threads(args.threads), _executor(args) as executor:
        with stats.stage("load"):
            scene = _load(args)
        result = bake_scene(scene, config, stats, progress=True, executor=executor, checkpoint=checkpoint_at)
    if not np.isfinite(result.bake.pages).all() or result.bake.pages.min() < 0:
        raise VoxgiError("internal error: non-finite or negative texels (please report)", args.scene)
    checkpoint()
    with stats.stage("write"):
        write_bake(args.output, result.bake, inputs=_inputs(args))
    write_stats(args, stats)
    print(result.summary(stats))
    size = os.path.getsize(args.output)
    print(f"wrote {args.output}  ({size / 2 ** 20:.1f} MiB, {stats.as_dict()['total_seconds']:.2f} s)")
    return 0


def _check_cluster(args):
    """The cluster and checkpoint flags, checked before any work; the
    Checkpoint asked for (None: none)."""
    from .bake.pipeline import Checkpoint
    if args.resume and not args.checkpoint:
        raise VoxgiError("--resume needs --checkpoint DIR (the folder of the bake to resume)")
    if (args.tls_ca_file or args.tls_cert or args.tls_key) and not args.scheduler:
        raise VoxgiError("--tls-ca-file, --tls-cert and --tls-key are for --scheduler tls://...")
    if args.insecure and not args.scheduler:
        raise VoxgiError("--insecure is for --scheduler tcp://...")
    if args.scheduler:
        from .bake.cluster import check_scheduler, security_for
        check_scheduler(args.scheduler, args.insecure)
        security_for(args.tls_ca_file, args.tls_cert, args.tls_key)
    if not args.checkpoint:
        return None
    folder = os.path.abspath(args.checkpoint)
    if os.path.exists(folder) and not os.path.isdir(folder):
        raise VoxgiError("--checkpoint names a file, not a folder", args.checkpoint)
    for path in _inputs(args) + [args.output]:
        if os.path.abspath(path) == folder:
            raise VoxgiError("--checkpoint names an input or the output", args.checkpoint)
    return Checkpoint(folder, bool(args.resume))


def _executor(args):
    """Where the bake's texel tiles run: this process, a local Dask
    cluster (--workers) or an existing one (--scheduler)."""
    from contextlib import nullcontext

    from .bake.executor import LocalExecutor
    if not (args.workers or args.scheduler):
        return nullcontext(LocalExecutor())
    from .bake.cluster import dask_executor
    return dask_executor(args.workers or 0, args.scheduler, args.threads, args.insecure,
                         (args.tls_ca_file, args.tls_cert, args.tls_key))


def cmd_audit(args):
    from .config import threads
    from .presets import solver_config
    from .scene import build_scene_bvh, pack
    from .scene.inspect import geometry_report
    from .solve.audit import audit
    from .voxels import resolution_for, voxelize
    _check_common(args)
    config = _configs(args, "solver", lambda: solver_config(args.preset, resolution=args.resolution,
                                                            cell_size=args.cell_size,
                                                            memory_budget_mb=args.memory_budget))
    with threads(args.threads):
        scene = _load(args)
        print(geometry_report(scene).summary())
        bvh, surfaces = build_scene_bvh(scene), pack(scene)
        vox = voxelize(scene, resolution_for(scene, config), config.cell_size, config.memory_budget_mb, surfaces, bvh)
        report = audit(scene, vox, bvh, surfaces, radius=args.radius, families=args.families, samples=args.samples,
                       seed=args.seed)
    print(f"{len(vox)} voxels, cell {vox.cell_size:.4g}")
    print(report.summary())
    for centroid, direction, kind in report.worst:
        print(f"  {kind:14s} voxel at {centroid} looking along {direction}")
    return 0


COMMANDS = {"scenes": cmd_scenes, "info": cmd_info, "render": cmd_render, "bake": cmd_bake, "audit": cmd_audit}


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    return run(COMMANDS[args.command], args)
