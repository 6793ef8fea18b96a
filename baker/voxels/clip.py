"""Clipping triangles to grid cells (docs/design.md section 2): candidate
cells per triangle side (pass 1: counting), the exact polygon of a side in
each cell (pass 2), and the polygon helpers the cell analysis reuses.

Coordinates inside the kernels are grid units: g = (p - origin) / h.
A side is (triangle, +1 front | -1 back); its facing is 2 * axis + (side
normal component along axis < 0), axis the dominant axis of the normal.
"""
import math

import numpy as np
from numba import njit, prange

from .tolerances import GRID_SNAP

MAX_POLY = 16


@njit(cache=True)
def side_axis(n):
    ax, ay, az = abs(n[0]), abs(n[1]), abs(n[2])
    if ax >= ay and ax >= az:
        return 0
    if ay >= az:
        return 1
    return 2


@njit(cache=True)
def _column_range(g, nrm, k, i0, i1, j0, j1, ia, ja, sign):
    """Cells along axis k crossed by the triangle's plane over the column
    [i0, i1] x [j0, j1] (grid units, axes ia, ja), clamped to the triangle's
    extent along k. A plane exactly on a cell boundary goes to the cell on
    the side its normal points to (sign)."""
    d = nrm[0] * g[0, 0] + nrm[1] * g[0, 1] + nrm[2] * g[0, 2]
    lo, hi = np.inf, -np.inf
    for ci in (i0, i1):
        for cj in (j0, j1):
            v = (d - nrm[ia] * ci - nrm[ja] * cj) / nrm[k]
            lo = min(lo, v)
            hi = max(hi, v)
    tlo = min(g[0, k], min(g[1, k], g[2, k]))
    thi = max(g[0, k], max(g[1, k], g[2, k]))
    lo = max(lo, tlo)
    hi = min(hi, thi)
    if sign > 0:
        return int(math.floor(lo)), int(math.floor(hi))
    return int(math.ceil(lo)) - 1, int(math.ceil(hi)) - 1


@njit(cache=True, inline="always")
def to_grid(x, o, inv_h):
    """Grid coordinate of scene coordinate x along an axis whose origin is o:
    within GRID_SNAP of a cell boundary, the boundary itself (the grid's
    origin is the scene's low corner less a cell, and (lo - (lo - h)) / h
    rounds to 0.99999999...: a wall on the scene's bounds would fall in the
    cell outside it, not the one it faces)."""
    g = (x - o) * inv_h
    r = math.floor(g + 0.5)
    return r if abs(g - r) < GRID_SNAP else g


@njit(cache=True)
def _grid_corners(corners, t, origin, inv_h):
    g = np.empty((3, 3))
    for c in range(3):
        for k in range(3):
            g[c, k] = to_grid(corners[t, c, k], origin[k], inv_h)
    return g


@njit(cache=True)
def _normal(g):
    ax, ay, az = g[1, 0] - g[0, 0], g[1, 1] - g[0, 1], g[1, 2] - g[0, 2]
    bx, by, bz = g[2, 0] - g[0, 0], g[2, 1] - g[0, 1], g[2, 2] - g[0, 2]
    n = np.empty(3)
    n[0], n[1], n[2] = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
    ln = math.sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2])
    n /= ln
    return n


@njit(cache=True, parallel=True)
def count_candidates(corners, sides_tri, sides_sign, origin, inv_h):
    """Pass 1: candidate cells of every triangle side, (ns,) int64."""
    ns = sides_tri.shape[0]
    out = np.zeros(ns, np.int64)
    for s in prange(ns):
        g = _grid_corners(corners, sides_tri[s], origin, inv_h)
        n = _normal(g)
        k = side_axis(n)
        sign = sides_sign[s] * (1 if n[k] > 0 else -1)
        ia, ja = (k + 1) % 3, (k + 2) % 3
        a0 = int(math.floor(min(g[0, ia], min(g[1, ia], g[2, ia]))))
        a1 = int(math.floor(max(g[0, ia], max(g[1, ia], g[2, ia]))))
        b0 = int(math.floor(min(g[0, ja], min(g[1, ja], g[2, ja]))))
        b1 = int(math.floor(max(g[0, ja], max(g[1, ja], g[2, ja]))))
        c = 0
        for i in range(a0, a1 + 1):
            for j in range(b0, b1 + 1):
                k0, k1 = _column_range(g, n, k, i, i + 1, j, j + 1, ia, ja, sign)
                if k1 >= k0:
                    c += k1 - k0 + 1
        out[s] = c
    return out


@njit(cache=True)
def _clip(px, py, pz, n, axis, value, keep_above):
    """Sutherland-Hodgman: keep the part of polygon (px, py, pz)[:n] with
    coordinate `axis` >= value (keep_above) or <= value; new vertices land
    exactly on the plane (no drift across it)."""
    nx = 1.0 if axis == 0 else 0.0
    ny = 1.0 if axis == 1 else 0.0
    nz = 1.0 if axis == 2 else 0.0
    return clip_plane(px, py, pz, n, nx, ny, nz, value, keep_above, axis)


