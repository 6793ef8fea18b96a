"""Linear propagation over digital lines: the sweep (docs/design.md section 4).

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
rows laid out in that axis's order, so the sweeps read memory in sequence.

What each voxel met on a line does is the visibility rule (visibility.py).
A voxel gathers along s or -s, never both, so the sweeps record the voxel
each ray met in the gathering voxel's own slot (hit, a column per family
of a batch): two lanes sweep the batch's families in parallel, then a pass
over the voxels adds B(hit) (n.s) dW / pi in the families' fixed order,
so the result is identical for any thread count.

What makes it fast (measured at a million voxels, where the waiting
voxels' data has left the cache by the time their line meets a surface;
the records' layouts are in records.py):
- the voxel rows are 32-byte float32 records in the axis's order;
- the line table is stamped with the sweep instead of cleared;
- waiting records come from a free list, so the live ones stay few and
  close together, and carry a bound that lets a line lying in a surface
  test its list in O(1) per voxel (such families cost O(L^2) per line
  without it);
- the sweep records a 4-byte hit instead of adding B(y) into the gathered
  sums (a random read-modify-write of 24 bytes into a large array),
  through a ring of prefetched stores; the collecting pass reads and
  writes the sums in sequence, once per HIT_BATCH families, with the
  quadrature sums S;
- the table entry and the head record are prefetched a few cells ahead
  (prefetching the head voxel's sums as well costs more than it saves: it
  needs a load of the record);
- the rare paths (cells with several voxels, cut cells, convex edges) are
  functions of their own: inlined, they slow the common path (register
  pressure);
- the loop's helpers are chosen by instruction counts (callgrind, one
  thread): a helper with array arguments marked inline="always" left
  numba's reference counting in the loop; `unlink` as a plain function
  costs nothing; the hit ring and the record pool written as functions
  cost more and are written out here.
"""
from collections import namedtuple

import numpy as np
from numba import njit, prange

from ..kernels.prefetch import prefetch
from ..startup import checkpoint
from .records import (EMPTY, LINE, P_CUT, P_NX, P_NY, P_NZ, P_SHEET, P_X, P_Y, P_Z, POS, R_BOUND, R_DEFER, R_NEXT,
                      R_NX, R_NY, R_NZ, R_PASSED, R_VOXEL, R_X, R_Y, R_Z, REC, RING, SHEET_FLAT, SHEET_KINDS, T_HEAD,
                      T_KEY, T_LAST, T_STAMP, edge_row, flush_hits, sheet_kind, unlink)
from .visibility import (CHECK, GATHER, WAIT, above_deferred, back_beyond_cut, below_deferred, convex_edge, defer,
                         deferred_t, defers, front_check, front_min, front_outcome, hits_back, in_front, order_cell,
                         misses_footprint, off_edge, over_surface, passes_parallel, passes_piece,
                         past_silhouette, sheet_convex_edge)

# The sweep's records (the one pack, in propagate_families; kernels unpack them at entry):
# - AxisVoxels, the voxels in one axis's order: starts (ng + 1,) each cell's first voxel, gcell (ng, 3) the
#   cells, order (n,) the voxels, pos (n * POS,) their float32 rows flat, pos_all (n, POS) in voxel order,
#   cutp (m, CUT) the cut planes;
# - Families, the direction set: vectors (nf, 3) canonical s, units (nf, 3) unit s, weights (nf,) dW / pi,
#   offsets (nf, 2) the line offsets mu, mu';
# - Lanes, each lane's scratch (first index: the lane): line tables, waiting records and their free list,
#   a cell's group buffer and keys, the cells' line ids.
AxisVoxels = namedtuple("AxisVoxels", ["starts", "gcell", "order", "pos", "pos_all", "cutp"])
Families = namedtuple("Families", ["vectors", "units", "weights", "offsets"])
Lanes = namedtuple("Lanes", ["tabs", "recs", "frees", "bufs", "bkeys", "lid"])

AHEAD_TABLE = 32  # cells ahead: prefetch the line's table entry
AHEAD_HEAD = 16   # ... its first waiting record
HIT_BATCH = 4     # families whose hits are collected in one pass
CALL_TRANSFERS = 1 << 25  # transfers (voxels x directions) per kernel call, about a quarter of a second
BOUND_SLACK = 1e-6  # rounding room of the waiting lists' bounds (float32), cells and relative
AHEAD_COLLECT = 24  # voxels ahead: the collecting pass prefetches the radiosity their rays met


