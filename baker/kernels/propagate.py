"""Linear propagation over digital lines (METHOD.md section 4).

For a family {s, -s}, s = (A, B, C) in the frame (X, Y, Z) = (dominant axis,
next, next) with A > 0, the naive digital lines
    mu  <= C X - A Z < mu  + A,    mu' <= B X - A Y < mu' + A
partition the grid; the line of cell (X, Y, Z) is
(floor((C X - A Z - mu) / A), floor((B X - A Y - mu') / A)) and X is the
position along it. Voxels are visited in the dominant-axis-major order
(precomputed once), so each line is met in increasing X without sorting:
a table keyed by line id holds the line's state (a sweep with a
line-state table). Along +s the sweep runs forwards, along -s backwards.
Families are processed grouped by dominant axis, over a copy of the voxel
data laid out in that axis's order, so the sweeps read memory in sequence.

Visibility (the rule of METHOD.md section 4): a voxel with n.s > 0 starts
a ray and joins the line's waiting list; every next voxel y is tested
against every waiting x with d_x = (c_x - c_y).n_y:
  y faces the rays (n_y.s < 0): x with d_x >= -tau h gathers B(y) and leaves;
  y turns its back (n_y.s > 0): x with d_x < -tau h is blocked (gathers 0,
    leaves) unless x or the last added voxel z forms a convex edge with y
    (d_z < 0, (c_y - c_z).n_z < 0, d_z >= -kappa h); then y joins the list.
y is hidden from x when another voxel q of y's cell has its plane between
them and the segment x -> y crosses it near that cell, on the side of y's
plane where q stands (a wall standing mid-cell on a floor).
Gathering writes only the gathering voxel, and a voxel gathers along s or
-s, never both: the two sweeps of a family run in parallel, and families
run in a fixed order, so the result is identical for any thread count.
"""
import numpy as np
from numba import njit, prange

EMPTY = -1
UNTOUCHED = -2


@njit(cache=True)
def _line_bounds(lo, hi, k, k1, k2, A, B, C, mu, mu2):
    """Range of line ids over the voxels' bounding box (lo, hi cells): (pmin, P, qmin, Q)."""
    x0, x1, y0, y1, z0, z1 = lo[k], hi[k], lo[k1], hi[k1], lo[k2], hi[k2]
    pmin = (min(C * x0, C * x1) - A * z1 - mu) // A
    pmax = (max(C * x0, C * x1) - A * z0 - mu) // A
    qmin = (min(B * x0, B * x1) - A * y1 - mu2) // A
    qmax = (max(B * x0, B * x1) - A * y0 - mu2) // A
    return pmin, pmax - pmin + 1, qmin, qmax - qmin + 1


@njit(cache=True, inline="always")
def _slot(p, q, dense, pmin, P, qmin, hkeys, mask):
    """Table slot of line (p, q): dense index (p fastest: the next cells of
    a column meet adjacent entries), or open addressing when the dense table
    would be far larger than the voxel set (sparse scenes). Measured: the
    table costs ~4 ns per voxel and family at any size; the waiting lists'
    revisits of voxels met long before dominate at large N (bench notes)."""
    idx = (q - qmin) * P + (p - pmin)
    if dense:
        return idx
    h = np.uint64(idx) * np.uint64(0x9E3779B97F4A7C15)
    h ^= h >> np.uint64(32)
    s = np.int64(h & np.uint64(mask))
    while True:
        kk = hkeys[s]
        if kk == idx:
            return s
        if kk == EMPTY:
            hkeys[s] = idx
            return s
        s = (s + 1) & mask


