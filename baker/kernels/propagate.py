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

Memory layout (what a sweep touches per voxel, measured to matter at a
million voxels, where the waiting voxels' data has left the cache by the
time their line meets a surface):
- pos (n, 8) float32 per voxel in the axis's order: centroid (grid
  coordinates), normal, the side of a cutting plane (0: not cut) and the
  index of that plane in cutp (only read for cut voxels);
- the line table (size, 4) int32 per line: stamp (the family that last
  used it: no clearing between families), head of the waiting list, last
  voxel added, hashed key;
- waiting records (n, 8) int32 from a free list, so the live ones stay
  few and close together: centroid and normal (float32 bits), the voxel's
  index in voxel order (-v-1 when cut), the next record;
- the gathered sums (n, 3) float64 in voxel order (written once per
  voxel and family, wherever its line met a surface), the quadrature sums
  S (n,) in the axis's order (written as the sweep passes).
The sweep prefetches, a few cells ahead, the table entry, then the head
record (prefetching the head voxel's sums as well was measured to cost more
than it saves: it needs a load of the record). The rare paths (cells with
several voxels, cut cells, convex edges) are functions of their own:
inlined, they slow the common path by a third (register pressure).
"""
import numpy as np
from numba import njit, prange

from .prefetch import prefetch

EMPTY = -1
CUT_REACH = 3.0   # cells around a cut voxel's cell where its cutting surface is taken to stand
AHEAD_TABLE = 32  # cells ahead: prefetch the line's table entry
AHEAD_HEAD = 16   # ... its first waiting record
RING = 64         # > AHEAD_TABLE, a power of two


@njit(cache=True, inline="always")
def _hash(idx, mask):
    h = np.uint64(idx) * np.uint64(0x9E3779B97F4A7C15)
    h ^= h >> np.uint64(32)
    return np.int64(h & np.uint64(mask))


@njit(cache=True, inline="always")
def _claim(idx, dense, tab, mask, stamp):
    """Slot of line idx in the table, set up empty if this family has not
    used it yet (dense: the id is the slot; else open addressing)."""
    s = idx if dense else _hash(idx, mask)
    while True:
        su = np.uint64(s)
        if tab[su, 0] != stamp:
            tab[su, 0] = stamp
            tab[su, 1] = EMPTY
            tab[su, 2] = EMPTY
            tab[su, 3] = idx
            return s
        if dense or tab[su, 3] == idx:
            return s
        s = (s + 1) & mask


@njit(cache=True, inline="always")
def _find(idx, dense, tab, mask, stamp):
    """Slot of line idx if this family uses it, else -1 (read only)."""
    if dense:
        return idx if tab[np.uint64(idx), 0] == stamp else EMPTY
    s = _hash(idx, mask)
    while tab[np.uint64(s), 0] == stamp:
        if tab[np.uint64(s), 3] == idx:
            return s
        s = (s + 1) & mask
    return EMPTY


@njit(cache=True)
def _separated(px, x, pos, y, buf, m, tau_h, lo0, lo1, lo2):
    """Is y hidden from x by another voxel q of y's cell? True when q's plane
    lies between them (beyond tau h on each side), the segment from x's
    centroid to y's crosses that plane within half a cell of y's cell (the
    26-connected line may step past the cell where it crosses), on the
    side of y's plane where q's piece is: a surface crossing the cell (a
    wall standing on a floor) is in the way."""
    for i in range(m):
        e = buf[i]
        q = e if e >= 0 else -e - 1
        if q == y:
            continue
        sx = sy = 0.0
        for c in range(3):
            nq = float(pos[q, 3 + c])
            sx += (float(px[x, c]) - float(pos[q, c])) * nq
            sy += (float(pos[y, c]) - float(pos[q, c])) * nq
        if (sx > tau_h and sy < -tau_h) or (sx < -tau_h and sy > tau_h):
            lam = sx / (sx - sy)
            x0, x1, x2 = float(px[x, 0]), float(px[x, 1]), float(px[x, 2])
            y0, y1, y2 = float(pos[y, 0]), float(pos[y, 1]), float(pos[y, 2])
            p0 = x0 + (y0 - x0) * lam
            p1 = x1 + (y1 - x1) * lam
            p2 = x2 + (y2 - x2) * lam
            if lo0 - 0.5 <= p0 <= lo0 + 1.5 and lo1 - 0.5 <= p1 <= lo1 + 1.5 and lo2 - 0.5 <= p2 <= lo2 + 1.5:
                # q's piece stands where the segment crosses: on the same side
                # of y's plane as q (a wall rising from a floor), not behind it
                # (the side of a box under its top: a convex edge)
                n0, n1, n2 = float(pos[y, 3]), float(pos[y, 4]), float(pos[y, 5])
                pside = (p0 - y0) * n0 + (p1 - y1) * n1 + (p2 - y2) * n2
                qside = (float(pos[q, 0]) - y0) * n0 + (float(pos[q, 1]) - y1) * n1 + (float(pos[q, 2]) - y2) * n2
                if pside * qside > 0.0:
                    return True
    return False


@njit(cache=True)
def _cut_by(px, x, pos, y, cutp, tau_h):
    """Is x's cell cut by y's own surface (x's cutting plane is y's plane)?
    Then x, behind y's plane even within tau, sees y's back, not its face."""
    j = np.int64(px[x, 7])
    n0, n1, n2 = float(pos[y, 3]), float(pos[y, 4]), float(pos[y, 5])
    dot = cutp[j, 0] * n0 + cutp[j, 1] * n1 + cutp[j, 2] * n2
    if abs(dot) <= 0.999:
        return False
    dy = float(pos[y, 0]) * n0 + float(pos[y, 1]) * n1 + float(pos[y, 2]) * n2
    return abs(cutp[j, 3] - dot * dy) < tau_h


@njit(cache=True)
def _cut_between(pa, a, pb, b, cutp, tau_h):
    """Voxel a was made by cutting its pieces with another surface's plane
    (a wall standing on a floor, a floor running under a wall): if b lies
    on the other side of that plane and the segment a-b crosses it within
    CUT_REACH cells of a's cell, or b's cell is cut by the same plane (the
    surface runs past both ends), that surface stands between them."""
    sign = float(pa[a, 6])
    if sign == 0.0:
        return False
    j = np.int64(pa[a, 7])
    nx, ny, nz, d = cutp[j, 0], cutp[j, 1], cutp[j, 2], cutp[j, 3]
    a0, a1, a2 = float(pa[a, 0]), float(pa[a, 1]), float(pa[a, 2])
    b0, b1, b2 = float(pb[b, 0]), float(pb[b, 1]), float(pb[b, 2])
    sa = a0 * nx + a1 * ny + a2 * nz - d
    sb = b0 * nx + b1 * ny + b2 * nz - d
    if sb * sign >= -tau_h or sa == sb:
        return False
    if pb[b, 6] != 0.0:
        jb = np.int64(pb[b, 7])
        dot = nx * cutp[jb, 0] + ny * cutp[jb, 1] + nz * cutp[jb, 2]
        if abs(dot) > 0.999 and abs(d - dot * cutp[jb, 3]) < tau_h:
            return True
    lam = sa / (sa - sb)
    p0 = a0 + (b0 - a0) * lam
    p1 = a1 + (b1 - a1) * lam
    p2 = a2 + (b2 - a2) * lam
    return cutp[j, 4] - CUT_REACH <= p0 <= cutp[j, 4] + 1.0 + CUT_REACH and \
        cutp[j, 5] - CUT_REACH <= p1 <= cutp[j, 5] + 1.0 + CUT_REACH and \
        cutp[j, 6] - CUT_REACH <= p2 <= cutp[j, 6] + 1.0 + CUT_REACH


@njit(cache=True)
def _order_cell(a, m, pos, ux, uy, uz, buf, bkey):
    """The m voxels of a cell from a, in order along the sweep (ties: +1
    before -1), into buf as v (n.s > 0) or -v-1."""
    for i in range(m):
        v = a + i
        t = float(pos[v, 0]) * ux + float(pos[v, 1]) * uy + float(pos[v, 2]) * uz
        o = float(pos[v, 3]) * ux + float(pos[v, 4]) * uy + float(pos[v, 5]) * uz
        j = i
        while j > 0 and (bkey[j - 1] > t or (bkey[j - 1] == t and buf[j - 1] < 0 and o > 0)):
            bkey[j] = bkey[j - 1]
            buf[j] = buf[j - 1]
            j -= 1
        bkey[j] = t
        buf[j] = v if o > 0 else -v - 1  # the sign carries the orientation


@njit(cache=True)
def _hidden(px, x, pos, y, xcut, ycut, d, g, m, buf, gcell, cutp, tau_h):
    """Is y, facing x's waiting ray within tau, hidden from x by another
    surface: one crossing y's cell, or one that cut x's or y's pieces?"""
    if m > 1 and _separated(px, x, pos, y, buf, m, tau_h, float(gcell[g, 0]), float(gcell[g, 1]), float(gcell[g, 2])):
        return True
    if xcut or ycut:
        return _cut_between(pos, y, px, x, cutp, tau_h) or _cut_between(px, x, pos, y, cutp, tau_h) or \
            (d < 0.0 and xcut and _cut_by(px, x, pos, y, cutp, tau_h))
    return False


