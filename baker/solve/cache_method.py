"""The cache method (docs/design.md section 5): photons -> bounces -> solution.

    current = B_1 = rho H_1;  H = H_1
    for k = 2, 3, ...:  H_k = propagate(current, D_{r_k});  H += H_k;  current = rho H_k
    stop when power(current) < tolerance * power(B_1), or at the bounce cap.

Only the newly arrived light is propagated, with about half the directions
of the previous bounce (or, with config.gather_rays, gathered at each
voxel by about half the rays of the previous bounce: solve/gather.py);
emitters' own E is never propagated (the photons carried it). B_ind = rho H is the light that bounced at least once; the
outgoing radiosity is B = E + rho H.
"""
from __future__ import annotations

from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np

from ..config import SolverConfig, threads
from ..progress import bar
from ..scene.prepared import prepare
from ..stats import Stats, release_freed_memory
from ..voxels import Voxels, resolution_for, voxelize
from .smoothing import pool_parents, smooth_photons
from .directions import direction_set
from .gather import GatherVoxels, gather_voxels, rays_for_bounce
from .photons import shoot_photons
from .propagate import LineSweeper


@dataclass(frozen=True)
class Solution:
    """voxels; irradiance H (n, 3) (all bounces that arrived, float64);
    radiosity B = E + rho H (n, 3); photon_power (n, 3) deposited by the
    first bounce and photon_centroid (n, 3) (power-weighted, the area
    centroid where no photon landed); bounce_power the power of each
    bounce's newly arrived radiosity; radii per propagated bounce; info."""
    voxels: Voxels
    irradiance: np.ndarray
    radiosity: np.ndarray
    photon_power: np.ndarray
    photon_centroid: np.ndarray
    bounce_power: list
    radii: list
    stop_reason: str
    info: dict = field(default_factory=dict)

    @property
    def bounces(self) -> int:
        """Bounces computed, the photon bounce included."""
        return len(self.bounce_power)

    @property
    def radiance(self) -> np.ndarray:
        """Outgoing radiance B / pi (n, 3)."""
        return self.radiosity / np.pi

    def summary(self) -> str:
        i = self.info
        return (f"voxels {len(self.voxels)} (cell {self.voxels.cell_size:.4g})  photons {i.get('photons', 0)} "
                f"({i.get('photons_landed', 0)} landed)  bounces {self.bounces} (stopped: {self.stop_reason})  "
                + (f"gather rays/bounce {i['gather_rays_per_bounce']}  gather rays {i.get('gather_rays', 0):.4g}"
                   if i.get("gather_rays_per_bounce") else
                   f"directions/bounce {i.get('directions_per_bounce', [])}  "
                   f"discrete rays {i.get('discrete_rays', 0):.4g}"))


MIN_POOL_AREA = 0.25  # in cells^2: smaller voxels pool their photons with a neighbour
MAX_TAIL_RATIO = 0.95  # the extrapolated tail's ratio at most: 19 times the last bounce


def first_bounce_irradiance(vox, deposited, photon_lum=0.0, smoothing=0.0, bvh=None):
    """H_1 = deposited power / area (n, 3).

    With smoothing k > 0 (and photons of luminance photon_lum): each voxel
    pools its photons with the neighbours on its surface that agree with
    it within k standard deviations of the photon noise
    (solve/smoothing.py: smooth_photons; bvh: the scene's, to see that nothing
    stands between them). Then a voxel under a quarter cell takes the
    pooled estimate (P + P_parent) / (A + A_parent) of itself and its
    largest neighbour on the same surface (photon noise scales as
    1 / sqrt(area): slivers would be spikes), P_parent the parent's
    smoothed estimate times its area where smoothing is on."""
    smoothed = smoothing > 0 and photon_lum > 0 and bvh is not None
    if smoothed:
        h1 = smooth_photons(bvh.arrays, vox.key, vox.cell, vox.centroid, vox.normal, vox.area, vox.dims,
                            vox.cell_size, np.ascontiguousarray(deposited, np.float64), float(photon_lum),
                            float(smoothing), vox.cut_plane, vox.cut_sign, vox.origin)
    else:
        h1 = deposited / vox.area[:, None]
    parent = pool_parents(vox.key, vox.cell, vox.centroid, vox.normal, vox.area, vox.dims,
                          vox.cell_size, MIN_POOL_AREA * vox.cell_size ** 2, vox.cut_plane, vox.cut_sign, vox.origin)
    tiny = np.nonzero(parent >= 0)[0]
    if len(tiny):
        # smoothed, a sliver's few photons may disagree with every neighbour by more than the test allows (a
        # 0.01-cell^2 corner piece of the furnace sphere read 0.87): it pools with its parent's smoothed estimate
        p = parent[tiny]
        parent_power = (h1[p] * vox.area[p][:, None]) if smoothed else deposited[p]
        h1[tiny] = (deposited[tiny] + parent_power) / (vox.area[tiny] + vox.area[p])[:, None]
    return h1


@contextmanager
def _bouncing(prepared, vox, gathered: bool, executor=None):
    """(LineSweeper of the voxels or None when the bounces are gathered,
    the executor's handle on what every bounce's tasks read: the
    sweeper's arrays or the gather's GatherVoxels; None without an
    executor), the handle let go after."""
    sweeper = None if gathered else LineSweeper(vox)
    release_freed_memory()
    handle = None
    if executor is not None:
        handle = executor.share(GatherVoxels.of(prepared, vox) if gathered else sweeper.shared())
    try:
        yield sweeper, handle
    finally:
        if handle is not None:
            executor.release(handle)


