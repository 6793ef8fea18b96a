"""The bake as one chain of stages: scene -> voxel solution -> charts ->
texels -> atlas -> Bake (docs/design.md section 8)."""
from __future__ import annotations

import platform
import warnings
from dataclasses import asdict, dataclass, replace

import numpy as np

from ..config import BakeConfig, threads
from ..errors import VoxgiWarning
from ..presets import bake_config
from ..stats import Stats


@dataclass(frozen=True)
class BakeResult:
    """A bake and what it came from: the Bake (bake/mesh.py), the voxel
    Solution, the TexelSet and Lightmaps, the lights the texels and the
    preview used (None when neither did), the lightcuts texels' TexelStats
    (None at the preview tier) and the counts recorded in the bake file."""
    bake: object
    solution: object
    texels: object
    maps: object
    lights: object | None
    texel_stats: object | None
    counts: dict
    run: str = ""   # where the texel tiles ran (executor.Executor.summary)

    def summary(self, stats: Stats) -> str:
        """The closing table of `voxbake bake`: counts, then time and peak
        memory per stage."""
        sol, c, ts = self.solution, self.counts, self.texel_stats
        info, vox = sol.info, sol.voxels
        rows = [("voxels", f"{len(vox):,} (cell {vox.cell_size:.4g})"),
                (("gather rays per bounce", " ".join(str(d) for d in info["gather_rays_per_bounce"]))
                 if info.get("gather_rays_per_bounce") else
                 ("directions per bounce", " ".join(str(d) for d in info.get("directions_per_bounce", [])) or "-")),
                ("photons", f"{info.get('photons', 0):,} ({info.get('photons_landed', 0):,} landed)"),
                ("bounces", f"{sol.bounces} ({sol.stop_reason})")]
        if ts is not None:
            v = self.lights.vpls.counts()
            rows += [("VPLs / average cut", f"{v['vpls']:,} ({v['vpls_direct']:,} direct, {v['vpls_indirect']:,} "
                                            f"indirect, {v['vpls_sky']:,} sky) / cut mean {ts.cut_mean:.0f}, max "
                                            f"{ts.cut_max}, {ts.shadow_rays:,} shadow rays"
                                            + (f"; bounced light by {ts.gather_rays:,} gather rays"
                                               if ts.gather_rays else ""))]
        else:
            rows += [("VPLs / average cut", "- (preview: texel values from the voxel solution)")]
        asked = c["texel_size_asked"]
        rows += [("texel size", f"{asked:.4g} scene units ({1 / asked:.3g} a unit; {c['texel_plan']})"
                  if c.get("texel_plan") else f"{asked:.4g} scene units ({1 / asked:.3g} a unit)"),
                 ("texels", f"{c['texels']:,} in {c['charts']:,} maps ({c['texels_covered']:,} sampled, "
                            f"{c['texels_inside']:,} inside geometry)")]
        rows += [("points shaded", f"{ts.points_shaded:,} ({ts.texels_shaded:,} texels, {ts.texels_interpolated:,} "
                                   f"interpolated; {ts.subtexel_triangles:,} small-triangle sides at their corners or centroid; "
                                   f"{ts.texels_antialiased:,} edge texels at {ts.texel_samples}x{ts.texel_samples})"
                  if ts is not None else "- (preview)")]
        rows += [("maps stored", f"{c['unique']:,} ({c['constant']:,} single-colour, dedup ratio "
                                 f"{self.maps.dedup_ratio:.2f})"),
                 ("pages", f"{c['pages']} x 512^2 ({c['texels_stored'] / max(1, c['pages']) / 512 ** 2:.0%} used)"),
                 ("triangles", f"{self.bake.triangle_count:,} baked")]
        pr = self.bake.probes
        if pr is not None:
            rows.append(("probes", f"{pr.count:,} ({' x '.join(str(int(d)) for d in pr.dims)}, "
                                   f"{int(pr.valid.sum()):,} valid), {pr.spacing:.4g} scene units apart, "
                                   f"{pr.rays:,} rays each"))
        moving = self.bake.scene.dynamic
        if moving:
            rows.append(("dynamic meshes", f"{len(moving)} ({sum(len(d.triangles) for d in moving):,} triangles; not "
                                           f"baked, lit by the probes): {', '.join(d.name for d in moving)}"))
        if self.run:
            rows.append(("workers", self.run))
        w = max(len(k) for k, _ in rows)
        out = [f"  {k:<{w}}  {v}" for k, v in rows]
        out.append(f"  {'stage':<{w}}  {'seconds':>8}  {'peak MiB':>9}")
        for name, e in stats.stages.items():
            out.append(f"  {name:<{w}}  {e['seconds']:8.2f}  {e.get('peak_rss_mb', 0):9.0f}")
        return "\n".join(out)


