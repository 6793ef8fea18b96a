"""Bounding volume hierarchy over triangles: binned SAH build, flat arrays.

Layout (depth-first): node i's left child is i + 1, its right child is
`right[i]`; a leaf has count[i] > 0 and holds triangles first[i] ..
first[i] + count[i] - 1 of the reordered triangle arrays. Triangles are
stored reordered as their corners (v0, v1, v2), with `tri_index` mapping
back to the scene's triangle numbers. The traversal reads the same tree
collapsed to 8-wide nodes (collapse_wide, the WIDE_* record below), through
`BVHArrays`; the binary arrays stay for tests and inspection.

Depth: the traversal keeps at most three pending nodes per level of the
8-wide tree (no deeper than the binary one) on a fixed stack of STACK_SIZE
entries, so the tree must stay shallower than a third of it. Binned SAH
can peel a few triangles per level off a degenerate input (sizes or
positions in a geometric progression: 16 bins over a range that shrinks
16-fold per level), so below MAX_SAH_DEPTH levels the build splits at the
median instead, which adds at most log2(triangles) < 32 levels.
"""
from collections import namedtuple

import numpy as np
from numba import njit

N_BINS = 16
LEAF_MAX = 4
COST_TRAVERSE = 1.0
COST_INTERSECT = 1.0
WIDTH = 8             # children per node of the tree the traversal reads
STACK_SIZE = 1024     # traversal stack entries (int32): at most WIDTH - 1 per level of the wide tree
MAX_SAH_DEPTH = 64    # deeper nodes split at the median: 7 (depth + 1) < 7 (MAX_SAH_DEPTH + 33) <= STACK_SIZE

BVHArrays = namedtuple("BVHArrays", [
    "wide",        # (nw, 64) float32 8-wide nodes, one 256-byte record each (WIDE_* below); node 0 is the root
    "wide_i",      # the same memory read as int32 (the child and count slots)
    "root_box",    # (6,) float64
    "tris",        # (nt, 9) float64 corners v0 v1 v2 in BVH order (float32 values)
    "tri_index",   # (nt,) int32 BVH order -> scene triangle
    # what rays pass (traverse.py): PASS_* per triangle, and the tables its test reads
    "tri_pass",    # (nt,) int8 PASS_OPAQUE | PASS_MASK (alpha-tested) | PASS_GLASS (thin, tinted)
    "tri_mat",     # (nt,) int32 material of each triangle in BVH order
    "tri_uv",      # (nt, 6) float64 texture coordinates of its corners (1 row when no triangle is masked)
    "mask_offset",  # (nm,) int64 first texel of a material's alpha texture in mask_data (-1: none)
    "mask_size",   # (nm, 2) int64 alpha texture width, height
    "mask_alpha",  # (nm,) float64 the base colour's alpha factor
    "mask_cutoff",  # (nm,) float64 alphaCutoff
    "mask_data",   # (texels,) float32 alpha texels of every masked material
    "glass_tint",  # (nm, 3) float64 transmittance t x base colour of thin glass
])

PASS_OPAQUE, PASS_MASK, PASS_GLASS = 0, 1, 2

# An 8-wide node's record: the eight children's boxes as structure of
# arrays (lo x of children 0-7, lo y, lo z, hi x, hi y, hi z), then per
# child its node (inner child) or first triangle (leaf), then its triangle
# count (0: an inner node; -1: no child in this slot; slots fill from 0).
# Eight slots of a coordinate are one 256-bit load, and the eight slab
# tests of a node compile to a few vector instructions where the CPU has
# them (AVX2/AVX-512); a ray visits about a third fewer nodes than in a
# 4-wide tree (bench/rays.py).
WIDE_LO = 0
WIDE_HI = 3 * WIDTH
WIDE_CHILD = 6 * WIDTH
WIDE_COUNT = 7 * WIDTH
WIDE_RECORD = 8 * WIDTH


@njit(cache=True)
def _surface(lo, hi):
    dx, dy, dz = max(hi[0] - lo[0], 0.0), max(hi[1] - lo[1], 0.0), max(hi[2] - lo[2], 0.0)
    return 2.0 * (dx * dy + dy * dz + dz * dx)


