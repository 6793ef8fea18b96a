"""The bake as one chain of stages: scene -> voxel solution -> charts ->
texels -> atlas -> Bake (docs/design.md section 8)."""
from __future__ import annotations

import platform
from dataclasses import asdict, dataclass, field

import numpy as np

from ..config import SolverConfig, solver_config, threads
from ..errors import ConfigError
from ..lightmap import AA_CONTRAST
from ..lights import LightcutsConfig, lightcuts_config
from ..stats import Stats

UV_MODES = ("per-triangle", "xatlas")
TEXEL_SAMPLES = {"preview": 1, "default": 2, "high": 4}   # anti-aliasing grid side per preset (lightcuts texels)
TEXEL_INTERPOLATE = {"default": 0.2}   # adaptive shading's agreement per preset (lightcuts texels; 0: every texel)
TEXEL_CONTRAST = {"default": 0.2}      # anti-aliasing's contrast per preset (else AA_CONTRAST)
TEXEL_EPSILON = {"default": 0.01}      # the texels' lightcuts epsilon where it differs from the preset's frames'
MAX_TEXEL_SAMPLES = 8


@dataclass(frozen=True)
class BakeConfig:
    """solver: the voxel solution's settings; uv: 'per-triangle' (the
    thesis's texture method) or 'xatlas' (charts); texel_density: texels per scene unit (None:
    one texel per voxel cell); preset: the name it came from; lightcuts:
    how texels are shaded (None: the voxel solution reconstructed at each
    texel, the preview tier; else lightcuts over the VPLs, the default and
    high tiers); texel_samples: lightcuts texels where the light changes
    sharply (a shadow's edge, a contact) take the mean of a texel_samples
    x texel_samples grid of points (1: one point per texel); texel_contrast:
    what is sharp, a difference from a neighbouring texel of more than this
    share of the larger; texel_interpolate: adaptive shading, texels
    between lattice texels that agree within this share of the largest
    take their mean instead of being shaded (0: every texel shaded)."""
    solver: SolverConfig = field(default_factory=SolverConfig)
    uv: str = "per-triangle"
    texel_density: float | None = None
    preset: str = "default"
    lightcuts: LightcutsConfig | None = None
    preview_vpls: int = 65_536
    texel_samples: int = 1
    texel_contrast: float = AA_CONTRAST
    texel_interpolate: float = 0.0

    def __post_init__(self):
        if not 1 <= self.texel_samples <= MAX_TEXEL_SAMPLES:
            raise ConfigError(f"texel samples must be a grid side from 1 to {MAX_TEXEL_SAMPLES} "
                              f"(got {self.texel_samples})")
        if not 0 <= self.texel_contrast < 1:
            raise ConfigError(f"texel contrast must lie in [0, 1) (got {self.texel_contrast})")
        if not 0 <= self.texel_interpolate < 1:
            raise ConfigError(f"texel interpolation must lie in [0, 1) (got {self.texel_interpolate})")
        if self.uv not in UV_MODES:
            raise ConfigError(f"unknown UV mode {self.uv!r}; choose from {', '.join(UV_MODES)}")
        if self.texel_density is not None and not (np.isfinite(self.texel_density) and self.texel_density > 0):
            raise ConfigError(f"texel density must be a positive number of texels per scene unit "
                              f"(got {self.texel_density})")


