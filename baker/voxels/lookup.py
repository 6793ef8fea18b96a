"""Which voxel holds a surface point (photon deposits, the voxel view), and
which neighbour a tiny voxel pools its photons with."""
import math

import numpy as np
from numba import njit, prange

from ..kernels.bvh import STACK_SIZE
from ..kernels.traverse import any_hit
from .tolerances import PARALLEL_COS

POOL_PLANE = 0.25  # cells: a neighbour's plane within this is the same surface for pooling


@njit(cache=True)
def voxel_of_hit(tri, back, px, py, pz, piece_key, piece_voxel, piece_plane, piece_sign, side_start, back_side,
                 origin, h, dims):
    """Voxel holding the point p that a ray hit on scene triangle `tri`
    (its back side if `back`): the voxel of that side's piece in p's cell
    (of the part on p's side, where another surface's plane cut the piece).
    A point on a cell face may round into a neighbour holding no piece of
    this side: then the side's piece in the nearest of the 26 neighbours.
    -1 for the back of a one-sided triangle."""
    s = back_side[tri] if back else tri
    if s < 0:
        return -1
    a, b = side_start[s], side_start[s + 1]
    c0 = int(math.floor((px - origin[0]) / h))
    c1 = int(math.floor((py - origin[1]) / h))
    c2 = int(math.floor((pz - origin[2]) / h))
    best, best_d = -1, np.inf
    for ring in range(2):
        for d0 in range(-ring, ring + 1):
            for d1 in range(-ring, ring + 1):
                for d2 in range(-ring, ring + 1):
                    x, y, z = c0 + d0, c1 + d1, c2 + d2
                    if x < 0 or y < 0 or z < 0 or x >= dims[0] or y >= dims[1] or z >= dims[2]:
                        continue
                    key = (np.int64(x) * dims[1] + y) * dims[2] + z
                    i = a + np.searchsorted(piece_key[a:b], key)
                    if i < b and piece_key[i] == key:
                        if piece_sign[i] != 0:
                            # a cut piece: its two parts are i and i + 1; take p's side
                            gx, gy, gz = (px - origin[0]) / h, (py - origin[1]) / h, (pz - origin[2]) / h
                            pl = piece_plane[i]  # offset relative to the cell (x, y, z)
                            side = 1 if (gx - x) * pl[0] + (gy - y) * pl[1] + (gz - z) * pl[2] - pl[3] >= 0.0 else -1
                            if piece_sign[i] != side and i + 1 < b and piece_key[i + 1] == key:
                                i += 1
                        if ring == 0:
                            return piece_voxel[i]
                        dd = ((x + 0.5) * h + origin[0] - px) ** 2 + ((y + 0.5) * h + origin[1] - py) ** 2 + \
                            ((z + 0.5) * h + origin[2] - pz) ** 2
                        if dd < best_d:
                            best, best_d = piece_voxel[i], dd
    return best


@njit(cache=True, inline="always")
def _same_side(a, b, vcell, vcentroid, cut_plane, cut_sign, origin, h):
    """Does b lie on a's side of the surface that cut a's cell (if any)?"""
    if cut_sign[a] == 0:
        return True
    s = 0.0
    for c in range(3):
        s += ((vcentroid[b, c] - origin[c]) / h - vcell[a, c]) * cut_plane[a, c]
    s -= cut_plane[a, 3]
    return (s >= 0.0) == (cut_sign[a] > 0)


@njit(cache=True, inline="always")
def _neighbour_key(vcell, i, d0, d1, d2, dims):
    """Key of the cell at offset (d0, d1, d2) from voxel i's, -1 outside the grid."""
    x, y, z = vcell[i, 0] + d0, vcell[i, 1] + d1, vcell[i, 2] + d2
    if x < 0 or y < 0 or z < 0 or x >= dims[0] or y >= dims[1] or z >= dims[2]:
        return np.int64(-1)
    return (np.int64(x) * dims[1] + y) * dims[2] + z


@njit(cache=True, inline="always")
def _same_surface(i, j, vcell, vcentroid, vnormal, cut_plane, cut_sign, origin, h):
    """Voxels i and j on one surface: normals within PARALLEL_COS, j's plane
    within POOL_PLANE cells of i's centroid, each on the other's side of
    any surface cutting its cell."""
    cos = vnormal[i, 0] * vnormal[j, 0] + vnormal[i, 1] * vnormal[j, 1] + vnormal[i, 2] * vnormal[j, 2]
    plane = (vcentroid[i, 0] - vcentroid[j, 0]) * vnormal[j, 0] + \
        (vcentroid[i, 1] - vcentroid[j, 1]) * vnormal[j, 1] + (vcentroid[i, 2] - vcentroid[j, 2]) * vnormal[j, 2]
    return cos > PARALLEL_COS and abs(plane) < POOL_PLANE * h and \
        _same_side(i, j, vcell, vcentroid, cut_plane, cut_sign, origin, h) and \
        _same_side(j, i, vcell, vcentroid, cut_plane, cut_sign, origin, h)


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


@njit(cache=True, parallel=True)
def flat_voxels(vkey, vcell, vcentroid, vnormal, planar, dims, h, smooth_cos, flat_cos, flat_plane):
    """(n,) bool: voxels on a flat stretch of surface: planar themselves,
    and every voxel in their cell or the 26 around it whose normal is
    within smooth_cos of theirs (their surface, or one parallel to it) is
    planar too, with a normal within flat_cos and a centroid within
    flat_plane cells of their plane. A floor, a wall or a box's face is
    flat up to its edges (a wall standing on a floor is another surface);
    a tessellated sphere or a scan is not, nor a floor under a thin slab
    resting on it a fraction of a cell above."""
    n = vkey.shape[0]
    out = np.zeros(n, np.bool_)
    for i in prange(n):
        if not planar[i]:
            continue
        ok = True
        for d0 in range(-1, 2):
            for d1 in range(-1, 2):
                for d2 in range(-1, 2):
                    key = _neighbour_key(vcell, i, d0, d1, d2, dims)
                    if key < 0 or not ok:
                        continue
                    j = np.searchsorted(vkey, key)
                    while j < n and vkey[j] == key and ok:
                        if j != i:
                            cos = vnormal[i, 0] * vnormal[j, 0] + vnormal[i, 1] * vnormal[j, 1] + \
                                vnormal[i, 2] * vnormal[j, 2]
                            if cos > smooth_cos:
                                off = (vcentroid[j, 0] - vcentroid[i, 0]) * vnormal[i, 0] + \
                                    (vcentroid[j, 1] - vcentroid[i, 1]) * vnormal[i, 1] + \
                                    (vcentroid[j, 2] - vcentroid[i, 2]) * vnormal[i, 2]
                                if not planar[j] or cos < flat_cos or abs(off) > flat_plane * h:
                                    ok = False
                        j += 1
        out[i] = ok
    return out