@njit(cache=True)
def build_bvh(corners, leaf_max):
    """corners (nt, 3, 3) float64 -> (lo, hi, right, first, count, order, depth).

    Binned SAH (Wald 2007): 16 bins on each axis of the centroid bounds; a
    node becomes a leaf when no split beats intersecting all its triangles
    and it holds at most 4 * leaf_max, or when it holds at most leaf_max.
    Nodes at depth MAX_SAH_DEPTH or more split at the median of their
    centroids along the widest axis. depth: the deepest node's level
    (root 0).
    """
    nt = corners.shape[0]
    cen = np.empty((nt, 3))
    tlo = np.empty((nt, 3))
    thi = np.empty((nt, 3))
    for i in range(nt):
        for k in range(3):
            a, b, c = corners[i, 0, k], corners[i, 1, k], corners[i, 2, k]
            tlo[i, k] = min(a, min(b, c))
            thi[i, k] = max(a, max(b, c))
            cen[i, k] = 0.5 * (tlo[i, k] + thi[i, k])
    order = np.arange(nt).astype(np.int32)
    max_nodes = 2 * nt + 1
    lo = np.empty((max_nodes, 3))
    hi = np.empty((max_nodes, 3))
    right = np.full(max_nodes, -1, np.int32)
    first = np.zeros(max_nodes, np.int32)
    count = np.zeros(max_nodes, np.int32)
    # task stack: start, end, parent, is_right, depth
    st_start = np.empty(128, np.int64)
    st_end = np.empty(128, np.int64)
    st_parent = np.empty(128, np.int64)
    st_right = np.empty(128, np.int64)
    st_depth = np.empty(128, np.int64)
    st_start[0], st_end[0], st_parent[0], st_right[0], st_depth[0] = 0, nt, -1, 0, 0
    sp = 1
    max_depth = 0
    n_nodes = 0
    bin_lo = np.empty((N_BINS, 3))
    bin_hi = np.empty((N_BINS, 3))
    bin_n = np.empty(N_BINS, np.int64)
    left_area = np.empty(N_BINS)
    left_n = np.empty(N_BINS, np.int64)
    while sp > 0:
        sp -= 1
        start, end, parent, is_right, depth = st_start[sp], st_end[sp], st_parent[sp], st_right[sp], st_depth[sp]
        max_depth = max(max_depth, depth)
        node = n_nodes
        n_nodes += 1
        if is_right:
            right[parent] = node
        clo = np.full(3, np.inf)
        chi = np.full(3, -np.inf)
        for k in range(3):
            lo[node, k] = np.inf
            hi[node, k] = -np.inf
        for j in range(start, end):
            t = order[j]
            for k in range(3):
                lo[node, k] = min(lo[node, k], tlo[t, k])
                hi[node, k] = max(hi[node, k], thi[t, k])
                clo[k] = min(clo[k], cen[t, k])
                chi[k] = max(chi[k], cen[t, k])
        n = end - start
        if n <= leaf_max:
            first[node], count[node] = start, n
            continue
        if depth >= MAX_SAH_DEPTH:
            mid = _median_split(order, cen, start, end, clo, chi)
        else:
            mid = _sah_split(order, cen, tlo, thi, start, end, clo, chi, lo[node], hi[node], leaf_max, bin_lo,
                             bin_hi, bin_n, left_area, left_n)
            if mid < 0:
                first[node], count[node] = start, n
                continue
        if sp + 2 > st_start.shape[0]:
            grow = st_start.shape[0] * 2
            st_start = np.concatenate((st_start, np.empty(grow, np.int64)))
            st_end = np.concatenate((st_end, np.empty(grow, np.int64)))
            st_parent = np.concatenate((st_parent, np.empty(grow, np.int64)))
            st_right = np.concatenate((st_right, np.empty(grow, np.int64)))
            st_depth = np.concatenate((st_depth, np.empty(grow, np.int64)))
        # push right first so the left child is built next (index node + 1)
        st_start[sp], st_end[sp], st_parent[sp], st_right[sp], st_depth[sp] = mid, end, node, 1, depth + 1
        sp += 1
        st_start[sp], st_end[sp], st_parent[sp], st_right[sp], st_depth[sp] = start, mid, node, 0, depth + 1
        sp += 1
    return lo[:n_nodes].copy(), hi[:n_nodes].copy(), right[:n_nodes].copy(), first[:n_nodes].copy(), \
        count[:n_nodes].copy(), order, max_depth


