"""Configuration as frozen dataclasses (the solver, lightcuts, the bake)
and the worker-thread setting; the presets that fill them are in
presets.py."""
from __future__ import annotations

import math
from contextlib import contextmanager
from dataclasses import dataclass, field

from .errors import ConfigError


MAX_GATHER = 65_536   # gather rays per point at most (the solver's and the texels')
MAX_GATHER_SPACING = 16.0   # cells between the gathered light's records at most (coarser says nothing useful)


@dataclass(frozen=True)
class SolverConfig:
    """Knobs of the voxel solver (docs/design.md sections 2-5).

    surface_cells: how many cells the scene's surfaces should cover (their
        area projected on each triangle's dominant axis, in cells^2, about
        the voxel count): the cell size follows the scene's surface area,
        not its bounding box, so a building gets finer cells than a box
        of the same size (docs/design.md section 11).
    resolution: cells along the scene's longest axis, instead of
        surface_cells (0: from surface_cells).
    cell_size: the cell size in scene units, instead of either (0: unset).
    radius: r of the first propagated bounce's direction set D_r
        (DirectionSet.n_directions of them).
    schedule: 'halving' (|D| about halved each bounce, floor r_min) or
        'constant' (same r every bounce), docs/design.md section 3.
    photons: photons shot from the lights for the first bounce (0: from
        photons_per_voxel).
    photons_per_voxel: photons per voxel when photons is 0: the photon
        noise of a voxel's first bounce follows this, not the scene size.
    photon_smoothing: a voxel's photon estimate is pooled with its
        neighbours on the same surface that agree with it within this many
        standard deviations of the photon noise (0: off).
    gather_rays: the bounces after the photons are gathered by this many
        rays per voxel at the first of them, halving bounce by bounce down
        to 64 (solve/gather.py), instead of propagated along digital lines
        (0: propagated, with radius and schedule).
    tolerance: stop when the power of the newly arrived radiosity falls
        below tolerance times that of the first bounce; the bounces left
        are added as the geometric series of the last two (a bounce cap
        stops without it).
    max_bounces: bounce cap (counting the photon bounce as 1).
    seed: random seed (the same seed gives the same solution for any
        thread count).
    threads: worker threads (0: all cores).
    memory_budget_mb: refuse a voxelization estimated above this.
    """
    surface_cells: int = 25_000
    resolution: int = 0
    cell_size: float = 0.0
    radius: int = 8
    schedule: str = "halving"
    r_min: int = 2
    photons: int = 0
    photons_per_voxel: float = 64.0
    photon_smoothing: float = 0.0
    gather_rays: int = 0
    tolerance: float = 1e-3
    max_bounces: int = 64
    seed: int = 0
    threads: int = 0
    memory_budget_mb: float = 8192.0

    def __post_init__(self):
        if self.schedule not in ("halving", "constant"):
            raise ConfigError(f"schedule must be 'halving' or 'constant', not {self.schedule!r}")
        if self.resolution < 0 or (self.resolution == 0 and self.cell_size <= 0 and self.surface_cells < 1):
            raise ConfigError("resolution must be >= 1 (or give a cell size, or surface cells >= 1)")
        if self.cell_size < 0:
            raise ConfigError(f"cell size must be positive (got {self.cell_size})")
        if self.radius < 1 or self.r_min < 1:
            raise ConfigError("direction radius must be >= 1")
        if self.photons < 0 or self.max_bounces < 1 or self.tolerance < 0:
            raise ConfigError("photons >= 0, max_bounces >= 1 and tolerance >= 0 are required")
        if not self.photon_smoothing >= 0:
            raise ConfigError(f"photon smoothing must be >= 0 standard deviations (got {self.photon_smoothing})")
        if not self.photons_per_voxel >= 0:
            raise ConfigError(f"photons per voxel must be >= 0 (got {self.photons_per_voxel})")
        if not 0 <= self.gather_rays <= MAX_GATHER:
            raise ConfigError(f"the solver's gather rays must lie in [0, {MAX_GATHER}] (got {self.gather_rays})")
        if self.threads < 0:
            raise ConfigError(f"threads must be >= 0 (0: all cores), not {self.threads}")
        if self.memory_budget_mb <= 0:
            raise ConfigError(f"memory budget must be positive (got {self.memory_budget_mb} MiB)")

    def photon_count(self, voxels: int) -> int:
        """Photons to shoot for a voxelization of this many voxels."""
        if self.photons > 0:
            return int(self.photons)
        return int(math.ceil(self.photons_per_voxel * voxels))

    def radii(self) -> list:
        """r_k of bounces 2, 3, ... (docs/design.md section 3): with 'halving',
        |D_{r_k}| ~ |D_{r_0}| / 2^k, i.e. r_k ~ r_0 / sqrt(2)^k, floor r_min."""
        out = []
        for k in range(self.max_bounces - 1):
            if self.schedule == "constant":
                out.append(self.radius)
            else:
                out.append(max(self.r_min, int(round(self.radius / 2 ** (k / 2)))))
        return out