@njit(cache=True, inline="always")
def _separated(x, y, buf, m, cen, nrm, tau_h, lo0, lo1, lo2, h):
    """Is y hidden from x by another voxel q of y's cell? True when q's plane
    lies between them (beyond tau h on each side), the segment from x's
    centroid to y's crosses that plane within half a cell of y's cell (the
    26-connected line may step past the cell where it crosses), on the
    side of y's plane where q's piece is: a surface crossing the cell (a
    wall standing on a floor) is in the way."""
    for i in range(m):
        e = buf[i]
        q = e if e >= 0 else -e - 1
        if q == x or q == y:
            continue
        sx = sy = 0.0
        for c in range(3):
            sx += (cen[x, c] - cen[q, c]) * nrm[q, c]
            sy += (cen[y, c] - cen[q, c]) * nrm[q, c]
        if (sx > tau_h and sy < -tau_h) or (sx < -tau_h and sy > tau_h):
            lam = sx / (sx - sy)
            px = cen[x, 0] + (cen[y, 0] - cen[x, 0]) * lam
            py = cen[x, 1] + (cen[y, 1] - cen[x, 1]) * lam
            pz = cen[x, 2] + (cen[y, 2] - cen[x, 2]) * lam
            if lo0 - 0.5 * h <= px <= lo0 + h + 0.5 * h and lo1 - 0.5 * h <= py <= lo1 + h + 0.5 * h and \
                    lo2 - 0.5 * h <= pz <= lo2 + h + 0.5 * h:
                # q's piece stands where the segment crosses: on the same side
                # of y's plane as q (a wall rising from a floor), not behind it
                # (the side of a box under its top: a convex edge)
                pside = (px - cen[y, 0]) * nrm[y, 0] + (py - cen[y, 1]) * nrm[y, 1] + (pz - cen[y, 2]) * nrm[y, 2]
                qside = (cen[q, 0] - cen[y, 0]) * nrm[y, 0] + (cen[q, 1] - cen[y, 1]) * nrm[y, 1] + \
                    (cen[q, 2] - cen[y, 2]) * nrm[y, 2]
                if pside * qside > 0.0:
                    return True
    return False


