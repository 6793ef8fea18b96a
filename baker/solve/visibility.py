"""The visibility rule of the linear propagation (docs/design.md section 4):
what a voxel met on a digital line does to the voxels waiting on it.

A voxel with n . s > 0 starts a ray along +s and waits on the line (its
record in the line's waiting list). For each next voxel y, each waiting x
is tested on its own, with d = (c_x - c_y) . n_y, how far x is in front of
y's plane (lengths in cells):

- `in_front`, `front_outcome`, `front_check`: y faces the rays
  (n_y . s < 0). x with d >= -tau gathers B(y) and leaves the list; x
  behind y's plane moves away from it and keeps waiting. Extra tests, each
  for a case the tau rule alone gets wrong:
  * a face of a two-sided sheet is seen from in front only (d >= 0), and
    never by its own surface's other face nearby (`back_to_back`: within
    kappa, normals within 60 degrees of opposite, a curved or noisy
    sheet's faces a cell apart), nor, on a convex sheet, the inner face
    the line meets just behind the waiting face's plane
    (`sheet_convex_edge`, with x or the voxel last added);
  * another surface standing between x and y (`hidden`): one crossing y's
    cell (`separated`, a wall standing on a floor), one that cut x's or
    y's pieces (`cut_between`, a floor running under a wall, or y's own
    plane cutting x's cell); it hides y when x's ray heads for
    it (HIDES), and x keeps waiting when the ray moves away from it
    (AWAY: y is on the line only because the line is a cell thick);
  * a surface the line ran along after x joined (`across`, a line a cell
    thick passing a wall inside the wall's cells).
- `hits_back`: y turns its back (n_y . s > 0). x with d < -tau hits that
  back: it gathers 0 and leaves, unless x and y, or the voxel z last added
  to the list and y, form a convex edge (`convex_edge`: the waiting one
  just behind y's plane, within kappa, and y behind its plane or within
  tau in front of it: a flat junction of two facings of a noisy surface).
  Then y joins the list.
- a voxel parallel to the line (n_y . s = 0) neither sends nor receives;
  `passes_parallel` notes it in the records of the voxels it separates.
- `order_cell`: voxels of one cell in order along the ray; on a tie a +1
  voxel before a -1 (a box resting on a floor), but a sheet's two faces
  -1 first (back to back).

The sweep (sweep.py) walks the lines and their waiting lists and asks
these functions what each pair does; what makes it fast (prefetching, the
ring of hits, stamped tables, the record pool, the lists' bounds) lives
there and in records.py. (The per-pair functions inlined into the sweep
take numbers, not arrays: numba's inlining of a function with array
arguments left reference counting in the sweep's loop (more
instructions per transfer under callgrind); the rarer tests are
functions of their own, called out of line.)
"""
import os

import numpy as np
from numba import config, njit

from ..voxels.tolerances import SAME_PLANE_COS
from .records import (C_CX, C_CY, C_CZ, C_D, C_NX, C_NY, C_NZ, C_R, EMPTY, P_CUT, P_NX, P_NY, P_NZ, P_SHEET, P_X,
                      P_Y, P_Z, R_DEFER, R_NEXT, R_NX, R_NY, R_NZ, R_PASSED, R_VOXEL, R_X, R_Y, R_Z, REC, SHEET_FLAT,
                      SHEET_KINDS, cut_row, cut_side, edge_row, is_sheet)

CUT_REACH = 3.0        # cells around a cut voxel's cell where its cutting surface is taken to stand
SEGMENT_REACH = 0.5    # cells beyond y's cell where a surface crossing it is taken to stand (the 26-connected
#                        line may step past the cell where it crosses)
FACES_AWAY = -0.5      # a voxel on a cutting surface faces away from the cut part below this cosine

OWN_BACK_COS = -0.5    # a sheet face within kappa of a waiting sheet face, facing it with a normal at least this
#                        opposite, is that surface's own other face (a noisy curved sheet's faces in one cell split
#                        into different facings: their normals can be 30-60 degrees off opposite)
DEFER = 0.5           # cells along the ray beyond a flat voxel where the ray meets its plane: beyond this, the gather
#                       is deferred (`defers`) to the voxel of that plane where the ray meets it
DEFER_MAX = 8.0       # cells: ... and under this (a gather deferred further would keep its voxel waiting, tested
#                       at every voxel the line meets, for as many cells: a bounce's cost would grow with the
#                       grazing rays' length, not stay O(voxels x directions))
DEFER_TIE = 1e-5      # cells: the deferral's tests clear their bounds by this (grid-aligned scenes put the ray's
#                       height exactly on them, where the rounding of one sum or another would decide)
# The clauses, each of which a test of tests/test_visibility_rule.py must miss (tests/test_clauses.py): with
# NUMBA_DISABLE_JIT=1 (the kernels run as Python) VOXGI_DISABLE_CLAUSE=<name> turns that one off. Compiled kernels
# never see the switch (OFF is 0 and every test of it folds away), so no cached kernel lacks a clause.
CLAUSES = ("separated", "cut_between", "passes_parallel", "across", "back_to_back", "order_ties",
           "back_beyond_cut", "convex_edge", "sheet_front", "defers", "sheet_convex_edge", "edge_of_x",
           "past_silhouette", "off_edge", "footprint")
