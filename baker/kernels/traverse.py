"""Ray queries on the BVH of `bvh.py`: closest hit and any hit (shadow rays).

`bvh` below is the tuple (lo, hi, right, first, count, v0, v1, v2, tri_index)
that `baker.bvh.BVH.arrays` returns. The scalar queries are called from
other kernels; the `*_batch` ones from Python, parallel over rays.
Triangles are hit from both sides (watertight test, float64); the caller
decides what the back side means.
"""
import numpy as np
from numba import njit, prange

_TINY = 1e-300


@njit(cache=True, inline="always")
def _inv(d):
    if abs(d) < 1e-30:
        return 1e30 if d >= 0.0 else -1e30
    return 1.0 / d


@njit(cache=True, inline="always")
def _box(lo, hi, i, ox, oy, oz, ix, iy, iz, tmin, tmax):
    """Entry distance of the ray into box i, or inf if it misses [tmin, tmax]."""
    t0 = (lo[i, 0] - ox) * ix
    t1 = (hi[i, 0] - ox) * ix
    tn, tf = min(t0, t1), max(t0, t1)
    t0 = (lo[i, 1] - oy) * iy
    t1 = (hi[i, 1] - oy) * iy
    tn, tf = max(tn, min(t0, t1)), min(tf, max(t0, t1))
    t0 = (lo[i, 2] - oz) * iz
    t1 = (hi[i, 2] - oz) * iz
    tn, tf = max(tn, min(t0, t1)), min(tf, max(t0, t1))
    tn = max(tn, tmin)
    tf = min(tf, tmax)
    return tn if tn <= tf * 1.0000000000000004 else np.inf


@njit(cache=True, inline="always")
def ray_shear(dx, dy, dz):
    """Per-ray set-up of the watertight test: axis permutation (kx, ky, kz)
    with kz the dominant axis, and the shear (sx, sy, sz)."""
    ax, ay, az = abs(dx), abs(dy), abs(dz)
    if ax >= ay and ax >= az:
        kz = 0
    elif ay >= az:
        kz = 1
    else:
        kz = 2
    kx = (kz + 1) % 3
    ky = (kx + 1) % 3
    d = (dx, dy, dz)
    if d[kz] < 0.0:
        kx, ky = ky, kx
    return kx, ky, kz, d[kx] / d[kz], d[ky] / d[kz], 1.0 / d[kz]


@njit(cache=True, inline="always")
def intersect_triangle(v0, v1, v2, j, o, kx, ky, kz, sx, sy, sz):
    """Watertight ray/triangle test (Woop, Benthin & Wald 2013, JCGT 2(1)):
    rays through a shared edge or vertex hit at least one of the triangles,
    never slip between them. Returns (t, u, v) with u, v the weights of
    v1, v2; t = inf on a miss."""
    ax, ay, az = v0[j, kx] - o[kx], v0[j, ky] - o[ky], v0[j, kz] - o[kz]
    bx, by, bz = v1[j, kx] - o[kx], v1[j, ky] - o[ky], v1[j, kz] - o[kz]
    cx, cy, cz = v2[j, kx] - o[kx], v2[j, ky] - o[ky], v2[j, kz] - o[kz]
    ax, ay = ax - sx * az, ay - sy * az
    bx, by = bx - sx * bz, by - sy * bz
    cx, cy = cx - sx * cz, cy - sy * cz
    eu = cx * by - cy * bx
    ev = ax * cy - ay * cx
    ew = bx * ay - by * ax
    if (eu < 0.0 or ev < 0.0 or ew < 0.0) and (eu > 0.0 or ev > 0.0 or ew > 0.0):
        return np.inf, 0.0, 0.0
    det = eu + ev + ew
    if det == 0.0:
        return np.inf, 0.0, 0.0
    t = (eu * sz * az + ev * sz * bz + ew * sz * cz) / det
    return t, ev / det, ew / det