@njit(cache=True)
def _sweep(starts, cell, cen, nrm, rad, gathered, quad, k, k1, k2, A, B, C, mu, mu2, ux, uy, uz, weight,
           forward, tau, kappa, dense, pmin, P, qmin, head, last, hkeys, mask, nxt, cosw, touched, buf, bkey):
    """One sweep of one direction (forwards: +s, backwards: -s) over voxels
    stored in this axis's order (index = position in the order). Lengths
    are in cells: cen holds centroids in cell units (float64)."""
    ng = starts.shape[0] - 1
    if not forward:
        ux, uy, uz = -ux, -uy, -uz
    n_touched = 0
    tau_h = tau
    kappa_h = kappa
    h = 1.0
    x_cur = np.int64(-(2 ** 62))
    pc = qc = np.int64(0)
    for gi in range(ng):
        g = gi if forward else ng - 1 - gi
        a, b = starts[g], starts[g + 1]
        X, Y, Z = np.int64(cell[a, k]), np.int64(cell[a, k1]), np.int64(cell[a, k2])
        if X != x_cur:
            # floor((C X - A Z - mu) / A) = floor((C X - mu) / A) - Z: one division per slab of X
            x_cur = X
            pc = (C * X - mu) // A
            qc = (B * X - mu2) // A
        p = pc - Z
        q = qc - Y
        s = _slot(p, q, dense, pmin, P, qmin, hkeys, mask)
        if head[s] == UNTOUCHED:
            head[s] = EMPTY
            last[s] = EMPTY
            touched[n_touched] = s
            n_touched += 1
        lo0, lo1, lo2 = float(cell[a, 0]), float(cell[a, 1]), float(cell[a, 2])
        # the cell's voxels in order along the sweep; ties: +1 before -1
        m = b - a
        if m == 1:
            o = nrm[a, 0] * ux + nrm[a, 1] * uy + nrm[a, 2] * uz
            buf[0] = a if o > 0 else -a - 1
        else:
            for i in range(m):
                v = a + i
                t = cen[v, 0] * ux + cen[v, 1] * uy + cen[v, 2] * uz
                o = nrm[v, 0] * ux + nrm[v, 1] * uy + nrm[v, 2] * uz
                j = i
                while j > 0 and (bkey[j - 1] > t or (bkey[j - 1] == t and buf[j - 1] < 0 and o > 0)):
                    bkey[j] = bkey[j - 1]
                    buf[j] = buf[j - 1]
                    j -= 1
                bkey[j] = t
                buf[j] = v if o > 0 else -v - 1  # the sign carries the orientation
        for i in range(m):
            e = buf[i]
            y = e if e >= 0 else -e - 1
            ny0, ny1, ny2 = nrm[y, 0], nrm[y, 1], nrm[y, 2]
            o = ny0 * ux + ny1 * uy + ny2 * uz
            if o == 0.0:
                continue  # parallel to the line: neither sends nor receives
            cy0, cy1, cy2 = cen[y, 0], cen[y, 1], cen[y, 2]
            prev = EMPTY
            x = head[s]
            if o < 0.0:
                # y faces the rays: waiting voxels in front of (or near) its plane see it
                while x != EMPTY:
                    nx_ = nxt[x]
                    d = (cen[x, 0] - cy0) * ny0 + (cen[x, 1] - cy1) * ny1 + (cen[x, 2] - cy2) * ny2
                    if d >= -tau_h:
                        if m == 1 or not _separated(x, y, buf, m, cen, nrm, tau_h, lo0, lo1, lo2, h):
                            w = cosw[x]
                            gathered[x, 0] += rad[y, 0] * w
                            gathered[x, 1] += rad[y, 1] * w
                            gathered[x, 2] += rad[y, 2] * w
                        if prev == EMPTY:
                            head[s] = nx_
                        else:
                            nxt[prev] = nx_
                    else:
                        prev = x
                    x = nx_
            else:
                # y turns its back: voxels behind its plane hit that back, unless convex edge
                z = last[s]
                z_edge = False
                if z != EMPTY:
                    dz = (cen[z, 0] - cy0) * ny0 + (cen[z, 1] - cy1) * ny1 + (cen[z, 2] - cy2) * ny2
                    ez = (cy0 - cen[z, 0]) * nrm[z, 0] + (cy1 - cen[z, 1]) * nrm[z, 1] + (cy2 - cen[z, 2]) * nrm[z, 2]
                    z_edge = dz < 0.0 and ez < 0.0 and dz >= -kappa_h
                while x != EMPTY:
                    nx_ = nxt[x]
                    d = (cen[x, 0] - cy0) * ny0 + (cen[x, 1] - cy1) * ny1 + (cen[x, 2] - cy2) * ny2
                    blocked = False
                    if d < -tau_h and not z_edge:
                        ex = (cy0 - cen[x, 0]) * nrm[x, 0] + (cy1 - cen[x, 1]) * nrm[x, 1] + \
                            (cy2 - cen[x, 2]) * nrm[x, 2]
                        blocked = not (ex < 0.0 and d >= -kappa_h)
                    if blocked:
                        if prev == EMPTY:
                            head[s] = nx_
                        else:
                            nxt[prev] = nx_
                    else:
                        prev = x
                    x = nx_
                w = o * weight
                cosw[y] = w
                quad[y] += w
                nxt[y] = head[s]
                head[s] = y
                last[s] = y
    for i in range(n_touched):
        s = touched[i]
        head[s] = UNTOUCHED
        last[s] = EMPTY
        if not dense:
            hkeys[s] = EMPTY


@njit(cache=True, parallel=True)
def _gather_permuted(order, cell, frac, normal, radiosity, cell_k, cen_k, nrm_k, rad_k):
    """Copies the voxel data into axis order: cell (int32), centroid in grid
    coordinates = cell + float32 fraction (float64), normal (float32 values
    as float64), radiosity (float32): the sweeps read memory in sequence."""
    n = order.shape[0]
    for i in prange(n):
        v = order[i]
        for c in range(3):
            cell_k[i, c] = cell[v, c]
            cen_k[i, c] = float(cell[v, c]) + float(frac[v, c])
            nrm_k[i, c] = normal[v, c]
            rad_k[i, c] = radiosity[v, c]