@njit(cache=True, inline="always")
def _hash(idx, mask):
    h = np.uint64(idx) * np.uint64(0x9E3779B97F4A7C15)
    h ^= h >> np.uint64(32)
    return np.int64(h & np.uint64(mask))


@njit(cache=True, inline="always")
def _claim(idx, dense, tab, mask, stamp):
    """Row offset of line idx in the flat table, set up empty if this sweep
    has not used it yet (dense: the id is the row; else open addressing)."""
    s = idx if dense else _hash(idx, mask)
    while True:
        r = np.uint64(LINE * s)
        if tab[r + T_STAMP] != stamp:
            tab[r + T_STAMP] = stamp
            tab[r + T_HEAD] = EMPTY
            tab[r + T_LAST] = EMPTY
            tab[r + T_KEY] = idx
            return r
        if dense or tab[r + T_KEY] == idx:
            return r
        s = (s + 1) & mask


@njit(cache=True, inline="always")
def _find(idx, dense, tab, mask, stamp):
    """Row offset of line idx if this sweep uses it, else -1 (read only)."""
    if dense:
        return LINE * idx if tab[np.uint64(LINE * idx) + T_STAMP] == stamp else EMPTY
    s = _hash(idx, mask)
    while tab[np.uint64(LINE * s) + T_STAMP] == stamp:
        if tab[np.uint64(LINE * s) + T_KEY] == idx:
            return LINE * s
        s = (s + 1) & mask
    return EMPTY