@njit(cache=True)
def _median_split(order, cen, start, end, clo, chi):
    """Sorts order[start:end] by centroid along the widest centroid axis and
    returns the middle."""
    axis = 0
    for k in range(1, 3):
        if chi[k] - clo[k] > chi[axis] - clo[axis]:
            axis = k
    seg = order[start:end].copy()
    keys = np.empty(end - start)
    for j in range(end - start):
        keys[j] = cen[seg[j], axis]
    perm = np.argsort(keys, kind="mergesort")
    for j in range(end - start):
        order[start + j] = seg[perm[j]]
    return start + (end - start) // 2


@njit(cache=True)
def _sah_split(order, cen, tlo, thi, start, end, clo, chi, nlo, nhi, leaf_max, bin_lo, bin_hi, bin_n, left_area,
               left_n):
    """Partitions order[start:end] at the best binned SAH split and returns
    the split point, or -1 when the node should be a leaf."""
    n = end - start
    best_cost, best_axis, best_bin = np.inf, -1, -1
    for axis in range(3):
        ext = chi[axis] - clo[axis]
        if ext <= 0.0:
            continue
        scale = N_BINS / ext
        for b in range(N_BINS):
            bin_n[b] = 0
            for k in range(3):
                bin_lo[b, k] = np.inf
                bin_hi[b, k] = -np.inf
        for j in range(start, end):
            t = order[j]
            b = min(int((cen[t, axis] - clo[axis]) * scale), N_BINS - 1)
            bin_n[b] += 1
            for k in range(3):
                bin_lo[b, k] = min(bin_lo[b, k], tlo[t, k])
                bin_hi[b, k] = max(bin_hi[b, k], thi[t, k])
        alo = np.full(3, np.inf)
        ahi = np.full(3, -np.inf)
        cnt = 0
        for b in range(N_BINS - 1):
            cnt += bin_n[b]
            for k in range(3):
                alo[k] = min(alo[k], bin_lo[b, k])
                ahi[k] = max(ahi[k], bin_hi[b, k])
            left_n[b] = cnt
            left_area[b] = _surface(alo, ahi) if cnt > 0 else 0.0
        alo[:] = np.inf
        ahi[:] = -np.inf
        cnt = 0
        for b in range(N_BINS - 1, 0, -1):
            cnt += bin_n[b]
            for k in range(3):
                alo[k] = min(alo[k], bin_lo[b, k])
                ahi[k] = max(ahi[k], bin_hi[b, k])
            ra = _surface(alo, ahi) if cnt > 0 else 0.0
            cost = left_area[b - 1] * left_n[b - 1] + ra * cnt
            if left_n[b - 1] > 0 and cnt > 0 and cost < best_cost:
                best_cost, best_axis, best_bin = cost, axis, b
    area = _surface(nlo, nhi)
    leaf_cost = COST_INTERSECT * n
    split_cost = COST_TRAVERSE + COST_INTERSECT * best_cost / area if area > 0 else np.inf
    if best_axis < 0 or (split_cost >= leaf_cost and n <= 4 * leaf_max):
        if best_axis < 0 and n > leaf_max:
            return start + n // 2  # all centroids equal: split by count
        return -1
    scale = N_BINS / (chi[best_axis] - clo[best_axis])
    i, j = start, end - 1
    while i <= j:
        b = min(int((cen[order[i], best_axis] - clo[best_axis]) * scale), N_BINS - 1)
        if b < best_bin:
            i += 1
        else:
            order[i], order[j] = order[j], order[i]
            j -= 1
    return i