@dataclass(frozen=True)
class LightcutsConfig:
    """How points are shaded by lightcuts over the VPLs (docs/design.md
    section 7): direct_vpls points on the area emitters; sky_vpls
    directions of the sky; epsilon the cut's relative error bound; cap the
    largest cut; seed. gather: a quality frame's bounced light is gathered
    from the voxel solution by this many rays at records gather_spacing
    voxel cells apart and interpolated between them (a final gather:
    render/lightcuts_frame.py; 0: the voxels' VPLs in the cuts, as the
    emitters'). A bake's texels take their own (BakeConfig.texel_gather)."""
    direct_vpls: int = 32_768
    sky_vpls: int = 1024
    epsilon: float = 0.02
    cap: int = 1000
    seed: int = 0
    gather: int = 0
    gather_spacing: float = 1.0

    def __post_init__(self):
        if self.direct_vpls < 0 or self.sky_vpls < 0:
            raise ConfigError("VPL counts must be >= 0")
        if not 0 <= self.epsilon < 1:
            raise ConfigError(f"epsilon must lie in [0, 1) (got {self.epsilon})")
        if self.cap < 1:
            raise ConfigError(f"the cut cap must be >= 1 (got {self.cap})")
        if not 0 <= self.gather <= MAX_GATHER:
            raise ConfigError(f"a frame's gather rays must lie in [0, {MAX_GATHER}] (got {self.gather})")
        if not 0 <= self.gather_spacing <= MAX_GATHER_SPACING:
            raise ConfigError(f"a frame's gather spacing must lie in [0, {MAX_GATHER_SPACING}] cells "
                              f"(got {self.gather_spacing})")


UV_MODES = ("auto", "per-triangle", "xatlas")
TEXEL_SOURCES = ("voxels", "lightcuts")
MAX_TEXEL_SAMPLES = 8
MAX_INDIRECT_STRIDE = 16
MAX_TEXELS_ACROSS = 4096


MAX_PROBE_RAYS = 49_152   # rays per probe at most


@dataclass(frozen=True)
class ProbeConfig:
    """The irradiance probe grid of a bake (probes/): spacing between
    probes in scene units (None: about `budget` probes over the scene's
    bounds); rays: the directions each probe gathers along (a spherical
    Fibonacci set; 0: no probes)."""
    spacing: float | None = None
    budget: int = 2048
    rays: int = 768

    def __post_init__(self):
        if self.spacing is not None and not (math.isfinite(self.spacing) and self.spacing > 0):
            raise ConfigError(f"the probe spacing must be a positive number of scene units (got {self.spacing})")
        if not 1 <= self.budget <= 1 << 20:
            raise ConfigError(f"the probe budget must lie in [1, {1 << 20}] (got {self.budget})")
        if not 0 <= self.rays <= MAX_PROBE_RAYS:
            raise ConfigError(f"probe rays must lie in [0, {MAX_PROBE_RAYS}] (got {self.rays})")


