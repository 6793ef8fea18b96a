"""What the pieces of one cell tell about each other (docs/design.md
section 2): pieces cut in two by another surface's plane (a floor running
under a wall), planes that separate other pieces (a wall between two
floors), side signatures that keep such pieces apart, and the merge of the
pieces into voxels (one per cell, facing and sheet).

Pieces are given in grid units, sorted by cell key (`order`, `runs`: the
boundaries of each cell's run in that order).
"""
import math

import numpy as np
from numba import njit, prange

from .clip import area_centroid, clip_plane, piece_polygon
from .tolerances import PARALLEL_COS, SHEET_BACK_COS

@njit(cache=True)
def merge_sheets(order, key, facing, sig, along, area, centroid, normal, sheet_gap):
    """Walks pieces sorted by (cell key, facing, side signature, position
    along the facing axis) and assigns each to a voxel: a new voxel starts
    at a new (cell, facing, signature) or when the piece's centroid is more than sheet_gap (grid units)
    off the current sheet's plane. Returns voxel id per sorted piece."""
    n = order.shape[0]
    vox = np.empty(n, np.int64)
    cur = -1
    sa = 0.0
    sc = np.zeros(3)
    sn = np.zeros(3)
    for i in range(n):
        p = order[i]
        q = order[i - 1] if i > 0 else p
        new = i == 0 or key[p] != key[q] or facing[p] != facing[q] or sig[p] != sig[q]
        if not new:
            # distance of this piece's centroid from the sheet's mean plane
            ln = math.sqrt(sn[0] * sn[0] + sn[1] * sn[1] + sn[2] * sn[2])
            d = 0.0
            for c in range(3):
                d += (centroid[p, c] / area[p] - sc[c] / sa) * sn[c] / ln
            if abs(d) > sheet_gap:
                new = True
        if new:
            cur += 1
            sa = 0.0
            sc[:] = 0.0
            sn[:] = 0.0
        sa += area[p]
        for c in range(3):
            sc[c] += centroid[p, c]
            sn[c] += normal[p, c] * area[p]
        vox[i] = cur
    return vox


@njit(cache=True)
def join_voxels(vox_of, same, link):
    """Union of voxels: pieces same[i] and same[i - 1] (positions in the
    sorted pieces) with link[i] put their voxels together. Returns the root
    (smallest id) of each voxel id."""
    n = int(vox_of[-1]) + 1 if vox_of.shape[0] else 0
    parent = np.arange(n)
    for i in range(1, same.shape[0]):
        if link[i]:
            a, b = vox_of[same[i]], vox_of[same[i - 1]]
            while parent[a] != a:
                a = parent[a]
            while parent[b] != b:
                b = parent[b]
            if a < b:
                parent[b] = a
            elif b < a:
                parent[a] = b
    for v in range(n):
        r = v
        while parent[r] != r:
            r = parent[r]
        parent[v] = r
    return parent


def cell_runs(order, key):
    """Boundaries (m + 1,) of the runs of equal cell key in pieces sorted by key (order)."""
    k = key[order]
    return np.concatenate([[0], np.flatnonzero(k[1:] != k[:-1]) + 1, [len(k)]]).astype(np.int64)