@njit(cache=True)
def _sweep(vox, lane, hit, nb, col, u, forward, tau, kappa, dense, mask, stamp):
    """One sweep of one direction u (forwards: +s, backwards: -s) over the
    voxels of vox (an AxisVoxels: index = position in the order; lengths in
    cells). lane: one lane's (tab, rec, recf, free, buf, bkey, lid), lid
    (ng,) the cells' line ids. The hot arrays come flat (pos, tab, rec,
    recf: rows of POS, LINE, REC, REC; hit: rows of nb, this family's
    column col) and are indexed with unsigned offsets."""
    starts, gcell, order, pos, pos_all, cutp = vox
    tab, rec, recf, free, buf, bkey, lid = lane
    ux, uy, uz = u
    pos2 = pos.reshape((-1, POS))
    ng = starts.shape[0] - 1
    if not forward:
        ux, uy, uz = -ux, -uy, -uz
    g0 = 0 if forward else ng - 1
    gstep = 1 if forward else -1
    nfree = 0
    ntop = 0
    ring_p = np.empty(RING, np.uint64)  # hits on their way to memory
    ring_v = np.empty(RING, np.int32)
    nh = 0
    for i0 in range(-AHEAD_TABLE, ng):
        # the prefetch pipeline: table entry, head record
        ia = i0 + AHEAD_TABLE
        if ia < ng:
            idx = np.int64(lid[np.uint64(g0 + gstep * ia)])
            prefetch(tab, LINE * (idx if dense else _hash(idx, mask)))
        ib = i0 + AHEAD_HEAD
        if 0 <= ib < ng:
            rb = _find(np.int64(lid[np.uint64(g0 + gstep * ib)]), dense, tab, mask, stamp)
            if rb != EMPTY:
                hb = tab[np.uint64(rb) + T_HEAD]
                if hb != EMPTY:
                    prefetch(rec, REC * hb)
        if i0 < 0:
            continue
        g = g0 + gstep * i0
        tr = _claim(np.int64(lid[np.uint64(g)]), dense, tab, mask, stamp)
        head = np.int64(tab[tr + T_HEAD])
        last = np.int64(tab[tr + T_LAST])
        a, b = np.int64(starts[np.uint64(g)]), np.int64(starts[np.uint64(g + 1)])
        m = b - a
        if m > 1:
            order_cell(a, m, pos2, ux, uy, uz, buf, bkey)
        for i in range(m):
            if m == 1:
                y = a
            else:
                e = buf[i]
                y = e if e >= 0 else -e - 1
            yr = np.uint64(POS * y)
            o = float(pos[yr + P_NX]) * ux + float(pos[yr + P_NY]) * uy + float(pos[yr + P_NZ]) * uz
            if o == 0.0:
                # parallel to the line: neither sends nor receives, but a waiting voxel clearly on one
                # side of its plane has passed a surface the line runs along (visibility.across)
                if head != EMPTY:
                    passes_parallel(y, pos2, head, rec, recf, tau, cutp, ux, uy, uz)
            elif o < 0.0:
                # y faces the rays: each waiting voxel gathers it, keeps waiting or is hidden from it
                if head == EMPTY:
                    continue
                ny0, ny1, ny2 = float(pos[yr + P_NX]), float(pos[yr + P_NY]), float(pos[yr + P_NZ])
                cy0, cy1, cy2 = float(pos[yr + P_X]), float(pos[yr + P_Y]), float(pos[yr + P_Z])
                ycut = pos[yr + P_CUT] != 0.0
                kraw = pos[yr + P_SHEET]
                kind = sheet_kind(kraw)
                dmin = front_min(kind, tau)
                # y the inner face of a convex two-sided surface the line runs along (visibility.front_check)
                z_sheet = dmin == 0.0 and last != EMPTY and sheet_convex_edge(
                    float(pos2[last, P_X]), float(pos2[last, P_Y]), float(pos2[last, P_Z]), float(pos2[last, P_NX]),
                    float(pos2[last, P_NY]), float(pos2[last, P_NZ]), y, pos2, kappa)
                prev = EMPTY
                j = head
                while j != EMPTY:
                    jr = np.uint64(REC * j)
                    nj = np.int64(rec[jr + R_NEXT])
                    pv = np.int64(rec[jr + R_DEFER])
                    if pv != EMPTY and below_deferred(pos_all, pv, cy0, cy1, cy2, tau):
                        # the line passed below the plane x deferred its gather on: x keeps what it recorded
                        head, nfree = unlink(j, nj, prev, head, rec, free, nfree)
                        j = nj
                        continue
                    d = (float(recf[jr + R_X]) - cy0) * ny0 + (float(recf[jr + R_Y]) - cy1) * ny1 + \
                        (float(recf[jr + R_Z]) - cy2) * ny2
                    if not in_front(d, dmin):  # x keeps waiting
                        prev = j
                        j = nj
                        continue
                    xe = np.int64(rec[jr + R_VOXEL])
                    x = xe if xe >= 0 else -xe - 1
                    what = front_outcome(d, dmin, tau, kappa, z_sheet, m, xe, ycut, rec[jr + R_PASSED])
                    if what == CHECK:
                        what = front_check(d, dmin, x, xe, y, z_sheet, m, ycut, g, rec, recf, jr, pos_all, pos2, buf,
                                           gcell, cutp, tau, kappa, ux, uy, uz)
                    fallback = False
                    if what != WAIT and kraw >= SHEET_KINDS and d > 0.0:
                        x0, x1, x2 = float(recf[jr + R_X]), float(recf[jr + R_Y]), float(recf[jr + R_Z])
                        er = edge_row(kraw)
                        if misses_footprint(cutp, er, x0, x1, x2, cy0, cy1, cy2, ux, uy, uz):
                            # x's ray passes a small piece by (visibility.misses_footprint): hidden, y does not
                            # matter; seen, y is what x gathers unless it meets a front further on
                            # (visibility.FALLBACK)
                            if what == GATHER and pv == EMPTY:
                                fallback = True
                            else:
                                what = WAIT
                        elif what == GATHER and not over_surface(cutp, er, x0, x1, x2) and \
                                off_edge(cutp, er, d, o, x0, x1, x2, cy0, cy1, cy2, ux, uy, uz):
                            # x beside y's surface, its ray meeting y's plane beyond the edge where the surface
                            # ends: it passes (visibility.off_edge)
                            what = WAIT
                    if what == WAIT:
                        prev = j
                        j = nj
                        continue
                    if what == GATHER or pv != EMPTY:
                        # x's ray met y (or, hidden, clears a deferred gather): record it, deferred (a store
                        # that misses the cache holds up every later store; a prefetch holds up nothing):
                        # prefetch the slot now, write it RING gathers later
                        hp = np.uint64(x * nb + col)
                        prefetch(hit, hp)
                        slot = nh & (RING - 1)
                        if nh >= RING:
                            hit[ring_p[slot]] = ring_v[slot]
                        ring_p[slot] = hp
                        val = order[np.uint64(y)] if what == GATHER else EMPTY
                        wait = fallback
                        if what == GATHER and not fallback and (kind >= SHEET_FLAT or pv != EMPTY):
                            ty = (cy0 - float(recf[jr + R_X])) * ux + (cy1 - float(recf[jr + R_Y])) * uy + \
                                (cy2 - float(recf[jr + R_Z])) * uz
                            if defers(kind, d, o, ty, tau):
                                # the ray meets y's plane further on: x records the voxel there, keeps waiting
                                val = defer(pv, val, d, o, rec, recf, jr, pos_all, ux, uy, uz, tau)
                                wait = True
                            elif pv >= 0 and ty > deferred_t(pv, rec, recf, jr, pos_all, ux, uy, uz) + 1.0:
                                val = pv  # the ray met the plane it deferred on before it reached y
                        ring_v[slot] = val
                        nh += 1
                        if wait:
                            prev = j
                            j = nj
                            continue
                    head, nfree = unlink(j, nj, prev, head, rec, free, nfree)  # x leaves the list
                    j = nj
            else:
                # y turns its back: waiting voxels that hit it leave, then y joins the list
                ny0, ny1, ny2 = float(pos[yr + P_NX]), float(pos[yr + P_NY]), float(pos[yr + P_NZ])
                cy0, cy1, cy2 = float(pos[yr + P_X]), float(pos[yr + P_Y]), float(pos[yr + P_Z])
                ycut = pos[yr + P_CUT] != 0.0
                z_known = False
                z_edge = False
                low = 0.0  # a lower bound of (c_x - c_y).n_y over the list once y joins it
                prev = EMPTY
                j = head
                if j != EMPTY:
                    jr = np.uint64(REC * j)
                    if recf[jr + R_NX] == pos[yr + P_NX] and recf[jr + R_NY] == pos[yr + P_NY] and \
                            recf[jr + R_NZ] == pos[yr + P_NZ]:
                        # y has the newest waiting voxel's normal (one surface's run along the line):
                        # that record's bound covers the list; when it clears -tau, no waiting voxel is
                        # behind y's plane and the list needs no test
                        lo = float(recf[jr + R_BOUND]) + (float(recf[jr + R_X]) - cy0) * ny0 + \
                            (float(recf[jr + R_Y]) - cy1) * ny1 + (float(recf[jr + R_Z]) - cy2) * ny2
                        if lo >= -tau + BOUND_SLACK:
                            j = EMPTY
                            low = min(lo, 0.0)
                while j != EMPTY:
                    jr = np.uint64(REC * j)
                    nj = np.int64(rec[jr + R_NEXT])
                    d = (float(recf[jr + R_X]) - cy0) * ny0 + (float(recf[jr + R_Y]) - cy1) * ny1 + \
                        (float(recf[jr + R_Z]) - cy2) * ny2
                    ex = 0.0
                    if d < -tau:
                        if not z_known:  # the convex-edge test of the voxel last added, once per y
                            z_known = True
                            z_edge = convex_edge(last, y, pos2, tau, kappa)
                        ex = (cy0 - float(recf[jr + R_X])) * float(recf[jr + R_NX]) + \
                            (cy1 - float(recf[jr + R_Y])) * float(recf[jr + R_NY]) + \
                            (cy2 - float(recf[jr + R_Z])) * float(recf[jr + R_NZ])
                    gone = hits_back(d, ex, z_edge, tau, kappa)
                    if gone:
                        kraw = pos[yr + P_SHEET]
                        x0, x1, x2 = float(recf[jr + R_X]), float(recf[jr + R_Y]), float(recf[jr + R_Z])
                        if sheet_kind(kraw) < SHEET_FLAT and past_silhouette(d, o, x0, x1, x2, cy0, cy1, cy2, ux, uy,
                                                                             uz, tau):
                            # a curved y: x's ray, level with y, already in front of y's tangent plane has passed
                            # a convex silhouette: it keeps waiting
                            gone = False
                        elif kraw >= SHEET_KINDS and passes_piece(cutp, edge_row(kraw), d, o, x0, x1, x2, cy0, cy1,
                                                                  cy2, ux, uy, uz):
                            gone = False  # x's ray crosses y's plane outside its footprint or beyond its edge
                    if gone:
                        xe = np.int64(rec[jr + R_VOXEL])
                        if (xe < 0 or ycut) and back_beyond_cut(pos_all, xe if xe >= 0 else -xe - 1, xe < 0, pos2, y,
                                                                ycut, cutp, tau, ux, uy, uz):
                            gone = False  # beyond a surface x's ray moves away from: x keeps waiting
                    if gone:
                        pv = np.int64(rec[jr + R_DEFER])
                        if pv != EMPTY and above_deferred(pos_all, pv, cy0, cy1, cy2, tau):
                            # x's ray hits y's back before the plane it deferred its gather on: nothing
                            xe = np.int64(rec[jr + R_VOXEL])
                            hp = np.uint64((xe if xe >= 0 else -xe - 1) * nb + col)
                            slot = nh & (RING - 1)
                            if nh >= RING:
                                hit[ring_p[slot]] = ring_v[slot]
                            ring_p[slot] = hp
                            ring_v[slot] = EMPTY
                            nh += 1
                        head, nfree = unlink(j, nj, prev, head, rec, free, nfree)  # x leaves the list
                    else:
                        prev = j
                        low = min(low, d)
                    j = nj
                # y joins the list, at its head: a record from the free list, else a new one from the pool
                if nfree > 0:
                    nfree -= 1
                    j = np.int64(free[np.uint64(nfree)])
                else:
                    j = ntop
                    ntop += 1
                jr = np.uint64(REC * j)
                for c in range(6):  # centroid and normal: R_X..R_NZ from P_X..P_NZ
                    recf[jr + np.uint64(c)] = pos[yr + np.uint64(c)]
                # min over the voxels waiting at and after this record of (c_x - c_y).n_y,
                # rounded down; removals keep it a bound, pushes go on top
                recf[jr + R_BOUND] = np.float32(low * (1.0 + BOUND_SLACK) - BOUND_SLACK)
                yv = np.int64(order[np.uint64(y)])
                rec[jr + R_VOXEL] = -yv - 1 if pos[yr + P_CUT] != 0.0 else yv
                rec[jr + R_NEXT] = head
                rec[jr + R_PASSED] = EMPTY  # no surface along the line passed yet
                rec[jr + R_DEFER] = EMPTY   # no gather deferred
                head = j
                last = y
        tab[tr + T_HEAD] = head
        tab[tr + T_LAST] = last
    flush_hits(hit, ring_p, ring_v, nh)