@njit(cache=True)
def _convex_edge(z, y, pos, kappa_h):
    """Do z (the voxel last added to the line) and y, which turns its back,
    form a convex edge: each just behind the other's plane, within kappa?"""
    z0, z1, z2 = float(pos[z, 0]), float(pos[z, 1]), float(pos[z, 2])
    y0, y1, y2 = float(pos[y, 0]), float(pos[y, 1]), float(pos[y, 2])
    dz = (z0 - y0) * float(pos[y, 3]) + (z1 - y1) * float(pos[y, 4]) + (z2 - y2) * float(pos[y, 5])
    ez = (y0 - z0) * float(pos[z, 3]) + (y1 - z1) * float(pos[z, 4]) + (y2 - z2) * float(pos[z, 5])
    return dz < 0.0 and ez < 0.0 and dz >= -kappa_h


@njit(cache=True, inline="always")
def _unlink(j, prev, head, rec, free, nfree):
    """Removes record j (after prev, or the head) from its list and frees
    it: returns the new head."""
    if prev == EMPTY:
        head = rec[j, 7]
    else:
        rec[prev, 7] = rec[j, 7]
    free[nfree] = j
    return head


@njit(cache=True)
def _sweep(starts, gcell, order, pos, pos_all, cutp, rad, gat, quad, k, k1, k2, A, B, C, mu, mu2, ux, uy, uz, weight,
           forward, tau, kappa, dense, pmin, P, qmin, tab, mask, stamp, rec, recf, free, buf, bkey):
    """One sweep of one direction (forwards: +s, backwards: -s) over the
    voxels in this axis's order (index = position in the order; lengths in
    cells). gcell (ng, 3) int32 the cells, starts (ng + 1,) their voxels.
    Rows are indexed through unsigned copies of the indices (yu, ju, su...):
    numba then skips the negative-index wrap-around, a third of the
    instructions of this loop."""
    ng = starts.shape[0] - 1
    if not forward:
        ux, uy, uz = -ux, -uy, -uz
    tau_h = tau
    kappa_h = kappa
    nfree = 0
    ntop = 0
    ring = np.empty(RING, np.int64)  # line ids of the next cells
    xa = np.int64(-(2 ** 62))
    pa = qa = np.int64(0)
    uk, uk1, uk2 = np.uint64(k), np.uint64(k1), np.uint64(k2)
    for i0 in range(-AHEAD_TABLE, ng):
        # the prefetch pipeline: line id and table entry, head record
        ia = i0 + AHEAD_TABLE
        if ia < ng:
            gau = np.uint64(ia if forward else ng - 1 - ia)
            X = np.int64(gcell[gau, uk])
            if X != xa:
                # floor((C X - A Z - mu) / A) = floor((C X - mu) / A) - Z: one division per slab of X
                xa = X
                pa = (C * X - mu) // A
                qa = (B * X - mu2) // A
            idx = (qa - np.int64(gcell[gau, uk1]) - qmin) * P + (pa - np.int64(gcell[gau, uk2]) - pmin)
            ring[np.uint64(ia & (RING - 1))] = idx
            prefetch(tab, idx if dense else _hash(idx, mask))
        ib = i0 + AHEAD_HEAD
        if 0 <= ib < ng:
            sb = _find(ring[np.uint64(ib & (RING - 1))], dense, tab, mask, stamp)
            if sb != EMPTY:
                hb = tab[np.uint64(sb), 1]
                if hb != EMPTY:
                    prefetch(rec, hb)
        if i0 < 0:
            continue
        g = i0 if forward else ng - 1 - i0
        s = _claim(ring[np.uint64(i0 & (RING - 1))], dense, tab, mask, stamp)
        su = np.uint64(s)
        head = np.int64(tab[su, 1])
        last = np.int64(tab[su, 2])
        gu = np.uint64(g)
        a, b = np.int64(starts[gu]), np.int64(starts[gu + np.uint64(1)])
        # the cell's voxels in order along the sweep; ties: +1 before -1
        m = b - a
        if m > 1:
            _order_cell(a, m, pos, ux, uy, uz, buf, bkey)
        for i in range(m):
            if m == 1:
                y = a
            else:
                e = buf[i]
                y = e if e >= 0 else -e - 1
            yu = np.uint64(y)
            ny0, ny1, ny2 = float(pos[yu, 3]), float(pos[yu, 4]), float(pos[yu, 5])
            o = ny0 * ux + ny1 * uy + ny2 * uz
            if o == 0.0:
                continue  # parallel to the line: neither sends nor receives
            cy0, cy1, cy2 = float(pos[yu, 0]), float(pos[yu, 1]), float(pos[yu, 2])
            ycut = pos[yu, 6] != 0.0
            prev = EMPTY
            j = head
            if o < 0.0:
                # y faces the rays: waiting voxels in front of (or near) its plane see it
                while j != EMPTY:
                    ju = np.uint64(j)
                    nj = np.int64(rec[ju, 7])
                    d = (float(recf[ju, 0]) - cy0) * ny0 + (float(recf[ju, 1]) - cy1) * ny1 + \
                        (float(recf[ju, 2]) - cy2) * ny2
                    if d >= -tau_h:
                        xe = np.int64(rec[ju, 6])
                        x = xe if xe >= 0 else -xe - 1
                        if (m == 1 and xe >= 0 and not ycut) or \
                                not _hidden(pos_all, x, pos, y, xe < 0, ycut, d, g, m, buf, gcell, cutp, tau_h):
                            w = (float(recf[ju, 3]) * ux + float(recf[ju, 4]) * uy + float(recf[ju, 5]) * uz) * weight
                            xu = np.uint64(x)
                            gat[xu, 0] += rad[yu, 0] * w
                            gat[xu, 1] += rad[yu, 1] * w
                            gat[xu, 2] += rad[yu, 2] * w
                        if prev == EMPTY:
                            head = nj
                        else:
                            rec[np.uint64(prev), 7] = nj
                        free[np.uint64(nfree)] = j
                        nfree += 1
                    else:
                        prev = j
                    j = nj
            else:
                # y turns its back: voxels behind its plane hit that back, unless convex edge
                z_known = False
                z_edge = False
                while j != EMPTY:
                    ju = np.uint64(j)
                    nj = np.int64(rec[ju, 7])
                    d = (float(recf[ju, 0]) - cy0) * ny0 + (float(recf[ju, 1]) - cy1) * ny1 + \
                        (float(recf[ju, 2]) - cy2) * ny2
                    blocked = False
                    if d < -tau_h:
                        if not z_known:
                            z_known = True
                            z_edge = _convex_edge(last, y, pos, kappa_h)
                        if not z_edge:
                            ex = (cy0 - float(recf[ju, 0])) * float(recf[ju, 3]) + \
                                (cy1 - float(recf[ju, 1])) * float(recf[ju, 4]) + \
                                (cy2 - float(recf[ju, 2])) * float(recf[ju, 5])
                            blocked = not (ex < 0.0 and d >= -kappa_h)
                    if blocked:
                        if prev == EMPTY:
                            head = nj
                        else:
                            rec[np.uint64(prev), 7] = nj
                        free[np.uint64(nfree)] = j
                        nfree += 1
                    else:
                        prev = j
                    j = nj
                quad[yu] += o * weight
                if nfree > 0:
                    nfree -= 1
                    j = np.int64(free[np.uint64(nfree)])
                else:
                    j = ntop
                    ntop += 1
                ju = np.uint64(j)
                for c in range(6):
                    recf[ju, c] = pos[yu, c]
                v = np.int64(order[yu])
                rec[ju, 6] = -v - 1 if ycut else v
                rec[ju, 7] = head
                head = j
                last = y
        tab[su, 1] = head
        tab[su, 2] = last


