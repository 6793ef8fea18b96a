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

Visibility (the rule of METHOD.md section 4): a voxel with n.s > 0 starts
a ray and joins the line's waiting list; every next voxel y is tested
against every waiting x with d_x = (c_x - c_y).n_y:
  y faces the rays (n_y.s < 0): x with d_x >= -tau h gathers B(y) and leaves;
  y turns its back (n_y.s > 0): x with d_x < -tau h is blocked (gathers 0,
    leaves) unless x or the last added voxel z forms a convex edge with y
    (d_z < 0, (c_y - c_z).n_z < 0, d_z >= -kappa h); then y joins the list.
y is hidden from x when another voxel q of y's cell has its plane between
them and the segment x -> y crosses it inside that cell (a wall standing
mid-cell on a floor).
Gathering writes only the gathering voxel, and a voxel gathers along s or
-s, never both: the two sweeps of a family run in parallel, and families
run in a fixed order, so the result is identical for any thread count.
"""
import math

import numpy as np
from numba import njit, prange

EMPTY = -1


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
def _slot(p, q, dense, pmin, qmin, Q, hkeys, mask):
    """Table slot of line (p, q): dense index, or open addressing when the
    dense table would be far larger than the voxel set (sparse scenes)."""
    idx = (p - pmin) * Q + (q - qmin)
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
def _separated(x, y, buf, m, centroid, normal, tau_h, lo0, lo1, lo2, h):
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
            sx += (centroid[x, c] - centroid[q, c]) * normal[q, c]
            sy += (centroid[y, c] - centroid[q, c]) * normal[q, c]
        if (sx > tau_h and sy < -tau_h) or (sx < -tau_h and sy > tau_h):
            lam = sx / (sx - sy)
            px = centroid[x, 0] + (centroid[y, 0] - centroid[x, 0]) * lam
            py = centroid[x, 1] + (centroid[y, 1] - centroid[x, 1]) * lam
            pz = centroid[x, 2] + (centroid[y, 2] - centroid[x, 2]) * lam
            if lo0 - 0.5 * h <= px <= lo0 + h + 0.5 * h and lo1 - 0.5 * h <= py <= lo1 + h + 0.5 * h and \
                    lo2 - 0.5 * h <= pz <= lo2 + h + 0.5 * h:
                # q's piece stands where the segment crosses: on the same side
                # of y's plane as q (a wall rising from a floor), not behind it
                # (the side of a box under its top: a convex edge)
                pside = (px - centroid[y, 0]) * normal[y, 0] + (py - centroid[y, 1]) * normal[y, 1] + \
                    (pz - centroid[y, 2]) * normal[y, 2]
                qside = (centroid[q, 0] - centroid[y, 0]) * normal[y, 0] + (centroid[q, 1] - centroid[y, 1]) * \
                    normal[y, 1] + (centroid[q, 2] - centroid[y, 2]) * normal[y, 2]
                if pside * qside > 0.0:
                    return True
    return False


@njit(cache=True)
def _sweep(order, starts, cell, origin, centroid, normal, radiosity, gathered, quad, k, k1, k2, A, B, C, mu, mu2,
           ux, uy, uz, weight, forward, h, tau, kappa, dense, pmin, qmin, Q, head, last, hkeys, mask, nxt,
           cosw, touched, buf, bkey):
    """One sweep of one direction (forwards: +s, backwards: -s)."""
    ng = starts.shape[0] - 1
    if not forward:
        ux, uy, uz = -ux, -uy, -uz
    n_touched = 0
    tau_h = tau * h
    kappa_h = kappa * h
    for gi in range(ng):
        g = gi if forward else ng - 1 - gi
        a, b = starts[g], starts[g + 1]
        v0 = order[a]
        X, Y, Z = np.int64(cell[v0, k]), np.int64(cell[v0, k1]), np.int64(cell[v0, k2])
        lo0 = origin[0] + cell[v0, 0] * h
        lo1 = origin[1] + cell[v0, 1] * h
        lo2 = origin[2] + cell[v0, 2] * h
        p = (C * X - A * Z - mu) // A
        q = (B * X - A * Y - mu2) // A
        s = _slot(p, q, dense, pmin, qmin, Q, hkeys, mask)
        if head[s] == -2:
            head[s] = EMPTY
            last[s] = EMPTY
            touched[n_touched] = s
            n_touched += 1
        # the cell's voxels in order along the sweep; ties: +1 before -1
        m = b - a
        for i in range(m):
            v = order[a + i]
            t = centroid[v, 0] * ux + centroid[v, 1] * uy + centroid[v, 2] * uz
            o = normal[v, 0] * ux + normal[v, 1] * uy + normal[v, 2] * uz
            j = i
            while j > 0 and (bkey[j - 1] > t or (bkey[j - 1] == t and buf[j - 1] < 0 and o > 0)):
                bkey[j] = bkey[j - 1]
                buf[j] = buf[j - 1]
                j -= 1
            bkey[j] = t
            buf[j] = v if o > 0 else -v - 1  # sign carries the orientation
        for i in range(m):
            e = buf[i]
            y = e if e >= 0 else -e - 1
            ny0, ny1, ny2 = normal[y, 0], normal[y, 1], normal[y, 2]
            o = ny0 * ux + ny1 * uy + ny2 * uz
            if o == 0.0:
                continue  # parallel to the line: neither sends nor receives
            cy0, cy1, cy2 = centroid[y, 0], centroid[y, 1], centroid[y, 2]
            prev = EMPTY
            x = head[s]
            if o < 0.0:
                # y faces the rays: waiting voxels in front of (or near) its plane see it
                while x != EMPTY:
                    nx_ = nxt[x]
                    d = (centroid[x, 0] - cy0) * ny0 + (centroid[x, 1] - cy1) * ny1 + (centroid[x, 2] - cy2) * ny2
                    if d >= -tau_h:
                        if m == 1 or not _separated(x, y, buf, m, centroid, normal, tau_h, lo0, lo1, lo2, h):
                            w = cosw[x]
                            gathered[x, 0] += radiosity[y, 0] * w
                            gathered[x, 1] += radiosity[y, 1] * w
                            gathered[x, 2] += radiosity[y, 2] * w
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
                    dz = (centroid[z, 0] - cy0) * ny0 + (centroid[z, 1] - cy1) * ny1 + (centroid[z, 2] - cy2) * ny2
                    ez = (cy0 - centroid[z, 0]) * normal[z, 0] + (cy1 - centroid[z, 1]) * normal[z, 1] + \
                        (cy2 - centroid[z, 2]) * normal[z, 2]
                    z_edge = dz < 0.0 and ez < 0.0 and dz >= -kappa_h
                while x != EMPTY:
                    nx_ = nxt[x]
                    d = (centroid[x, 0] - cy0) * ny0 + (centroid[x, 1] - cy1) * ny1 + (centroid[x, 2] - cy2) * ny2
                    blocked = False
                    if d < -tau_h:
                        blocked = True
                        if z_edge:
                            blocked = False
                        else:
                            ex = (cy0 - centroid[x, 0]) * normal[x, 0] + (cy1 - centroid[x, 1]) * normal[x, 1] + \
                                (cy2 - centroid[x, 2]) * normal[x, 2]
                            if ex < 0.0 and d >= -kappa_h:
                                blocked = False
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
        head[s] = -2
        last[s] = EMPTY
        if not dense:
            hkeys[s] = EMPTY


@njit(cache=True, parallel=True)
def propagate_families(orders, starts, cell, origin, cell_lo, cell_hi, centroid, normal, radiosity, vectors, axes, units,
                       weights, offsets, h, tau, kappa, max_group, table_size):
    """Gathers radiosity over every family of a direction set.

    orders (3, n) int64: voxel order with axis 0, 1, 2 major; starts (3, ng+1)
    the cell boundaries in each order; cell_lo, cell_hi (3,) the cells'
    bounding box; table_size a power of two >= 2 * cells. vectors (nf, 3) int
    canonical s; axes (nf,) dominant axis; units (nf, 3) unit s; weights
    (nf,) dW(s) / pi; offsets (nf, 2) line offsets mu, mu'.
    Returns gathered (n, 3) = sum_s B(I(x, s)) (n.s) dW / pi and the
    quadrature's own cosine integral S(n_x) (n,), both float64.
    """
    n = cell.shape[0]
    ng = starts.shape[1] - 1
    gathered = np.zeros((n, 3))
    quad = np.zeros(n)
    nf = vectors.shape[0]
    # per sweep (2): line table (dense or hashed), linked list, cos weights
    size = table_size
    heads = np.full((2, size), -2, np.int64)
    lasts = np.full((2, size), EMPTY, np.int64)
    hkeys = np.full((2, size), EMPTY, np.int64)
    nxts = np.empty((2, n), np.int64)
    cosws = np.empty((2, n))
    toucheds = np.empty((2, ng), np.int64)
    bufs = np.empty((2, max_group), np.int64)
    bkeys = np.empty((2, max_group))
    for f in range(nf):
        k = axes[f]
        k1, k2 = (k + 1) % 3, (k + 2) % 3
        A, B, C = np.int64(vectors[f, k]), np.int64(vectors[f, k1]), np.int64(vectors[f, k2])
        mu, mu2 = np.int64(offsets[f, 0]), np.int64(offsets[f, 1])
        pmin, P, qmin, Q = _line_bounds(cell_lo, cell_hi, k, k1, k2, A, B, C, mu, mu2)
        dense = P * Q <= size
        mask = size - 1
        order = orders[k]
        st = starts[k]
        for sweep in prange(2):
            _sweep(order, st, cell, origin, centroid, normal, radiosity, gathered, quad, k, k1, k2, A, B, C, mu, mu2,
                   units[f, 0], units[f, 1], units[f, 2], weights[f], sweep == 0, h, tau, kappa, dense, pmin, qmin,
                   Q, heads[sweep], lasts[sweep], hkeys[sweep], mask, nxts[sweep], cosws[sweep], toucheds[sweep],
                   bufs[sweep], bkeys[sweep])
    return gathered, quad