@njit(cache=True)
def side_signatures(order, runs, key, facing, area, centroid, normal, tol, patch, crowd, min_plane):
    """For pieces sorted by cell key (order), a signature per piece: bit i
    set when the piece lies in front of (beyond tol, grid units) the plane
    of the i-th piece of another facing and another smooth patch in the
    same cell, not facing back at it (within 25 degrees). Pieces of one
    facing with different signatures are cut apart by another surface
    crossing the cell (a wall standing on two floors) and must not merge
    (docs/design.md section 4, straddling voxels). In a cell of more than
    crowd pieces only pieces of at least min_plane cells^2 count (a wall
    through a plant, not each leaf: voxelize.merge_clutter); at most 63
    planes count per cell."""
    n = order.shape[0]
    sig = np.zeros(n, np.int64)
    for r in range(runs.shape[0] - 1):
        a, b = runs[r], runs[r + 1]
        if b - a < 2:
            continue
        planes = order[a:b]
        if b - a > crowd:
            planes = planes[area[planes] >= min_plane]
        planes = planes[:63]
        for i in range(a, b):
            p = order[i]
            s = np.int64(0)
            for j in range(planes.shape[0]):
                q = planes[j]
                if facing[q] == facing[p] or patch[q] == patch[p]:
                    continue
                cos = normal[p, 0] * normal[q, 0] + normal[p, 1] * normal[q, 1] + normal[p, 2] * normal[q, 2]
                if cos < SHEET_BACK_COS:
                    continue  # the other face of a two-sided surface (curved: its pieces' planes differ)
                d = 0.0
                for c in range(3):
                    d += (centroid[p, c] / area[p] - centroid[q, c] / area[q]) * normal[q, c]
                if d > tol:
                    s |= np.int64(1) << np.int64(j)
            sig[p] = s
    return sig


@njit(cache=True, parallel=True)
def find_straddlers(by_cell, runs, key, facing, piece_tri, piece_cell, area, centroid, normal, corners, origin, inv_h,
                    min_part, patch, crowd, min_cutter):
    """For each piece: the piece of another facing, triangle and smooth
    patch (patches.py) in the same cell, not facing back at it, whose plane cuts it into two parts
    of at least min_part cells^2 each (a floor running under a wall), else
    -1. One cut per piece: the one that leaves the larger smaller part. In
    a cell of more than crowd pieces only pieces of at least min_cutter
    cells^2 cut (a wall through a plant, not each leaf through the others:
    the pairs would cost crowd^2 clippings and the clutter merges anyway,
    voxelize.merge_clutter)."""
    n = by_cell.shape[0]
    cut = np.full(n, -1, np.int64)
    for r in prange(runs.shape[0] - 1):   # cells apart: each writes only its own pieces' cut
        a, b = runs[r], runs[r + 1]
        if b - a < 2:
            continue
        cutters = by_cell[a:b]
        if b - a > crowd:
            cutters = cutters[area[cutters] >= min_cutter]
        for i in range(a, b):
            p = by_cell[i]
            best, best_part = -1, min_part
            qx, qy, qz, m = piece_polygon(corners, piece_tri[p], origin, inv_h, piece_cell[p])
            for q in cutters:
                if facing[q] == facing[p] or piece_tri[q] == piece_tri[p] or patch[q] == patch[p]:
                    continue
                nx, ny, nz = normal[q, 0], normal[q, 1], normal[q, 2]
                if nx * normal[p, 0] + ny * normal[p, 1] + nz * normal[p, 2] < SHEET_BACK_COS:
                    continue  # facing back within 25 degrees: the other face of a two-sided surface
                #             (a curved one: its triangles' planes differ a little), not a surface across
                d = (centroid[q, 0] * nx + centroid[q, 1] * ny + centroid[q, 2] * nz) / area[q]
                lo, hi = np.inf, -np.inf
                for v in range(m):
                    s = qx[v] * nx + qy[v] * ny + qz[v] * nz - d
                    lo = min(lo, s)
                    hi = max(hi, s)
                if lo >= 0.0 or hi <= 0.0:
                    continue
                fx, fy, fz, fm = clip_plane(qx, qy, qz, m, nx, ny, nz, d, True)
                af, _, _, _ = area_centroid(fx, fy, fz, fm)
                part = min(af, area[p] - af)
                if part > best_part:
                    best, best_part = q, part
            cut[p] = best
    return cut


