"""Mesh topology: which triangles share an edge (by corner positions)."""
import numpy as np
from numba import njit


def triangle_adjacency(vertices, triangles):
    """Triangles sharing an edge, by corner positions (meshes that repeat a
    vertex at a UV or normal seam are still connected there): CSR
    (start (nt + 1,) int64, neighbours (k,) int32), each list sorted."""
    nt = len(triangles)
    if nt == 0:
        return np.zeros(1, np.int64), np.zeros(0, np.int32)
    weld = row_labels(np.asarray(vertices, np.float64))
    corner = weld[np.asarray(triangles)]
    e = np.concatenate([corner[:, [0, 1]], corner[:, [1, 2]], corner[:, [2, 0]]])
    e.sort(axis=1)
    tri = np.tile(np.arange(nt, dtype=np.int64), 3)
    order = np.lexsort((tri, e[:, 1], e[:, 0]))
    e, tri = e[order], tri[order]
    new = np.ones(len(e), bool)
    new[1:] = (e[1:] != e[:-1]).any(axis=1)
    start = np.flatnonzero(np.append(new, True))
    a, b = _edge_pairs(start.astype(np.int64), tri)
    keep = a != b
    a, b = a[keep], b[keep]
    pairs = np.unique(np.stack([np.concatenate([a, b]), np.concatenate([b, a])], axis=1), axis=0)
    counts = np.bincount(pairs[:, 0], minlength=nt)
    offsets = np.zeros(nt + 1, np.int64)
    np.cumsum(counts, out=offsets[1:])
    return offsets, pairs[:, 1].astype(np.int32)


def row_labels(a):
    """(n,) int64: each row of a (n, j) labelled by the rank of its value
    among the distinct rows, in lexicographic order (np.unique(a, axis=0,
    return_inverse=True)'s inverse, which sorts the rows as records,
    several times slower). Rows equal as numbers share a label."""
    if not len(a):
        return np.zeros(0, np.int64)
    order = np.lexsort(a.T[::-1])
    s = a[order]
    new = np.ones(len(a), bool)
    new[1:] = (s[1:] != s[:-1]).any(axis=1)
    out = np.empty(len(a), np.int64)
    out[order] = np.cumsum(new) - 1
    return out


@njit(cache=True)
def _edge_pairs(start, tri):
    """Every pair of triangles on one edge (runs start[i]..start[i+1])."""
    n = 0
    for r in range(start.shape[0] - 1):
        k = start[r + 1] - start[r]
        n += k * (k - 1) // 2
    a = np.empty(n, np.int64)
    b = np.empty(n, np.int64)
    n = 0
    for r in range(start.shape[0] - 1):
        for i in range(start[r], start[r + 1]):
            for j in range(i + 1, start[r + 1]):
                a[n] = tri[i]
                b[n] = tri[j]
                n += 1
    return a, b