@njit(cache=True, parallel=True)
def _permute(order, st, cell, pos_all, radiosity, pos, gcell, rad):
    """Lays the voxel data out in an axis's order."""
    n = order.shape[0]
    for i in prange(n):
        v = order[i]
        for c in range(8):
            pos[i, c] = pos_all[v, c]
        for c in range(3):
            rad[i, c] = radiosity[v, c]
    for g in prange(st.shape[0] - 1):
        v = order[st[g]]
        for c in range(3):
            gcell[g, c] = cell[v, c]


@njit(cache=True, parallel=True)
def _scatter_add(order, quad_k, quad):
    """Adds an axis's quadrature sums back in voxel order and clears them."""
    for i in prange(order.shape[0]):
        quad[order[i]] += quad_k[i]
        quad_k[i] = 0.0


@njit(cache=True, parallel=True)
def _families(fams, st, gcell, order, pos, pos_all, cutp, rad, gat, quad_k, cell_lo, cell_hi, vectors, units, weights,
              offsets, k, tau, kappa, size, tabs, recs, frees, bufs, bkeys, stamp0):
    k1, k2 = (k + 1) % 3, (k + 2) % 3
    for fi in range(fams.shape[0]):
        f = fams[fi]
        A, B, C = np.int64(vectors[f, k]), np.int64(vectors[f, k1]), np.int64(vectors[f, k2])
        mu, mu2 = np.int64(offsets[f, 0]), np.int64(offsets[f, 1])
        x0, x1, y0, y1, z0, z1 = cell_lo[k], cell_hi[k], cell_lo[k1], cell_hi[k1], cell_lo[k2], cell_hi[k2]
        pmin = (min(C * x0, C * x1) - A * z1 - mu) // A
        pmax = (max(C * x0, C * x1) - A * z0 - mu) // A
        qmin = (min(B * x0, B * x1) - A * y1 - mu2) // A
        qmax = (max(B * x0, B * x1) - A * y0 - mu2) // A
        P = pmax - pmin + 1
        dense = P * (qmax - qmin + 1) <= size
        for sw in prange(2):
            _sweep(st, gcell, order, pos, pos_all, cutp, rad, gat, quad_k, k, k1, k2, A, B, C, mu, mu2, units[f, 0],
                   units[f, 1], units[f, 2], weights[f], sw == 0, tau, kappa, dense, pmin, P, qmin, tabs[sw], size - 1,
                   stamp0 + fi, recs[sw], recs[sw].view(np.float32), frees[sw], bufs[sw], bkeys[sw])


