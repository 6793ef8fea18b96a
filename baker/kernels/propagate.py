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
plane where q stands (a wall standing mid-cell on a floor), or when x
passed, on the line, a voxel parallel to the line (a wall the line runs
along) and y is beyond tau on the other side of its plane.
Double-sided surfaces are sheets: two voxels, one per face, at the same
centroid. A face of a sheet is seen from in front only (d_x >= 0), never
by its sheet's other face; on a tie the face toward the ray comes first.
A voxel gathers along s or -s, never both, so the sweeps record the voxel
each ray met in the gathering voxel's own slot (hit, a column per family
of a batch): two lanes sweep the batch's families in parallel, then a pass
over the voxels adds B(hit) (n.s) dW / pi in the families' fixed order,
so the result is identical for any thread count.

Memory layout (what a sweep touches per voxel, measured to matter at a
million voxels, where the waiting voxels' data has left the cache by the
time their line meets a surface):
- pos (n, 8) float32 per voxel in the axis's order: centroid (grid
  coordinates), normal, the side of a cutting plane (0: not cut) and the
  index of that plane in cutp (not cut: 1 for a face of a two-sided
  sheet);
- the line table (size, 4) int32 per line: stamp (the family that last
  used it: no clearing between families), head of the waiting list, last
  voxel added, hashed key;
- waiting records (n, REC) int32 from a free list, so the live ones stay
  few and close together: centroid and normal (float32 bits), the voxel's
  index in voxel order (-v-1 when cut), the next record, a lower bound of
  (c_x - c).n over the voxels waiting at and after it (float32), and the
  last voxel parallel to the line it passed (-1: none).
  A line lying in a surface meets the surface's voxels one after another,
  all waiting, each with the same normal: testing each new one against the
  whole list made such families cost O(L^2) per line (7x a usual family
  at 384 cells, and growing with the resolution); with the bound, a voxel
  with the newest record's normal tests the list in O(1) when nothing on
  it can be behind its plane, with the same outcome;
- hit (n, HIT_BATCH) int32 in voxel order: the voxel the ray met (written
  once per voxel and family, wherever its line met a surface). Adding
  B(y) into the gathered sums there instead made the sweep 1.6x slower at
  a million voxels (measured): a random read-modify-write of 24 bytes into
  24 MB per gather. The hit is a 4-byte write, and the collecting pass
  reads and writes the sums in sequence, once per HIT_BATCH families,
  with the quadrature sums S (the sweep kept them per axis and lane: 16
  bytes per voxel more, and an update per voxel it starts a ray from).
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
HIT_BATCH = 4     # families whose hits are collected in one pass
RING = 32         # hits a sweep keeps before writing them
AHEAD_COLLECT = 24  # voxels ahead: the collecting pass prefetches the radiosity their rays met
REC = 10          # int32 per waiting record
BOUND_SLACK = 1e-6  # rounding room of the waiting lists' bounds (float32), cells and relative


@njit(cache=True, inline="always")
def _hash(idx, mask):
    h = np.uint64(idx) * np.uint64(0x9E3779B97F4A7C15)
    h ^= h >> np.uint64(32)
    return np.int64(h & np.uint64(mask))


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
    if abs(sb) <= tau_h:
        # b lies on that surface (a face of it, or of a sheet along it): the side it faces
        facing = float(pb[b, 3]) * nx + float(pb[b, 4]) * ny + float(pb[b, 5]) * nz
        return facing * sign < -0.5
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
def _sheet(pos, v, cutp):
    """Is voxel v one face of a two-sided sheet (a double-sided surface: its
    back is the voxel of the other facing, at the same centroid)?"""
    if pos[v, 6] == 0.0:
        return pos[v, 7] != 0.0
    return cutp[np.int64(pos[v, 7]), 7] != 0.0


@njit(cache=True)
def _passed(w, pos, j, rec, recf, tau_h):
    """The line passes voxel w, parallel to it: every waiting voxel (list
    from record j) beyond tau of w's plane remembers w (the last such)."""
    w0, w1, w2 = float(pos[w, 0]), float(pos[w, 1]), float(pos[w, 2])
    n0, n1, n2 = float(pos[w, 3]), float(pos[w, 4]), float(pos[w, 5])
    while j != EMPTY:
        jr = np.uint64(REC * j)
        s = (float(recf[jr]) - w0) * n0 + (float(recf[jr + np.uint64(1)]) - w1) * n1 + \
            (float(recf[jr + np.uint64(2)]) - w2) * n2
        if abs(s) > tau_h:
            rec[jr + np.uint64(9)] = w
        j = np.int64(rec[jr + np.uint64(7)])