(SEPARATED, CUT_BETWEEN, PASSES_PARALLEL, ACROSS, BACK_TO_BACK, ORDER_TIES, BACK_BEYOND_CUT, CONVEX_EDGE,
 SHEET_FRONT, DEFERS, SHEET_CONVEX_EDGE, EDGE_OF_X, PAST_SILHOUETTE, OFF_EDGE, FOOTPRINT) = range(1, len(CLAUSES) + 1)


def _clause_off() -> int:
    name = os.environ.get("VOXGI_DISABLE_CLAUSE", "")
    if not name or not config.DISABLE_JIT:
        return 0
    if name not in CLAUSES:
        raise ValueError(f"VOXGI_DISABLE_CLAUSE={name!r}: not a clause ({', '.join(CLAUSES)})")
    return CLAUSES.index(name) + 1


OFF = _clause_off()

CLEAR, HIDES, AWAY = 0, 1, 2  # a surface between x and y: none; in the way of x's ray; behind it (the ray moves
#                               away from it: y is on the line only because the line is a cell thick)



@njit(cache=True)
def separated(px, x, pos, y, buf, m, tau_h, lo0, lo1, lo2, ux, uy, uz, cutp):
    """Is y hidden from x by another voxel q of y's cell? HIDES when q's
    plane lies between them (beyond tau on each side), the segment from x's
    centroid to y's crosses that plane within SEGMENT_REACH of y's cell, on
    the side of y's plane where q's piece is, and x's ray (along u) heads
    for that plane: a surface crossing the cell (a wall standing on a
    floor) is in the way, provided the ray meets that plane before it comes
    level with y. AWAY when such planes are there but x's ray moves away
    from (or along) each of them, or meets them only beyond y: it never
    reaches their other side where y is. Else CLEAR."""
    if OFF == SEPARATED:
        return CLEAR
    out = CLEAR
    for i in range(m):
        e = buf[i]
        q = e if e >= 0 else -e - 1
        if q == y:
            continue
        sx = sy = 0.0
        for c in range(3):
            nq = float(pos[q, P_NX + c])
            sx += (float(px[x, P_X + c]) - float(pos[q, P_X + c])) * nq
            sy += (float(pos[y, P_X + c]) - float(pos[q, P_X + c])) * nq
        if (sx > tau_h and sy < -tau_h) or (sx < -tau_h and sy > tau_h):
            lam = sx / (sx - sy)
            x0, x1, x2 = float(px[x, P_X]), float(px[x, P_Y]), float(px[x, P_Z])
            y0, y1, y2 = float(pos[y, P_X]), float(pos[y, P_Y]), float(pos[y, P_Z])
            p0 = x0 + (y0 - x0) * lam
            p1 = x1 + (y1 - x1) * lam
            p2 = x2 + (y2 - x2) * lam
            r = SEGMENT_REACH
            k = pos[q, P_SHEET]
            if k >= SHEET_KINDS and OFF != FOOTPRINT:
                rad = cutp[edge_row(k), C_R]
                if rad > 0.0 and (p0 - float(pos[q, P_X])) ** 2 + (p1 - float(pos[q, P_Y])) ** 2 + \
                        (p2 - float(pos[q, P_Z])) ** 2 > rad * rad:
                    continue  # q a small piece, the segment passing it by
            if lo0 - r <= p0 <= lo0 + 1.0 + r and lo1 - r <= p1 <= lo1 + 1.0 + r and lo2 - r <= p2 <= lo2 + 1.0 + r:
                # q's piece stands where the segment crosses: on the same side
                # of y's plane as q (a wall rising from a floor), not behind it
                # (the side of a box under its top: a convex edge)
                n0, n1, n2 = float(pos[y, P_NX]), float(pos[y, P_NY]), float(pos[y, P_NZ])
                pside = (p0 - y0) * n0 + (p1 - y1) * n1 + (p2 - y2) * n2
                qside = (float(pos[q, P_X]) - y0) * n0 + (float(pos[q, P_Y]) - y1) * n1 + \
                    (float(pos[q, P_Z]) - y2) * n2
                if pside * qside > 0.0:
                    # x's ray heads for q's plane and meets it before it comes level with y: in its
                    # way; a ray meeting it only further on passes y on its own side (q a curved
                    # surface's piece, its plane met at a grazing angle)
                    nu = float(pos[q, P_NX]) * ux + float(pos[q, P_NY]) * uy + float(pos[q, P_NZ]) * uz
                    if nu * sx < 0.0 and -sx / nu <= (y0 - x0) * ux + (y1 - x1) * uy + (y2 - x2) * uz + tau_h:
                        return HIDES
                    out = AWAY
    return out


