"""Voxelization kernels (METHOD.md section 2): candidate cells per triangle
side, exact clipping of the triangle to each cell, merge of the pieces.

Coordinates inside the kernels are grid units: g = (p - origin) / h.
A side is (triangle, +1 front | -1 back); its facing is 2 * axis + (side
normal component along axis < 0), axis the dominant axis of the normal.
"""
import math

import numpy as np
from numba import njit, prange

from ..surfaces import albedo_at

MAX_POLY = 16


@njit(cache=True)
def _side_axis(n):
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


@njit(cache=True)
def _grid_corners(corners, t, origin, inv_h):
    g = np.empty((3, 3))
    for c in range(3):
        for k in range(3):
            g[c, k] = (corners[t, c, k] - origin[k]) * inv_h
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
        k = _side_axis(n)
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
    return _clip_plane(px, py, pz, n, nx, ny, nz, value, keep_above, axis)


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
        k = _side_axis(n)
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
                    area, cx, cy, cz = _area_centroid(qx, qy, qz, m)
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
def merge_sheets(order, key, facing, sig, along, area, centroid, normal, sheet_gap):
    """Walks pieces sorted by (cell key, facing, side signature, position
    along the facing axis) and assigns each to a voxel: a new voxel starts
    at a new (cell, facing, signature) or when the piece's centroid is more than sheet_gap (grid units)
    off the current sheet's plane. Returns voxel id per sorted piece."""
    n = order.shape[0]
    vox = np.empty(n, np.int64)
    cur = -1
    sa = 0.0
    sc = np.zeros(3)
    sn = np.zeros(3)
    for i in range(n):
        p = order[i]
        q = order[i - 1] if i > 0 else p
        new = i == 0 or key[p] != key[q] or facing[p] != facing[q] or sig[p] != sig[q]
        if not new:
            # distance of this piece's centroid from the sheet's mean plane
            ln = math.sqrt(sn[0] * sn[0] + sn[1] * sn[1] + sn[2] * sn[2])
            d = 0.0
            for c in range(3):
                d += (centroid[p, c] / area[p] - sc[c] / sa) * sn[c] / ln
            if abs(d) > sheet_gap:
                new = True
        if new:
            cur += 1
            sa = 0.0
            sc[:] = 0.0
            sn[:] = 0.0
        sa += area[p]
        for c in range(3):
            sc[c] += centroid[p, c]
            sn[c] += normal[p, c] * area[p]
        vox[i] = cur
    return vox


@njit(cache=True, parallel=True)
def textured_albedo(surf, corners, piece_tri, piece_cell, origin, h, samples):
    """Albedo of each piece averaged over the piece (METHOD.md section 2:
    texture-aware, not one sample): samples^2 points of the R2 low-
    discrepancy sequence (Roberts 2018; a regular grid aliases with regular
    textures) over the cell's face across the triangle's dominant axis,
    projected on the triangle's plane, keeping the points inside both the
    triangle and the cell."""
    n = piece_tri.shape[0]
    out = np.zeros((n, 3))
    for p in prange(n):
        t = piece_tri[p]
        v0 = corners[t, 0]
        e1 = corners[t, 1] - v0
        e2 = corners[t, 2] - v0
        nx, ny, nz = e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]
        nrm = np.array([nx, ny, nz])
        k = _side_axis(nrm)
        ia, ja = (k + 1) % 3, (k + 2) % 3
        d = nrm[0] * v0[0] + nrm[1] * v0[1] + nrm[2] * v0[2]
        # barycentric solve in the projection along k
        a11, a12, a21, a22 = e1[ia], e2[ia], e1[ja], e2[ja]
        det = a11 * a22 - a12 * a21
        sr = sg = sb = 0.0
        cnt = 0
        for si in range(samples * samples):
            ra = 0.5 + si * 0.7548776662466927
            rb = 0.5 + si * 0.5698402909980532
            ra -= math.floor(ra)
            rb -= math.floor(rb)
            q = np.empty(3)
            q[ia] = origin[ia] + (piece_cell[p, ia] + ra) * h
            q[ja] = origin[ja] + (piece_cell[p, ja] + rb) * h
            q[k] = (d - nrm[ia] * q[ia] - nrm[ja] * q[ja]) / nrm[k]
            ck = (q[k] - origin[k]) / h - piece_cell[p, k]
            if ck < 0.0 or ck > 1.0:
                continue
            ri, rj = q[ia] - v0[ia], q[ja] - v0[ja]
            b1 = (ri * a22 - rj * a12) / det
            b2 = (a11 * rj - a21 * ri) / det
            if b1 < 0.0 or b2 < 0.0 or b1 + b2 > 1.0:
                continue
            r, g, b = albedo_at(surf, t, b1, b2)
            sr += r
            sg += g
            sb += b
            cnt += 1
        if cnt == 0:  # a sliver between the sample points: the triangle's centre
            r, g, b = albedo_at(surf, t, 1.0 / 3.0, 1.0 / 3.0)
            sr, sg, sb, cnt = r, g, b, 1
        out[p, 0], out[p, 1], out[p, 2] = sr / cnt, sg / cnt, sb / cnt
    return out