@njit(cache=True)
def _across(rec, recf, jr, pos, y, tau_h):
    """Is y beyond tau on the other side of the plane of the surface the
    line ran along after the waiting voxel x (record at jr) joined it? A
    line parallel to a wall, a cell thick, can pass from one side of the
    wall to the other inside the wall's cells (a lid's inner edge looking
    down along the box's wall, the floor just outside it)."""
    w = np.int64(rec[jr + np.uint64(9)])
    w0, w1, w2 = float(pos[w, 0]), float(pos[w, 1]), float(pos[w, 2])
    n0, n1, n2 = float(pos[w, 3]), float(pos[w, 4]), float(pos[w, 5])
    sx = (float(recf[jr]) - w0) * n0 + (float(recf[jr + np.uint64(1)]) - w1) * n1 + \
        (float(recf[jr + np.uint64(2)]) - w2) * n2
    sy = (float(pos[y, 0]) - w0) * n0 + (float(pos[y, 1]) - w1) * n1 + (float(pos[y, 2]) - w2) * n2
    return (sx > tau_h and sy < -tau_h) or (sx < -tau_h and sy > tau_h)


@njit(cache=True)
def _back_to_back(rec, recf, jr, pos_all, pos, y, cutp):
    """Is y, facing the waiting voxel x (record at jr) within tau of x's
    plane, the back of x's own sheet (both faces of two-sided surfaces, with
    normals opposite within 8 degrees: on a curved sheet the faces in one
    cell can come from different pieces)? Then x does not see it: a digital
    line a cell thick can meet the sheet's other face in the next cell
    before it leaves the sheet's plane."""
    dot = float(recf[jr + np.uint64(3)]) * float(pos[y, 3]) + float(recf[jr + np.uint64(4)]) * float(pos[y, 4]) + \
        float(recf[jr + np.uint64(5)]) * float(pos[y, 5])
    if dot > -0.99:
        return False
    xe = np.int64(rec[jr + np.uint64(6)])
    x = xe if xe >= 0 else -xe - 1
    return _sheet(pos, y, cutp) and _sheet(pos_all, x, cutp)


@njit(cache=True)
def _order_cell(a, m, pos, ux, uy, uz, buf, bkey, cutp):
    """The m voxels of a cell from a, in order along the sweep, into buf as
    v (n.s > 0) or -v-1. Ties (the same centroid): +1 before -1, a box
    resting on a floor (the floor's ray meets the box's bottom); but the two
    faces of a sheet come -1 first, back to back (the ray from behind meets
    the face on its side, the face on the other side sends its ray on)."""
    for i in range(m):
        v = a + i
        t = float(pos[v, 0]) * ux + float(pos[v, 1]) * uy + float(pos[v, 2]) * uz
        o = float(pos[v, 3]) * ux + float(pos[v, 4]) * uy + float(pos[v, 5]) * uz
        late = (o > 0) == _sheet(pos, v, cutp)  # on a tie, after the others
        j = i
        while j > 0:
            if bkey[j - 1] < t:
                break
            if bkey[j - 1] == t:
                e = buf[j - 1]
                q = e if e >= 0 else -e - 1
                if late or (e >= 0) != _sheet(pos, q, cutp):
                    break
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
def _claim(idx, dense, tab, mask, stamp):
    """Row offset of line idx in the flat table (4 int32 per line: stamp,
    head, last, key), set up empty if this family has not used it yet
    (dense: the id is the row; else open addressing)."""
    s = idx if dense else _hash(idx, mask)
    while True:
        r = np.uint64(4 * s)
        if tab[r] != stamp:
            tab[r] = stamp
            tab[r + np.uint64(1)] = EMPTY
            tab[r + np.uint64(2)] = EMPTY
            tab[r + np.uint64(3)] = idx
            return r
        if dense or tab[r + np.uint64(3)] == idx:
            return r
        s = (s + 1) & mask


@njit(cache=True, inline="always")
def _find(idx, dense, tab, mask, stamp):
    """Row offset of line idx if this family uses it, else -1 (read only)."""
    if dense:
        return 4 * idx if tab[np.uint64(4 * idx)] == stamp else EMPTY
    s = _hash(idx, mask)
    while tab[np.uint64(4 * s)] == stamp:
        if tab[np.uint64(4 * s + 3)] == idx:
            return 4 * s
        s = (s + 1) & mask
    return EMPTY