@dataclass(frozen=True)
class Checkpoint:
    """--checkpoint FOLDER (and --resume): where the solve's result and
    each finished texel tile are kept (executor.TileStore)."""
    folder: str
    resume: bool = False


def bake_scene(scene, config: BakeConfig | None = None, stats: Stats | None = None, progress=False, bvh=None,
               surfaces=None, executor=None, checkpoint: Checkpoint | None = None) -> BakeResult:
    """Scene (or a Prepared) -> BakeResult, on config.solver.threads
    threads; the texel tiles on `executor` (bake/executor.py; None: in
    this process), kept in and taken from `checkpoint`'s folder. The
    result is the same whatever the executor."""
    from .executor import LocalExecutor
    config = config or bake_config()
    stats = stats or Stats("bake")
    executor = executor or LocalExecutor()
    executor.start()
    with threads(config.solver.threads):
        return _bake(scene, config, stats, progress, bvh, surfaces, executor, checkpoint)


def bake_identity(prepared, config) -> str:
    """sha256 (hex) of what a bake's solution and tiles depend on: the
    scene's packed surfaces (geometry, materials, textures, lights, sky),
    the settings (threads aside) and voxgi's sources."""
    import hashlib
    import json

    from ..kernel_cache import source_digest
    settings = asdict(config)
    settings["solver"] = {k: v for k, v in settings["solver"].items() if k != "threads"}
    h = hashlib.sha256(json.dumps(settings, sort_keys=True, default=str).encode())
    h.update((source_digest() or "").encode())
    arrays = prepared.surfaces.arrays
    for name in arrays._fields:
        a = np.ascontiguousarray(getattr(arrays, name))
        h.update(f"{name}{a.dtype.str}{a.shape}".encode())
        h.update(a.data)
    return h.hexdigest()


def _texels(prepared, solution, charts, config, stats, progress, texel_size=None, executor=None):
    """(TexelSet, Lights or None, TexelStats or None, counts): the texel
    values of the preview tier (the voxel solution) or of lightcuts."""
    from ..lightmap import lightcuts_texels, preview_texels
    from ..lights import build_lights
    from ..progress import bar
    if config.lightcuts is None:
        with stats.stage("texels"), bar(1, "texels", "stage", progress) as b:
            texels = preview_texels(prepared, solution, charts, config.solver.seed)
            b.update(1)
        return texels, None, None, {}
    lc = config.lightcuts
    with stats.stage("lights"):
        lights = build_lights(prepared, solution, lc)
    with stats.stage("texels"), bar(None, "lightcuts texels", "texel", progress) as b:
        texels, st = lightcuts_texels(prepared, solution, charts, lights, config, b.update, texel_size, executor)
    return texels, lights, st, dict(lights.vpls.counts(), **asdict(st), epsilon=lc.epsilon, cut_cap=lc.cap)


def _meta(scene, config, solution, counts) -> dict:
    """The bake's settings and counts as the file records them."""
    return {"preset": config.preset, "uv": config.uv, "texel_density": config.texel_density,
            "texel_values": "voxel solution (reconstructed at each texel)" if config.lightcuts is None else
            "lightcuts over the VPLs",
            # the thread count is the machine's, not the bake's: the same bake is the same bytes on any
            "solver": {k: v for k, v in asdict(config.solver).items() if k != "threads"},
            # the frames' gather is not the texels' (texel_indirect below)
            "lightcuts": {k: v for k, v in asdict(config.lightcuts).items() if not k.startswith("gather")}
            if config.lightcuts else None,
            "texel_samples": config.texel_samples if config.lightcuts else 1,
            "texel_interpolate": config.texel_interpolate if config.lightcuts else 0.0,
            "texel_indirect": {"stride": config.texel_indirect_stride, "cap": config.texel_indirect_cap,
                               "gather": config.texel_gather, "gather_spacing": config.texel_gather_spacing}
            if config.lightcuts else None,
            "seed": config.solver.seed, "scene": scene.path, "solution": {k: v for k, v in solution.info.items()
                                                                           if k != "history"},
            "counts": counts, "python": platform.python_version(), "numpy": np.__version__}