@njit(cache=True)
def cut_between(pa, a, pb, b, cutp, tau_h, ux, uy, uz, a_waits):
    """Voxel a was made by cutting its pieces with another surface's plane
    (a wall standing on a floor, a floor running under a wall): if b lies
    on the other side of that plane and the segment a-b crosses it within
    CUT_REACH cells of a's cell, or b's cell is cut by the same plane (the
    surface runs past both ends), that surface stands between them: HIDES
    when the waiting voxel's ray (along u; a_waits: a is the waiting voxel,
    else b) heads for that plane, AWAY when it moves away from or along it
    (y is on the line only because the line is a cell thick); b on that
    surface facing away from a: HIDES when a waits, AWAY when b waits (a
    lies behind b's own plane); else CLEAR."""
    if OFF == CUT_BETWEEN:
        return CLEAR
    if pa[a, P_CUT] == 0.0:
        return CLEAR
    sign = cut_side(pa, a)
    j = cut_row(pa, a)
    nx, ny, nz, d = cutp[j, C_NX], cutp[j, C_NY], cutp[j, C_NZ], cutp[j, C_D]
    a0, a1, a2 = float(pa[a, P_X]), float(pa[a, P_Y]), float(pa[a, P_Z])
    b0, b1, b2 = float(pb[b, P_X]), float(pb[b, P_Y]), float(pb[b, P_Z])
    sa = a0 * nx + a1 * ny + a2 * nz - d
    sb = b0 * nx + b1 * ny + b2 * nz - d
    if abs(sb) <= tau_h:
        # b lies on that surface (a face of it, or of a sheet along it): the side it faces. Facing
        # away from a, it hides a from a waiting voxel a; a waiting voxel b on it leaves a behind
        # its own plane (the floor under a box, met after the box's side on a line a cell thick):
        # b's ray moves away from a, b keeps waiting
        if a_waits and abs(sa) > tau_h and (nx * ux + ny * uy + nz * uz) * sign >= 0.0:
            # a's ray runs along or away from the surface b lies on: it passes b, either face (on
            # the line only because the line is a cell thick; a scan's base beside a floor piece)
            return AWAY
        facing = float(pb[b, P_NX]) * nx + float(pb[b, P_NY]) * ny + float(pb[b, P_NZ]) * nz
        if facing * sign < FACES_AWAY:
            return HIDES if a_waits else AWAY
        return CLEAR
    if sb * sign >= -tau_h or sa == sb:
        return CLEAR
    # the waiting voxel's ray heads for the plane from its side and meets it before it comes level
    # with the other voxel: the surface is in its way. A ray that meets the plane only further on
    # passes the other voxel on its own side (a curved surface's plane, met at a grazing angle).
    side = sign if a_waits else -sign
    nu = nx * ux + ny * uy + nz * uz
    way = AWAY
    if nu * side < 0.0:
        sw, ahead = (sa, (b0 - a0) * ux + (b1 - a1) * uy + (b2 - a2) * uz) if a_waits else \
            (sb, (a0 - b0) * ux + (a1 - b1) * uy + (a2 - b2) * uz)
        if -sw / nu <= ahead + tau_h:
            way = HIDES
    if pb[b, P_CUT] != 0.0:
        jb = cut_row(pb, b)
        dot = nx * cutp[jb, C_NX] + ny * cutp[jb, C_NY] + nz * cutp[jb, C_NZ]
        if abs(dot) > SAME_PLANE_COS and abs(d - dot * cutp[jb, C_D]) < tau_h:
            return way
    lam = sa / (sa - sb)
    p0 = a0 + (b0 - a0) * lam
    p1 = a1 + (b1 - a1) * lam
    p2 = a2 + (b2 - a2) * lam
    if cutp[j, C_CX] - CUT_REACH <= p0 <= cutp[j, C_CX] + 1.0 + CUT_REACH and \
            cutp[j, C_CY] - CUT_REACH <= p1 <= cutp[j, C_CY] + 1.0 + CUT_REACH and \
            cutp[j, C_CZ] - CUT_REACH <= p2 <= cutp[j, C_CZ] + 1.0 + CUT_REACH:
        return way
    return CLEAR


