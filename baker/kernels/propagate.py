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
def _separated(x, y, buf, m, rec, tau_h, lo0, lo1, lo2, h):
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
            sx += (rec[x, c] - rec[q, c]) * rec[q, 3 + c]
            sy += (rec[y, c] - rec[q, c]) * rec[q, 3 + c]
        if (sx > tau_h and sy < -tau_h) or (sx < -tau_h and sy > tau_h):
            lam = sx / (sx - sy)
            px = rec[x, 0] + (rec[y, 0] - rec[x, 0]) * lam
            py = rec[x, 1] + (rec[y, 1] - rec[x, 1]) * lam
            pz = rec[x, 2] + (rec[y, 2] - rec[x, 2]) * lam
            if lo0 - 0.5 * h <= px <= lo0 + h + 0.5 * h and lo1 - 0.5 * h <= py <= lo1 + h + 0.5 * h and \
                    lo2 - 0.5 * h <= pz <= lo2 + h + 0.5 * h:
                # q's piece stands where the segment crosses: on the same side
                # of y's plane as q (a wall rising from a floor), not behind it
                # (the side of a box under its top: a convex edge)
                pside = (px - rec[y, 0]) * rec[y, 3] + (py - rec[y, 1]) * rec[y, 4] + (pz - rec[y, 2]) * rec[y, 5]
                qside = (rec[q, 0] - rec[y, 0]) * rec[y, 3] + (rec[q, 1] - rec[y, 1]) * rec[y, 4] + \
                    (rec[q, 2] - rec[y, 2]) * rec[y, 5]
                if pside * qside > 0.0:
                    return True
    return False


CUT_REACH = 3.0  # cells around a cut voxel's cell where its cutting surface is taken to stand


@njit(cache=True, inline="always")
def _unlink(head, s, nxt, prev, nx_):
    """Removes from line s's waiting list the voxel after prev (head if none)."""
    if prev == EMPTY:
        head[s] = nx_
    else:
        nxt[prev] = nx_


@njit(cache=True, inline="always")
def _cut_by(x, y, rec, cp, tau_h):
    """Is x's cell cut by y's own surface (x's cutting plane is y's plane)?
    Then x, behind y's plane even within tau, sees y's back, not its face."""
    if rec[x, 15] == 0.0:
        return False
    dot = cp[x, 0] * rec[y, 3] + cp[x, 1] * rec[y, 4] + cp[x, 2] * rec[y, 5]
    if abs(dot) <= 0.999:
        return False
    dy = rec[y, 0] * rec[y, 3] + rec[y, 1] * rec[y, 4] + rec[y, 2] * rec[y, 5]
    return abs(cp[x, 3] - dot * dy) < tau_h


@njit(cache=True, inline="always")
def _cut_between(a, b, rec, cp, cell, tau_h):
    """Voxel a was made by cutting its pieces with another surface's plane
    (a wall standing on a floor, a floor running under a wall): if b lies
    on the other side of that plane and the segment a-b crosses it within
    CUT_REACH cells of a's cell, or b's cell is cut by the same plane (the
    surface runs past both ends), that surface stands between them."""
    sign = rec[a, 15]
    if sign == 0.0:
        return False
    nx, ny, nz, d = cp[a, 0], cp[a, 1], cp[a, 2], cp[a, 3]
    sa = rec[a, 0] * nx + rec[a, 1] * ny + rec[a, 2] * nz - d
    sb = rec[b, 0] * nx + rec[b, 1] * ny + rec[b, 2] * nz - d
    if sb * sign >= -tau_h or sa == sb:
        return False
    if rec[b, 15] != 0.0:
        dot = nx * cp[b, 0] + ny * cp[b, 1] + nz * cp[b, 2]
        if abs(dot) > 0.999 and abs(d - dot * cp[b, 3]) < tau_h:
            return True
    lam = sa / (sa - sb)
    for c in range(3):
        p = rec[a, c] + (rec[b, c] - rec[a, c]) * lam
        if p < cell[a, c] - CUT_REACH or p > cell[a, c] + 1.0 + CUT_REACH:
            return False
    return True


