"""The bounced light at texel points by a final gather into the voxel
solution (docs/design.md section 8): K rays over the point's hemisphere,
cosine-distributed, each reading the outgoing radiance of the voxel it
hits, B_ind / pi (the solution's radiosity less emission: the emitters'
own light is the sharp part's). Then

    H(p) = integral of L cos dw  ~=  (pi / K) sum_k B_ind(hit_k) / pi = mean_k B_ind(hit_k)

The directions are one fixed stratified set (a Fibonacci spiral on the
unit disk lifted onto the hemisphere, Malley's method), turned into each
point's frame: points of one plane take the same world directions, so
the estimate's error varies smoothly along a surface instead of as noise,
and it is the same for any thread count.

A ray that hits the back of a one-sided surface, or a voxel facing away
from it, reads nothing (a two-sided sheet's voxel emits on its normal's
side, as its VPL does); through thin glass it reads the pane's voxel and
goes on, tinted.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ..kernels.bvh import PASS_GLASS, STACK_SIZE
from ..kernels.traverse import closest_hit, hit_normal
from ..voxels.lookup import voxel_of_hit

GLASS_LAYERS = 8   # panes a gather ray crosses before it stops (a window's two faces, a display case)


def gather_directions(k: int) -> np.ndarray:
    """k cosine-distributed unit directions about +z (k, 3)."""
    i = np.arange(k) + 0.5
    r = np.sqrt(i / k)
    phi = i * np.pi * (3.0 - np.sqrt(5.0))
    x, y = r * np.cos(phi), r * np.sin(phi)
    return np.ascontiguousarray(np.stack([x, y, np.sqrt(np.maximum(0.0, 1.0 - x * x - y * y))], 1))


@njit(cache=True, inline="always")
def _frame(nx, ny, nz):
    if abs(nx) < 0.9:
        ax, ay, az = 1.0, 0.0, 0.0
    else:
        ax, ay, az = 0.0, 1.0, 0.0
    tx, ty, tz = ay * nz - az * ny, az * nx - ax * nz, ax * ny - ay * nx
    tl = math.sqrt(tx * tx + ty * ty + tz * tz)
    tx, ty, tz = tx / tl, ty / tl, tz / tl
    return tx, ty, tz, ny * tz - nz * ty, nz * tx - nx * tz, nx * ty - ny * tx


@njit(cache=True, parallel=True, error_model="numpy")
def gather_kernel(bvh, double, mat_of, b_ind, vnormal, pieces, points, normals, offset, local, out):
    """out[i] (3,) the gathered irradiance at points[i] (normal
    normals[i], rays from offset along it) over the directions `local`."""
    n = len(points)
    k_n = len(local)
    for i in prange(n):
        stack = np.empty(STACK_SIZE, np.int32)
        nx, ny, nz = normals[i, 0], normals[i, 1], normals[i, 2]
        tx, ty, tz, bx, by, bz = _frame(nx, ny, nz)
        ox0, oy0, oz0 = points[i, 0] + offset * nx, points[i, 1] + offset * ny, points[i, 2] + offset * nz
        a0 = a1 = a2 = 0.0
        for k in range(k_n):
            lx, ly, lz = local[k, 0], local[k, 1], local[k, 2]
            dx = lx * tx + ly * bx + lz * nx
            dy = lx * ty + ly * by + lz * ny
            dz = lx * tz + ly * bz + lz * nz
            ox, oy, oz = ox0, oy0, oz0
            w0 = w1 = w2 = 1.0
            for _layer in range(GLASS_LAYERS):
                t, j, u, v = closest_hit(bvh, stack, ox, oy, oz, dx, dy, dz, 0.0, np.inf)
                if j < 0:   # the sky's light is the sky's cut's (lights.sky_light)
                    break
                hx, hy, hz = hit_normal(bvh, j)
                tri = bvh.tri_index[j]
                back = hx * dx + hy * dy + hz * dz > 0.0
                px, py, pz = ox + t * dx, oy + t * dy, oz + t * dz
                if not back or double[mat_of[tri]]:
                    vi = voxel_of_hit(tri, back, px, py, pz, pieces)
                    if vi >= 0 and vnormal[vi, 0] * dx + vnormal[vi, 1] * dy + vnormal[vi, 2] * dz < 0.0:
                        a0 += w0 * b_ind[vi, 0]
                        a1 += w1 * b_ind[vi, 1]
                        a2 += w2 * b_ind[vi, 2]
                if bvh.tri_pass[j] != PASS_GLASS:
                    break
                g = bvh.glass_tint[bvh.tri_mat[j]]
                w0, w1, w2 = w0 * g[0], w1 * g[1], w2 * g[2]
                if w0 <= 0.0 and w1 <= 0.0 and w2 <= 0.0:
                    break
                step = 1e-6 * max(1.0, t)   # past the pane, not onto it again
                ox, oy, oz = px + step * dx, py + step * dy, pz + step * dz
        out[i, 0] = a0 / k_n
        out[i, 1] = a1 / k_n
        out[i, 2] = a2 / k_n


def gather_bounced(prepared, solution, points, normals, offset, rays) -> np.ndarray:
    """(N, 3) float64: the bounced light at points (unit normals, the side
    that receives) gathered from the voxel solution by `rays` rays each."""
    a = prepared.surfaces.arrays
    v = solution.voxels
    b_ind = np.ascontiguousarray(np.maximum(solution.radiosity - v.emission, 0.0), np.float64)
    out = np.zeros((len(points), 3))
    if len(points):
        gather_kernel(prepared.bvh.arrays, a.double_sided, a.tri_material, b_ind,
                      np.ascontiguousarray(v.normal, np.float64), v.lookup(),
                      np.ascontiguousarray(points, np.float64), np.ascontiguousarray(normals, np.float64),
                      float(offset), gather_directions(int(rays)), out)
    return out