@njit(cache=True, parallel=True)
def _permute(order, st, cell, pos_all, pos, gcell):
    """Lays the voxel data out in an axis's order."""
    n = order.shape[0]
    for i in prange(n):
        v = order[i]
        for c in range(POS):
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
        xa = x + AHEAD_COLLECT
        if xa < n:
            for i in range(nf):
                ya = hit[xa, i]
                if ya >= 0:
                    prefetch(radiosity, ya)
        n0, n1, n2 = float(pos_all[x, P_NX]), float(pos_all[x, P_NY]), float(pos_all[x, P_NZ])
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
def _family(f, fi, col, vox, hit, cell_lo, cell_hi, fam, k, tau, kappa, size, lanes, lane, stamp0):
    """Both sweeps of family f (its fi-th of this axis), its hits into
    column col, with lane `lane`'s line table and records."""
    k1, k2 = (k + 1) % 3, (k + 2) % 3
    A, B, C = np.int64(fam.vectors[f, k]), np.int64(fam.vectors[f, k1]), np.int64(fam.vectors[f, k2])
    mu, mu2 = np.int64(fam.offsets[f, 0]), np.int64(fam.offsets[f, 1])
    x0, x1, y0, y1, z0, z1 = cell_lo[k], cell_hi[k], cell_lo[k1], cell_hi[k1], cell_lo[k2], cell_hi[k2]
    pmin = (min(C * x0, C * x1) - A * z1 - mu) // A
    pmax = (max(C * x0, C * x1) - A * z0 - mu) // A
    qmin = (min(B * x0, B * x1) - A * y1 - mu2) // A
    qmax = (max(B * x0, B * x1) - A * y0 - mu2) // A
    P = pmax - pmin + 1
    dense = P * (qmax - qmin + 1) <= size
    tab, rec, lid = lanes.tabs[lane], lanes.recs[lane], lanes.lid[lane]
    _line_ids(vox.gcell, k, A, B, C, mu, mu2, pmin, P, qmin, lid)
    one = (tab.reshape(-1), rec.reshape(-1), rec.view(np.float32).reshape(-1), lanes.frees[lane], lanes.bufs[lane],
           lanes.bkeys[lane], lid)
    for sw in range(2):
        # a stamp per sweep: the lane's table serves both
        _sweep(vox, one, hit.reshape(-1), hit.shape[1], col, (fam.units[f, 0], fam.units[f, 1], fam.units[f, 2]),
               sw == 0, tau, kappa, dense, size - 1, 2 * (stamp0 + fi) + sw)


