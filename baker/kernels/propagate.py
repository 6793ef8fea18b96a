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
Gathering writes only the gathering voxel. Families are swept several per
pass (one read of the voxel data serves all of them), in two fixed slots
with their own sums added in a fixed order, so the result is identical for
any thread count.
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
    would be far larger than the voxel set (sparse scenes)."""
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
def _pos(cell, cen, v, c):
    """Grid coordinate c of voxel v's centroid (the axis copy holds them as
    float64 cell + fraction)."""
    return cen[v, c]


@njit(cache=True, inline="always")
def _separated(x, y, buf, m, cell, frac, nrm, tau_h, lo0, lo1, lo2, h):
    """Is y hidden from x by another voxel q of y's cell? True when q's plane
    lies between them (beyond tau h on each side), the segment from x's
    centroid to y's crosses that plane within half a cell of y's cell (the
    26-connected line may step past the cell where it crosses), on the
    side of y's plane where q's piece is: a surface crossing the cell (a
    wall standing on a floor) is in the way."""
    x0, x1, x2 = _pos(cell, frac, x, 0), _pos(cell, frac, x, 1), _pos(cell, frac, x, 2)
    y0, y1, y2 = _pos(cell, frac, y, 0), _pos(cell, frac, y, 1), _pos(cell, frac, y, 2)
    for i in range(m):
        e = buf[i]
        q = e if e >= 0 else -e - 1
        if q == x or q == y:
            continue
        q0, q1, q2 = _pos(cell, frac, q, 0), _pos(cell, frac, q, 1), _pos(cell, frac, q, 2)
        m0, m1, m2 = float(nrm[q, 0]), float(nrm[q, 1]), float(nrm[q, 2])
        sx = (x0 - q0) * m0 + (x1 - q1) * m1 + (x2 - q2) * m2
        sy = (y0 - q0) * m0 + (y1 - q1) * m1 + (y2 - q2) * m2
        if (sx > tau_h and sy < -tau_h) or (sx < -tau_h and sy > tau_h):
            lam = sx / (sx - sy)
            px = x0 + (y0 - x0) * lam
            py = x1 + (y1 - x1) * lam
            pz = x2 + (y2 - x2) * lam
            if lo0 - 0.5 * h <= px <= lo0 + h + 0.5 * h and lo1 - 0.5 * h <= py <= lo1 + h + 0.5 * h and \
                    lo2 - 0.5 * h <= pz <= lo2 + h + 0.5 * h:
                # q's piece stands where the segment crosses: on the same side
                # of y's plane as q (a wall rising from a floor), not behind it
                # (the side of a box under its top: a convex edge)
                n0, n1, n2 = float(nrm[y, 0]), float(nrm[y, 1]), float(nrm[y, 2])
                pside = (px - y0) * n0 + (py - y1) * n1 + (pz - y2) * n2
                qside = (q0 - y0) * n0 + (q1 - y1) * n1 + (q2 - y2) * n2
                if pside * qside > 0.0:
                    return True
    return False


@njit(cache=True)
def _sweep(starts, cell, cen, nrm, rad, gathered, quad, k, k1, k2, fams, vectors, units, weights, offsets, forward,
           tau, kappa, dense, pmin, P, qmin, state, hkeys, mask, nxt, touched, n_touched, pc, qc, buf, bkey):
    """One pass over the voxels (stored in this axis's order; lengths in
    cells) sweeping the F families `fams` at once in one direction
    (forwards: +s, backwards: -s): each voxel's data is read once for all
    F. Per family j: its line table state[j] (head and last added voxel of
    each line's waiting list, side by side), hkeys[j], linked list nxt[j],
    touched slots."""
    ng = starts.shape[0] - 1
    nfam = fams.shape[0]
    sgn = 1.0 if forward else -1.0
    tau_h = tau
    kappa_h = kappa
    h = 1.0
    x_cur = np.int64(-(2 ** 62))
    for gi in range(ng):
        g = gi if forward else ng - 1 - gi
        a, b = starts[g], starts[g + 1]
        X, Y, Z = np.int64(cell[a, k]), np.int64(cell[a, k1]), np.int64(cell[a, k2])
        if X != x_cur:
            # floor((C X - A Z - mu) / A) = floor((C X - mu) / A) - Z: divisions once per slab of X
            x_cur = X
            for j in range(nfam):
                f = fams[j]
                A = np.int64(vectors[f, k])
                pc[j] = (np.int64(vectors[f, k2]) * X - np.int64(offsets[f, 0])) // A
                qc[j] = (np.int64(vectors[f, k1]) * X - np.int64(offsets[f, 1])) // A
        lo0, lo1, lo2 = float(cell[a, 0]), float(cell[a, 1]), float(cell[a, 2])
        m = b - a
        for j in range(nfam):
            f = fams[j]
            ux, uy, uz = sgn * units[f, 0], sgn * units[f, 1], sgn * units[f, 2]
            weight = weights[f]
            s = _slot(pc[j] - Z, qc[j] - Y, dense[j], pmin[j], P[j], qmin[j], hkeys[j], mask)
            if state[j, s, 0] == UNTOUCHED:
                state[j, s, 0] = EMPTY
                state[j, s, 1] = EMPTY
                touched[j, n_touched[j]] = s
                n_touched[j] += 1
            # the cell's voxels in order along the sweep; ties: +1 before -1
            if m == 1:
                o = nrm[a, 0] * ux + nrm[a, 1] * uy + nrm[a, 2] * uz
                buf[0] = a if o > 0 else -a - 1
            else:
                for i in range(m):
                    v = a + i
                    t = cen[v, 0] * ux + cen[v, 1] * uy + cen[v, 2] * uz
                    o = nrm[v, 0] * ux + nrm[v, 1] * uy + nrm[v, 2] * uz
                    jj = i
                    while jj > 0 and (bkey[jj - 1] > t or (bkey[jj - 1] == t and buf[jj - 1] < 0 and o > 0)):
                        bkey[jj] = bkey[jj - 1]
                        buf[jj] = buf[jj - 1]
                        jj -= 1
                    bkey[jj] = t
                    buf[jj] = v if o > 0 else -v - 1  # the sign carries the orientation
            for i in range(m):
                e = buf[i]
                y = e if e >= 0 else -e - 1
                ny0, ny1, ny2 = nrm[y, 0], nrm[y, 1], nrm[y, 2]
                o = ny0 * ux + ny1 * uy + ny2 * uz
                if o == 0.0:
                    continue  # parallel to the line: neither sends nor receives
                cy0, cy1, cy2 = cen[y, 0], cen[y, 1], cen[y, 2]
                prev = EMPTY
                x = state[j, s, 0]
                if o < 0.0:
                    # y faces the rays: waiting voxels in front of (or near) its plane see it
                    while x != EMPTY:
                        nx_ = nxt[j, x]
                        d = (cen[x, 0] - cy0) * ny0 + (cen[x, 1] - cy1) * ny1 + (cen[x, 2] - cy2) * ny2
                        if d >= -tau_h:
                            if m == 1 or not _separated(x, y, buf, m, cell, cen, nrm, tau_h, lo0, lo1, lo2, h):
                                w = (nrm[x, 0] * ux + nrm[x, 1] * uy + nrm[x, 2] * uz) * weight
                                gathered[x, 0] += rad[y, 0] * w
                                gathered[x, 1] += rad[y, 1] * w
                                gathered[x, 2] += rad[y, 2] * w
                            if prev == EMPTY:
                                state[j, s, 0] = nx_
                            else:
                                nxt[j, prev] = nx_
                        else:
                            prev = x
                        x = nx_
                else:
                    # y turns its back: voxels behind its plane hit that back, unless convex edge
                    z = state[j, s, 1]
                    z_edge = False
                    if z != EMPTY:
                        dz = (cen[z, 0] - cy0) * ny0 + (cen[z, 1] - cy1) * ny1 + (cen[z, 2] - cy2) * ny2
                        ez = (cy0 - cen[z, 0]) * nrm[z, 0] + (cy1 - cen[z, 1]) * nrm[z, 1] + \
                            (cy2 - cen[z, 2]) * nrm[z, 2]
                        z_edge = dz < 0.0 and ez < 0.0 and dz >= -kappa_h
                    while x != EMPTY:
                        nx_ = nxt[j, x]
                        d = (cen[x, 0] - cy0) * ny0 + (cen[x, 1] - cy1) * ny1 + (cen[x, 2] - cy2) * ny2
                        blocked = False
                        if d < -tau_h and not z_edge:
                            ex = (cy0 - cen[x, 0]) * nrm[x, 0] + (cy1 - cen[x, 1]) * nrm[x, 1] + \
                                (cy2 - cen[x, 2]) * nrm[x, 2]
                            blocked = not (ex < 0.0 and d >= -kappa_h)
                        if blocked:
                            if prev == EMPTY:
                                state[j, s, 0] = nx_
                            else:
                                nxt[j, prev] = nx_
                        else:
                            prev = x
                        x = nx_
                    quad[y] += o * weight
                    nxt[j, y] = state[j, s, 0]
                    state[j, s, 0] = y
                    state[j, s, 1] = y
    for j in range(nfam):
        for i in range(n_touched[j]):
            s = touched[j, i]
            state[j, s, 0] = UNTOUCHED
            state[j, s, 1] = EMPTY
            if not dense[j]:
                hkeys[j, s] = EMPTY
        n_touched[j] = 0


@njit(cache=True, parallel=True)
def _gather_permuted(order, cell, frac, normal, radiosity, cell_k, cen_k, nrm_k, rad_k):
    """Copies the voxel data into axis order: cell (int32), centroid in grid
    coordinates = cell + float32 fraction (float64), normal (float32 values
    as float64), radiosity (float32): the sweep reads memory in sequence."""
    n = order.shape[0]
    for i in prange(n):
        v = order[i]
        for c in range(3):
            cell_k[i, c] = cell[v, c]
            cen_k[i, c] = float(cell[v, c]) + float(frac[v, c])
            nrm_k[i, c] = normal[v, c]
            rad_k[i, c] = radiosity[v, c]


def propagate_families(orders, starts, cell, cell_lo, cell_hi, frac, normal, radiosity, vectors, axes,
                       units, weights, offsets, tau, kappa, max_group, table_size, hashed, per_pass=4):
    """Gathers radiosity over every family of a direction set.

    Lengths in cells: frac (n, 3) float32 the centroid's position within its
    cell (centroid = cell + frac, grid coordinates), normal (n, 3) float32,
    tau and kappa in cells; hashed: some family needs the hashed table.
    orders (3, n) int32: voxel order with axis 0, 1, 2 major; starts (3, ng+1)
    the cell boundaries in each order; cell_lo, cell_hi (3,) the cells'
    bounding box; table_size the line table's size (a power of two when
    hashed). vectors (nf, 3) canonical s; axes (nf,) dominant axis; units
    (nf, 3) unit s; weights (nf,) dW(s) / pi; offsets (nf, 2) line offsets.
    Families are swept per_pass at a time (one read of the voxel data for
    all of them), in two fixed slots with their own sums, added in a fixed
    order: the same result for any thread count.
    Returns gathered (n, 3) = sum_s B(I(x, s)) (n.s) dW / pi and the
    quadrature's own cosine integral S(n_x) (n,), both float64.
    """
    n = cell.shape[0]
    gathered = np.zeros((n, 3))
    quad = np.zeros(n)
    if n == 0:
        return gathered, quad
    ng = starts.shape[1] - 1
    F = max(1, int(per_pass))
    slots = 2
    state = np.empty((slots, F, table_size, 2), np.int32)
    state[..., 0] = UNTOUCHED
    state[..., 1] = EMPTY
    hkeys = np.full((slots, F, table_size if hashed else 1), EMPTY, np.int64)
    nxt = np.empty((slots, F, n), np.int32)
    touched = np.empty((slots, F, ng), np.int32)
    cell_k = np.empty((n, 3), np.int32)
    cen_k = np.empty((n, 3))
    nrm_k = np.empty((n, 3))
    rad_k = np.empty((n, 3), np.float32)
    g_k = np.empty((slots, n, 3))
    q_k = np.empty((slots, n))
    for k in range(3):
        fams = np.nonzero(axes == k)[0].astype(np.int64)
        if len(fams) == 0:
            continue
        _gather_permuted(orders[k], cell, frac, normal, radiosity, cell_k, cen_k, nrm_k, rad_k)
        g_k[:] = 0.0
        q_k[:] = 0.0
        chunks = [fams[i:i + F] for i in range(0, len(fams), F)]
        bounds = np.array([_line_bounds(cell_lo, cell_hi, k, (k + 1) % 3, (k + 2) % 3, np.int64(vectors[f, k]),
                                        np.int64(vectors[f, (k + 1) % 3]), np.int64(vectors[f, (k + 2) % 3]),
                                        np.int64(offsets[f, 0]), np.int64(offsets[f, 1])) for f in fams],
                          np.int64).reshape(-1, 4)
        bmap = {int(f): i for i, f in enumerate(fams)}
        padded = np.full((len(chunks), F), -1, np.int64)
        for c, ch in enumerate(chunks):
            padded[c, :len(ch)] = ch
        info = np.zeros((len(chunks), F, 4), np.int64)
        for c, ch in enumerate(chunks):
            for j, f in enumerate(ch):
                info[c, j] = bounds[bmap[int(f)]]
        _passes(padded, info, starts[k], cell_k, cen_k, nrm_k, rad_k, g_k, q_k, vectors, units, weights, offsets,
                k, tau, kappa, table_size, state, hkeys, nxt, touched, max_group)
        _scatter_add(orders[k], g_k, q_k, gathered, quad)
    return gathered, quad


@njit(cache=True, parallel=True)
def _passes(chunks, info, st, cell_k, cen_k, nrm_k, rad_k, g_k, q_k, vectors, units, weights, offsets, k, tau,
            kappa, size, state, hkeys, nxt, touched, max_group):
    """Slot j (of 2) sweeps chunks j, j + 2, ...: each chunk's families
    forwards then backwards, into the slot's own sums."""
    k1, k2 = (k + 1) % 3, (k + 2) % 3
    nchunks, F = chunks.shape[0], chunks.shape[1]
    for slot in prange(2):
        buf = np.empty(max_group, np.int64)
        bkey = np.empty(max_group)
        pc = np.empty(F, np.int64)
        qc = np.empty(F, np.int64)
        n_touched = np.zeros(F, np.int64)
        for c in range(slot, nchunks, 2):
            nf = 0
            while nf < F and chunks[c, nf] >= 0:
                nf += 1
            fams = chunks[c, :nf]
            dense = np.empty(nf, np.bool_)
            pmin = np.empty(nf, np.int64)
            P = np.empty(nf, np.int64)
            qmin = np.empty(nf, np.int64)
            for j in range(nf):
                pmin[j], P[j], qmin[j] = info[c, j, 0], info[c, j, 1], info[c, j, 2]
                dense[j] = info[c, j, 1] * info[c, j, 3] <= size
            for forward in (True, False):
                _sweep(st, cell_k, cen_k, nrm_k, rad_k, g_k[slot], q_k[slot], k, k1, k2, fams, vectors, units,
                       weights, offsets, forward, tau, kappa, dense, pmin, P, qmin, state[slot],
                       hkeys[slot], size - 1, nxt[slot], touched[slot], n_touched, pc, qc, buf, bkey)


@njit(cache=True, parallel=True)
def _scatter_add(order, g_k, q_k, gathered, quad):
    """Adds the two slots' sums (slot 0, then slot 1) back in voxel order."""
    for i in prange(order.shape[0]):
        v = order[i]
        for slot in range(2):
            gathered[v, 0] += g_k[slot, i, 0]
            gathered[v, 1] += g_k[slot, i, 1]
            gathered[v, 2] += g_k[slot, i, 2]
            quad[v] += q_k[slot, i]
