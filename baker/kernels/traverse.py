"""Ray queries on the BVH of `bvh.py`: closest hit and any hit (shadow rays).

`bvh` below is the tuple (lo, hi, right, first, count, v0, e1, e2, tri_index)
that `baker.bvh.BVH.arrays` returns. The scalar queries are called from
other kernels; the `*_batch` ones from Python, parallel over rays.
Triangles are hit from both sides (Moller-Trumbore, float64); the caller
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
def intersect_triangle(v0, e1, e2, j, ox, oy, oz, dx, dy, dz):
    """Moller-Trumbore; returns (t, u, v), t = inf on a miss. Edges and
    vertices count as inside (u, v >= 0, u + v <= 1)."""
    px = dy * e2[j, 2] - dz * e2[j, 1]
    py = dz * e2[j, 0] - dx * e2[j, 2]
    pz = dx * e2[j, 1] - dy * e2[j, 0]
    det = e1[j, 0] * px + e1[j, 1] * py + e1[j, 2] * pz
    if det == 0.0:
        return np.inf, 0.0, 0.0
    inv = 1.0 / det
    tx, ty, tz = ox - v0[j, 0], oy - v0[j, 1], oz - v0[j, 2]
    u = (tx * px + ty * py + tz * pz) * inv
    if u < 0.0 or u > 1.0:
        return np.inf, 0.0, 0.0
    qx = ty * e1[j, 2] - tz * e1[j, 1]
    qy = tz * e1[j, 0] - tx * e1[j, 2]
    qz = tx * e1[j, 1] - ty * e1[j, 0]
    v = (dx * qx + dy * qy + dz * qz) * inv
    if v < 0.0 or u + v > 1.0:
        return np.inf, 0.0, 0.0
    t = (e2[j, 0] * qx + e2[j, 1] * qy + e2[j, 2] * qz) * inv
    return t, u, v


@njit(cache=True)
def closest_hit(bvh, ox, oy, oz, dx, dy, dz, tmin, tmax):
    """First hit with t in (tmin, tmax): (t, bvh-order triangle j, u, v);
    j = -1 on a miss."""
    lo, hi, right, first, count, v0, e1, e2 = bvh[0], bvh[1], bvh[2], bvh[3], bvh[4], bvh[5], bvh[6], bvh[7]
    ix, iy, iz = _inv(dx), _inv(dy), _inv(dz)
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
                t, u, v = intersect_triangle(v0, e1, e2, j, ox, oy, oz, dx, dy, dz)
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
    lo, hi, right, first, count, v0, e1, e2 = bvh[0], bvh[1], bvh[2], bvh[3], bvh[4], bvh[5], bvh[6], bvh[7]
    ix, iy, iz = _inv(dx), _inv(dy), _inv(dz)
    stack = np.empty(96, np.int32)
    sp = 0
    if _box(lo, hi, 0, ox, oy, oz, ix, iy, iz, tmin, tmax) == np.inf:
        return False
    node = 0
    while True:
        if count[node] > 0:
            f = first[node]
            for j in range(f, f + count[node]):
                t, u, v = intersect_triangle(v0, e1, e2, j, ox, oy, oz, dx, dy, dz)
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