def propagate_families(orders, starts, cell, cell_lo, cell_hi, pos_all, cutp, radiosity, vectors, axes, units, weights,
                       offsets, tau, kappa, max_group, table_size, hashed):
    """Gathers radiosity over every family of a direction set.

    Lengths in cells. pos_all (n, 8) float32 per voxel: centroid in grid
    coordinates, normal, the side of the plane that cut its pieces (0:
    none) and that plane's row in cutp (m, 7) float64 (normal, offset n.g,
    the voxel's cell). orders (3, n) int32: voxel order with axis 0, 1, 2
    major; starts (3, ng+1) the cell boundaries in each order; cell (n, 3)
    int32; cell_lo, cell_hi (3,) the cells' bounding box; table_size the
    line table's rows (a power of two when hashed: the dense range of some
    family would exceed what the voxels need). vectors (nf, 3) canonical
    s; axes (nf,) dominant axis; units (nf, 3) unit s; weights (nf,)
    dW(s) / pi; offsets (nf, 2) line offsets mu, mu'.
    Returns gathered (n, 3) = sum_s B(I(x, s)) (n.s) dW / pi and the
    quadrature's own cosine integral S(n_x) (n,), both float64.
    """
    n = cell.shape[0]
    gathered = np.zeros((n, 3))
    quad = np.zeros(n)
    if n == 0:
        return gathered, quad
    ng = starts.shape[1] - 1
    pos = np.empty((n, 8), np.float32)
    gcell = np.empty((ng, 3), np.int32)
    rad = np.empty((n, 3))
    quad_k = np.zeros(n)
    tabs = np.full((2, table_size, 4), -1, np.int32)
    # waiting records: only the live ones are touched (a few per cent of n)
    recs = np.empty((2, n, 8), np.int32)
    frees = np.empty((2, n), np.int32)
    bufs = np.empty((2, max_group), np.int64)
    bkeys = np.empty((2, max_group))
    stamp = 0
    for k in range(3):
        fams = np.nonzero(axes == k)[0]
        if len(fams) == 0:
            continue
        _permute(orders[k], starts[k], cell, pos_all, radiosity, pos, gcell, rad)
        _families(fams, starts[k], gcell, orders[k], pos, pos_all, cutp, rad, gathered, quad_k, cell_lo, cell_hi,
                  vectors, units, weights, offsets, k, tau, kappa, table_size, tabs, recs, frees, bufs, bkeys, stamp)
        stamp += len(fams)
        _scatter_add(orders[k], quad_k, quad)
    return gathered, quad