@njit(cache=True, inline="always")
def _unlink(j, nj, prev, head, rec, free, nfree):
    """Removes waiting record j (followed by nj) from its list, after prev
    (the head if none), and frees it: returns the list's head."""
    if prev == EMPTY:
        head = nj
    else:
        rec[np.uint64(REC * prev + 7)] = nj
    free[np.uint64(nfree)] = j
    return head


@njit(cache=True)
def _sweep(starts, lid, gcell2, order, pos, pos_all, cutp, hit, nb, col, ux, uy, uz, weight, forward, tau, kappa,
           dense, tab, mask, stamp, rec, recf, free, buf, bkey):
    """One sweep of one direction (forwards: +s, backwards: -s) over the
    voxels in this axis's order (index = position in the order; lengths in
    cells). gcell (ng, 3) int32 the cells, starts (ng + 1,) their voxels.
    The hot arrays come flat (pos, tab, rec, recf: rows of 8, 4, 8, 8; hit:
    rows of nb, this family's column col) and are indexed with unsigned
    offsets: numba then needs neither the rows' strides (registers) nor
    wrap-around code for negative indices; together, half the instructions
    of this loop."""
    pos2 = pos.reshape((-1, 8))
    ng = starts.shape[0] - 1
    if not forward:
        ux, uy, uz = -ux, -uy, -uz
    g0 = 0 if forward else ng - 1
    gstep = 1 if forward else -1
    tau_h = tau
    kappa_h = kappa
    nfree = 0
    ntop = 0
    U1 = np.uint64(1)
    U2 = np.uint64(2)
    ring_p = np.empty(RING, np.uint64)  # hits on their way to memory
    ring_v = np.empty(RING, np.int32)
    nh = 0
    for i0 in range(-AHEAD_TABLE, ng):
        # the prefetch pipeline: table entry, head record
        ia = i0 + AHEAD_TABLE
        if ia < ng:
            idx = np.int64(lid[np.uint64(g0 + gstep * ia)])
            prefetch(tab, 4 * (idx if dense else _hash(idx, mask)))
        ib = i0 + AHEAD_HEAD
        if 0 <= ib < ng:
            rb = _find(np.int64(lid[np.uint64(g0 + gstep * ib)]), dense, tab, mask, stamp)
            if rb != EMPTY:
                hb = tab[np.uint64(rb + 1)]
                if hb != EMPTY:
                    prefetch(rec, REC * hb)
        if i0 < 0:
            continue
        g = g0 + gstep * i0
        tr = _claim(np.int64(lid[np.uint64(g)]), dense, tab, mask, stamp)
        head = np.int64(tab[tr + U1])
        last = np.int64(tab[tr + U2])
        a, b = np.int64(starts[np.uint64(g)]), np.int64(starts[np.uint64(g + 1)])
        # the cell's voxels in order along the sweep; ties: +1 before -1
        m = b - a
        if m > 1:
            _order_cell(a, m, pos2, ux, uy, uz, buf, bkey, cutp)
        for i in range(m):
            if m == 1:
                y = a
            else:
                e = buf[i]
                y = e if e >= 0 else -e - 1
            yr = np.uint64(8 * y)
            ny0, ny1, ny2 = float(pos[yr + np.uint64(3)]), float(pos[yr + np.uint64(4)]), float(pos[yr + np.uint64(5)])
            o = ny0 * ux + ny1 * uy + ny2 * uz
            if o == 0.0:
                # parallel to the line: neither sends nor receives, but a waiting voxel clearly on one
                # side of its plane has passed a surface the line runs along (see _across)
                if head != EMPTY:
                    _passed(y, pos2, head, rec, recf, tau_h)
                continue
            cy0, cy1, cy2 = float(pos[yr]), float(pos[yr + U1]), float(pos[yr + U2])
            ycut = pos[yr + np.uint64(6)] != 0.0
            prev = EMPTY
            j = head
            if o < 0.0:
                # y faces the rays: waiting voxels in front of (or near) its plane see it; in
                # front of a sheet's face strictly (within tau behind it, its other face is the
                # one facing them)
                dmin = -tau_h
                if j != EMPTY:
                    if not ycut:
                        if pos[yr + np.uint64(7)] != 0.0:
                            dmin = 0.0
                    elif _sheet(pos2, y, cutp):
                        dmin = 0.0
                while j != EMPTY:
                    jr = np.uint64(REC * j)
                    nj = np.int64(rec[jr + np.uint64(7)])
                    d = (float(recf[jr]) - cy0) * ny0 + (float(recf[jr + U1]) - cy1) * ny1 + \
                        (float(recf[jr + U2]) - cy2) * ny2
                    # x sees y: in front of its plane, and y not the back of x's sheet
                    if d >= dmin and not (dmin == 0.0 and d <= tau_h and
                                          _back_to_back(rec, recf, jr, pos_all, pos2, y, cutp)):
                        xe = np.int64(rec[jr + np.uint64(6)])
                        x = xe if xe >= 0 else -xe - 1
                        if ((m == 1 and xe >= 0 and not ycut) or
                                not _hidden(pos_all, x, pos2, y, xe < 0, ycut, d, g, m, buf, gcell2, cutp, tau_h)) and \
                                (rec[jr + np.uint64(9)] == EMPTY or not _across(rec, recf, jr, pos2, y, tau_h)):
                            # deferred store: prefetched now, written RING gathers later (a
                            # store that misses the cache holds up every later store; a
                            # prefetch holds up nothing): 1.1x at a million voxels
                            hp = np.uint64(x * nb + col)
                            prefetch(hit, hp)
                            slot = nh & (RING - 1)
                            if nh >= RING:
                                hit[ring_p[slot]] = ring_v[slot]
                            ring_p[slot] = hp
                            ring_v[slot] = order[np.uint64(y)]
                            nh += 1
                        head = _unlink(j, nj, prev, head, rec, free, nfree)
                        nfree += 1
                    else:
                        prev = j
                    j = nj
            else:
                # y turns its back: voxels behind its plane hit that back, unless convex edge
                z_known = False
                z_edge = False
                low = 0.0  # a lower bound of (c_x - c_y).n_y over the list once y joins it
                if j != EMPTY:
                    jr = np.uint64(REC * j)
                    if recf[jr + np.uint64(3)] == pos[yr + np.uint64(3)] and \
                            recf[jr + np.uint64(4)] == pos[yr + np.uint64(4)] and \
                            recf[jr + np.uint64(5)] == pos[yr + np.uint64(5)]:
                        # y has the newest waiting voxel's normal (one surface's run along the
                        # line): that voxel's bound covers the list; when it clears -tau, no
                        # waiting voxel is behind y's plane and the list needs no test
                        lo = float(recf[jr + np.uint64(8)]) + (float(recf[jr]) - cy0) * ny0 + \
                            (float(recf[jr + U1]) - cy1) * ny1 + (float(recf[jr + U2]) - cy2) * ny2
                        if lo >= -tau_h + BOUND_SLACK:
                            j = EMPTY
                            low = min(lo, 0.0)
                while j != EMPTY:
                    jr = np.uint64(REC * j)
                    nj = np.int64(rec[jr + np.uint64(7)])
                    d = (float(recf[jr]) - cy0) * ny0 + (float(recf[jr + U1]) - cy1) * ny1 + \
                        (float(recf[jr + U2]) - cy2) * ny2
                    blocked = False
                    if d < -tau_h:
                        if not z_known:
                            z_known = True
                            z_edge = _convex_edge(last, y, pos2, kappa_h)
                        if not z_edge:
                            ex = (cy0 - float(recf[jr])) * float(recf[jr + np.uint64(3)]) + \
                                (cy1 - float(recf[jr + U1])) * float(recf[jr + np.uint64(4)]) + \
                                (cy2 - float(recf[jr + U2])) * float(recf[jr + np.uint64(5)])
                            blocked = not (ex < 0.0 and d >= -kappa_h)
                    if blocked:
                        head = _unlink(j, nj, prev, head, rec, free, nfree)
                        nfree += 1
                    else:
                        prev = j
                        low = min(low, d)
                    j = nj
                if nfree > 0:
                    nfree -= 1
                    j = np.int64(free[np.uint64(nfree)])
                else:
                    j = ntop
                    ntop += 1
                jr = np.uint64(REC * j)
                for c in range(6):
                    recf[jr + np.uint64(c)] = pos[yr + np.uint64(c)]
                # min over the voxels waiting at and after this record of (c_x - c_y).n_y,
                # rounded down; removals keep it a bound, pushes go on top
                recf[jr + np.uint64(8)] = np.float32(low * (1.0 + BOUND_SLACK) - BOUND_SLACK)
                v = np.int64(order[np.uint64(y)])
                rec[jr + np.uint64(6)] = -v - 1 if ycut else v
                rec[jr + np.uint64(7)] = head
                rec[jr + np.uint64(9)] = EMPTY  # no surface along the line passed yet
                head = j
                last = y
        tab[tr + U1] = head
        tab[tr + U2] = last
    for i in range(max(0, nh - RING), nh):
        hit[ring_p[i & (RING - 1)]] = ring_v[i & (RING - 1)]


