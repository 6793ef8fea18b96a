"""Smooth patches: the pieces of one cell that belong to one smooth
surface (docs/design.md section 2).

A scanned or finely tessellated curved surface puts many small triangles
into a cell, their planes tilted against each other by the curvature and
the scan's noise. Read as separate surfaces, each piece's plane would cut
or separate the others, and the cell's single surface would fall apart
into a dozen slivers of voxels (the Stanford bunny at 64 cells: 4.4 voxels
per cell and facing, most of them too small to catch a photon, each
hiding the others from the propagation). Pieces of one cell whose
triangles share an edge, on the same side, with normals within
SMOOTH_COS of each other, are one patch (transitively). With the pieces
of its triangles' other sides (a two-sided surface's other face) it is
one *surface*: a surface never cuts, separates or splits into sheets
itself; other surfaces (a wall standing on a floor, a box on a table:
creases sharper than SMOOTH_COS, or no shared edge) still do. The pieces
of a patch of one facing always merge into one voxel.
"""
import numpy as np
from numba import njit


@njit(cache=True)
def _root(parent, i):
    while parent[i] != i:
        parent[i] = parent[parent[i]]
        i = parent[i]
    return i


@njit(cache=True)
def _join(parent, p, q):
    rp, rq = _root(parent, p), _root(parent, q)
    if rp < rq:
        parent[rq] = rp
    elif rq < rp:
        parent[rp] = rq


@njit(cache=True)
def smooth_patches(by_cell, runs, piece_tri, normal, adj_start, adj, smooth_cos):
    """(patch (m,) int64, surface (m,) int64) of each piece. Patch: pieces of
    one cell whose triangles share an edge and whose side normals agree
    within smooth_cos, joined transitively (one face of a smooth surface).
    Surface: the same with either side of each triangle, and a triangle's
    two sides joined (both faces of a smooth two-sided surface: a surface
    never cuts or separates itself). Ids are the smallest piece index."""
    m = by_cell.shape[0]
    parent = np.arange(m)
    both = np.arange(m)
    for r in range(runs.shape[0] - 1):
        a, b = runs[r], runs[r + 1]
        k = b - a
        if k < 2:
            continue
        # the cell's pieces sorted by triangle: a neighbour's pieces found by binary search
        tris = np.empty(k, np.int64)
        for i in range(k):
            tris[i] = piece_tri[by_cell[a + i]]
        srt = np.argsort(tris, kind="mergesort")
        for i in range(k):
            p = by_cell[a + i]
            t = piece_tri[p]
            for e in range(adj_start[t] - 1, adj_start[t + 1]):
                u = t if e < adj_start[t] else adj[e]  # the triangle itself (its other side), then its neighbours
                lo, hi = 0, k
                while lo < hi:
                    mid = (lo + hi) // 2
                    if tris[srt[mid]] < u:
                        lo = mid + 1
                    else:
                        hi = mid
                while lo < k and tris[srt[lo]] == u:
                    q = by_cell[a + srt[lo]]
                    lo += 1
                    if q == p:
                        continue
                    cos = normal[p, 0] * normal[q, 0] + normal[p, 1] * normal[q, 1] + normal[p, 2] * normal[q, 2]
                    if u == t or abs(cos) > smooth_cos:
                        _join(both, p, q)
                    if u != t and cos > smooth_cos:
                        _join(parent, p, q)
    patch = np.empty(m, np.int64)
    surface = np.empty(m, np.int64)
    for i in range(m):
        patch[i] = _root(parent, i)
        surface[i] = _root(both, i)
    return patch, surface
