"""Configuration as frozen dataclasses, the presets preview/default/high,
and the worker-thread setting."""
from __future__ import annotations

import difflib
import math
from contextlib import contextmanager
from dataclasses import dataclass, fields, replace

from .errors import ConfigError


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
    tolerance: stop when the power of the newly arrived radiosity falls
        below tolerance times that of the first bounce.
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
        if self.threads < 0:
            raise ConfigError(f"threads must be >= 0 (0: all cores), not {self.threads}")
        if self.memory_budget_mb <= 0:
            raise ConfigError(f"memory budget must be positive (got {self.memory_budget_mb} MiB)")

    def resolution_for(self, scene) -> int:
        """Cells along the scene's longest axis (ignored when cell_size > 0)."""
        if self.resolution > 0 or self.cell_size > 0:
            return int(self.resolution)
        from .voxels import surface_resolution
        return surface_resolution(scene, self.surface_cells)

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


PRESETS = {
    # retuned from bench/tradeoff.py (bench/results/tradeoff.md): the preview shows the voxels themselves, where
    # smoothing the photons and twice the surface cells pay on every test scene; default and high shade texels by
    # lightcuts, where the smoothing made the Cornell box's lightmaps 1-1.5% brighter and worse (3.7% -> 4.6%)
    "preview": SolverConfig(surface_cells=12_500, radius=4, photons_per_voxel=32, photon_smoothing=2.0,
                            tolerance=1e-2, max_bounces=16),
    "default": SolverConfig(surface_cells=25_000, radius=8, photons_per_voxel=64, photon_smoothing=0.0,
                            tolerance=1e-3, max_bounces=64),
    "high": SolverConfig(surface_cells=100_000, radius=12, photons_per_voxel=128, photon_smoothing=0.0,
                         tolerance=1e-4, max_bounces=128),
}


def solver_config(preset: str = "default", **overrides) -> SolverConfig:
    """A preset with the given fields replaced (None values are left at the
    preset's). An unknown preset or field name raises ConfigError."""
    if preset not in PRESETS:
        raise ConfigError(f"unknown preset {preset!r}; choose from {', '.join(PRESETS)}")
    names = [f.name for f in fields(SolverConfig)]
    for key in overrides:
        if key not in names:
            near = difflib.get_close_matches(key, names, n=1)
            hint = f" (did you mean {near[0]!r}?)" if near else f"; settings: {', '.join(names)}"
            raise ConfigError(f"unknown solver setting {key!r}{hint}")
    return replace(PRESETS[preset], **{k: v for k, v in overrides.items() if v is not None})


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