@njit(cache=True, parallel=True)
def clip_pieces(corners, sides_tri, sides_sign, origin, inv_h, offsets, dims, piece_cell, piece_area,
                piece_centroid, piece_normal, piece_side):
    """Pass 2: clip every side to its candidate cells. Fills, at
    offsets[s] + m: cell (x, y, z) int32, area (grid units^2; 0 = empty),
    area-weighted centroid (grid units), side unit normal, side index."""
    ns = sides_tri.shape[0]
    for s in prange(ns):
        g = _grid_corners(corners, sides_tri[s], origin, inv_h)
        n = _normal(g)
        k = side_axis(n)
        sgn = sides_sign[s]
        sign = sgn * (1 if n[k] > 0 else -1)
        ia, ja = (k + 1) % 3, (k + 2) % 3
        a0 = int(math.floor(min(g[0, ia], min(g[1, ia], g[2, ia]))))
        a1 = int(math.floor(max(g[0, ia], max(g[1, ia], g[2, ia]))))
        b0 = int(math.floor(min(g[0, ja], min(g[1, ja], g[2, ja]))))
        b1 = int(math.floor(max(g[0, ja], max(g[1, ja], g[2, ja]))))
        slot = offsets[s]
        px = np.empty(MAX_POLY)
        py = np.empty(MAX_POLY)
        pz = np.empty(MAX_POLY)
        for i in range(a0, a1 + 1):
            for j in range(b0, b1 + 1):
                k0, k1 = _column_range(g, n, k, i, i + 1, j, j + 1, ia, ja, sign)
                for kk in range(k0, k1 + 1):
                    cell = np.empty(3, np.int64)
                    cell[k], cell[ia], cell[ja] = kk, i, j
                    for c in range(3):
                        px[c], py[c], pz[c] = g[c, 0], g[c, 1], g[c, 2]
                    qx, qy, qz, m = _clip_to_cell(px, py, pz, cell)
                    area, cx, cy, cz = area_centroid(qx, qy, qz, m)
                    in_grid = True
                    for c in range(3):
                        if cell[c] < 0 or cell[c] >= dims[c]:
                            in_grid = False
                    if not in_grid:
                        area = 0.0
                    for c in range(3):
                        piece_cell[slot, c] = cell[c]
                        piece_normal[slot, c] = sgn * n[c]
                    piece_area[slot] = area
                    piece_centroid[slot, 0] = cx
                    piece_centroid[slot, 1] = cy
                    piece_centroid[slot, 2] = cz
                    piece_side[slot] = s
                    slot += 1


@njit(cache=True)
def _clip_to_cell(px, py, pz, cell):
    """Triangle (px, py, pz)[:3] (grid units) clipped to the unit cube of `cell`."""
    m = 3
    qx, qy, qz = px, py, pz
    for axis in range(3):
        if m == 0:
            break
        qx, qy, qz, m = _clip(qx, qy, qz, m, axis, float(cell[axis]), True)
        if m == 0:
            break
        qx, qy, qz, m = _clip(qx, qy, qz, m, axis, float(cell[axis] + 1), False)
    return qx, qy, qz, m


@njit(cache=True)
def piece_polygon(corners, tri, origin, inv_h, cell):
    """The polygon of scene triangle `tri` clipped to `cell` (grid units)."""
    px = np.empty(MAX_POLY)
    py = np.empty(MAX_POLY)
    pz = np.empty(MAX_POLY)
    for c in range(3):
        px[c] = to_grid(corners[tri, c, 0], origin[0], inv_h)
        py[c] = to_grid(corners[tri, c, 1], origin[1], inv_h)
        pz[c] = to_grid(corners[tri, c, 2], origin[2], inv_h)
    return _clip_to_cell(px, py, pz, cell)


@njit(cache=True)
def clip_plane(px, py, pz, n, nx, ny, nz, d, keep_front, snap_axis=-1):
    """Sutherland-Hodgman: keep the part of polygon (px, py, pz)[:n] with
    (p . n - d) >= 0 (keep_front) or <= 0. With snap_axis (an axis-aligned
    plane), new vertices get that coordinate exactly d."""
    ox = np.empty(MAX_POLY)
    oy = np.empty(MAX_POLY)
    oz = np.empty(MAX_POLY)
    m = 0
    for i in range(n):
        j = (i + 1) % n
        ci = px[i] * nx + py[i] * ny + pz[i] * nz - d
        cj = px[j] * nx + py[j] * ny + pz[j] * nz - d
        if not keep_front:
            ci, cj = -ci, -cj
        if ci >= 0.0:
            ox[m], oy[m], oz[m] = px[i], py[i], pz[i]
            m += 1
        if (ci >= 0.0) != (cj >= 0.0) and m < MAX_POLY:
            t = ci / (ci - cj)
            ox[m] = px[i] + t * (px[j] - px[i])
            oy[m] = py[i] + t * (py[j] - py[i])
            oz[m] = pz[i] + t * (pz[j] - pz[i])
            if snap_axis == 0:
                ox[m] = d
            elif snap_axis == 1:
                oy[m] = d
            elif snap_axis == 2:
                oz[m] = d
            m += 1
    return ox, oy, oz, m


@njit(cache=True)
def area_centroid(qx, qy, qz, m):
    """Area and area-weighted centroid sum of a planar polygon (fan triangles)."""
    area = 0.0
    cx = cy = cz = 0.0
    for v in range(1, m - 1):
        ux, uy, uz = qx[v] - qx[0], qy[v] - qy[0], qz[v] - qz[0]
        wx, wy, wz = qx[v + 1] - qx[0], qy[v + 1] - qy[0], qz[v + 1] - qz[0]
        crx, cry, crz = uy * wz - uz * wy, uz * wx - ux * wz, ux * wy - uy * wx
        a = 0.5 * math.sqrt(crx * crx + cry * cry + crz * crz)
        area += a
        cx += a * (qx[0] + qx[v] + qx[v + 1]) / 3.0
        cy += a * (qy[0] + qy[v] + qy[v + 1]) / 3.0
        cz += a * (qz[0] + qz[v] + qz[v + 1]) / 3.0
    return area, cx, cy, cz