# ---- the pull sweep: senders gather as the sweep reaches them ----------------------------------------------
#
# Sweeping the voxels in the order opposite to the rays (the order of -u for rays along u), a
# voxel x sending along u meets, on its line, the voxels its ray would cross, nearest first:
# they were visited before it. Each line keeps that history, newest first: the newest item
# inline in the line's item (its centroid, normal, radiosity, flags), older ones in a pool.
# x scans it with the same tests the waiting list applies (a receiver within tau: gather, or
# hidden: 0; a back face beyond tau: blocked unless a convex edge with x or with the last
# back face passed), so the result is identical; but x's sums are written as the sweep
# passes x (in sequence), and what it reads is the line's item, fetched ahead.
HF_VOXEL = (1 << 28) - 1
HF_CUT = 1 << 28
HF_RECEIVER = 1 << 29
HF_MULTI = 1 << 30


@njit(cache=True)
def _hidden_pull(x, h, d, starts, gcell, pos, cutp, tau_h):
    """_hidden for a scanner x and a history item h (both axis positions)."""
    if pos[h, 6] != 0.0 or pos[x, 6] != 0.0:
        if _cut_between(pos, h, pos, x, cutp, tau_h) or _cut_between(pos, x, pos, h, cutp, tau_h) or \
                (d < 0.0 and pos[x, 6] != 0.0 and _cut_by(pos, x, pos, h, cutp, tau_h)):
            return True
    g = np.searchsorted(starts, h, "right") - 1
    a, b = starts[g], starts[g + 1]
    if b - a > 1:
        buf = np.empty(b - a, np.int64)
        for i in range(b - a):
            buf[i] = a + i
        return _separated(pos, x, pos, h, buf, b - a, tau_h, float(gcell[g, 0]), float(gcell[g, 1]),
                          float(gcell[g, 2]))
    return False


