"""The direct voxel view (the thesis's "direct voxel view"): primary rays
from the camera; each visible surface point shows its voxel's outgoing
radiance B / pi (the voxel of the hit cell whose facing matches the side
seen, nearest sheet). A look at the solution itself, not a final image.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from .kernels.traverse import STACK_SIZE, closest_hit, hit_normal
from .kernels.voxelize import facing_of
from .render import primary_ray


@njit(cache=True)
def _voxel_at(px, py, pz, f, vkey, vfacing, vcentroid, vnormal, origin, h, dims):
    """Voxel with facing f in the cell of p (nearest sheet), else in the 26
    neighbours (nearest centroid), else -1."""
    c0 = int(math.floor((px - origin[0]) / h))
    c1 = int(math.floor((py - origin[1]) / h))
    c2 = int(math.floor((pz - origin[2]) / h))
    for ring in range(2):
        best, best_d = -1, np.inf
        for d0 in range(-ring, ring + 1):
            for d1 in range(-ring, ring + 1):
                for d2 in range(-ring, ring + 1):
                    x, y, z = c0 + d0, c1 + d1, c2 + d2
                    if x < 0 or y < 0 or z < 0 or x >= dims[0] or y >= dims[1] or z >= dims[2]:
                        continue
                    key = (np.int64(x) * dims[1] + y) * dims[2] + z
                    lo = np.searchsorted(vkey, key)
                    while lo < vkey.shape[0] and vkey[lo] == key:
                        if vfacing[lo] == f:
                            if ring == 0:
                                dd = abs((px - vcentroid[lo, 0]) * vnormal[lo, 0] + (py - vcentroid[lo, 1])
                                         * vnormal[lo, 1] + (pz - vcentroid[lo, 2]) * vnormal[lo, 2])
                            else:
                                dd = (px - vcentroid[lo, 0]) ** 2 + (py - vcentroid[lo, 1]) ** 2 + \
                                    (pz - vcentroid[lo, 2]) ** 2
                            if dd < best_d:
                                best, best_d = lo, dd
                        lo += 1
        if best >= 0:
            return best
    return -1


@njit(cache=True, parallel=True)
def _rows(bvh, double, mat_of, cam, radiance, vkey, vfacing, vcentroid, vnormal, origin, h, dims, width, height,
          row0, row1, out):
    n = (row1 - row0) * width
    for k in prange(n):
        stack = np.empty(STACK_SIZE, np.int32)
        y = row0 + k // width
        x = k % width
        ox, oy, oz, dx, dy, dz = primary_ray(cam, x, y, 0.5, 0.5, width, height)
        t, j, u, v = closest_hit(bvh, stack, ox, oy, oz, dx, dy, dz, 0.0, np.inf)
        if j < 0:
            continue
        nx, ny, nz = hit_normal(bvh, j)
        if nx * dx + ny * dy + nz * dz > 0.0:
            if not double[mat_of[bvh[6][j]]]:
                continue  # a one-sided back: black
            nx, ny, nz = -nx, -ny, -nz
        vi = _voxel_at(ox + t * dx, oy + t * dy, oz + t * dz, facing_of(nx, ny, nz), vkey, vfacing, vcentroid,
                       vnormal, origin, h, dims)
        if vi >= 0:
            out[y, x, 0] = radiance[vi, 0]
            out[y, x, 1] = radiance[vi, 1]
            out[y, x, 2] = radiance[vi, 2]


def render_voxels(bvh, surfaces, solution, camera_arr, width, height, progress=None):
    """Linear image (height, width, 3) float32 of the voxels' radiance B / pi."""
    from .render import render_bands
    v = solution.voxels
    return render_bands(_rows, width, height,
                        (bvh.arrays, surfaces.arrays[3], surfaces.arrays[0], camera_arr,
                         np.ascontiguousarray(solution.radiance), v.key, v.facing, v.centroid, v.normal, v.origin,
                         v.cell_size, v.dims, int(width), int(height)), progress)
