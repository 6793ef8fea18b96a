"""The preview tier's texel values: the voxel solution's irradiance H
reconstructed at a texel's sample point (docs/design.md section 8).

A voxel holds one value for its whole piece of surface; showing that value
per texel would show the voxels as blotches. The texel's value is instead a
weighted mean over the voxels of the same surface around its point p:

    H(p) = sum_j w_j H_j / sum_j w_j,
    w_j  = prod over axes a of max(0, 1 - |c_j - p|_a / h)  (a tent over the
           voxel centroids c_j, one cell wide) x min(1, A_j / (A_MIN h^2))

over the voxels j in the 27 cells around p that lie on p's surface and
side: normal within 45 degrees of the texel's side normal (SMOOTH_COS),
centroid within PLANE_REACH cells of p's plane, on p's side of any surface
that cut either voxel's cell, and joined to p by a segment (both ends
lifted `offset` off the surface) that no triangle blocks. The last two
keep light from crossing a wall: a floor texel beside a wall never mixes
in the floor on the wall's other side. Slivers (A_j small) weigh little:
their photon estimates are the noisiest. The tent is continuous in p, so
the texels are smooth across voxel boundaries; where no neighbour
qualifies, p's own voxel (`voxel_of_hit`) gives the value.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ..kernels.bvh import STACK_SIZE
from ..kernels.traverse import any_hit
from ..voxels.lookup import voxel_of_hit
from ..voxels.tolerances import SMOOTH_COS
from .texels import CHUNK, side_normal

PLANE_REACH = 0.5   # cells: neighbour centroids further off p's plane are another surface
A_MIN = 0.25        # cells^2: voxels smaller than this weigh in proportion to their area


@njit(cache=True, inline="always")
def _on_side(v, px, py, pz, cell, cut_plane, cut_sign, origin, h):
    """Does point p lie on voxel v's side of the surface that cut its cell?"""
    if cut_sign[v] == 0:
        return True
    s = 0.0
    g = (px, py, pz)
    for a in range(3):
        s += ((g[a] - origin[a]) / h - cell[v, a]) * cut_plane[v, a]
    s -= cut_plane[v, 3]
    return (s >= 0.0) == (cut_sign[v] > 0)


@njit(cache=True, parallel=True)
def reconstruct(bvh, corners, texel_tri, texel_back, point, covered, irradiance, voxels, pieces, offset):
    """H (N, 3) float64 at every covered texel (sampling triangle
    texel_tri[k], its back if texel_back[k]); found (N,) bool (False: no
    voxel holds the point's side, the value is 0). voxels: VoxelArrays,
    pieces: PieceLookup (Voxels.arrays(), .lookup())."""
    vkey, vcell, vcentroid, vnormal, varea = voxels.key, voxels.cell, voxels.centroid, voxels.normal, voxels.area
    cut_plane, cut_sign, origin, h, dims = voxels.cut_plane, voxels.cut_sign, pieces.origin, pieces.h, pieces.dims
    total = point.shape[0]
    out = np.zeros((total, 3))
    found = np.zeros(total, np.bool_)
    nv = vkey.shape[0]
    a_min = A_MIN * h * h
    for ch in prange((total + CHUNK - 1) // CHUNK):
        stack = np.empty(STACK_SIZE, np.int32)
        for k in range(ch * CHUNK, min(total, (ch + 1) * CHUNK)):
            t = texel_tri[k]
            if not covered[k] or t < 0:
                continue
            back = texel_back[k]
            nx, ny, nz = side_normal(corners, t, back)
            px, py, pz = point[k, 0], point[k, 1], point[k, 2]
            home = voxel_of_hit(t, back, px, py, pz, pieces)
            if home < 0:
                continue
            found[k] = True
            ox, oy, oz = px + offset * nx, py + offset * ny, pz + offset * nz
            c0 = int(math.floor((px - origin[0]) / h))
            c1 = int(math.floor((py - origin[1]) / h))
            c2 = int(math.floor((pz - origin[2]) / h))
            s0 = s1 = s2 = 0.0
            sw = 0.0
            for d0 in range(-1, 2):
                for d1 in range(-1, 2):
                    for d2 in range(-1, 2):
                        x, y, z = c0 + d0, c1 + d1, c2 + d2
                        if x < 0 or y < 0 or z < 0 or x >= dims[0] or y >= dims[1] or z >= dims[2]:
                            continue
                        key = (np.int64(x) * dims[1] + y) * dims[2] + z
                        j = np.searchsorted(vkey, key)
                        while j < nv and vkey[j] == key:
                            v = j
                            j += 1
                            ex = vcentroid[v, 0] - px
                            ey = vcentroid[v, 1] - py
                            ez = vcentroid[v, 2] - pz
                            w = (max(0.0, 1.0 - abs(ex) / h) * max(0.0, 1.0 - abs(ey) / h) *
                                 max(0.0, 1.0 - abs(ez) / h))
                            if w <= 0.0:
                                continue
                            if v != home:
                                if vnormal[v, 0] * nx + vnormal[v, 1] * ny + vnormal[v, 2] * nz < SMOOTH_COS:
                                    continue
                                if abs(ex * nx + ey * ny + ez * nz) > PLANE_REACH * h:
                                    continue
                                if not _on_side(v, px, py, pz, vcell, cut_plane, cut_sign, origin, h):
                                    continue
                                if not _on_side(home, vcentroid[v, 0], vcentroid[v, 1], vcentroid[v, 2], vcell,
                                                cut_plane, cut_sign, origin, h):
                                    continue
                                # p lifted along its normal to c_j lifted along its own: the segment stays
                                # off a convex surface curving between them
                                fx = ex + offset * (vnormal[v, 0] - nx)
                                fy = ey + offset * (vnormal[v, 1] - ny)
                                fz = ez + offset * (vnormal[v, 2] - nz)
                                dist = math.sqrt(fx * fx + fy * fy + fz * fz)
                                if dist > 0.0 and any_hit(bvh, stack, ox, oy, oz, fx / dist, fy / dist, fz / dist,
                                                          0.0, dist):
                                    continue
                            w *= min(1.0, varea[v] / a_min)
                            s0 += w * irradiance[v, 0]
                            s1 += w * irradiance[v, 1]
                            s2 += w * irradiance[v, 2]
                            sw += w
            if sw > 0.0:
                out[k, 0], out[k, 1], out[k, 2] = s0 / sw, s1 / sw, s2 / sw
            else:
                out[k, 0], out[k, 1], out[k, 2] = irradiance[home, 0], irradiance[home, 1], irradiance[home, 2]
    return out, found