@njit(cache=True, parallel=True)
def _permute(order, st, cell, pos_all, pos, gcell):
    """Lays the voxel data out in an axis's order."""
    n = order.shape[0]
    for i in prange(n):
        v = order[i]
        for c in range(8):
            pos[i, c] = pos_all[v, c]
    for g in prange(st.shape[0] - 1):
        v = order[st[g]]
        for c in range(3):
            gcell[g, c] = cell[v, c]


@njit(cache=True)
def _line_ids(gcell, k, A, B, C, mu, mu2, pmin, P, qmin, lid):
    """Line id of every cell for one family (shared by its two sweeps):
    (floor((C X - A Z - mu) / A) - pmin) + P (floor((B X - A Y - mu') / A) - qmin),
    with floor((C X - A Z - mu) / A) = floor((C X - mu) / A) - Z: one
    division per slab of X."""
    k1, k2 = (k + 1) % 3, (k + 2) % 3
    xa = np.int64(-(2 ** 62))
    pa = qa = np.int64(0)
    for g in range(gcell.shape[0]):
        X = np.int64(gcell[g, k])
        if X != xa:
            xa = X
            pa = (C * X - mu) // A
            qa = (B * X - mu2) // A
        lid[g] = (qa - np.int64(gcell[g, k1]) - qmin) * P + (pa - np.int64(gcell[g, k2]) - pmin)


