"""Texture-aware albedo and emission of a piece: the base-colour and
emissive textures averaged over the piece, not one sample (docs/design.md
section 2); for a masked material, over the piece's points that are not
cut out, and the share of them that are not (its coverage)."""
import math
from collections import namedtuple

import numpy as np
from numba import njit, prange

from ..kernels.bvh import PASS_MASK
from ..kernels.traverse import cut_out
from ..scene.surfaces import albedo_at, emission_at
from .clip import side_axis

# traverse.cut_out's tables in scene triangle order (scene/bvh.ray_passes with the identity order)
MaskArrays = namedtuple("MaskArrays", ["tri_pass", "tri_mat", "tri_uv", "mask_offset", "mask_size", "mask_alpha",
                                       "mask_cutoff", "mask_data"])


def mask_arrays(scene) -> MaskArrays:
    from ..scene.bvh import ray_passes
    return MaskArrays(*ray_passes(scene, np.arange(len(scene.triangles)))[:8])


@njit(cache=True, inline="always")
def r2_point(si, cell, origin, h, v0, nrm, k, d, a11, a12, a21, a22, det, q):
    """The si-th point of a piece, into q (3,): the R2 low-discrepancy
    sequence (Roberts 2018; a regular grid aliases with regular textures)
    over the face of the piece's `cell` across the triangle's dominant
    axis k, projected on the triangle's plane (normal nrm, n.x = d, corner
    v0; a.. and det its edges' 2x2 projection along k); its barycentrics
    (b1, b2) and whether it lies inside both the triangle and the cell."""
    ia, ja = (k + 1) % 3, (k + 2) % 3
    ra = 0.5 + si * 0.7548776662466927
    rb = 0.5 + si * 0.5698402909980532
    ra -= math.floor(ra)
    rb -= math.floor(rb)
    q[ia] = origin[ia] + (cell[ia] + ra) * h
    q[ja] = origin[ja] + (cell[ja] + rb) * h
    q[k] = (d - nrm[ia] * q[ia] - nrm[ja] * q[ja]) / nrm[k]
    ck = (q[k] - origin[k]) / h - cell[k]
    if ck < 0.0 or ck > 1.0:
        return 0.0, 0.0, False
    ri, rj = q[ia] - v0[ia], q[ja] - v0[ja]
    b1 = (ri * a22 - rj * a12) / det
    b2 = (a11 * rj - a21 * ri) / det
    return b1, b2, b1 >= 0.0 and b2 >= 0.0 and b1 + b2 <= 1.0


@njit(cache=True, parallel=True)
def textured_albedo(surf, masks, corners, piece_tri, piece_cell, origin, h, samples):
    """Albedo (n, 3) of each piece averaged over the piece (docs/design.md
    section 2: texture-aware, not one sample), its coverage (n,): the
    share of its points a mask does not cut out (the albedo is the mean
    over the points that are not), and its emitted radiance L_e (n, 3)
    averaged the same way.
    samples^2 points of the R2 low-discrepancy sequence (Roberts 2018; a
    regular grid aliases with regular textures) over the cell's face
    across the triangle's dominant axis, projected on the triangle's
    plane, keeping the points inside both the triangle and the cell."""
    n = piece_tri.shape[0]
    out = np.zeros((n, 3))
    emit = np.zeros((n, 3))
    coverage = np.ones(n)
    for p in prange(n):
        t = piece_tri[p]
        v0 = corners[t, 0]
        e1 = corners[t, 1] - v0
        e2 = corners[t, 2] - v0
        nx, ny, nz = e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]
        nrm = np.array([nx, ny, nz])
        k = side_axis(nrm)
        ia, ja = (k + 1) % 3, (k + 2) % 3
        d = nrm[0] * v0[0] + nrm[1] * v0[1] + nrm[2] * v0[2]
        # barycentric solve in the projection along k
        a11, a12, a21, a22 = e1[ia], e2[ia], e1[ja], e2[ja]
        det = a11 * a22 - a12 * a21
        sr = sg = sb = 0.0
        er = eg = eb = 0.0
        cnt = 0
        hold = 0
        masked = masks.tri_pass[t] == PASS_MASK
        q = np.empty(3)
        for si in range(samples * samples):
            b1, b2, ok = r2_point(si, piece_cell[p], origin, h, v0, nrm, k, d, a11, a12, a21, a22, det, q)
            if not ok:
                continue
            cnt += 1
            if masked and cut_out(masks, t, b1, b2):
                continue
            r, g, b = albedo_at(surf, t, b1, b2)
            sr += r
            sg += g
            sb += b
            r, g, b = emission_at(surf, t, b1, b2)
            er += r
            eg += g
            eb += b
            hold += 1
        if cnt == 0:  # a sliver between the sample points: the triangle's centre
            cnt = 1
            if not (masked and cut_out(masks, t, 1.0 / 3.0, 1.0 / 3.0)):
                sr, sg, sb = albedo_at(surf, t, 1.0 / 3.0, 1.0 / 3.0)
                er, eg, eb = emission_at(surf, t, 1.0 / 3.0, 1.0 / 3.0)
                hold = 1
        if hold == 0:  # all cut out (the piece is left out of the voxels): the centre's albedo
            sr, sg, sb = albedo_at(surf, t, 1.0 / 3.0, 1.0 / 3.0)
            er, eg, eb = emission_at(surf, t, 1.0 / 3.0, 1.0 / 3.0)
        k = 1.0 / max(hold, 1)
        out[p, 0], out[p, 1], out[p, 2] = sr * k, sg * k, sb * k
        emit[p, 0], emit[p, 1], emit[p, 2] = er * k, eg * k, eb * k
        coverage[p] = hold / cnt
    return out, coverage, emit