@njit(cache=True)
def _sweep(starts, cell, rec, cp, k, k1, k2, A, B, C, mu, mu2, ux, uy, uz, weight, forward, tau, kappa, dense, pmin,
           P, qmin, head, last, hkeys, mask, nxt, touched, buf, bkey):
    """One sweep of one direction (forwards: +s, backwards: -s) over voxels
    stored in this axis's order (index = position in the order). Lengths
    are in cells. rec (n, 16) holds, per voxel, what a sweep touches
    together (two cache lines): centroid 0-2, normal 3-5, cos weight 6
    (forwards) or 7 (backwards), gathered 8-10, S 11, radiosity 12-14, the
    voxel's side of the plane that cut its cell 15 (0: not cut); that plane
    is cp (n, 4), read only for cut voxels."""
    ng = starts.shape[0] - 1
    cw = 6 if forward else 7
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
        s = _slot(pc - Z, qc - Y, dense, pmin, P, qmin, hkeys, mask)
        if head[s] == UNTOUCHED:
            head[s] = EMPTY
            last[s] = EMPTY
            touched[n_touched] = s
            n_touched += 1
        lo0, lo1, lo2 = float(cell[a, 0]), float(cell[a, 1]), float(cell[a, 2])
        # the cell's voxels in order along the sweep; ties: +1 before -1
        m = b - a
        if m == 1:
            o = rec[a, 3] * ux + rec[a, 4] * uy + rec[a, 5] * uz
            buf[0] = a if o > 0 else -a - 1
        else:
            for i in range(m):
                v = a + i
                t = rec[v, 0] * ux + rec[v, 1] * uy + rec[v, 2] * uz
                o = rec[v, 3] * ux + rec[v, 4] * uy + rec[v, 5] * uz
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
            ny0, ny1, ny2 = rec[y, 3], rec[y, 4], rec[y, 5]
            o = ny0 * ux + ny1 * uy + ny2 * uz
            if o == 0.0:
                continue  # parallel to the line: neither sends nor receives
            cy0, cy1, cy2 = rec[y, 0], rec[y, 1], rec[y, 2]
            prev = EMPTY
            x = head[s]
            if o < 0.0:
                # y faces the rays: waiting voxels in front of (or near) its plane see it
                while x != EMPTY:
                    nx_ = nxt[x]
                    d = (rec[x, 0] - cy0) * ny0 + (rec[x, 1] - cy1) * ny1 + (rec[x, 2] - cy2) * ny2
                    if d >= -tau_h:
                        seen = m == 1 or not _separated(x, y, buf, m, rec, tau_h, lo0, lo1, lo2, h)
                        if seen and (rec[x, 15] != 0.0 or rec[y, 15] != 0.0):  # a surface cuts x's or y's cell
                            seen = not _cut_between(y, x, rec, cp, cell, tau_h) and \
                                not _cut_between(x, y, rec, cp, cell, tau_h) and \
                                not (d < 0.0 and _cut_by(x, y, rec, cp, tau_h))
                        if seen:
                            w = rec[x, cw]
                            rec[x, 8] += rec[y, 12] * w
                            rec[x, 9] += rec[y, 13] * w
                            rec[x, 10] += rec[y, 14] * w
                        _unlink(head, s, nxt, prev, nx_)
                    else:
                        prev = x
                    x = nx_
            else:
                # y turns its back: voxels behind its plane hit that back, unless convex edge
                z = last[s]
                z_edge = False
                if z != EMPTY:
                    dz = (rec[z, 0] - cy0) * ny0 + (rec[z, 1] - cy1) * ny1 + (rec[z, 2] - cy2) * ny2
                    ez = (cy0 - rec[z, 0]) * rec[z, 3] + (cy1 - rec[z, 1]) * rec[z, 4] + (cy2 - rec[z, 2]) * rec[z, 5]
                    z_edge = dz < 0.0 and ez < 0.0 and dz >= -kappa_h
                while x != EMPTY:
                    nx_ = nxt[x]
                    d = (rec[x, 0] - cy0) * ny0 + (rec[x, 1] - cy1) * ny1 + (rec[x, 2] - cy2) * ny2
                    blocked = False
                    if d < -tau_h and not z_edge:
                        ex = (cy0 - rec[x, 0]) * rec[x, 3] + (cy1 - rec[x, 1]) * rec[x, 4] + \
                            (cy2 - rec[x, 2]) * rec[x, 5]
                        blocked = not (ex < 0.0 and d >= -kappa_h)
                    if blocked:
                        _unlink(head, s, nxt, prev, nx_)
                    else:
                        prev = x
                    x = nx_
                w = o * weight
                rec[y, cw] = w
                rec[y, 11] += w
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
def _gather_permuted(order, cell, frac, normal, cut, radiosity, cell_k, rec, cp):
    """Lays the voxel data out in axis order: cell (int32) and the record
    (centroid = cell + float32 fraction, normal, radiosity; sums zeroed)."""
    n = order.shape[0]
    for i in prange(n):
        v = order[i]
        for c in range(3):
            cell_k[i, c] = cell[v, c]
            rec[i, c] = float(cell[v, c]) + float(frac[v, c])
            rec[i, 3 + c] = normal[v, c]
            rec[i, 8 + c] = 0.0
            rec[i, 12 + c] = radiosity[v, c]
        rec[i, 11] = 0.0
        for c in range(4):
            cp[i, c] = cut[v, c]
        rec[i, 15] = cut[v, 4]