@njit(cache=True, parallel=True)
def _collect(hit, nf, fams, units, weights, pos_all, radiosity, gat, quad):
    """Adds the gathers of nf families (fams, in order) that the sweeps
    recorded in hit (n, HIT_BATCH): per voxel the voxel its ray met (-1:
    none; reset here), gathered along s or -s, whichever its front faces;
    and their terms of S(n) = sum |n.s| dW / pi (what a sweep would add
    for each voxel it starts a ray from, in the same order as the gathers:
    a closed scene of uniform radiosity gathers exactly S)."""
    n = hit.shape[0]
    for x in prange(n):
        # the radiosity rows met are scattered: prefetch those of a voxel AHEAD_COLLECT on
        # (1.15x on one thread at a million voxels)
        xa = x + AHEAD_COLLECT
        if xa < n:
            for i in range(nf):
                ya = hit[xa, i]
                if ya >= 0:
                    prefetch(radiosity, ya)
        n0, n1, n2 = float(pos_all[x, 3]), float(pos_all[x, 4]), float(pos_all[x, 5])
        g0, g1, g2 = gat[x, 0], gat[x, 1], gat[x, 2]
        sq = quad[x]
        for i in range(nf):
            f = fams[i]
            ux, uy, uz = units[f, 0], units[f, 1], units[f, 2]
            o = n0 * ux + n1 * uy + n2 * uz  # as the sweep along s or -s computes it
            if o < 0.0:
                o = n0 * -ux + n1 * -uy + n2 * -uz
            w = o * weights[f]
            sq += w
            y = hit[x, i]
            if y >= 0:
                hit[x, i] = EMPTY
                g0 += radiosity[y, 0] * w
                g1 += radiosity[y, 1] * w
                g2 += radiosity[y, 2] * w
        gat[x, 0] = g0
        gat[x, 1] = g1
        gat[x, 2] = g2
        quad[x] = sq