def propagate_families(orders, starts, cell, cell_lo, cell_hi, frac, normal, radiosity, vectors, axes,
                       units, weights, offsets, tau, kappa, max_group, table_size, hashed):
    """Gathers radiosity over every family of a direction set.

    Lengths in cells: frac (n, 3) float32 the centroid's position within its
    cell (centroid = cell + frac, grid coordinates), normal (n, 3) float32,
    tau and kappa in cells. orders (3, n) int32: voxel order with axis 0, 1,
    2 major; starts (3, ng+1) the cell boundaries in each order; cell_lo,
    cell_hi (3,) the cells' bounding box; table_size the line table's size
    (a power of two when hashed: some family's dense range would exceed
    it). vectors (nf, 3) canonical s; axes (nf,) dominant axis; units (nf, 3) unit s; weights
    (nf,) dW(s) / pi; offsets (nf, 2) line offsets mu, mu'.
    Returns gathered (n, 3) = sum_s B(I(x, s)) (n.s) dW / pi and the
    quadrature's own cosine integral S(n_x) (n,), both float64.
    """
    n = cell.shape[0]
    gathered = np.zeros((n, 3))
    quad = np.zeros(n)
    if n == 0:
        return gathered, quad
    scratch = _scratch(n, starts.shape[1] - 1, max_group, table_size, hashed)
    cell_k = np.empty((n, 3), np.int32)
    cen_k = np.empty((n, 3))
    nrm_k = np.empty((n, 3))
    rad_k = np.empty((n, 3), np.float32)
    g_k = np.empty((n, 3))
    q_k = np.empty(n)
    for k in range(3):
        fams = np.nonzero(axes == k)[0]
        if len(fams) == 0:
            continue
        _gather_permuted(orders[k], cell, frac, normal, radiosity, cell_k, cen_k, nrm_k, rad_k)
        g_k[:] = 0.0
        q_k[:] = 0.0
        _families(fams, starts[k], cell_k, cen_k, nrm_k, rad_k, g_k, q_k, cell_lo, cell_hi, vectors, units,
                  weights, offsets, k, tau, kappa, table_size, *scratch)
        _scatter_add(orders[k], g_k, q_k, gathered, quad)
    return gathered, quad


def _scratch(n, ng, max_group, table_size, hashed):
    """Per sweep (2): line table (head, last; hashed keys only when hashing),
    linked list, cos weights, touched slots, the cell's sort buffer."""
    return (np.full((2, table_size), UNTOUCHED, np.int32), np.full((2, table_size), EMPTY, np.int32),
            np.full((2, table_size if hashed else 1), EMPTY, np.int64), np.empty((2, n), np.int32),
            np.empty((2, n)),
            np.empty((2, ng), np.int32), np.empty((2, max_group), np.int64), np.empty((2, max_group)))


@njit(cache=True, parallel=True)
def _families(fams, st, cell_k, cen_k, nrm_k, rad_k, g_k, q_k, cell_lo, cell_hi, vectors, units, weights, offsets,
              k, tau, kappa, size, heads, lasts, hkeys, nxts, cosws, toucheds, bufs, bkeys):
    k1, k2 = (k + 1) % 3, (k + 2) % 3
    for fi in range(fams.shape[0]):
        f = fams[fi]
        A, B, C = np.int64(vectors[f, k]), np.int64(vectors[f, k1]), np.int64(vectors[f, k2])
        mu, mu2 = np.int64(offsets[f, 0]), np.int64(offsets[f, 1])
        pmin, P, qmin, Q = _line_bounds(cell_lo, cell_hi, k, k1, k2, A, B, C, mu, mu2)
        dense = P * Q <= size
        for sweep in prange(2):
            _sweep(st, cell_k, cen_k, nrm_k, rad_k, g_k, q_k, k, k1, k2, A, B, C, mu, mu2, units[f, 0], units[f, 1],
                   units[f, 2], weights[f], sweep == 0, tau, kappa, dense, pmin, P, qmin, heads[sweep],
                   lasts[sweep], hkeys[sweep], size - 1, nxts[sweep], cosws[sweep], toucheds[sweep], bufs[sweep],
                   bkeys[sweep])


@njit(cache=True, parallel=True)
def _scatter_add(order, g_k, q_k, gathered, quad):
    for i in prange(order.shape[0]):
        v = order[i]
        gathered[v, 0] += g_k[i, 0]
        gathered[v, 1] += g_k[i, 1]
        gathered[v, 2] += g_k[i, 2]
        quad[v] += q_k[i]