@njit(cache=True)
def passes_parallel(w, pos, j, rec, recf, tau_h, cutp, ux, uy, uz):
    """The line passes voxel w, parallel to it (along u): every waiting
    voxel (list from record j) beyond tau of w's plane remembers w (the
    last such), unless w is a small piece (its edge row's footprint radius)
    that its ray passes further from than that radius (a frame's side
    beside a ray leaving the wall it hangs on)."""
    if OFF == PASSES_PARALLEL:
        return
    w0, w1, w2 = float(pos[w, P_X]), float(pos[w, P_Y]), float(pos[w, P_Z])
    n0, n1, n2 = float(pos[w, P_NX]), float(pos[w, P_NY]), float(pos[w, P_NZ])
    rad = 0.0
    k = pos[w, P_SHEET]
    if k >= SHEET_KINDS and OFF != FOOTPRINT:
        rad = cutp[edge_row(k), C_R]
    while j != EMPTY:
        jr = np.uint64(REC * j)
        r0, r1, r2 = float(recf[jr + R_X]) - w0, float(recf[jr + R_Y]) - w1, float(recf[jr + R_Z]) - w2
        s = r0 * n0 + r1 * n1 + r2 * n2
        if abs(s) > tau_h:
            far = False
            if rad > 0.0:
                t = r0 * ux + r1 * uy + r2 * uz  # the ray's point nearest w: r - t u from w's centroid
                far = (r0 - t * ux) ** 2 + (r1 - t * uy) ** 2 + (r2 - t * uz) ** 2 > rad * rad
            if not far:
                rec[jr + R_PASSED] = w
        j = np.int64(rec[jr + R_NEXT])


@njit(cache=True)
def across(rec, recf, jr, pos, y, tau_h):
    """Is y beyond tau on the other side of the plane of the surface the
    line ran along after the waiting voxel x (record at jr) joined it? A
    line parallel to a wall, a cell thick, can pass from one side of the
    wall to the other inside the wall's cells (a lid's inner edge looking
    down along the box's wall, the floor just outside it)."""
    if OFF == ACROSS:
        return False
    w = np.int64(rec[jr + R_PASSED])
    w0, w1, w2 = float(pos[w, P_X]), float(pos[w, P_Y]), float(pos[w, P_Z])
    n0, n1, n2 = float(pos[w, P_NX]), float(pos[w, P_NY]), float(pos[w, P_NZ])
    sx = (float(recf[jr + R_X]) - w0) * n0 + (float(recf[jr + R_Y]) - w1) * n1 + \
        (float(recf[jr + R_Z]) - w2) * n2
    sy = (float(pos[y, P_X]) - w0) * n0 + (float(pos[y, P_Y]) - w1) * n1 + (float(pos[y, P_Z]) - w2) * n2
    return (sx > tau_h and sy < -tau_h) or (sx < -tau_h and sy > tau_h)


@njit(cache=True)
def back_to_back(rec, recf, jr, pos_all, pos, y, d, kappa_h):
    """Is y, facing the waiting voxel x (record at jr), d = (c_x - c_y) . n_y
    in front of y's plane, the other face of x's own two-sided surface?
    Both are faces of sheets, with normals opposite within OWN_BACK_COS
    (on a curved or noisy sheet the faces in one cell can come from
    different pieces, grouped into different facings), each within kappa
    of the other's plane. A continuous ray
    leaving a smooth two-sided surface's face never meets that surface's
    other face nearby (it would have to cross the surface first); a digital
    line a cell thick does, for a few cells, where the surface is curved or
    noisy. Then x does not see it. (Another sheet facing x from more than
    kappa away is seen; two sheets closer than that are one surface at
    this resolution.)"""
    if OFF == BACK_TO_BACK:
        return False
    if d > kappa_h:
        return False
    dot = float(recf[jr + R_NX]) * float(pos[y, P_NX]) + float(recf[jr + R_NY]) * float(pos[y, P_NY]) + \
        float(recf[jr + R_NZ]) * float(pos[y, P_NZ])
    if dot > OWN_BACK_COS:
        return False
    xe = np.int64(rec[jr + R_VOXEL])
    x = xe if xe >= 0 else -xe - 1
    if not (is_sheet(pos, y) and is_sheet(pos_all, x)):
        return False
    ex = (float(pos[y, P_X]) - float(recf[jr + R_X])) * float(recf[jr + R_NX]) + \
        (float(pos[y, P_Y]) - float(recf[jr + R_Y])) * float(recf[jr + R_NY]) + \
        (float(pos[y, P_Z]) - float(recf[jr + R_Z])) * float(recf[jr + R_NZ])
    return ex <= kappa_h