def solve(scene, config: SolverConfig, stats: Stats | None = None, bvh=None, surfaces=None, progress=False,
          keep_bounces=False, executor=None) -> Solution:
    """Scene (or a Prepared: scene/prepared.py) -> Solution by photons and
    linear propagation (the cache method), with config.threads worker
    threads (the process's setting is put back after); the photon blocks
    and the propagation's blocks of directions on `executor`
    (bake/executor.py; None: in this process, the same sums)."""
    with threads(config.threads):
        return _solve(scene, config, stats or Stats("solve"), bvh, surfaces, progress, keep_bounces, executor)


def _solve(scene, config, stats, bvh, surfaces, progress, keep_bounces, executor):
    with stats.stage("bvh"):
        prepared = prepare(scene, bvh, surfaces)
    scene, bvh, surfaces = prepared.scene, prepared.bvh, prepared.surfaces
    with stats.stage("voxelize"):
        vox = voxelize(scene, resolution_for(scene, config), config.cell_size, config.memory_budget_mb, surfaces,
                       bvh, executor)
        release_freed_memory()
    n = len(vox)
    n_photons = config.photon_count(n)
    with stats.stage("photons"), bar(n_photons, "photons", "photon", progress) as pbar:
        dep, pcen, landed, emitted = shoot_photons(scene, surfaces, bvh, vox, n_photons, config.seed,
                                                   pbar.update, executor)
        release_freed_memory()
    area = vox.area[:, None]
    h1 = first_bounce_irradiance(vox, dep, float(np.sum(emitted)) / max(n_photons, 1), config.photon_smoothing, bvh)
    lum = dep.sum(axis=1)
    centroid = np.where(lum[:, None] > 0, pcen / np.where(lum > 0, lum, 1.0)[:, None], vox.centroid)
    del pcen, lum  # (n, 3) arrays the propagation does not need: less peak memory
    current = vox.albedo * h1
    history = [h1] if keep_bounces else None
    total = h1.copy() if keep_bounces else h1  # H accumulates in place
    del h1
    p1 = float((current * area).sum())
    bounce_power = [p1]
    radii_used, directions, per_bounce = [], [], []
    rays = gather_rays = 0
    if p1 > 0:
        stop = f"bounce cap ({config.max_bounces})"
    elif landed and float(dep.sum()) > 0:
        stop = "nothing reflected (albedo 0 wherever the light landed)"
    else:
        stop = "no light reached a surface"
    if p1 > 0 and config.max_bounces > 1:
        radii = config.radii()
        gathered = config.gather_rays > 0
        with stats.stage("propagation"), bar(len(radii), "bounces", "bounce", progress) as bbar, \
                _bouncing(prepared, vox, gathered, executor) as (sweeper, shared):
            cache = {}
            targets = {}   # the gather's rays' voxels, once the bounces' rays stop changing (gather_voxels)
            for k, r in enumerate(radii, start=2):
                if gathered:
                    g = rays_for_bounce(config.gather_rays, k)
                    hk = gather_voxels(prepared, vox, current, g, targets, executor, shared, k)
                    gather_rays += n * g
                    per_bounce.append(g)
                else:
                    dirs = cache.get(r) or cache.setdefault(r, direction_set(r))
                    hk = sweeper.irradiance(current, dirs, sweeper.offsets(dirs, config.seed, k), executor, shared, k)
                    rays += n * dirs.n_directions
                    radii_used.append(r)
                    directions.append(dirs.n_directions)
                total += hk
                np.multiply(vox.albedo, hk, out=current)  # in place: no second (n, 3) array
                pk = float((current * area).sum())
                bounce_power.append(pk)
                if keep_bounces:
                    history.append(hk)
                bbar.update(1)
                bbar.set_postfix(new=f"{pk / p1:.2e}")
                if pk <= config.tolerance * p1:
                    stop = f"tolerance ({pk / p1:.2e} <= {config.tolerance:g} of the first bounce)"
                    q = pk / bounce_power[-2] if bounce_power[-2] > 0 else 0.0
                    if 0.0 < q < 1.0:
                        # the bounces not propagated, as the geometric series of the last two: by then each
                        # bounce is the one before times the scene's mean reflectance, near enough
                        q = min(q, MAX_TAIL_RATIO)
                        total += hk * (q / (1.0 - q))
                        stop += f", the rest extrapolated (ratio {q:.3f})"
                    break
    elif p1 > 0:
        stop = "bounce cap (1)"
    radiosity = vox.emission + vox.albedo * total
    info = {"photons": int(n_photons), "photons_landed": landed, "emitted_power": emitted.tolist(),
            "discrete_rays": int(rays), "voxels": n, "cell_size": vox.cell_size,
            "directions_per_bounce": directions, "gather_rays": int(gather_rays),
            "gather_rays_per_bounce": per_bounce, "bounces": len(bounce_power),
            "stop_reason": stop, "voxel_bytes": vox.nbytes}
    if keep_bounces:
        info["history"] = history
    stats.count(**{k: v for k, v in info.items() if k != "history"})
    return Solution(vox, total, radiosity, dep, centroid, bounce_power, radii_used, stop, info)
