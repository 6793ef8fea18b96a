"""The bake as one chain of stages: scene -> voxel solution -> charts ->
texels -> atlas -> Bake (docs/design.md section 8)."""
from __future__ import annotations

import platform
from dataclasses import asdict, dataclass, field

import numpy as np

from ..config import SolverConfig, solver_config, threads
from ..errors import ConfigError
from ..stats import Stats

UV_MODES = ("per-triangle", "xatlas")


@dataclass(frozen=True)
class BakeConfig:
    """solver: the voxel solution's settings; uv: 'per-triangle' (the
    thesis's texture method) or 'xatlas' (charts); texel_density: texels per scene unit (None:
    one texel per voxel cell); preset: the name it came from.

    Texel values: every tier reconstructs the voxel solution at the texels
    (the preview tier's method) until lightcuts shade texels; the presets
    differ in the solution's resolution, directions and photons."""
    solver: SolverConfig = field(default_factory=SolverConfig)
    uv: str = "per-triangle"
    texel_density: float | None = None
    preset: str = "default"

    def __post_init__(self):
        if self.uv not in UV_MODES:
            raise ConfigError(f"unknown UV mode {self.uv!r}; choose from {', '.join(UV_MODES)}")
        if self.texel_density is not None and not (np.isfinite(self.texel_density) and self.texel_density > 0):
            raise ConfigError(f"texel density must be a positive number of texels per scene unit "
                              f"(got {self.texel_density})")


def bake_config(preset="default", uv="per-triangle", texel_density=None, **solver_overrides) -> BakeConfig:
    return BakeConfig(solver_config(preset, **solver_overrides), uv, texel_density, preset)


def bake_scene(scene, config: BakeConfig | None = None, stats: Stats | None = None, progress=False, bvh=None,
               surfaces=None):
    """Scene -> Bake (bake/mesh.py), on config.solver.threads threads."""
    config = config or bake_config()
    stats = stats or Stats("bake")
    with threads(config.solver.threads):
        return _bake(scene, config, stats, progress, bvh, surfaces)


def _bake(scene, config, stats, progress, bvh, surfaces):
    from ..lightmap import atlas_for, layout_for, preview_texels, texel_size_for
    from ..progress import bar
    from ..scene import build_scene_bvh, pack
    from ..solve import solve
    from ..startup import checkpoint
    from .mesh import baked_scene
    with stats.stage("bvh"):
        bvh = bvh or build_scene_bvh(scene)
        surfaces = surfaces or pack(scene)
    solution = solve(scene, config.solver, stats=stats, bvh=bvh, surfaces=surfaces, progress=progress)
    checkpoint()
    with stats.stage("charts"):
        charts = layout_for(scene, texel_size_for(solution, config.texel_density), config.uv)
    checkpoint()
    with stats.stage("texels"), bar(1, "texels", "stage", progress) as b:
        texels = preview_texels(scene, solution, bvh, surfaces, charts, config.solver.seed)
        b.update(1)
    with stats.stage("atlas"):
        maps = atlas_for(scene, texels)
    checkpoint()
    counts = dict(maps.counts, charts=int(getattr(charts, "charts", len(charts))),
                  texels_covered=int(texels.covered.sum()), texels_inside=int(texels.inside.sum()),
                  dedup_ratio=round(maps.dedup_ratio, 4), texel_size=float(np.min(charts.texel)))
    stats.count(**counts)
    meta = {"preset": config.preset, "uv": config.uv, "texel_density": config.texel_density,
            "texel_values": "voxel solution (reconstructed at each texel)", "solver": asdict(config.solver),
            "seed": config.solver.seed, "scene": scene.path, "solution": {k: v for k, v in solution.info.items()
                                                                           if k != "history"},
            "counts": counts, "python": platform.python_version(), "numpy": np.__version__}
    if not scene.cameras:  # a viewer opens the bake at a camera: the automatic one that sees the scene
        from dataclasses import replace
        scene = replace(scene, cameras=(replace(scene.camera(None, bvh), name="auto"),))
    bake = baked_scene(scene, charts, maps, meta)
    return bake, solution, texels, maps