def _bake(scene, config, stats, progress, bvh, surfaces, executor, checkpoint_at):
    from ..lightmap import atlas_for, layout_for
    from ..lightmap.values import capped_note, check_texel_budget, plan_texels
    from ..lights import build_lights, ordered_vpls
    from ..probes import bake_probes, grid_for
    from ..progress import bar
    from ..scene import camera_for, prepare
    from ..solve import solve
    from ..startup import checkpoint
    from .mesh import baked_scene
    budget = config.solver.memory_budget_mb
    plan = None
    if config.texel_density:   # refused before any work when the pages cannot fit
        plan = plan_texels(scene, None, config.texel_density, uv=config.uv)
        check_texel_budget(scene, plan.texel_size, plan.uv, budget, f"--texel-density {config.texel_density:g}")
    probe_grid = None
    if config.probes.rays:   # a grid over the limit is refused before any work
        lo, hi = scene.bounds()
        probe_grid = grid_for(lo, hi, config.probes.spacing, config.probes.budget)
    with stats.stage("bvh"):
        prepared = prepare(scene, bvh, surfaces)
    scene = prepared.scene
    solution = None
    if checkpoint_at is not None:
        from .executor import TileStore
        with stats.stage("checkpoint"):
            executor.store = TileStore(checkpoint_at.folder, bake_identity(prepared, config), checkpoint_at.resume)
            solution = executor.store.get_solution() if checkpoint_at.resume else None
    if solution is None:
        solution = solve(prepared, config.solver, stats=stats, progress=progress, executor=executor)
        if executor.store is not None:
            with stats.stage("checkpoint"):
                executor.store.put_solution(solution)
    checkpoint()
    probes = None
    if probe_grid is not None:
        with stats.stage("probes"), bar(int(np.prod(probe_grid[2])), "probes", "probe", progress) as pbar:
            probes = bake_probes(prepared, solution, probe_grid, config.probes.rays, config.solver.seed, executor,
                                 pbar.update)
        stats.count(probes=probes.count, probes_valid=int(probes.valid.sum()), probe_spacing=probes.spacing,
                    probe_rays=probes.rays)
    checkpoint()
    with stats.stage("charts"):
        if plan is None:   # the preset's size: from the voxel cell and the scene's extent, within the memory budget
            plan = plan_texels(scene, float(solution.voxels.cell_size), None, config.texels_across, config.uv,
                               budget)
        texel_size = plan.texel_size
        charts = layout_for(scene, texel_size, plan.uv)
    note = capped_note(charts, texel_size)
    if note:
        warnings.warn(note, VoxgiWarning, stacklevel=2)
    checkpoint()
    config = replace(config, uv=plan.uv)   # the layout made, as the file records it
    texels, lights, texel_stats, shading = _texels(prepared, solution, charts, config, stats, progress, texel_size,
                                                   executor)
    stats.count(**{f"tiles_{k}": v for k, v in executor.counts.items()}, workers=executor.workers)
    with stats.stage("atlas"):
        maps = atlas_for(scene, texels)
    checkpoint()
    counts = dict(maps.counts, charts=charts.chart_count,
                  texels_covered=int(texels.covered.sum()), texels_inside=int(texels.inside.sum()),
                  dedup_ratio=round(maps.dedup_ratio, 4), texel_size=float(np.min(charts.texel)),
                  texel_size_asked=float(texel_size), texel_plan=plan.why, **shading)
    stats.count(**counts)
    meta = _meta(scene, config, solution, counts)
    ordered = None
    if config.preview_vpls > 0:
        with stats.stage("lights"):
            if lights is None:
                lights = build_lights(prepared, solution, config.preview_lightcuts)
            lo, hi = scene.bounds()
            ordered = ordered_vpls(lights.vpls, config.preview_vpls, 0.5 * float(np.linalg.norm(hi - lo)),
                                   config.solver.seed)
        counts["preview_vpls"] = len(ordered)  # (meta holds counts: the file records it too)
        stats.count(preview_vpls=len(ordered))
    if not scene.cameras:  # a viewer opens the bake at a camera: the automatic one that sees the scene
        scene = replace(scene, cameras=(replace(camera_for(scene, None, prepared.bvh), name="auto"),))
    bake = baked_scene(scene, charts, maps, meta, ordered, probes)
    return BakeResult(bake, solution, texels, maps, lights, texel_stats, counts,
                      executor.summary() if texel_stats is not None else "")
