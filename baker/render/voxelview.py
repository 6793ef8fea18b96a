"""The direct voxel view (the thesis's "direct voxel view"): primary rays
from the camera (4 x 4 per pixel, box-filtered); each visible surface
point shows its voxel's outgoing radiance B / pi (the voxel of the hit cell whose facing matches the side
seen, nearest sheet). A look at the solution itself, not a final image.
"""
from __future__ import annotations

import numpy as np
from numba import njit, prange

from ..kernels.bvh import STACK_SIZE
from ..kernels.traverse import closest_hit, hit_normal
from ..voxels.lookup import voxel_of_hit
from .camera import primary_ray, render_bands, subpixel


SUBPIXELS = 4  # per axis: the pixel's value is the mean over SUBPIXELS^2 stratified points (a box filter, as the
#               path tracer's), so a pixel the edge of a surface crosses is not all background


@njit(cache=True, parallel=True)
def _rows(bvh, double, mat_of, cam, radiance, pieces, width, height, row0, row1, out):
    n = (row1 - row0) * width
    w = 1.0 / (SUBPIXELS * SUBPIXELS)
    for k in prange(n):
        stack = np.empty(STACK_SIZE, np.int32)
        y = row0 + k // width
        x = k % width
        r0 = r1 = r2 = 0.0
        for sub in range(SUBPIXELS * SUBPIXELS):
            fx, fy = subpixel(sub, SUBPIXELS)
            ox, oy, oz, dx, dy, dz = primary_ray(cam, x, y, fx, fy, width, height)
            t, j, u, v = closest_hit(bvh, stack, ox, oy, oz, dx, dy, dz, 0.0, np.inf)
            if j < 0:
                continue
            nx, ny, nz = hit_normal(bvh, j)
            tri = bvh.tri_index[j]
            back = nx * dx + ny * dy + nz * dz > 0.0
            if back and not double[mat_of[tri]]:
                continue  # a one-sided back: black
            vi = voxel_of_hit(tri, back, ox + t * dx, oy + t * dy, oz + t * dz, pieces)
            if vi >= 0:
                r0 += radiance[vi, 0]
                r1 += radiance[vi, 1]
                r2 += radiance[vi, 2]
        out[y, x, 0] = r0 * w
        out[y, x, 1] = r1 * w
        out[y, x, 2] = r2 * w


def render_voxels(bvh, surfaces, solution, camera_arr, width, height, progress=None):
    """Linear image (height, width, 3) float32 of the voxels' radiance B / pi."""
    v = solution.voxels
    return render_bands(_rows, width, height,
                        (bvh.arrays, surfaces.arrays.double_sided, surfaces.arrays.tri_material, camera_arr,
                         np.ascontiguousarray(solution.radiance), v.lookup(), int(width), int(height)), progress)