def propagate_families(orders, starts, cell, cell_lo, cell_hi, frac, normal, cut, radiosity, vectors, axes,
                       units, weights, offsets, tau, kappa, max_group, table_size, hashed):
    """Gathers radiosity over every family of a direction set.

    Lengths in cells: frac (n, 3) float32 the centroid's position within its
    cell (centroid = cell + frac, grid coordinates), normal (n, 3) float32,
    cut (n, 5) the plane (normal, offset) of a surface that cut the voxel's
    pieces and the voxel's side of it (0: none),
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
    rec = np.empty((n, 16))
    cp = np.empty((n, 4))
    for k in range(3):
        fams = np.nonzero(axes == k)[0]
        if len(fams) == 0:
            continue
        _gather_permuted(orders[k], cell, frac, normal, cut, radiosity, cell_k, rec, cp)
        _families(fams, starts[k], cell_k, rec, cp, cell_lo, cell_hi, vectors, units, weights, offsets, k, tau, kappa,
                  table_size, *scratch)
        _scatter_add(orders[k], rec, gathered, quad)
    return gathered, quad


def _scratch(n, ng, max_group, table_size, hashed):
    """Per sweep (2): line table (head, last; hashed keys only when hashing),
    linked list, touched slots, the cell's sort buffer."""
    return (np.full((2, table_size), UNTOUCHED, np.int32), np.full((2, table_size), EMPTY, np.int32),
            np.full((2, table_size if hashed else 1), EMPTY, np.int64), np.empty((2, n), np.int32),
            np.empty((2, ng), np.int32), np.empty((2, max_group), np.int64), np.empty((2, max_group)))


@njit(cache=True, parallel=True)
def _families(fams, st, cell_k, rec, cp, cell_lo, cell_hi, vectors, units, weights, offsets, k, tau, kappa, size,
              heads, lasts, hkeys, nxts, toucheds, bufs, bkeys):
    k1, k2 = (k + 1) % 3, (k + 2) % 3
    for fi in range(fams.shape[0]):
        f = fams[fi]
        A, B, C = np.int64(vectors[f, k]), np.int64(vectors[f, k1]), np.int64(vectors[f, k2])
        mu, mu2 = np.int64(offsets[f, 0]), np.int64(offsets[f, 1])
        pmin, P, qmin, Q = _line_bounds(cell_lo, cell_hi, k, k1, k2, A, B, C, mu, mu2)
        dense = P * Q <= size
        for sweep in prange(2):
            _sweep(st, cell_k, rec, cp, k, k1, k2, A, B, C, mu, mu2, units[f, 0], units[f, 1], units[f, 2], weights[f],
                   sweep == 0, tau, kappa, dense, pmin, P, qmin, heads[sweep], lasts[sweep], hkeys[sweep], size - 1,
                   nxts[sweep], toucheds[sweep], bufs[sweep], bkeys[sweep])


@njit(cache=True, parallel=True)
def _scatter_add(order, rec, gathered, quad):
    """Adds an axis's sums back in voxel order."""
    for i in prange(order.shape[0]):
        v = order[i]
        gathered[v, 0] += rec[i, 8]
        gathered[v, 1] += rec[i, 9]
        gathered[v, 2] += rec[i, 10]
        quad[v] += rec[i, 11]