@njit(cache=True)
def order_cell(a, m, pos, ux, uy, uz, buf, bkey):
    """The m voxels of a cell from a, in order along the sweep, into buf as
    v (n.s > 0) or -v-1. Ties (the same centroid): +1 before -1, a box
    resting on a floor (the floor's ray meets the box's bottom); but the two
    faces of a sheet come -1 first, back to back (the ray from behind meets
    the face on its side, the face on the other side sends its ray on)."""
    for i in range(m):
        v = a + i
        t = float(pos[v, P_X]) * ux + float(pos[v, P_Y]) * uy + float(pos[v, P_Z]) * uz
        o = float(pos[v, P_NX]) * ux + float(pos[v, P_NY]) * uy + float(pos[v, P_NZ]) * uz
        late = (o > 0) == is_sheet(pos, v)  # on a tie, after the others
        if OFF == ORDER_TIES:
            late = True  # ties in the cell's own order
        j = i
        while j > 0:
            if bkey[j - 1] < t:
                break
            if bkey[j - 1] == t:
                e = buf[j - 1]
                q = e if e >= 0 else -e - 1
                if late or (e >= 0) != is_sheet(pos, q):
                    break
            bkey[j] = bkey[j - 1]
            buf[j] = buf[j - 1]
            j -= 1
        bkey[j] = t
        buf[j] = v if o > 0 else -v - 1  # the sign carries the orientation


@njit(cache=True)
def hidden(px, x, pos, y, xcut, ycut, d, g, m, buf, gcell, cutp, tau_h, ux, uy, uz):
    """Is y, facing x's waiting ray (along u) within tau, hidden from x by
    another surface: one crossing y's cell, or one that cut x's or y's
    pieces? HIDES (x's ray heads into such a surface), AWAY (such surfaces
    stand between them, but x's ray moves away from each: x keeps waiting)
    or CLEAR."""
    out = CLEAR
    if m > 1:
        out = separated(px, x, pos, y, buf, m, tau_h, float(gcell[g, 0]), float(gcell[g, 1]), float(gcell[g, 2]),
                        ux, uy, uz, cutp)
        if out == HIDES:
            return HIDES
    if xcut or ycut:
        c = cuts_between(px, x, pos, y, cutp, tau_h, ux, uy, uz)
        if c != CLEAR:
            return c
    return out


@njit(cache=True)
def cuts_between(px, x, pos, y, cutp, tau_h, ux, uy, uz):
    """A surface that cut y's or x's pieces between them (`cut_between`
    both ways, x waiting): HIDES if either is in x's ray's way, else AWAY
    if either stands between, else CLEAR."""
    out = CLEAR
    for k in range(2):
        c = cut_between(pos, y, px, x, cutp, tau_h, ux, uy, uz, False) if k == 0 else \
            cut_between(px, x, pos, y, cutp, tau_h, ux, uy, uz, True)
        if c == HIDES:
            return HIDES
        if c == AWAY:
            out = AWAY
    return out


@njit(cache=True)
def back_beyond_cut(px, x, xcut, pos, y, ycut, cutp, tau_h, ux, uy, uz):
    """x's ray would hit the back of y, but a surface that cut x's or y's
    pieces stands between them and x's ray moves away from it (AWAY, and
    no such surface in the ray's way): the back lies on that surface's
    other side, out of the ray's reach, as a face of y would be (`hidden`):
    x keeps waiting. (A floor piece beside a scan's base, cut by the
    scan's plane: the scan's sheet in its cell, beyond that plane, faces
    the ray with one face and turns its back with the other.)"""
    if OFF == BACK_BEYOND_CUT:
        return False
    return (xcut or ycut) and cuts_between(px, x, pos, y, cutp, tau_h, ux, uy, uz) == AWAY


@njit(cache=True)
def convex_edge(z, y, pos, tau_h, kappa_h):
    """Do z (the voxel last added to the line) and y, which turns its back,
    form a convex edge: z just behind y's plane, within kappa, and y behind
    z's plane or within tau in front of it (two facings of one noisy
    surface in a cell: a flat junction)?"""
    if OFF == CONVEX_EDGE:
        return False
    z0, z1, z2 = float(pos[z, P_X]), float(pos[z, P_Y]), float(pos[z, P_Z])
    y0, y1, y2 = float(pos[y, P_X]), float(pos[y, P_Y]), float(pos[y, P_Z])
    dz = (z0 - y0) * float(pos[y, P_NX]) + (z1 - y1) * float(pos[y, P_NY]) + (z2 - y2) * float(pos[y, P_NZ])
    ez = (y0 - z0) * float(pos[z, P_NX]) + (y1 - z1) * float(pos[z, P_NY]) + (y2 - z2) * float(pos[z, P_NZ])
    return dz < 0.0 and ez < tau_h and dz >= -kappa_h