@njit(cache=True, parallel=True)
def _families(fams, vox, radiosity, hit, gat, quad, cell_lo, cell_hi, fam, k, tau, kappa, size, lanes, stamp0):
    """The families `fams` of one axis in batches of hit.shape[1]: two lanes
    share a batch (lane l takes its families l, l + 2, ...; each lane has
    its own table, records and line ids, and a family its own hit column),
    then the batch's gathers are collected in family order. The lanes are
    fixed by the family's place, not by the threads: the same sums for any
    thread count. Two lanes sweeping the same direction through the same
    voxel data at about the same time share the cache (better than two
    sweeps of one family in parallel)."""
    nb = hit.shape[1]
    for b0 in range(0, fams.shape[0], nb):
        nbf = min(nb, fams.shape[0] - b0)
        for lane in prange(2):
            for col in range(lane, nbf, 2):
                _family(fams[b0 + col], b0 + col, col, vox, hit, cell_lo, cell_hi, fam, k, tau, kappa, size, lanes,
                        lane, stamp0)
        _collect(hit, nbf, fams[b0:b0 + nbf], fam.units, fam.weights, vox.pos_all, radiosity, gat, quad)


def propagate_families(orders, starts, cell, cell_lo, cell_hi, pos_all, cutp, radiosity, vectors, axes, units, weights,
                       offsets, tau, kappa, max_group, table_size, hashed):
    """Gathers radiosity over every family of a direction set.

    Lengths in cells. pos_all (n, POS) float32 voxel rows and cutp (m, CUT)
    float64 cut planes (records.py). orders (3, n) int32: voxel order with axis 0, 1, 2
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
    pos = np.empty((n, POS), np.float32)
    gcell = np.empty((ng, 3), np.int32)
    tabs = np.full((2, table_size, LINE), EMPTY, np.int32)
    # waiting records: only the live ones are touched (a few per cent of n)
    recs = np.empty((2, n, REC), np.int32)
    frees = np.empty((2, n), np.int32)
    bufs = np.empty((2, max_group), np.int64)
    bkeys = np.empty((2, max_group))
    lid = np.empty((2, ng), np.int32)  # the cells' line ids, per lane (< 2^31: LineSweeper.line_table)
    hit = np.full((n, HIT_BATCH), EMPTY, np.int32)  # the voxel each ray met, per family of a batch
    # a call per slice of about CALL_TRANSFERS transfers (whole batches, in order: the same sums), so that
    # a command's Ctrl-C can stop between them (startup.checkpoint)
    per_call = HIT_BATCH * max(1, CALL_TRANSFERS // (2 * HIT_BATCH * n))
    lanes = Lanes(tabs, recs, frees, bufs, bkeys, lid)
    fam = Families(vectors, units, weights, offsets)
    stamp = 0
    for k in range(3):
        fams = np.nonzero(axes == k)[0]
        if len(fams) == 0:
            continue
        _permute(orders[k], starts[k], cell, pos_all, pos, gcell)
        vox = AxisVoxels(starts[k], gcell, orders[k], pos.reshape(-1), pos_all, cutp)
        for f0 in range(0, len(fams), per_call):
            checkpoint()
            part = fams[f0:f0 + per_call]
            _families(part, vox, radiosity, hit, gathered, quad, cell_lo, cell_hi, fam, k, tau, kappa, table_size,
                      lanes, stamp)
            stamp += len(part)  # stamps 2 (stamp + fi) + sweep: distinct for every sweep of the bounce
    return gathered, quad