@njit(cache=True)
def _scan_deep(x, j, pool, pos, rad, starts, gcell, cutp, ux, uy, uz, tau_h, kappa_h, zc0, zc1, zc2, zn0, zn1, zn2,
               out):
    """Continues x's scan at pool record j (items older than the inline
    one, read from pos and rad). Writes the gathered radiosity into out
    (3,) and returns True when x gathers."""
    cx0, cx1, cx2 = float(pos[x, 0]), float(pos[x, 1]), float(pos[x, 2])
    nx0, nx1, nx2 = float(pos[x, 3]), float(pos[x, 4]), float(pos[x, 5])
    while j != EMPTY:
        hf = pool[j, 0]
        h = hf & HF_VOXEL
        c0, c1, c2 = float(pos[h, 0]), float(pos[h, 1]), float(pos[h, 2])
        n0, n1, n2 = float(pos[h, 3]), float(pos[h, 4]), float(pos[h, 5])
        d = (cx0 - c0) * n0 + (cx1 - c1) * n1 + (cx2 - c2) * n2
        if hf & HF_RECEIVER:
            if d >= -tau_h:
                if (hf & (HF_CUT | HF_MULTI)) or pos[x, 6] != 0.0:
                    if _hidden_pull(x, h, d, starts, gcell, pos, cutp, tau_h):
                        return False
                out[0] = rad[h, 0]
                out[1] = rad[h, 1]
                out[2] = rad[h, 2]
                return True
        else:
            if d < -tau_h:
                dz = (zc0 - c0) * n0 + (zc1 - c1) * n1 + (zc2 - c2) * n2
                ez = (c0 - zc0) * zn0 + (c1 - zc1) * zn1 + (c2 - zc2) * zn2
                ex = (c0 - cx0) * nx0 + (c1 - cx1) * nx1 + (c2 - cx2) * nx2
                if not (dz < 0.0 and ez < 0.0 and dz >= -kappa_h) and not (ex < 0.0 and d >= -kappa_h):
                    return False
            zc0, zc1, zc2, zn0, zn1, zn2 = c0, c1, c2, n0, n1, n2
        j = pool[j, 1]
    return False


