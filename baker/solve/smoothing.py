"""The first bounce's photon estimate, pooled over a surface: a voxel
with little area joins a neighbour on its surface (pool_parents), and a
voxel's photons are pooled with the neighbours on its surface that agree
with it within the photon noise (smooth_photons); docs/design.md
section 5."""
import math

import numpy as np
from numba import njit, prange

from ..kernels.bvh import STACK_SIZE
from ..kernels.traverse import any_hit
from ..voxels.lookup import _neighbour_key, _same_surface


@njit(cache=True, parallel=True)
def pool_parents(vkey, vcell, vcentroid, vnormal, varea, dims, h, min_area, cut_plane, cut_sign, origin):
    """For each voxel smaller than min_area: the largest voxel of the same
    surface around it (normals within ~25 degrees, of any facing: a curved
    surface's voxels of two facings share a cell; planes within h / 4, in
    its cell or the 26 neighbours, on the same side of any surface cutting
    either one's cell), else -1. Photon
    estimates of tiny voxels (a triangle grazing a cell corner) are pooled
    with it: one photon in a 1e-6-cell sliver would otherwise be a spike.
    The 25 degrees are PARALLEL_COS, the h / 4 is POOL_PLANE (in cells)."""
    n = vkey.shape[0]
    parent = np.full(n, -1, np.int64)
    for i in prange(n):
        if varea[i] >= min_area:
            continue
        best, best_a = -1, 0.0
        for d0 in range(-1, 2):
            for d1 in range(-1, 2):
                for d2 in range(-1, 2):
                    key = _neighbour_key(vcell, i, d0, d1, d2, dims)
                    if key < 0:
                        continue
                    lo = np.searchsorted(vkey, key)
                    while lo < n and vkey[lo] == key:
                        j = lo
                        lo += 1
                        if j == i or varea[j] <= best_a or varea[j] <= varea[i]:
                            continue
                        if _same_surface(i, j, vcell, vcentroid, vnormal, cut_plane, cut_sign, origin, h):
                            best, best_a = j, varea[j]
        parent[i] = best
    return parent


@njit(cache=True, inline="always")
def _clear(bvh, stack, vcentroid, vnormal, i, j, lift):
    """Nothing between voxels i's and j's centroids, each lifted off its surface."""
    ox, oy, oz = vcentroid[i, 0] + lift * vnormal[i, 0], vcentroid[i, 1] + lift * vnormal[i, 1], \
        vcentroid[i, 2] + lift * vnormal[i, 2]
    ex, ey, ez = vcentroid[j, 0] + lift * vnormal[j, 0] - ox, vcentroid[j, 1] + lift * vnormal[j, 1] - oy, \
        vcentroid[j, 2] + lift * vnormal[j, 2] - oz
    d = math.sqrt(ex * ex + ey * ey + ez * ez)
    if d <= 0.0:
        return True
    return not any_hit(bvh, stack, ox, oy, oz, ex / d, ey / d, ez / d, 0.0, d)


@njit(cache=True, parallel=True)
def smooth_photons(bvh, vkey, vcell, vcentroid, vnormal, varea, dims, h, deposited, photon_lum, k, cut_plane,
                   cut_sign, origin):
    """Each voxel's photon estimate pooled with its neighbours on the same
    surface (the 26 cells around it; normals within ~25 degrees, planes
    within h / 4, on the same side of any surface cutting either cell, and
    nothing between their centroids lifted h / 10 off the surface: a wall
    standing on a floor, or a box resting on it, separates the floor's
    voxels on its two sides) whose estimate agrees with its own within k standard deviations of the
    photon noise: H_i = (P_i + sum P_j) / (A_i + sum A_j), (n, 3).

    The noise of an estimate P / A from photons of luminance photon_lum
    has variance photon_lum * lum(P) / A^2 (Poisson); the test takes both
    variances at the larger of the two rates (a sliver that caught 10
    photons where 21 were due is 3.6 of its own deviations low, but 2.4 of
    the expected ones), floored at one photon's worth so that an empty
    voxel agrees with a neighbour that caught one or two. A shadow edge, where neighbours differ by more than
    the noise, stays sharp; on an evenly lit surface a voxel averages with
    up to 8 neighbours (the photon noise falls about 3x). Each voxel reads
    the unpooled estimates only: the result does not depend on the order
    or the thread count."""
    n = vkey.shape[0]
    out = np.empty((n, 3))
    lift = 0.1 * h
    for i in prange(n):
        stack = np.empty(STACK_SIZE, np.int32)
        li = deposited[i, 0] + deposited[i, 1] + deposited[i, 2]
        hi = li / varea[i]
        p0, p1, p2, a = deposited[i, 0], deposited[i, 1], deposited[i, 2], varea[i]
        for d0 in range(-1, 2):
            for d1 in range(-1, 2):
                for d2 in range(-1, 2):
                    key = _neighbour_key(vcell, i, d0, d1, d2, dims)
                    if key < 0:
                        continue
                    j = np.searchsorted(vkey, key)
                    while j < n and vkey[j] == key:
                        if j != i:
                            if _same_surface(i, j, vcell, vcentroid, vnormal, cut_plane, cut_sign, origin, h):
                                lj = deposited[j, 0] + deposited[j, 1] + deposited[j, 2]
                                hj = lj / varea[j]
                                # both counts' Poisson variance at the larger rate (what a sparse count of
                                # a small voxel should be tested against), floored at one photon
                                hm = max(hi, hj)
                                vi = photon_lum * max(hm * varea[i], photon_lum) / (varea[i] * varea[i])
                                vj = photon_lum * max(hm * varea[j], photon_lum) / (varea[j] * varea[j])
                                if (hi - hj) ** 2 <= k * k * (vi + vj) and \
                                        _clear(bvh, stack, vcentroid, vnormal, i, j, lift):
                                    p0 += deposited[j, 0]
                                    p1 += deposited[j, 1]
                                    p2 += deposited[j, 2]
                                    a += varea[j]
                        j += 1
        out[i, 0] = p0 / a
        out[i, 1] = p1 / a
        out[i, 2] = p2 / a
    return out