@njit(cache=True)
def pack_nodes(lo, hi, right, count):
    """child_box (nn, 12): for each inner node the boxes (lo xyz, hi xyz) of
    its left child (node + 1) and right child, float64 (rounded outward
    to float32 by the caller)."""
    nn = right.shape[0]
    cb = np.zeros((nn, 12))
    for i in range(nn):
        if count[i] == 0 and right[i] >= 0:  # (an empty tree's root has no children)
            a, b = i + 1, right[i]
            for k in range(3):
                cb[i, k] = lo[a, k]
                cb[i, 3 + k] = hi[a, k]
                cb[i, 6 + k] = lo[b, k]
                cb[i, 9 + k] = hi[b, k]
    return cb


@njit(cache=True)
def reorder_triangles(corners, order):
    """(nt, 9) corners v0 v1 v2 in BVH order (float64)."""
    nt = order.shape[0]
    out = np.empty((nt, 9))
    for i in range(nt):
        t = order[i]
        for c in range(3):
            for k in range(3):
                out[i, 3 * c + k] = corners[t, c, k]
    return out


@njit(cache=True)
def _area(lo, hi, i):
    dx, dy, dz = hi[i, 0] - lo[i, 0], hi[i, 1] - lo[i, 1], hi[i, 2] - lo[i, 2]
    return dx * dy + dy * dz + dz * dx


@njit(cache=True)
def collapse_wide(lo, hi, right, first, count, width):
    """The binary tree (depth-first, as build_bvh returns it) as a
    `width`-wide one: each wide node takes a binary node's two children and
    opens the inner one of largest surface area until it holds `width`
    (Wald et al. 2008, "Getting rid of packets"). Returns boxes (nw, width,
    6) float64 (lo xyz, hi xyz per slot), child (nw, width) int32 and cnt
    (nw, width) int32 (the WIDE_CHILD / WIDE_COUNT slots), wide nodes in
    depth-first order."""
    nn = right.shape[0]
    boxes = np.zeros((nn, width, 6))
    child = np.full((nn, width), -1, np.int32)
    cnt = np.full((nn, width), -1, np.int32)
    todo = np.empty(nn + 1, np.int64)   # binary nodes waiting for a wide node, with the wide id given
    todo_w = np.empty(nn + 1, np.int64)
    todo[0], todo_w[0] = 0, 0
    sp = 1
    nw = 1
    kids = np.empty(width, np.int64)
    ids = np.empty(width, np.int64)
    while sp > 0:
        sp -= 1
        b, w = todo[sp], todo_w[sp]
        if count[b] == 0 and right[b] < 0:  # an empty tree (no triangles): no slots
            continue
        if count[b] > 0:  # a leaf root: one slot
            kids[0] = b
            k = 1
        else:
            kids[0], kids[1] = b + 1, right[b]
            k = 2
            while k < width:
                best, best_a = -1, -1.0
                for i in range(k):
                    c = kids[i]
                    if count[c] == 0:
                        a = _area(lo, hi, c)
                        if a > best_a:
                            best, best_a = i, a
                if best < 0:
                    break
                c = kids[best]
                kids[best] = c + 1
                kids[k] = right[c]
                k += 1
        # children in left-to-right order keep the depth-first layout
        for i in range(1, k):
            j = i
            while j > 0 and kids[j - 1] > kids[j]:
                kids[j - 1], kids[j] = kids[j], kids[j - 1]
                j -= 1
        for i in range(k):
            c = kids[i]
            for q in range(3):
                boxes[w, i, q] = lo[c, q]
                boxes[w, i, 3 + q] = hi[c, q]
            if count[c] > 0:
                child[w, i], cnt[w, i] = first[c], count[c]
        # inner children get wide ids in order; pushed in reverse so the first is built next
        for i in range(k):
            if count[kids[i]] == 0:
                ids[i] = nw
                child[w, i], cnt[w, i] = nw, 0
                nw += 1
        for i in range(k - 1, -1, -1):
            if count[kids[i]] == 0:
                todo[sp], todo_w[sp] = kids[i], ids[i]
                sp += 1
    return boxes[:nw].copy(), child[:nw].copy(), cnt[:nw].copy()
