"""Where a voxel's surface ends inside its cell (docs/design.md section 4,
clause 11): the edge of a box's top, a hole's rim, a wall's end; and the
footprint of a small piece with no edge line (clause 12): a frame's
moulding, a chandelier's arm.

A voxel's plane (its centroid and normal) crosses its cell in a polygon,
the cross-section. A surface that runs on through the cell covers it
(within a few per cent on a curved one); a voxel covering under EDGE_FILL
of it ends inside the cell. Its edge is taken as the straight line across
the cross-section, perpendicular to the offset from the cross-section's
centroid to the voxel's, that leaves the voxel's area on the voxel's side:
a half-plane e . g >= t of the voxel's plane (grid units). Exact for a
straight edge (a box's top), an approximation at a corner (two edges).
"""
import math

import numpy as np
from numba import njit, prange

from .clip import MAX_POLY, area_centroid, clip_plane

EDGE_FILL = 0.9      # a voxel covering less of its plane's cross-section of its cell ends inside it
EDGE_OFFSET = 0.02   # cells: ... when its centroid lies at least this far from the cross-section's (else no
#                      direction: a small piece in the middle of its cell)


@njit(cache=True)
def _cross_section(c0, c1, c2, n0, n1, n2, cell):
    """The polygon of the plane through c with normal n inside `cell`."""
    # two in-plane axes
    if abs(n0) < 0.9:
        a0, a1, a2 = 0.0, -n2, n1
    else:
        a0, a1, a2 = n2, 0.0, -n0
    la = math.sqrt(a0 * a0 + a1 * a1 + a2 * a2)
    a0, a1, a2 = a0 / la, a1 / la, a2 / la
    b0, b1, b2 = n1 * a2 - n2 * a1, n2 * a0 - n0 * a2, n0 * a1 - n1 * a0
    px = np.empty(MAX_POLY)
    py = np.empty(MAX_POLY)
    pz = np.empty(MAX_POLY)
    r = 2.0  # beyond the cell's diagonal from any point of it
    for i, (sa, sb) in enumerate(((-r, -r), (r, -r), (r, r), (-r, r))):
        px[i] = c0 + sa * a0 + sb * b0
        py[i] = c1 + sa * a1 + sb * b1
        pz[i] = c2 + sa * a2 + sb * b2
    m = 4
    for axis in range(3):
        for hi in range(2):
            nx = 1.0 if axis == 0 else 0.0
            ny = 1.0 if axis == 1 else 0.0
            nz = 1.0 if axis == 2 else 0.0
            px, py, pz, m = clip_plane(px, py, pz, m, nx, ny, nz, float(cell[axis] + hi), hi == 0, axis)
            if m < 3:
                return px, py, pz, 0
    return px, py, pz, m


@njit(cache=True)
def _voxel_section(centroid, normal, cell, i):
    """The cross-section of voxel i's plane with its cell: the polygon
    (px, py, pz, m) and its area and area-weighted centroid sums (area 0
    when the plane misses the cell)."""
    px, py, pz, m = _cross_section(centroid[i, 0], centroid[i, 1], centroid[i, 2], normal[i, 0], normal[i, 1],
                                   normal[i, 2], cell[i])
    if m < 3:
        return px, py, pz, m, 0.0, 0.0, 0.0, 0.0
    a, sx, sy, sz = area_centroid(px, py, pz, m)
    return px, py, pz, m, a, sx, sy, sz


@njit(cache=True, parallel=True)
def edge_planes(cell, centroid, normal, area, eligible, out):
    """cell (n, 3) int, centroid (n, 3) grid units, normal (n, 3), area (n,)
    in cells^2, eligible (n,) bool. Writes out (n, 4): the edge's in-plane
    unit normal e (towards the surface) and t (e . g >= t on the surface),
    or zeros where the surface does not end in the cell."""
    for i in prange(cell.shape[0]):
        out[i, 0] = out[i, 1] = out[i, 2] = out[i, 3] = 0.0
        if not eligible[i]:
            continue
        c0, c1, c2 = centroid[i, 0], centroid[i, 1], centroid[i, 2]
        n0, n1, n2 = normal[i, 0], normal[i, 1], normal[i, 2]
        px, py, pz, m, a_cs, sx, sy, sz = _voxel_section(centroid, normal, cell, i)
        if a_cs <= 0.0 or area[i] >= EDGE_FILL * a_cs:
            continue
        e0, e1, e2 = c0 - sx / a_cs, c1 - sy / a_cs, c2 - sz / a_cs
        k = e0 * n0 + e1 * n1 + e2 * n2  # into the plane
        e0, e1, e2 = e0 - k * n0, e1 - k * n1, e2 - k * n2
        le = math.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
        if le < EDGE_OFFSET:
            continue
        e0, e1, e2 = e0 / le, e1 / le, e2 / le
        lo, hi = np.inf, -np.inf
        for v in range(m):
            s = px[v] * e0 + py[v] * e1 + pz[v] * e2
            lo, hi = min(lo, s), max(hi, s)
        for _ in range(40):  # the offset leaving the voxel's area on its side
            t = 0.5 * (lo + hi)
            qx, qy, qz, q = clip_plane(px, py, pz, m, e0, e1, e2, t, True)
            a = area_centroid(qx, qy, qz, q)[0] if q >= 3 else 0.0
            if a > area[i]:
                lo = t
            else:
                hi = t
        out[i, 0], out[i, 1], out[i, 2], out[i, 3] = e0, e1, e2, 0.5 * (lo + hi)