@njit(cache=True)
def _sweep_pull(starts, gcell, pos, cutp, rad, acc, k, k1, k2, A, B, C, mu, mu2, ux, uy, uz, weight, forward, tau,
                kappa, dense, pmin, P, qmin, tab, mask, stamp, items, itemsf, itemsd, pool, buf, bkey, out):
    """One sweep: in the axis order (forward) for rays along -s, in reverse
    for rays along +s; every voxel sending along the rays gathers from its
    line's history, every voxel not parallel to the line joins it."""
    ng = starts.shape[0] - 1
    if forward:
        ux, uy, uz = -ux, -uy, -uz
    tau_h = tau
    kappa_h = kappa
    ntop = 0   # pool records used
    nitem = 0  # line items used by this family
    ring = np.empty(RING, np.int64)
    xa = np.int64(-(2 ** 62))
    pa = qa = np.int64(0)
    for i0 in range(-AHEAD_TABLE, ng):
        ia = i0 + AHEAD_TABLE
        if ia < ng:
            ga = ia if forward else ng - 1 - ia
            X = np.int64(gcell[ga, k])
            if X != xa:
                xa = X
                pa = (C * X - mu) // A
                qa = (B * X - mu2) // A
            idx = (qa - np.int64(gcell[ga, k1]) - qmin) * P + (pa - np.int64(gcell[ga, k2]) - pmin)
            ring[ia & (RING - 1)] = idx
            prefetch(tab, idx if dense else _hash(idx, mask))
        ib = i0 + AHEAD_HEAD
        if 0 <= ib < ng:
            sb = _find(ring[ib & (RING - 1)], dense, tab, mask, stamp)
            if sb != EMPTY:
                prefetch(items, tab[sb, 2])
        if i0 < 0:
            continue
        g = i0 if forward else ng - 1 - i0
        s = _claim(ring[i0 & (RING - 1)], dense, tab, mask, stamp)
        it = tab[s, 2]
        if it == EMPTY:
            it = nitem
            nitem += 1
            tab[s, 2] = it
            items[it, 0] = EMPTY
            items[it, 1] = EMPTY
        a, b = starts[g], starts[g + 1]
        m = b - a
        if m > 1:
            _order_cell(a, m, pos, ux, uy, uz, buf, bkey)
        for i in range(m):
            if m == 1:
                y = a
            else:
                e = buf[m - 1 - i]  # the cell's voxels against the rays
                y = e if e >= 0 else -e - 1
            ny0, ny1, ny2 = float(pos[y, 3]), float(pos[y, 4]), float(pos[y, 5])
            o = ny0 * ux + ny1 * uy + ny2 * uz
            if o == 0.0:
                continue
            cy0, cy1, cy2 = float(pos[y, 0]), float(pos[y, 1]), float(pos[y, 2])
            hf_old = items[it, 0]
            if o > 0.0:
                # y sends along the rays: scan its line's history, nearest first
                w = o * weight
                acc[y, 3] += w
                if hf_old != EMPTY:
                    c0, c1, c2 = float(itemsf[it, 2]), float(itemsf[it, 3]), float(itemsf[it, 4])
                    n0, n1, n2 = float(itemsf[it, 5]), float(itemsf[it, 6]), float(itemsf[it, 7])
                    d = (cy0 - c0) * n0 + (cy1 - c1) * n1 + (cy2 - c2) * n2
                    if hf_old & HF_RECEIVER:
                        if d >= -tau_h:
                            if not ((hf_old & (HF_CUT | HF_MULTI)) or pos[y, 6] != 0.0) or \
                                    not _hidden_pull(y, hf_old & HF_VOXEL, d, starts, gcell, pos, cutp, tau_h):
                                acc[y, 0] += itemsd[it, 4] * w
                                acc[y, 1] += itemsd[it, 5] * w
                                acc[y, 2] += itemsd[it, 6] * w
                        elif _scan_deep(y, items[it, 1], pool, pos, rad, starts, gcell, cutp, ux, uy, uz, tau_h,
                                        kappa_h, cy0, cy1, cy2, ny0, ny1, ny2, out):
                            acc[y, 0] += out[0] * w
                            acc[y, 1] += out[1] * w
                            acc[y, 2] += out[2] * w
                    else:
                        passed = True
                        if d < -tau_h:
                            # a back face beyond tau: blocked unless y (the last sender before it) and it form a
                            # convex edge
                            ex = (c0 - cy0) * ny0 + (c1 - cy1) * ny1 + (c2 - cy2) * ny2
                            passed = ex < 0.0 and d >= -kappa_h
                        if passed and _scan_deep(y, items[it, 1], pool, pos, rad, starts, gcell, cutp, ux, uy, uz,
                                                 tau_h, kappa_h, c0, c1, c2, n0, n1, n2, out):
                            acc[y, 0] += out[0] * w
                            acc[y, 1] += out[1] * w
                            acc[y, 2] += out[2] * w
            # y joins the history: the inline item moves to the pool
            if hf_old != EMPTY:
                pool[ntop, 0] = hf_old
                pool[ntop, 1] = items[it, 1]
                items[it, 1] = ntop
                ntop += 1
            hf = y
            if o < 0.0:
                hf |= HF_RECEIVER
            if pos[y, 6] != 0.0:
                hf |= HF_CUT
            if m > 1:
                hf |= HF_MULTI
            items[it, 0] = hf
            itemsf[it, 2] = pos[y, 0]
            itemsf[it, 3] = pos[y, 1]
            itemsf[it, 4] = pos[y, 2]
            itemsf[it, 5] = pos[y, 3]
            itemsf[it, 6] = pos[y, 4]
            itemsf[it, 7] = pos[y, 5]
            itemsd[it, 4] = rad[y, 0]
            itemsd[it, 5] = rad[y, 1]
            itemsd[it, 6] = rad[y, 2]