WAIT, GATHER, HIDDEN, CHECK = 0, 1, 2, 3   # what a waiting voxel in front of a voxel facing it does


@njit(cache=True, inline="always")
def front_min(sheet, tau_h):
    """How far behind the plane of y (facing the rays; sheet: its P_SHEET
    field) a waiting voxel may lie and still see it: tau, or 0 for a face of
    a sheet (within tau behind it, its other face is the one facing the
    waiting voxel)."""
    if OFF == SHEET_FRONT:
        return -tau_h
    return 0.0 if (sheet == 1.0 or sheet == 1.0 + SHEET_FLAT) else -tau_h


@njit(cache=True, inline="always")
def defers(kind, d, o, ty, tau_h):
    """x gathers y, facing its ray (o = n_y . u < 0), with d = (c_x - c_y) . n_y
    and ty = (c_y - c_x) . u (y's place along the ray). Does it defer the
    gather? When y is flat (kind: its P_SHEET field) and x's ray passes
    over y, beyond tau above y's plane, and meets that plane over DEFER
    cells further on: a line a cell thick meets a floor, or a box's face,
    at a grazing angle cells before the ray does (the light of a box's
    base comes from the floor in its own contact shadow). x then records
    y (`defer`) and keeps waiting: the next voxels of y's plane along the
    line, or a surface the line meets before that plane, replace it, and x
    keeps it when the line passes below that plane (`below_deferred`) or
    ends (over a surface's edge too: the ray would pass it, but what lies
    beyond is not known here). Deferred over DEFER_MAX cells at most: the
    bounce's cost stays O(voxels x directions)."""
    if OFF == DEFERS:
        return False
    if kind < SHEET_FLAT:
        return False
    above = d + ty * o  # the ray's height over y's plane where it passes y
    return above > tau_h + DEFER_TIE and above > -o * DEFER + DEFER_TIE and above < -o * DEFER_MAX - DEFER_TIE


@njit(cache=True, inline="always")
def below_deferred(pos_all, p, c0, c1, c2, tau_h):
    """Does a voxel at (c0, c1, c2) lie beyond tau behind the plane of the
    voxel p (voxel order) a waiting voxel deferred its gather on?
    Then the line has passed below that plane: the ray met it, and the
    waiting voxel keeps p."""
    return (c0 - float(pos_all[p, P_X])) * float(pos_all[p, P_NX]) + \
        (c1 - float(pos_all[p, P_Y])) * float(pos_all[p, P_NY]) + \
        (c2 - float(pos_all[p, P_Z])) * float(pos_all[p, P_NZ]) < -tau_h - DEFER_TIE


@njit(cache=True, inline="always")
def above_deferred(pos_all, p, c0, c1, c2, tau_h):
    """Does a voxel at (c0, c1, c2) lie beyond tau in front of the plane of
    voxel p (voxel order) a waiting voxel deferred its gather on?
    A back the ray hits there stands before that plane (a sheet's other
    face on the plane itself does not)."""
    return (c0 - float(pos_all[p, P_X])) * float(pos_all[p, P_NX]) + \
        (c1 - float(pos_all[p, P_Y])) * float(pos_all[p, P_NY]) + \
        (c2 - float(pos_all[p, P_Z])) * float(pos_all[p, P_NZ]) > tau_h + DEFER_TIE


@njit(cache=True)
def deferred_t(p, rec, recf, jr, pos_all, ux, uy, uz):
    """How far along its ray (cells) the waiting voxel of record jr meets
    the plane of voxel p (inf when the ray runs away from it)."""
    n0, n1, n2 = float(pos_all[p, P_NX]), float(pos_all[p, P_NY]), float(pos_all[p, P_NZ])
    o = n0 * ux + n1 * uy + n2 * uz
    if o >= 0.0:
        return np.inf
    return ((float(recf[jr + R_X]) - float(pos_all[p, P_X])) * n0 + (float(recf[jr + R_Y]) - float(pos_all[p, P_Y])) *
            n1 + (float(recf[jr + R_Z]) - float(pos_all[p, P_Z])) * n2) / -o


@njit(cache=True)
def defer(pv, yv, d, o, rec, recf, jr, pos_all, ux, uy, uz, tau_h):
    """The waiting voxel x (record at jr, d and o as in `defers`) defers its
    gather on flat y (yv: y in voxel order): it records y, the voxel of
    y's plane furthest along the line so far, and keeps waiting: the
    line's next voxels of that plane replace it (each passing the rule's
    tests, as y did: a wall standing on the floor between stays in the
    way), up to the one near where the ray meets the plane, which it
    gathers. It keeps a plane it deferred on (pv, its R_DEFER) that the
    ray meets first. Sets the record's R_DEFER; returns what x records."""
    if pv != EMPTY and deferred_t(pv, rec, recf, jr, pos_all, ux, uy, uz) < d / -o - tau_h:
        return pv
    rec[jr + R_DEFER] = yv
    return yv


