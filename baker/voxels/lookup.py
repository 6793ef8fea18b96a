"""Which voxel holds a surface point (photon deposits, the voxel view),
which voxels are neighbours on one surface (used by the photon pooling of
solve/smoothing.py), and which voxels are flat."""
import math

import numpy as np
from numba import njit, prange

from .tolerances import PARALLEL_COS

POOL_PLANE = 0.25  # cells: a neighbour's plane within this is the same surface for pooling


@njit(cache=True)
def voxel_of_hit(tri, back, px, py, pz, pieces):
    """Voxel holding the point p that a ray hit on scene triangle `tri`
    (its back side if `back`): the voxel of that side's piece in p's cell
    (of the part on p's side, where another surface's plane cut the piece).
    A point on a cell face may round into a neighbour holding no piece of
    this side: then the side's piece in the nearest of the 26 neighbours.
    -1 for the back of a one-sided triangle. pieces: a PieceLookup
    (Voxels.lookup())."""
    piece_key, piece_voxel, piece_plane, piece_sign = pieces.key, pieces.voxel, pieces.plane, pieces.sign
    side_start, back_side, origin, h, dims = pieces.side_start, pieces.back_side, pieces.origin, pieces.h, pieces.dims
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
