"""The presets preview / default / high: one table of every setting a
preset chooses (the voxel solver, lightcuts, the bake's texels), and the
functions that turn a preset and a user's overrides into the frozen
configurations of config.py. The command line's choices and help text are
generated from this table."""
from __future__ import annotations

import difflib
from dataclasses import dataclass, fields, replace

from .config import TEXEL_SOURCES, BakeConfig, LightcutsConfig, ProbeConfig, SolverConfig
from .errors import ConfigError


@dataclass(frozen=True)
class Preset:
    """about: one line for --help; solver: the voxel solution; lightcuts:
    quality frames and the VPLs (of the viewer's preview too); texels:
    where a bake's texel values come from, 'voxels' (the voxel solution
    reconstructed at each texel) or 'lightcuts'; texel_epsilon: the
    lightcuts error bound of a bake's texels; texel_samples,
    texel_contrast, texel_interpolate: the texels' anti-aliasing grid, what
    counts as a sharp change, and adaptive shading's agreement;
    texel_indirect_stride, texel_indirect_cap, texel_gather: the bounced
    light's sparse lattice, its cuts' cap, and its gather rays per point
    that replace those cuts, texel_gather_spacing the cells between the
    gather's records (config.BakeConfig); texel_cap: the cap of
    the texels' cuts of the emitters' light (None: the lightcuts');
    texels_across: texels over the scene's thinnest extent where that is
    finer than a voxel cell (0: one texel per cell); uv: the lightmap
    layout (config.UV_MODES); probes: the irradiance probe grid's budget
    and rays (config.ProbeConfig)."""
    name: str
    about: str
    solver: SolverConfig
    lightcuts: LightcutsConfig
    texels: str
    texel_epsilon: float
    texel_samples: int
    texel_contrast: float
    texel_interpolate: float
    texel_indirect_stride: int = 1
    texel_indirect_cap: int = 4000
    texel_gather: int = 0
    texel_cap: int | None = None
    texel_gather_spacing: float = 0.0
    texels_across: int = 0
    uv: str = "auto"
    probes: ProbeConfig = ProbeConfig()


# The preview keeps per-triangle maps, its texels the voxels' light read at each: on the staircase --uv auto took
# xatlas, 34 s of charting, and its texels' view fell from 0.95 to 0.877 of the path tracer's (60% of blocks within
# 10%, from 87%).
# Tuned by bench/tradeoff.py, bench/bake_error.py and bench/real_scenes.py (bench/results/): the preview shows the
# voxels themselves, where smoothing the photons pays; default and high shade texels by lightcuts, where it made
# the Cornell box's lightmaps brighter and worse. Every preset gathers the bounces after the photons by rays at the
# voxels: on the real scenes the digital lines lost light at thin and curved things (balusters, a chandelier),
# 4-11% of the view's mean at default and up to 26% at preview, where the gather came within 0.6-5% of the path
# tracer in about the same time; on the Cornell box it takes about twice as long (the lines stay as --gather-rays 0, with
# the radius). The default bake's texels take a tighter epsilon than its frames because a lightmap is looked at
# for longer; its adaptive shading and coarser contrast keep its time near the preview's. The default solve spends
# on photons what it once spent on gather rays (160 a voxel and 128 rays, not 64 and 256; bench/results/pixels.md):
# the first bounce's photon noise was what a voxel's value was off by (a furnace's voxel view 0.95-1.03 of exact, now
# 0.98-1.02), the later bounces average it away whatever their rays, and the solve takes no longer.
PRESETS = {p.name: p for p in (
    Preset("preview", "coarse voxels, texels from the voxel solution: seconds",
           SolverConfig(surface_cells=12_500, radius=4, photons_per_voxel=32, photon_smoothing=2.0, tolerance=1e-2,
                        max_bounces=16, gather_rays=64),
           LightcutsConfig(direct_vpls=4096, sky_vpls=256, epsilon=0.05, cap=300, gather=64),
           texels="voxels", texel_epsilon=0.05, texel_samples=1, texel_contrast=0.1, texel_interpolate=0.0,
           uv="per-triangle", probes=ProbeConfig(budget=256, rays=192)),
    Preset("default", "direct light by lightcuts at every texel, bounced light gathered from the voxels, shadow edges "
                      "anti-aliased",
           SolverConfig(surface_cells=25_000, radius=6, photons_per_voxel=160, photon_smoothing=2.0, tolerance=1e-2,
                        max_bounces=64, gather_rays=128),
           LightcutsConfig(direct_vpls=32_768, sky_vpls=1024, epsilon=0.02, cap=1000, gather=256),
           texels="lightcuts", texel_epsilon=0.01, texel_samples=2, texel_contrast=0.2, texel_interpolate=0.2,
           texel_indirect_stride=2, texel_indirect_cap=1000, texel_gather=256, texel_cap=200,
           texel_gather_spacing=1.0, texels_across=64, probes=ProbeConfig(budget=2048, rays=768)),
    Preset("high", "finer voxels, more photons, gather rays and VPLs; every texel shaded",
           SolverConfig(surface_cells=100_000, radius=12, photons_per_voxel=128, photon_smoothing=0.0,
                        tolerance=1e-3, max_bounces=128, gather_rays=1024),
           LightcutsConfig(direct_vpls=131_072, sky_vpls=4096, epsilon=0.01, cap=2000, gather=1024,
                           gather_spacing=2.0),
           texels="lightcuts", texel_epsilon=0.01, texel_samples=4, texel_contrast=0.1, texel_interpolate=0.0,
           texel_indirect_stride=2, texel_indirect_cap=8000, texel_gather=1024, texel_gather_spacing=2.0,
           texels_across=128, probes=ProbeConfig(budget=8192, rays=3072)),
)}


