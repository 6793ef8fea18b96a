"""Visibility audit (docs/design.md section 4): how often does the discrete
first voxel I(x, s) of the linear method differ from the first surface a
continuous ray from x's centroid along s hits (through the BVH)?

For a sample of families, the propagation runs once with "radiosity" =
voxel index + 1: a voxel gathers at most once per direction, so
gathered / S recovers exactly which voxel it saw (or none). The same
voxels then cast continuous rays. Agreement: the same voxel, a voxel of
the same facing within 2 cells (the digital line is a cell thick), or
nothing on both sides (an escape, or the back of a one-sided surface).
The rate is cosine-weighted, like the light it would carry.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..kernels.rng import STREAM_AUDIT_FAMILIES, STREAM_AUDIT_VOXELS, rand01
from ..startup import checkpoint
from .directions import DirectionSet, direction_set
from .propagate import TAU, LineSweeper


@dataclass(frozen=True)
class AuditReport:
    pairs: int               # (voxel, direction) pairs compared
    disagreement: float      # cos-weighted fraction of pairs that disagree
    sees_through: float      # the line sees beyond the ray's first surface (leak-like)
    misses: float            # the line stops well before the ray's first front face (occlusion-like)
    other_surface: float     # the voxel seen is over 2 cells to the side of the ray
    worst: list              # up to 10 (voxel centroid, direction, kind) examples
    blind: float = 0.0       # of misses: the line sees nothing where the ray meets a front face (light lost)

    def summary(self) -> str:
        return (f"visibility audit: {self.pairs} (voxel, direction) pairs, cos-weighted disagreement "
                f"{100 * self.disagreement:.2f}% (sees through {100 * self.sees_through:.2f}%, "
                f"misses {100 * self.misses:.2f}% of which blind {100 * self.blind:.2f}%, off the ray {100 * self.other_surface:.2f}%)")


def _single_family(dirs: DirectionSet, f: int) -> DirectionSet:
    return DirectionSet(dirs.radius, dirs.vectors[f:f + 1], dirs.axis[f:f + 1], dirs.unit[f:f + 1],
                        dirs.solid_angle[f:f + 1])


def discrete_sources(sweeper: LineSweeper, dirs: DirectionSet, f: int, seed: int = 0):
    """For family f: (source (n,) int64: the voxel each voxel saw along the
    direction it faces, -1 for none; sign (n,) +1 / -1 / 0: which of s, -s
    it looks along (0: parallel))."""
    one = _single_family(dirs, f)
    n = sweeper.n
    rad = np.zeros((n, 3))
    rad[:, 0] = np.arange(1, n + 1, dtype=np.float64)
    g, s = sweeper.gather(rad, one, sweeper.offsets(dirs, seed, 2)[f:f + 1])
    src = np.full(n, -1, np.int64)
    ok = s > 0
    src[ok] = np.rint(g[ok, 0] / s[ok]).astype(np.int64) - 1
    cos = sweeper.normal.astype(np.float64) @ one.unit[0]
    return src, np.sign(cos).astype(np.int64), s


def audit(scene, voxels, bvh, surfaces, radius: int = 4, families: int = 16, samples: int = 4000,
          seed: int = 0) -> AuditReport:
    """Compares I(x, s) with continuous rays for `samples` voxels of each of
    `families` families of D_radius (seeded)."""
    sweeper = LineSweeper(voxels)
    dirs = direction_set(radius)
    h = voxels.cell_size
    eps = 1e-6 * float(np.abs(scene.vertices).max() or 1.0)
    fam = sorted({int(rand01(seed, STREAM_AUDIT_FAMILIES, i) * dirs.n_families) for i in range(families)})
    totals = np.zeros(5)  # weight: all, sees through, misses, other surface, blind
    worst, pairs = [], 0
    double = scene.double_sided[scene.material_ids]
    for f in fam:
        checkpoint()
        src, sgn, weight = discrete_sources(sweeper, dirs, f, seed)
        cand = np.nonzero(weight > 0)[0]
        if len(cand) == 0:
            continue
        pick = cand[(np.array([rand01(seed, STREAM_AUDIT_VOXELS + f, i) for i in range(min(samples, len(cand)))]) *
                     len(cand)).astype(np.int64)]
        u = dirs.unit[f][None, :] * sgn[pick, None]
        # the ray starts tau in front of the centroid: on a curved surface the centroid of a
        # cell's piece lies behind the surface (by the sagitta), and a ray from there would
        # meet the surface's own back at once (the discrete rule allows the same tau)
        o = voxels.centroid[pick] + voxels.normal[pick] * max(eps, TAU * h)
        t, tri, _, _ = bvh.closest(o, u)
        corners = surfaces.arrays.corners
        back = np.zeros(len(pick), bool)
        hit_tri = tri >= 0
        c = corners[tri[hit_tri]]
        nt = np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0])
        back[hit_tri] = np.einsum("ij,ij->i", nt, u[hit_tri]) > 0
        front_hit = hit_tri & ~(back & ~double[np.maximum(tri, 0)])
        d = src[pick]
        w = weight[pick]
        seen = d >= 0
        rel = voxels.centroid[np.maximum(d, 0)] - o
        t_src = np.einsum("ij,ij->i", rel, u)
        lateral = np.linalg.norm(rel - t_src[:, None] * u, axis=1)
        t_c = np.where(hit_tri, t, np.inf)
        off = seen & (lateral > 2 * h)
        through = seen & ~off & (t_src > t_c + 2 * h)
        missed = (seen & ~off & (t_src < t_c - 2 * h)) | (~seen & front_hit)
        other = off
        agree = ~(through | missed | other)
        totals += [w.sum(), w[through].sum(), w[missed].sum(), w[other].sum(), w[~seen & front_hit].sum()]
        pairs += len(pick)
        for k in np.nonzero(~agree)[0][:2]:
            if len(worst) < 10:
                kind = "sees through" if through[k] else ("misses" if missed[k] else "other surface")
                worst.append((voxels.centroid[pick[k]].round(4).tolist(), u[k].round(3).tolist(), kind))
    if totals[0] == 0:
        return AuditReport(pairs, 0.0, 0.0, 0.0, 0.0, worst, 0.0)
    r = totals[1:] / totals[0]
    return AuditReport(pairs, float(r[:3].sum()), float(r[0]), float(r[1]), float(r[2]), worst, float(r[3]))