def cell_runs(order, key):
    """Boundaries (m + 1,) of the runs of equal cell key in pieces sorted by key (order)."""
    k = key[order]
    return np.concatenate([[0], np.flatnonzero(k[1:] != k[:-1]) + 1, [len(k)]]).astype(np.int64)


@njit(cache=True)
def side_signatures(order, runs, key, facing, area, centroid, normal, tol):
    """For pieces sorted by cell key (order), a signature per piece: bit i
    set when the piece lies in front of (beyond tol, grid units) the plane
    of the i-th piece of another facing in the same cell, not facing back
    at it (within 25 degrees). Pieces of one
    facing with different signatures are cut apart by another surface
    crossing the cell (a wall standing on two floors) and must not merge
    (METHOD.md section 4, straddling voxels). Cells with more than 63
    pieces keep signature 0 for the excess planes."""
    n = order.shape[0]
    sig = np.zeros(n, np.int64)
    for r in range(runs.shape[0] - 1):
        a, b = runs[r], runs[r + 1]
        if b - a > 1:
            for i in range(a, b):
                p = order[i]
                s = np.int64(0)
                for j in range(a, min(b, a + 63)):
                    q = order[j]
                    if facing[q] == facing[p]:
                        continue
                    if normal[p, 0] * normal[q, 0] + normal[p, 1] * normal[q, 1] + normal[p, 2] * normal[q, 2] < -0.9:
                        continue  # the other face of a two-sided surface (curved: its pieces' planes differ)
                    d = 0.0
                    for c in range(3):
                        d += (centroid[p, c] / area[p] - centroid[q, c] / area[q]) * normal[q, c]
                    if d > tol:
                        s |= np.int64(1) << np.int64(j - a)
                sig[p] = s
    return sig


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
def _piece_polygon(corners, tri, origin, inv_h, cell):
    """The polygon of scene triangle `tri` clipped to `cell` (grid units)."""
    px = np.empty(MAX_POLY)
    py = np.empty(MAX_POLY)
    pz = np.empty(MAX_POLY)
    for c in range(3):
        px[c] = (corners[tri, c, 0] - origin[0]) * inv_h
        py[c] = (corners[tri, c, 1] - origin[1]) * inv_h
        pz[c] = (corners[tri, c, 2] - origin[2]) * inv_h
    return _clip_to_cell(px, py, pz, cell)


@njit(cache=True)
def _clip_plane(px, py, pz, n, nx, ny, nz, d, keep_front, snap_axis=-1):
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
def _area_centroid(qx, qy, qz, m):
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