@njit(cache=True)
def closest_hit(bvh, ox, oy, oz, dx, dy, dz, tmin, tmax):
    """First hit with t in (tmin, tmax): (t, bvh-order triangle j, u, v);
    j = -1 on a miss."""
    lo, hi, right, first, count, v0, v1, v2 = bvh[0], bvh[1], bvh[2], bvh[3], bvh[4], bvh[5], bvh[6], bvh[7]
    ix, iy, iz = _inv(dx), _inv(dy), _inv(dz)
    kx, ky, kz, sx, sy, sz = ray_shear(dx, dy, dz)
    o = (ox, oy, oz)
    best_t, best_j, best_u, best_v = tmax, -1, 0.0, 0.0
    stack = np.empty(96, np.int32)
    stack_t = np.empty(96)
    sp = 0
    if _box(lo, hi, 0, ox, oy, oz, ix, iy, iz, tmin, best_t) == np.inf:
        return np.inf, -1, 0.0, 0.0
    node = 0
    while True:
        if count[node] > 0:
            f = first[node]
            for j in range(f, f + count[node]):
                t, u, v = intersect_triangle(v0, v1, v2, j, o, kx, ky, kz, sx, sy, sz)
                if tmin < t < best_t:
                    best_t, best_j, best_u, best_v = t, j, u, v
            node = -1
        else:
            a, b = node + 1, right[node]
            ta = _box(lo, hi, a, ox, oy, oz, ix, iy, iz, tmin, best_t)
            tb = _box(lo, hi, b, ox, oy, oz, ix, iy, iz, tmin, best_t)
            if ta > tb:
                a, b, ta, tb = b, a, tb, ta
            if ta == np.inf:
                node = -1
            else:
                node = a
                if tb != np.inf:
                    stack[sp] = b
                    stack_t[sp] = tb
                    sp += 1
        while node < 0:
            if sp == 0:
                if best_j < 0:
                    return np.inf, -1, 0.0, 0.0
                return best_t, best_j, best_u, best_v
            sp -= 1
            if stack_t[sp] <= best_t:
                node = stack[sp]


@njit(cache=True)
def any_hit(bvh, ox, oy, oz, dx, dy, dz, tmin, tmax):
    """True if anything is hit with t in (tmin, tmax)."""
    lo, hi, right, first, count, v0, v1, v2 = bvh[0], bvh[1], bvh[2], bvh[3], bvh[4], bvh[5], bvh[6], bvh[7]
    ix, iy, iz = _inv(dx), _inv(dy), _inv(dz)
    kx, ky, kz, sx, sy, sz = ray_shear(dx, dy, dz)
    o = (ox, oy, oz)
    stack = np.empty(96, np.int32)
    sp = 0
    if _box(lo, hi, 0, ox, oy, oz, ix, iy, iz, tmin, tmax) == np.inf:
        return False
    node = 0
    while True:
        if count[node] > 0:
            f = first[node]
            for j in range(f, f + count[node]):
                t, u, v = intersect_triangle(v0, v1, v2, j, o, kx, ky, kz, sx, sy, sz)
                if tmin < t < tmax:
                    return True
            node = -1
        else:
            a, b = node + 1, right[node]
            ta = _box(lo, hi, a, ox, oy, oz, ix, iy, iz, tmin, tmax)
            tb = _box(lo, hi, b, ox, oy, oz, ix, iy, iz, tmin, tmax)
            if ta > tb:
                a, b, ta, tb = b, a, tb, ta
            if ta == np.inf:
                node = -1
            else:
                node = a
                if tb != np.inf:
                    stack[sp] = b
                    sp += 1
        if node < 0:
            if sp == 0:
                return False
            sp -= 1
            node = stack[sp]


@njit(cache=True, parallel=True)
def closest_hit_batch(bvh, origins, dirs, tmin, tmax):
    """origins, dirs (n, 3) float64 -> t (n,) float64 (inf: miss),
    triangle (n,) int32 (scene numbering, -1: miss), u, v (n,) float64."""
    n = origins.shape[0]
    t_out = np.empty(n)
    tri = np.empty(n, np.int32)
    u_out = np.empty(n)
    v_out = np.empty(n)
    index = bvh[8]
    for i in prange(n):
        t, j, u, v = closest_hit(bvh, origins[i, 0], origins[i, 1], origins[i, 2], dirs[i, 0], dirs[i, 1],
                                 dirs[i, 2], tmin, tmax[i])
        t_out[i], u_out[i], v_out[i] = t, u, v
        tri[i] = index[j] if j >= 0 else -1
    return t_out, tri, u_out, v_out


@njit(cache=True, parallel=True)
def any_hit_batch(bvh, origins, dirs, tmin, tmax):
    """(n,) bool: occluded within (tmin, tmax[i])."""
    n = origins.shape[0]
    out = np.empty(n, np.bool_)
    for i in prange(n):
        out[i] = any_hit(bvh, origins[i, 0], origins[i, 1], origins[i, 2], dirs[i, 0], dirs[i, 1], dirs[i, 2],
                         tmin, tmax[i])
    return out


@njit(cache=True, inline="always")
def hit_normal(bvh, j):
    """Unit geometric normal (winding order) of BVH-order triangle j."""
    v0, v1, v2 = bvh[5], bvh[6], bvh[7]
    ax, ay, az = v1[j, 0] - v0[j, 0], v1[j, 1] - v0[j, 1], v1[j, 2] - v0[j, 2]
    bx, by, bz = v2[j, 0] - v0[j, 0], v2[j, 1] - v0[j, 1], v2[j, 2] - v0[j, 2]
    nx, ny, nz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
    ln = np.sqrt(nx * nx + ny * ny + nz * nz)
    return nx / ln, ny / ln, nz / ln