@njit(cache=True)
def split_pieces(cut, piece_tri, piece_cell, area, centroid, normal, corners, origin, inv_h, extra_index,
                 out_area, out_cen, out_plane, out_sign):
    """Cuts each piece p with cut[p] >= 0 by that piece's plane: the front
    part stays in slot p (sign +1), the back part goes to slot
    extra_index[p] (sign -1); both remember the plane (normal, offset, grid
    units) so that a hit point can be told which part it lies on."""
    n = cut.shape[0]
    for p in range(n):
        q = cut[p]
        if q < 0:
            continue
        qx, qy, qz, m = piece_polygon(corners, piece_tri[p], origin, inv_h, piece_cell[p])
        nx, ny, nz = normal[q, 0], normal[q, 1], normal[q, 2]
        d = (centroid[q, 0] * nx + centroid[q, 1] * ny + centroid[q, 2] * nz) / area[q]
        for part in range(2):
            fx, fy, fz, fm = clip_plane(qx, qy, qz, m, nx, ny, nz, d, part == 0)
            a, cx, cy, cz = area_centroid(fx, fy, fz, fm)
            slot = p if part == 0 else extra_index[p]
            out_area[slot] = a
            out_cen[slot, 0], out_cen[slot, 1], out_cen[slot, 2] = cx, cy, cz
            out_plane[slot, 0], out_plane[slot, 1], out_plane[slot, 2], out_plane[slot, 3] = nx, ny, nz, d
            out_sign[slot] = 1 if part == 0 else -1


@njit(cache=True)
def separating_planes(by_cell, runs, piece_tri, area, centroid, normal, tol, patch, planes, has):
    """Cells where the plane of a piece q has two pieces of other triangles
    and smooth patches, not parallel to it, clearly on both sides (beyond tol cells): a surface
    standing between them inside the cell (a wall between two floors).
    Writes q's plane (normal, offset; grid units) into planes[i] and True
    into has[i] for every piece i of such a cell, but a piece meeting q at
    a convex edge (each behind the other's plane: a box's front and its
    side in the cell of the box's corner): q stands behind it."""
    for r in range(runs.shape[0] - 1):
        a, b = runs[r], runs[r + 1]
        if b - a > 2:
            for j in range(a, b):
                q = by_cell[j]
                nx, ny, nz = normal[q, 0], normal[q, 1], normal[q, 2]
                d = (centroid[q, 0] * nx + centroid[q, 1] * ny + centroid[q, 2] * nz) / area[q]
                front = back = False
                for i in range(a, b):
                    p = by_cell[i]
                    if piece_tri[p] == piece_tri[q] or patch[p] == patch[q]:
                        continue
                    if abs(normal[p, 0] * nx + normal[p, 1] * ny + normal[p, 2] * nz) >= PARALLEL_COS:
                        continue
                    sd = (centroid[p, 0] * nx + centroid[p, 1] * ny + centroid[p, 2] * nz) / area[p] - d
                    if sd > tol:
                        front = True
                    elif sd < -tol:
                        back = True
                if front and back:
                    for i in range(a, b):
                        p = by_cell[i]
                        if patch[p] == patch[q] and p != q:
                            continue  # q's own surface is not across itself
                        if p != q:
                            # p and q meeting at a convex edge (a box's front and its side, each behind the
                            # other's plane): q stands behind p, never between p and what p faces
                            mx, my, mz = normal[p, 0], normal[p, 1], normal[p, 2]
                            dp = (centroid[p, 0] * mx + centroid[p, 1] * my + centroid[p, 2] * mz) / area[p]
                            sp = (centroid[p, 0] * nx + centroid[p, 1] * ny + centroid[p, 2] * nz) / area[p] - d
                            sq = (centroid[q, 0] * mx + centroid[q, 1] * my + centroid[q, 2] * mz) / area[q] - dp
                            if sp < -tol and sq < -tol:
                                continue
                        planes[p, 0], planes[p, 1], planes[p, 2], planes[p, 3] = nx, ny, nz, d
                        has[p] = True
                    break