@njit(cache=True)
def find_straddlers(by_cell, runs, key, facing, piece_tri, piece_cell, area, centroid, normal, corners, origin, inv_h,
                    min_part):
    """For each piece: the piece of another facing and another triangle in
    the same cell, not facing back at it, whose plane cuts it into two parts
    of at least min_part cells^2 each (a floor running under a wall), else
    -1. One cut per piece: the one that leaves the larger smaller part."""
    n = by_cell.shape[0]
    cut = np.full(n, -1, np.int64)
    for r in range(runs.shape[0] - 1):
        a, b = runs[r], runs[r + 1]
        if b - a > 1:
            for i in range(a, b):
                p = by_cell[i]
                best, best_part = -1, min_part
                qx, qy, qz, m = _piece_polygon(corners, piece_tri[p], origin, inv_h, piece_cell[p])
                for j in range(a, b):
                    q = by_cell[j]
                    if facing[q] == facing[p] or piece_tri[q] == piece_tri[p]:
                        continue
                    nx, ny, nz = normal[q, 0], normal[q, 1], normal[q, 2]
                    if nx * normal[p, 0] + ny * normal[p, 1] + nz * normal[p, 2] < -0.9:
                        continue  # facing back within 25 degrees: the other face of a two-sided surface
                    #             (a curved one: its triangles' planes differ a little), not a surface across
                    d = (centroid[q, 0] * nx + centroid[q, 1] * ny + centroid[q, 2] * nz) / area[q]
                    lo, hi = np.inf, -np.inf
                    for v in range(m):
                        s = qx[v] * nx + qy[v] * ny + qz[v] * nz - d
                        lo = min(lo, s)
                        hi = max(hi, s)
                    if lo >= 0.0 or hi <= 0.0:
                        continue
                    fx, fy, fz, fm = _clip_plane(qx, qy, qz, m, nx, ny, nz, d, True)
                    af, _, _, _ = _area_centroid(fx, fy, fz, fm)
                    part = min(af, area[p] - af)
                    if part > best_part:
                        best, best_part = q, part
                cut[p] = best
    return cut


@njit(cache=True)
def split_pieces(cut, piece_tri, piece_cell, area, centroid, normal, corners, origin, inv_h, extra_index,
                 out_area, out_cen, out_plane, out_sign):
    """Cuts each piece p with cut[p] >= 0 by that piece's plane: the front
    part stays in slot p (sign +1), the back part goes to slot
    extra_index[p] (sign -1); both remember the plane (normal, offset, grid
    units) so that a hit point can be told which part it lies on."""
    n = cut.shape[0]
    for p in range(n):
        q = cut[p]
        if q < 0:
            continue
        qx, qy, qz, m = _piece_polygon(corners, piece_tri[p], origin, inv_h, piece_cell[p])
        nx, ny, nz = normal[q, 0], normal[q, 1], normal[q, 2]
        d = (centroid[q, 0] * nx + centroid[q, 1] * ny + centroid[q, 2] * nz) / area[q]
        for part in range(2):
            fx, fy, fz, fm = _clip_plane(qx, qy, qz, m, nx, ny, nz, d, part == 0)
            a, cx, cy, cz = _area_centroid(fx, fy, fz, fm)
            slot = p if part == 0 else extra_index[p]
            out_area[slot] = a
            out_cen[slot, 0], out_cen[slot, 1], out_cen[slot, 2] = cx, cy, cz
            out_plane[slot, 0], out_plane[slot, 1], out_plane[slot, 2], out_plane[slot, 3] = nx, ny, nz, d
            out_sign[slot] = 1 if part == 0 else -1


@njit(cache=True)
def separating_planes(by_cell, runs, piece_tri, area, centroid, normal, tol, planes, has):
    """Cells where the plane of a piece q has two pieces of other triangles,
    not parallel to it, clearly on both sides (beyond tol cells): a surface
    standing between them inside the cell (a wall between two floors).
    Writes q's plane (normal, offset; grid units) into planes[i] and True
    into has[i] for every piece i of such a cell."""
    for r in range(runs.shape[0] - 1):
        a, b = runs[r], runs[r + 1]
        if b - a > 2:
            for j in range(a, b):
                q = by_cell[j]
                nx, ny, nz = normal[q, 0], normal[q, 1], normal[q, 2]
                d = (centroid[q, 0] * nx + centroid[q, 1] * ny + centroid[q, 2] * nz) / area[q]
                front = back = False
                for i in range(a, b):
                    p = by_cell[i]
                    if piece_tri[p] == piece_tri[q]:
                        continue
                    if abs(normal[p, 0] * nx + normal[p, 1] * ny + normal[p, 2] * nz) >= 0.9:
                        continue
                    sd = (centroid[p, 0] * nx + centroid[p, 1] * ny + centroid[p, 2] * nz) / area[p] - d
                    if sd > tol:
                        front = True
                    elif sd < -tol:
                        back = True
                if front and back:
                    for i in range(a, b):
                        p = by_cell[i]
                        planes[p, 0], planes[p, 1], planes[p, 2], planes[p, 3] = nx, ny, nz, d
                        has[p] = True
                    break