FOOT_AREA = 0.25     # cells^2: a planar voxel at most this large whose plane its cell's voxels cover under
#                      EDGE_FILL is a small piece (a frame's moulding, a baluster's face, a chandelier's arm) ...
FOOT_MARGIN = 1.3    # ... and a ray meets it only within this many times the radius of a disc of its area
FOOT_PLANE = 0.1     # cells: voxels of a cell whose planes agree within SAME_PLANE_COS and this offset are one
#                      surface (the two halves of a cut one)


@njit(cache=True, parallel=True)
def footprint_radii(starts, cell, centroid, normal, area, eligible, same_cos, out):
    """starts (ng + 1,) the cells' first voxels (voxels grouped by cell),
    cell (n, 3) int, centroid (n, 3) grid units, normal (n, 3), area (n,) cells^2, eligible
    (n,) bool. Writes out (n,): the radius (cells) of a small piece's
    footprint, a disc about its centroid (FOOT_MARGIN times that of a disc
    of its area), or 0 where the voxel is not a small piece: over FOOT_AREA,
    or its surface (its own voxel with any other of the cell in its plane
    and facing, the halves of a cut surface) covers its plane's cross-section
    of the cell within EDGE_FILL (a surface running on through the cell,
    however little of the cell it clips: a wall is never one)."""
    for g in prange(starts.shape[0] - 1):
        for i in range(starts[g], starts[g + 1]):
            out[i] = 0.0
            if not eligible[i] or area[i] > FOOT_AREA:
                continue
            a_cs = _voxel_section(centroid, normal, cell, i)[4]
            if a_cs <= 0.0:
                continue
            c0, c1, c2 = centroid[i, 0], centroid[i, 1], centroid[i, 2]
            n0, n1, n2 = normal[i, 0], normal[i, 1], normal[i, 2]
            same = 0.0
            for j in range(starts[g], starts[g + 1]):
                cj = normal[j, 0] * n0 + normal[j, 1] * n1 + normal[j, 2] * n2
                dj = (centroid[j, 0] - c0) * n0 + (centroid[j, 1] - c1) * n1 + (centroid[j, 2] - c2) * n2
                if cj >= same_cos and abs(dj) <= FOOT_PLANE:
                    same += area[j]
            if same >= EDGE_FILL * a_cs:
                continue
            out[i] = FOOT_MARGIN * math.sqrt(area[i] / math.pi)


def footprints(cell, centroid, normal, area, eligible):
    """(n,) footprint radii (footprint_radii) of voxels grouped by cell:
    cell (n, 3) int, centroid (n, 3) grid units, normal (n, 3), area (n,)
    cells^2, eligible (n,) bool (the propagation takes planar voxels with
    no edge line: a box's top at its edge is a strip a disc fits badly, and
    a ray let past it runs into the box's side from behind; a noisy scan's
    curved pieces let its lines through its shell)."""
    from .tolerances import SAME_PLANE_COS
    n = len(cell)
    out = np.zeros(n)
    if n == 0:
        return out
    cell = np.ascontiguousarray(cell, np.int64)
    new = np.ones(n, bool)
    new[1:] = np.any(cell[1:] != cell[:-1], axis=1)
    starts = np.append(np.nonzero(new)[0], n).astype(np.int64)
    footprint_radii(starts, cell, np.ascontiguousarray(centroid, np.float64),
                    np.ascontiguousarray(normal, np.float64), np.ascontiguousarray(area, np.float64),
                    np.ascontiguousarray(eligible, np.bool_), SAME_PLANE_COS, out)
    return out