@njit(cache=True, parallel=True)
def _families_pull(fams, st, gcell, pos, cutp, rad, acc, cell_lo, cell_hi, vectors, units, weights, offsets, k, tau,
                   kappa, size, tabs, items, pools, bufs, bkeys, outs, stamp0):
    k1, k2 = (k + 1) % 3, (k + 2) % 3
    for fi in range(fams.shape[0]):
        f = fams[fi]
        A, B, C = np.int64(vectors[f, k]), np.int64(vectors[f, k1]), np.int64(vectors[f, k2])
        mu, mu2 = np.int64(offsets[f, 0]), np.int64(offsets[f, 1])
        x0, x1, y0, y1, z0, z1 = cell_lo[k], cell_hi[k], cell_lo[k1], cell_hi[k1], cell_lo[k2], cell_hi[k2]
        pmin = (min(C * x0, C * x1) - A * z1 - mu) // A
        pmax = (max(C * x0, C * x1) - A * z0 - mu) // A
        qmin = (min(B * x0, B * x1) - A * y1 - mu2) // A
        qmax = (max(B * x0, B * x1) - A * y0 - mu2) // A
        P = pmax - pmin + 1
        dense = P * (qmax - qmin + 1) <= size
        for sw in prange(2):
            _sweep_pull(st, gcell, pos, cutp, rad, acc, k, k1, k2, A, B, C, mu, mu2, units[f, 0], units[f, 1],
                        units[f, 2], weights[f], sw == 0, tau, kappa, dense, pmin, P, qmin, tabs[sw], size - 1,
                        stamp0 + fi, items[sw], items[sw].view(np.float32), items[sw].view(np.float64), pools[sw],
                        bufs[sw], bkeys[sw], outs[sw])


@njit(cache=True, parallel=True)
def _scatter_acc(order, acc, gathered, quad):
    """Adds an axis's sums (gathered, S) back in voxel order and clears them."""
    for i in prange(order.shape[0]):
        v = order[i]
        for c in range(3):
            gathered[v, c] += acc[i, c]
            acc[i, c] = 0.0
        quad[v] += acc[i, 3]
        acc[i, 3] = 0.0


def _aligned(shape, dtype, align=64):
    """np.empty with the first element on an `align`-byte boundary (rows of
    64 bytes then each sit in one cache line)."""
    dtype = np.dtype(dtype)
    count = int(np.prod(shape))
    raw = np.empty(count * dtype.itemsize + align, np.uint8)
    off = (-raw.ctypes.data) % align
    return raw[off:off + count * dtype.itemsize].view(dtype).reshape(shape)


def propagate_families_pull(orders, starts, cell, cell_lo, cell_hi, pos_all, cutp, radiosity, vectors, axes, units,
                            weights, offsets, tau, kappa, max_group, table_size, hashed):
    """propagate_families by pull sweeps (same arguments, same result)."""
    n = cell.shape[0]
    gathered = np.zeros((n, 3))
    quad = np.zeros(n)
    if n == 0:
        return gathered, quad
    if n > HF_VOXEL:
        raise ValueError("too many voxels for the propagation's 28-bit voxel index")
    ng = starts.shape[1] - 1
    pos = np.empty((n, 8), np.float32)
    gcell = np.empty((ng, 3), np.int32)
    rad = np.empty((n, 3))
    acc = np.zeros((n, 4))
    tabs = np.full((2, table_size, 4), -1, np.int32)
    items = _aligned((2, ng, 16), np.int32)   # only the lines a family meets are touched
    pools = np.empty((2, n, 2), np.int32)
    bufs = np.empty((2, max_group), np.int64)
    bkeys = np.empty((2, max_group))
    outs = np.empty((2, 3))
    stamp = 0
    for k in range(3):
        fams = np.nonzero(axes == k)[0]
        if len(fams) == 0:
            continue
        _permute(orders[k], starts[k], cell, pos_all, radiosity, pos, gcell, rad)
        _families_pull(fams, starts[k], gcell, pos, cutp, rad, acc, cell_lo, cell_hi, vectors, units, weights, offsets,
                       k, tau, kappa, table_size, tabs, items, pools, bufs, bkeys, outs, stamp)
        stamp += len(fams)
        _scatter_acc(orders[k], acc, gathered, quad)
    return gathered, quad