@njit(cache=True, inline="always")
def in_front(d, dmin):
    """y faces the rays (n_y . s < 0); x waits, d = (c_x - c_y) . n_y. Does x
    lie in front of y's plane (or behind it by less than -dmin)? If not,
    x's ray moves away from y's plane: x keeps waiting."""
    return d >= dmin


@njit(cache=True)
def sheet_convex_edge(w0, w1, w2, wn0, wn1, wn2, y, pos, kappa_h):
    """Does w (centroid w0..w2, normal wn0..wn2) form a convex edge with the
    other face of y's sheet (y's centroid, normal -n_y): w just in front of
    y's plane, within kappa (just behind the other face's), and y behind
    w's plane? Then a ray from w along a convex two-sided surface meets
    the sheet's inner face only because the digital line is a cell thick:
    it passes (the continuous ray leaves the surface), as it passes the
    other face's back by `convex_edge`."""
    if OFF == SHEET_CONVEX_EDGE:
        return False
    y0, y1, y2 = float(pos[y, P_X]), float(pos[y, P_Y]), float(pos[y, P_Z])
    dw = (w0 - y0) * float(pos[y, P_NX]) + (w1 - y1) * float(pos[y, P_NY]) + (w2 - y2) * float(pos[y, P_NZ])
    ew = (y0 - w0) * wn0 + (y1 - w1) * wn1 + (y2 - w2) * wn2
    return dw > 0.0 and dw <= kappa_h and ew < 0.0


@njit(cache=True, inline="always")
def front_outcome(d, dmin, tau_h, kappa_h, z_sheet, m, xe, ycut, passed):
    """y faces the rays and x lies in front of its plane (in_front); xe is
    x's record's voxel (negative: its pieces were cut), m the voxels of y's
    cell, passed the surface along the line x passed (EMPTY: none). Returns
    GATHER (x sees y), or CHECK: y may be the back of x's own sheet, the
    inner face of a convex sheet x's ray runs along (z_sheet: along the
    voxel last added to the list), or hidden from x by another surface;
    `front_check` decides."""
    if (dmin == 0.0 and (d <= kappa_h or z_sheet)) or m > 1 or xe < 0 or ycut or passed != EMPTY:
        return CHECK
    return GATHER


@njit(cache=True)
def front_check(d, dmin, x, xe, y, z_sheet, m, ycut, g, rec, recf, jr, pos_all, pos2, buf, gcell, cutp, tau_h,
                kappa_h, ux, uy, uz):
    """The rarer cases of front_outcome: WAIT when y is the back of x's own
    sheet, or the other face of a sheet whose face forms a convex edge with
    x or (z_sheet) with the voxel last added to the list, or another
    surface stands between them that x's ray moves away from; HIDDEN when
    x's ray heads into another surface standing between them (x leaves the
    list with nothing), else GATHER."""
    if dmin == 0.0 and d <= kappa_h:
        if back_to_back(rec, recf, jr, pos_all, pos2, y, d, kappa_h):
            return WAIT
        if sheet_convex_edge(float(recf[jr + R_X]), float(recf[jr + R_Y]), float(recf[jr + R_Z]),
                             float(recf[jr + R_NX]), float(recf[jr + R_NY]), float(recf[jr + R_NZ]), y, pos2, kappa_h):
            return WAIT
    if z_sheet:
        return WAIT
    if not (m == 1 and xe >= 0 and not ycut):
        h = hidden(pos_all, x, pos2, y, xe < 0, ycut, d, g, m, buf, gcell, cutp, tau_h, ux, uy, uz)
        if h == HIDES:
            return HIDDEN
        if h == AWAY:
            return WAIT
    if rec[jr + R_PASSED] != EMPTY and across(rec, recf, jr, pos2, y, tau_h):
        return HIDDEN
    return GATHER


@njit(cache=True, inline="always")
def hits_back(d, ex, z_edge, tau_h, kappa_h):
    """y turns its back (n_y . s > 0); x waits, d = (c_x - c_y) . n_y and
    ex = (c_y - c_x) . n_x. Does x hit y's back (gather nothing, leave)? Yes
    when x lies beyond tau behind y's plane, unless the voxel last added to
    the list and y form a convex edge (z_edge), or x and y do (x just
    behind y's plane, within kappa; y behind x's plane, or within tau in
    front of it)."""
    if OFF == EDGE_OF_X:
        return d < -tau_h and not z_edge
    return d < -tau_h and not z_edge and not (ex < tau_h and d >= -kappa_h)