def preset(name: str) -> Preset:
    """The preset of this name; ConfigError for an unknown one."""
    if name not in PRESETS:
        raise ConfigError(f"unknown preset {name!r}; choose from {', '.join(PRESETS)}")
    return PRESETS[name]


def _overridden(base, overrides: dict, what: str):
    """base with the given fields replaced (None values are left at
    base's); an unknown field raises ConfigError with the nearest name."""
    names = [f.name for f in fields(base)]
    for key in overrides:
        if key not in names:
            near = difflib.get_close_matches(key, names, n=1)
            hint = f" (did you mean {near[0]!r}?)" if near else f"; settings: {', '.join(names)}"
            raise ConfigError(f"unknown {what} setting {key!r}{hint}")
    return replace(base, **{k: v for k, v in overrides.items() if v is not None})


def solver_config(name: str = "default", **overrides) -> SolverConfig:
    """A preset's solver settings with the given fields replaced."""
    return _overridden(preset(name).solver, overrides, "solver")


def lightcuts_config(name: str = "default", **overrides) -> LightcutsConfig:
    """A preset's lightcuts settings (of its frames) with the given fields
    replaced."""
    return _overridden(preset(name).lightcuts, overrides, "lightcuts")


def bake_config(name="default", uv=None, texel_density=None, texels=None, epsilon=None,
                direct_vpls=None, preview_vpls=65_536, texel_samples=None, texel_contrast=None,
                texel_interpolate=None, texel_indirect_stride=None, texel_gather=None, texel_gather_spacing=None,
                texels_across=None, probe_spacing=None, probe_rays=None, **solver_overrides) -> BakeConfig:
    """A preset's bake settings; every None takes the preset's value.
    texels: 'voxels' or 'lightcuts'; epsilon: the texels' lightcuts error
    bound; probe_spacing, probe_rays: the probe grid's (ProbeConfig);
    the rest as config.BakeConfig, solver_overrides as solver_config."""
    p = preset(name)
    uv = uv or p.uv
    texels = texels or p.texels
    if texels not in TEXEL_SOURCES:
        raise ConfigError(f"texel values come from 'voxels' or 'lightcuts', not {texels!r}")
    solver = solver_config(name, **solver_overrides)
    texel_lightcuts = lightcuts_config(name, epsilon=epsilon if epsilon is not None else p.texel_epsilon,
                                       direct_vpls=direct_vpls, seed=solver.seed,
                                       cap=p.texel_cap if p.texel_cap is not None else p.lightcuts.cap)
    if preview_vpls is None or preview_vpls < 0:
        raise ConfigError(f"the preview's VPL count must be >= 0 (got {preview_vpls})")
    return BakeConfig(
        solver, uv, texel_density, name, texel_lightcuts if texels == "lightcuts" else None, int(preview_vpls),
        int(texel_samples if texel_samples is not None else p.texel_samples),
        float(texel_contrast if texel_contrast is not None else p.texel_contrast),
        float(texel_interpolate if texel_interpolate is not None else p.texel_interpolate),
        int(texel_indirect_stride if texel_indirect_stride is not None else p.texel_indirect_stride),
        int(p.texel_indirect_cap),
        int(texel_gather if texel_gather is not None else p.texel_gather),
        float(texel_gather_spacing if texel_gather_spacing is not None else p.texel_gather_spacing),
        preview_lightcuts=lightcuts_config(name, seed=solver.seed),
        texels_across=int(texels_across if texels_across is not None else p.texels_across),
        probes=replace(p.probes, spacing=probe_spacing if probe_spacing is not None else p.probes.spacing,
                       rays=int(probe_rays if probe_rays is not None else p.probes.rays)))


def help_table() -> str:
    """The presets' values as --help shows them."""
    rows = []
    for p in PRESETS.values():
        s, lc = p.solver, p.lightcuts
        rows.append(f"  {p.name:<8} {p.about}\n"
                    f"           surface cells {s.surface_cells:,}, "
                    + (f"bounces gathered by {s.gather_rays} rays per voxel" if s.gather_rays else f"radius {s.radius}")
                    + f", photons/voxel {s.photons_per_voxel:g}, smoothing {s.photon_smoothing:g}, tolerance "
                    f"{s.tolerance:g}, bounces <= {s.max_bounces}\n"
                    f"           direct VPLs {lc.direct_vpls:,}, sky VPLs {lc.sky_vpls:,}, epsilon "
                    f"{lc.epsilon:g}, cut <= {lc.cap:,}\n"
                    f"           a bake's texels from {p.texels}"
                    + (f" (epsilon {p.texel_epsilon:g}, {p.texel_samples}x{p.texel_samples} at edges, "
                       f"cut <= {p.texel_cap or lc.cap:,}, interpolate {p.texel_interpolate:g}, bounced light and "
                       f"sky every {p.texel_indirect_stride} texels, "
                       + (f"bounced by {p.texel_gather} gather rays)" if p.texel_gather else
                          f"cut <= {p.texel_indirect_cap:,})")
                       if p.texels == "lightcuts" else "")
                    + f"\n           about {p.probes.budget:,} irradiance probes of {p.probes.rays:,} rays")
    return "presets:\n" + "\n".join(rows)