@dataclass(frozen=True)
class BakeConfig:
    """solver: the voxel solution's settings; uv: 'per-triangle' (the
    thesis's texture method), 'xatlas' (charts) or 'auto' (per-triangle
    unless its maps would be mostly margin: lightmap/values.py,
    plan_texels); texel_density: texels per scene unit (None: one texel
    per voxel cell, or the scene's thinnest extent over texels_across
    where that is finer, within the memory budget); preset: the name it
    came from; lightcuts: how texels are shaded (None: the voxel solution
    reconstructed at each texel, the preview tier; else lightcuts over the
    VPLs, the default and high tiers); preview_lightcuts: the VPLs of the
    viewer's progressive preview when texels are not shaded by lightcuts;
    texel_samples: lightcuts texels where the light changes sharply (a
    shadow's edge, a contact) take the mean of a texel_samples x
    texel_samples grid of points (1: one point per texel); texel_contrast:
    what is sharp, a difference from a neighbouring texel of more than this
    share of the larger; texel_interpolate: adaptive shading, texels
    between lattice texels that agree within this share of the largest
    take their mean instead of being shaded (0: every texel shaded);
    texel_indirect_stride: lightcuts texels' smooth light (the voxels'
    VPLs and the sky), which varies slowly, is shaded on every stride-th
    texel of every stride-th row of a map (the bounced light by its own
    cut of at most texel_indirect_cap) and interpolated bilinearly between
    them where they agree within texel_contrast, while the sharp light
    (the emitters' VPLs, punctual lights) is shaded at every texel and
    anti-aliasing point (1: all together at every point, one cut of the
    lightcuts' cap); texel_gather: with a stride above 1, the smooth
    lattice's bounced light is gathered from the voxel solution by this
    many rays per point (solve/gather.py) instead of a cut over the
    voxels' VPLs (0: the cut); texel_gather_spacing: the gathered light
    is gathered at records this many voxel cells apart over the surfaces
    and interpolated between them (lightmap/smooth_cache.py), except where
    they disagree (0: at each map's lattice); probes: the irradiance probe
    grid (ProbeConfig)."""
    solver: SolverConfig = field(default_factory=SolverConfig)
    uv: str = "per-triangle"
    texel_density: float | None = None
    preset: str = "default"
    lightcuts: LightcutsConfig | None = None
    preview_vpls: int = 65_536
    texel_samples: int = 1
    texel_contrast: float = 0.1
    texel_interpolate: float = 0.0
    texel_indirect_stride: int = 1
    texel_indirect_cap: int = 4000
    texel_gather: int = 0
    texel_gather_spacing: float = 0.0
    preview_lightcuts: LightcutsConfig = field(default_factory=LightcutsConfig)
    texels_across: int = 0
    probes: ProbeConfig = field(default_factory=ProbeConfig)

    def __post_init__(self):
        if not 1 <= self.texel_samples <= MAX_TEXEL_SAMPLES:
            raise ConfigError(f"texel samples must be a grid side from 1 to {MAX_TEXEL_SAMPLES} "
                              f"(got {self.texel_samples})")
        if not 0 <= self.texel_contrast < 1:
            raise ConfigError(f"texel contrast must lie in [0, 1) (got {self.texel_contrast})")
        if not 0 <= self.texel_interpolate < 1:
            raise ConfigError(f"texel interpolation must lie in [0, 1) (got {self.texel_interpolate})")
        if not 1 <= self.texel_indirect_stride <= MAX_INDIRECT_STRIDE:
            raise ConfigError(f"the bounced light's texel stride must lie in [1, {MAX_INDIRECT_STRIDE}] "
                              f"(got {self.texel_indirect_stride})")
        if self.texel_indirect_cap < 1:
            raise ConfigError(f"the bounced light's cut cap must be >= 1 (got {self.texel_indirect_cap})")
        if not 0 <= self.texel_gather <= MAX_GATHER:
            raise ConfigError(f"the bounced light's gather rays must lie in [0, {MAX_GATHER}] (got {self.texel_gather})")
        if not (math.isfinite(self.texel_gather_spacing) and 0 <= self.texel_gather_spacing <= MAX_GATHER_SPACING):
            raise ConfigError(f"the gathered light's record spacing must lie in [0, {MAX_GATHER_SPACING}] cells "
                              f"(got {self.texel_gather_spacing})")
        if self.uv not in UV_MODES:
            raise ConfigError(f"unknown UV mode {self.uv!r}; choose from {', '.join(UV_MODES)}")
        if self.texel_density is not None and not (math.isfinite(self.texel_density) and self.texel_density > 0):
            raise ConfigError(f"texel density must be a positive number of texels per scene unit "
                              f"(got {self.texel_density})")
        if not 0 <= self.texels_across <= MAX_TEXELS_ACROSS:
            raise ConfigError(f"texels across the scene must lie in [0, {MAX_TEXELS_ACROSS}] (got {self.texels_across})")
        if self.preview_vpls < 0:
            raise ConfigError(f"the preview's VPL count must be >= 0 (got {self.preview_vpls})")


def check_threads(n) -> int:
    """A thread count as given (0: all cores); ConfigError if negative."""
    n = int(n or 0)
    if n < 0:
        raise ConfigError(f"--threads must be >= 0 (0: all cores), not {n}")
    return n


@contextmanager
def threads(n: int = 0):
    """numba's worker threads set to n (0: all) for the duration, then put
    back: a library call never leaves the process's setting changed."""
    import numba
    n = check_threads(n)
    before = numba.get_num_threads()
    if n:
        numba.set_num_threads(max(1, min(n, numba.config.NUMBA_NUM_THREADS)))
    try:
        yield numba.get_num_threads()
    finally:
        numba.set_num_threads(before)
