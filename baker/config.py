"""Configuration as frozen dataclasses, and the presets preview/default/high."""
from __future__ import annotations

from dataclasses import dataclass, fields, replace


@dataclass(frozen=True)
class SolverConfig:
    """Knobs of the voxel solver (METHOD.md sections 2-5).

    resolution: cells along the scene's longest axis (ignored when
        cell_size > 0, which sets the cell size in scene units).
    radius: r of the first propagated bounce's direction set D_r
        (|D_r| = 24 r^2 + 2).
    schedule: 'halving' (|D| about halved each bounce, floor r_min) or
        'constant' (same r every bounce), METHOD.md section 3.
    photons: photons shot from the emitters for the first bounce.
    tolerance: stop when the power of the newly arrived radiosity falls
        below tolerance times that of the first bounce.
    max_bounces: bounce cap (counting the photon bounce as 1).
    memory_budget_mb: refuse a voxelization estimated above this.
    """
    resolution: int = 64
    cell_size: float = 0.0
    radius: int = 8
    schedule: str = "halving"
    r_min: int = 2
    photons: int = 1_000_000
    tolerance: float = 1e-3
    max_bounces: int = 64
    seed: int = 0
    threads: int = 0
    memory_budget_mb: float = 8192.0

    def __post_init__(self):
        if self.schedule not in ("halving", "constant"):
            raise ValueError(f"schedule must be 'halving' or 'constant', not {self.schedule!r}")
        if self.resolution < 1 and self.cell_size <= 0:
            raise ValueError("resolution must be >= 1 (or give a cell size)")
        if self.radius < 1 or self.r_min < 1:
            raise ValueError("direction radius must be >= 1")
        if self.photons < 0 or self.max_bounces < 1 or self.tolerance < 0:
            raise ValueError("photons >= 0, max_bounces >= 1 and tolerance >= 0 are required")

    def radii(self) -> list:
        """r_k of bounces 2, 3, ... (METHOD.md section 3): with 'halving',
        |D_{r_k}| ~ |D_{r_0}| / 2^k, i.e. r_k ~ r_0 / sqrt(2)^k, floor r_min."""
        out = []
        for k in range(self.max_bounces - 1):
            if self.schedule == "constant":
                out.append(self.radius)
            else:
                out.append(max(self.r_min, int(round(self.radius / 2 ** (k / 2)))))
        return out


PRESETS = {
    "preview": SolverConfig(resolution=32, radius=4, photons=200_000, tolerance=1e-2, max_bounces=16),
    "default": SolverConfig(resolution=64, radius=8, photons=1_000_000, tolerance=1e-3, max_bounces=64),
    "high": SolverConfig(resolution=128, radius=12, photons=4_000_000, tolerance=1e-4, max_bounces=128),
}


def solver_config(preset: str = "default", **overrides) -> SolverConfig:
    """A preset with the given fields replaced (None values are ignored)."""
    if preset not in PRESETS:
        raise ValueError(f"unknown preset {preset!r}; choose from {', '.join(PRESETS)}")
    names = {f.name for f in fields(SolverConfig)}
    changes = {k: v for k, v in overrides.items() if v is not None and k in names}
    return replace(PRESETS[preset], **changes)