@njit(cache=True, inline="always")
def past_silhouette(d, o, x0, x1, x2, y0, y1, y2, ux, uy, uz, tau_h):
    """y, a voxel of a curved surface, turns its back (o = n_y . s > 0) and
    x waits behind its plane (d = (c_x - c_y) . n_y < -tau). Has x's ray
    passed y's surface by? Yes when the ray, level with y (the point of the
    ray nearest y's centroid along s), is in front of y's tangent plane by
    more than tau: it crossed that plane before it came level with y. On a
    convex surface seen from outside (a scan's silhouette) the ray is then
    outside the surface: the line, a cell thick, meets the back of the
    surface's far side only because it is a cell thick. A ray that hits
    y's back is level with it at or behind the plane (a concave surface
    seen from inside, a flat one: flat voxels never pass)."""
    if OFF == PAST_SILHOUETTE:
        return False
    ty = (y0 - x0) * ux + (y1 - x1) * uy + (y2 - x2) * uz
    return d + ty * o > tau_h


EDGE_REACH = 2.0  # cells from y's centroid within which the edge test trusts y's edge line (a straight line
#                   through its cell: further out the surface may turn)


@njit(cache=True, inline="always")
def over_surface(cutp, row, x0, x1, x2):
    """Does x lie over y's surface, inside the half-plane of y's edge (cutp[row])?"""
    return x0 * cutp[row, C_NX] + x1 * cutp[row, C_NY] + x2 * cutp[row, C_NZ] >= cutp[row, C_D]


@njit(cache=True, inline="always")
def off_edge(cutp, row, d, o, x0, x1, x2, y0, y1, y2, ux, uy, uz):
    """Does x's ray meet y's plane beyond the edge where y's surface ends in
    y's cell (cutp[row]: e . g >= t on the surface)? d = (c_x - c_y) . n_y,
    o = n_y . u. A line a cell thick meets the whole cell of a surface's
    edge: a box's top, a hole's rim, looked enlarged by half a cell on each
    side (the Cornell box's ceiling saw its boxes' lit tops 12% too large).
    Only within EDGE_REACH cells of y. The sweep asks only for x beside the
    surface (not `over_surface`): from over a box's top, a ray passing the
    top's edge runs down along the box's side, whose backs a line a cell
    thick meets (light lost: a furnace with obstacles fell to 0.925); and a
    back passed from over the surface let light into a closed box at its
    corners, where one straight edge line is a poor fit."""
    if OFF == OFF_EDGE:
        return False
    t = -d / o
    p0, p1, p2 = x0 + t * ux, x1 + t * uy, x2 + t * uz
    r0, r1, r2 = p0 - y0, p1 - y1, p2 - y2
    if r0 * r0 + r1 * r1 + r2 * r2 > EDGE_REACH * EDGE_REACH:
        return False
    return p0 * cutp[row, C_NX] + p1 * cutp[row, C_NY] + p2 * cutp[row, C_NZ] < cutp[row, C_D]


@njit(cache=True, inline="always")
def misses_footprint(cutp, row, x0, x1, x2, y0, y1, y2, ux, uy, uz):
    """Does x's ray (along u) pass y, a small piece, further from its
    centroid than its footprint radius (cutp[row], its edge row: C_R > 0,
    edges.footprint_radii)? A ray that meets a disc passes within its
    radius of its centre, whatever its angle: the test never lets through
    a ray the piece stops, and needs no plane (a chandelier's curved arm, a
    sliver). A line a cell thick meets all of a frame's moulding, a
    baluster's face, a chandelier's arm in its cell: a wall behind such
    things saw a fifth of the light the rays from it see."""
    rad = cutp[row, C_R]
    if rad <= 0.0 or OFF == FOOTPRINT:
        return False
    r0, r1, r2 = y0 - x0, y1 - x1, y2 - x2
    t = r0 * ux + r1 * uy + r2 * uz
    return (r0 - t * ux) ** 2 + (r1 - t * uy) ** 2 + (r2 - t * uz) ** 2 > rad * rad


@njit(cache=True, inline="always")
def passes_piece(cutp, row, d, o, x0, x1, x2, y0, y1, y2, ux, uy, uz):
    """Does x's ray pass y by, y a voxel with an edge row (cutp[row])? When
    it meets y's plane outside a small piece's footprint (`misses_footprint`)
    or, x beside y's surface, beyond the edge where the surface ends
    (`off_edge`)."""
    if misses_footprint(cutp, row, x0, x1, x2, y0, y1, y2, ux, uy, uz):
        return True
    return not over_surface(cutp, row, x0, x1, x2) and off_edge(cutp, row, d, o, x0, x1, x2, y0, y1, y2, ux, uy, uz)
