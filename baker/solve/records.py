"""The packed records of the linear propagation, field by field (docs/design.md
section 4; why this layout: solve/sweep.py).

The sweep reads these as flat arrays with unsigned offsets (row * width +
field): numba then needs neither the rows' strides nor wrap-around code
for negative indices, which halves the instructions of its loop. The named
offsets below are what every kernel indexes with.

Voxel rows, `pos` (n, POS) float32, one per voxel (in voxel order, and a
copy in the sweep axis's order):
"""
import numpy as np
from numba import njit


# Field offsets are numpy uint64 so that `row + FIELD` stays unsigned in numba (a plain int would make it int64,
# and every flat index would get a negative-index check); row widths are plain ints.
_u = np.uint64

POS = 8
P_X, P_Y, P_Z = _u(0), _u(1), _u(2)      # centroid, grid coordinates (1e-7 of the grid's extent in float32;
#                                          tau is 0.1 cell)
P_NX, P_NY, P_NZ = _u(3), _u(4), _u(5)   # unit normal
P_CUT = _u(6)    # 0: the voxel's pieces were not cut by another surface; else +-(row + 1): the side of the cutting
#                  plane it lies on (the sign) and that plane's row in the cut table
P_SHEET = _u(7)  # 1: a face of a two-sided sheet (its back is the other facing's voxel, at the same centroid);
#                  plus SHEET_FLAT: the voxel lies on a flat stretch of surface (voxels.lookup.flat_voxels);
#                  plus SHEET_KINDS * (row + 1) where the voxel's surface ends inside its cell: its edge's row in
#                  the cut table (`sheet_kind`, `edge_row`)
SHEET_FLAT = 2.0
SHEET_KINDS = 4.0
MAX_CUT_ROWS = 2 ** 24 - 1  # rows a float32 P_CUT can name exactly

# Cut table, `cutp` (m, CUT) float64, one row per cut voxel, then one per edge voxel (the same fields: the
# edge's in-plane unit normal e pointing into the surface, the offset t (e . g >= t on the surface), its cell):
# an edge row may also (or only: e = 0, t = 0) give a small piece's footprint radius
CUT = 8
C_NX, C_NY, C_NZ = _u(0), _u(1), _u(2)   # the cutting plane's unit normal
C_D = _u(3)                              # its offset: n . g = C_D for g on the plane (grid coordinates)
C_CX, C_CY, C_CZ = _u(4), _u(5), _u(6)   # the cut voxel's cell
C_R = _u(7)                              # edge rows: the footprint radius of a small piece (0: none; edges.py)

# Waiting records, `rec` (REC int32 per record; fields marked f hold float32 bits, read through `recf`):
REC = 11
R_X, R_Y, R_Z = _u(0), _u(1), _u(2)      # f the waiting voxel's centroid
R_NX, R_NY, R_NZ = _u(3), _u(4), _u(5)   # f its normal
R_VOXEL = _u(6)   # its index in voxel order (-v-1 when its pieces were cut)
R_NEXT = _u(7)    # the next record of the line's list (EMPTY: the last)
R_BOUND = _u(8)   # f a lower bound of (c_x - c) . n over the voxels waiting at and after this record, c and n
#                   this record's centroid and normal
R_PASSED = _u(9)  # the last voxel parallel to the line that it passed (EMPTY: none)
R_DEFER = _u(10)  # the flat voxel (voxel order) it deferred its gather on (EMPTY: none; visibility.defers)

# Line table, `tab` (size, LINE) int32, one row per line id (dense) or hashed slot:
LINE = 4
T_STAMP = _u(0)   # the sweep that last used the row (no clearing between sweeps)
T_HEAD = _u(1)    # the line's first waiting record (EMPTY: none)
T_LAST = _u(2)    # the voxel last added to its list (the convex-edge test's z)
T_KEY = _u(3)     # the line id (hashed tables)

EMPTY = -1
RING = 32                    # hits a sweep keeps before writing them (sweep.py)


@njit(cache=True, inline="always")
def cut_row(pos, v):
    """Row in the cut table of voxel v's cutting plane (v cut: P_CUT != 0)."""
    return np.int64(abs(pos[v, P_CUT])) - 1


@njit(cache=True, inline="always")
def cut_side(pos, v):
    """+1 / -1: the side of its cutting plane voxel v lies on (v cut)."""
    return 1.0 if pos[v, P_CUT] > 0.0 else -1.0


@njit(cache=True, inline="always")
def sheet_kind(k):
    """A P_SHEET field without its edge row: 0, 1 (sheet), + SHEET_FLAT (flat)."""
    if k < SHEET_KINDS:  # most voxels: no edge, no division
        return k
    return k - SHEET_KINDS * np.floor(k / SHEET_KINDS)


@njit(cache=True, inline="always")
def edge_row(k):
    """The cut table's row of the edge of a voxel whose P_SHEET field is k
    (-1: its surface does not end inside its cell)."""
    return np.int64(k / SHEET_KINDS) - 1


@njit(cache=True, inline="always")
def is_sheet(pos, v):
    """Is voxel v a face of a two-sided sheet?"""
    k = sheet_kind(pos[v, P_SHEET])
    return k == 1.0 or k == 1.0 + SHEET_FLAT


# Helpers of the sweep (sweep.py says which of its steps are functions and why).

@njit(cache=True)
def unlink(j, nj, prev, head, rec, free, nfree):
    """Removes waiting record j (followed by nj) from its list, after prev
    (the head if none), and frees it: returns (the list's head, nfree)."""
    if prev == EMPTY:
        head = nj
    else:
        rec[np.uint64(REC * prev) + R_NEXT] = nj
    free[np.uint64(nfree)] = j
    return head, nfree + 1


@njit(cache=True)
def flush_hits(hit, ring_p, ring_v, nh):
    """Writes the hits still in the ring."""
    for i in range(max(0, nh - RING), nh):
        hit[ring_p[i & (RING - 1)]] = ring_v[i & (RING - 1)]