@njit(cache=True)
def _family(f, fi, col, st, gcell, order, pos, pos_all, cutp, hit, cell_lo, cell_hi, vectors, units, weights,
            offsets, k, tau, kappa, size, tab, rec, free, buf, bkey, lid, stamp0):
    """Both sweeps of family f (its fi-th of this axis), its hits into
    column col, with one lane's line table and records."""
    k1, k2 = (k + 1) % 3, (k + 2) % 3
    A, B, C = np.int64(vectors[f, k]), np.int64(vectors[f, k1]), np.int64(vectors[f, k2])
    mu, mu2 = np.int64(offsets[f, 0]), np.int64(offsets[f, 1])
    x0, x1, y0, y1, z0, z1 = cell_lo[k], cell_hi[k], cell_lo[k1], cell_hi[k1], cell_lo[k2], cell_hi[k2]
    pmin = (min(C * x0, C * x1) - A * z1 - mu) // A
    pmax = (max(C * x0, C * x1) - A * z0 - mu) // A
    qmin = (min(B * x0, B * x1) - A * y1 - mu2) // A
    qmax = (max(B * x0, B * x1) - A * y0 - mu2) // A
    P = pmax - pmin + 1
    dense = P * (qmax - qmin + 1) <= size
    _line_ids(gcell, k, A, B, C, mu, mu2, pmin, P, qmin, lid)
    for sw in range(2):
        # a stamp per sweep: the lane's table serves both
        _sweep(st, lid, gcell, order, pos, pos_all, cutp, hit.reshape(-1), hit.shape[1], col,
               units[f, 0], units[f, 1], units[f, 2], weights[f], sw == 0, tau, kappa, dense,
               tab.reshape(-1), size - 1, 2 * (stamp0 + fi) + sw, rec.reshape(-1), rec.view(np.float32).reshape(-1),
               free, buf, bkey)


@njit(cache=True, parallel=True)
def _families(fams, st, gcell, order, pos, pos_all, cutp, radiosity, hit, gat, quad, cell_lo, cell_hi, vectors,
              units, weights, offsets, k, tau, kappa, size, tabs, recs, frees, bufs, bkeys, lid, stamp0):
    """The families of one axis in batches of hit.shape[1]: two lanes share
    a batch (lane l takes its families l, l + 2, ...; each lane has its own
    table, records and line ids, and a family its own hit column),
    then the batch's gathers are collected in family order. The lanes are
    fixed by the family's place, not by the threads: the same sums for any
    thread count. Two lanes sweeping the same direction through the same
    voxel data at about the same time share the cache (1.1x against the
    two sweeps of one family in parallel, at a million voxels)."""
    nb = hit.shape[1]
    pf = pos.reshape(-1)
    for b0 in range(0, fams.shape[0], nb):
        nbf = min(nb, fams.shape[0] - b0)
        for lane in prange(2):
            for col in range(lane, nbf, 2):
                _family(fams[b0 + col], b0 + col, col, st, gcell, order, pf, pos_all, cutp, hit, cell_lo,
                        cell_hi, vectors, units, weights, offsets, k, tau, kappa, size, tabs[lane], recs[lane],
                        frees[lane], bufs[lane], bkeys[lane], lid[lane], stamp0)
        _collect(hit, nbf, fams[b0:b0 + nbf], units, weights, pos_all, radiosity, gat, quad)


def propagate_families(orders, starts, cell, cell_lo, cell_hi, pos_all, cutp, radiosity, vectors, axes, units, weights,
                       offsets, tau, kappa, max_group, table_size, hashed):
    """Gathers radiosity over every family of a direction set.

    Lengths in cells. pos_all (n, 8) float32 per voxel: centroid in grid
    coordinates, normal, the side of the plane that cut its pieces (0:
    none) and that plane's row in cutp (m, 8) float64 (normal, offset n.g,
    the voxel's cell, 1 for a sheet's face), or when not cut 1 for a face
    of a two-sided sheet. orders (3, n) int32: voxel order with axis 0, 1, 2
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
    tabs = np.full((2, table_size, 4), -1, np.int32)
    # waiting records: only the live ones are touched (a few per cent of n)
    recs = np.empty((2, n, REC), np.int32)
    frees = np.empty((2, n), np.int32)
    bufs = np.empty((2, max_group), np.int64)
    bkeys = np.empty((2, max_group))
    lid = np.empty((2, ng), np.int32)  # the cells' line ids, per lane (< 2^31: LineSweeper.line_table)
    hit = np.full((n, HIT_BATCH), EMPTY, np.int32)  # the voxel each ray met, per family of a batch
    stamp = 0
    for k in range(3):
        fams = np.nonzero(axes == k)[0]
        if len(fams) == 0:
            continue
        _permute(orders[k], starts[k], cell, pos_all, pos, gcell)
        _families(fams, starts[k], gcell, orders[k], pos, pos_all, cutp, radiosity, hit, gathered, quad, cell_lo,
                  cell_hi, vectors, units, weights, offsets, k, tau, kappa, table_size, tabs, recs, frees, bufs, bkeys,
                  lid, stamp)
        stamp += len(fams)  # stamps 2 (stamp + fi) + sweep
    return gathered, quad