def bake_config(preset="default", uv="per-triangle", texel_density=None, texels=None, epsilon=None,
                direct_vpls=None, preview_vpls=65_536, texel_samples=None, texel_contrast=None,
                texel_interpolate=None, **solver_overrides) -> BakeConfig:
    """A preset's bake settings. texels: 'voxels' or 'lightcuts' (default:
    voxels for preview, lightcuts for default and high); texel_samples:
    the anti-aliasing grid (default: the preset's, TEXEL_SAMPLES);
    texel_interpolate: adaptive shading (default: the preset's,
    TEXEL_INTERPOLATE); epsilon: the texels' lightcuts epsilon (default:
    TEXEL_EPSILON, else the preset's)."""
    texels = texels or ("voxels" if preset == "preview" else "lightcuts")
    if texels not in ("voxels", "lightcuts"):
        raise ConfigError(f"texel values come from 'voxels' or 'lightcuts', not {texels!r}")
    solver = solver_config(preset, **solver_overrides)
    if epsilon is None:
        epsilon = TEXEL_EPSILON.get(preset)
    lc = lightcuts_config(preset, epsilon=epsilon, direct_vpls=direct_vpls, seed=solver.seed) \
        if texels == "lightcuts" else None
    if preview_vpls is None or preview_vpls < 0:
        raise ConfigError(f"the preview's VPL count must be >= 0 (got {preview_vpls})")
    if texel_samples is None:
        texel_samples = TEXEL_SAMPLES.get(preset, 1)
    if texel_interpolate is None:
        texel_interpolate = TEXEL_INTERPOLATE.get(preset, 0.0)
    if texel_contrast is None:
        texel_contrast = TEXEL_CONTRAST.get(preset, AA_CONTRAST)
    return BakeConfig(solver, uv, texel_density, preset, lc, int(preview_vpls), int(texel_samples),
                      float(texel_contrast), float(texel_interpolate))


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
    shading = {}
    lights = None
    if config.lightcuts is None:
        with stats.stage("texels"), bar(1, "texels", "stage", progress) as b:
            texels = preview_texels(scene, solution, bvh, surfaces, charts, config.solver.seed)
            b.update(1)
    else:
        from ..lights import build_lights
        from ..lightmap import lightcuts_texels
        lc = config.lightcuts
        with stats.stage("lights"):
            lights = build_lights(scene, solution, surfaces, lc, bvh)
        shading.update(lights.vpls.counts())
        with stats.stage("texels"), bar(None, "lightcuts texels", "texel", progress) as b:
            texels, st = lightcuts_texels(scene, solution, bvh, surfaces, charts, lights, lc.epsilon, lc.cap,
                                          config.solver.seed, b.update, config.texel_samples,
                                          config.texel_contrast, config.texel_interpolate)
        shading.update(st, epsilon=lc.epsilon, cut_cap=lc.cap)
    with stats.stage("atlas"):
        maps = atlas_for(scene, texels)
    checkpoint()
    counts = dict(maps.counts, charts=int(getattr(charts, "charts", len(charts))),
                  texels_covered=int(texels.covered.sum()), texels_inside=int(texels.inside.sum()),
                  dedup_ratio=round(maps.dedup_ratio, 4), texel_size=float(np.min(charts.texel)), **shading)
    stats.count(**counts)
    meta = {"preset": config.preset, "uv": config.uv, "texel_density": config.texel_density,
            "texel_values": "voxel solution (reconstructed at each texel)" if config.lightcuts is None else
            "lightcuts over the VPLs",
            # the thread count is the machine's, not the bake's: the same bake is the same bytes on any
            "solver": {k: v for k, v in asdict(config.solver).items() if k != "threads"},
            "lightcuts": asdict(config.lightcuts) if config.lightcuts else None,
            "texel_samples": config.texel_samples if config.lightcuts else 1,
            "texel_interpolate": config.texel_interpolate if config.lightcuts else 0.0,
            "seed": config.solver.seed, "scene": scene.path, "solution": {k: v for k, v in solution.info.items()
                                                                           if k != "history"},
            "counts": counts, "python": platform.python_version(), "numpy": np.__version__}
    ordered = None
    if config.preview_vpls > 0:
        from ..lights import build_lights, ordered_vpls
        with stats.stage("lights"):
            if lights is None:
                lights = build_lights(scene, solution, surfaces, lightcuts_config(
                    config.preset if config.preset in ("preview", "default", "high") else "default",
                    seed=config.solver.seed), bvh)
            lo, hi = scene.bounds()
            ordered = ordered_vpls(lights.vpls, config.preview_vpls, 0.5 * float(np.linalg.norm(hi - lo)),
                                   config.solver.seed)
        counts["preview_vpls"] = len(ordered)
        stats.count(preview_vpls=len(ordered))
    if not scene.cameras:  # a viewer opens the bake at a camera: the automatic one that sees the scene
        from dataclasses import replace
        scene = replace(scene, cameras=(replace(scene.camera(None, bvh), name="auto"),))
    bake = baked_scene(scene, charts, maps, meta, ordered)
    return bake, solution, texels, maps
