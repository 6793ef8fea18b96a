"""The light tree (docs/design.md section 7, after Walter et al. 2005): a
binary tree over the VPLs, built top-down in O(n log n) from flat arrays,
stored depth-first (a node's left child is the next node).

Split: each node's VPLs as 6D points (position, and the normal scaled by
an eighth of the scene's diagonal, so that a node of opposite-facing lights
splits by facing), cut in two halves of equal count on the axis of
largest extent, found by a 64-bin histogram (no sort: linear per level).
Area VPLs and sky directions get subtrees of their own under the root.

Per node: position bounds (lo, hi); normal cone (axis, cos of its half
angle); power (sum of its leaves', per channel) and its luminance;
representative: a leaf of its subtree drawn in proportion to luminance
(from the children's representatives, seeded per node: the child holding
it keeps it).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from ..kernels.colour import LUMINANCE
from ..kernels.rng import keyed, seed_unit
from .vpl import KIND_AREA, KIND_DIRECTIONAL

BINS = 64
NORMAL_WEIGHT = 0.125  # normals count as positions this fraction of the scene's diagonal apart


@dataclass(frozen=True)
class LightTree:
    """Nodes depth-first: lo, hi (m, 3); axis (m, 3), cos (m,) the normal
    cone; power (m, 3); lum (m,); rep (m,) int64 VPL index; right (m,)
    int64 (the left child is node + 1; -1: a leaf, whose VPL is rep); kind
    (m,) int8 of the node's VPLs (root: -1 when it joins two kinds)."""
    lo: np.ndarray
    hi: np.ndarray
    axis: np.ndarray
    cos: np.ndarray
    power: np.ndarray
    lum: np.ndarray
    rep: np.ndarray
    right: np.ndarray
    kind: np.ndarray

    def __len__(self):
        return len(self.lum)

    @property
    def depth(self) -> int:
        return int(_depth(self.right))


@njit(cache=True)
def _depth(right):
    best = 0
    stack = [(0, 1)]
    while len(stack):
        node, d = stack.pop()
        best = max(best, d)
        if right[node] >= 0:
            stack.append((node + 1, d + 1))
            stack.append((right[node], d + 1))
    return best


@njit(cache=True)
def _bounds(pts, a, b, out, k):
    """out[k] = (lo 6, hi 6) of rows a..b-1 of pts."""
    for ax in range(6):
        out[k, ax] = np.inf
        out[k, 6 + ax] = -np.inf
    for i in range(a, b):
        for ax in range(6):
            v = pts[i, ax]
            out[k, ax] = min(out[k, ax], v)
            out[k, 6 + ax] = max(out[k, 6 + ax], v)


@njit(cache=True)
def _split(pts, order, a, b, box, hist, row):
    """Splits rows a..b-1 (bounds `box`: lo 6, hi 6) in two halves of equal
    count on the axis of largest extent (a 64-bin histogram finds the bin
    of the median, a partition at its edge; a split the bins cannot make
    falls back to a partition by rank). Permutes pts and order in
    lockstep; returns the split point."""
    best_axis, best_ext, lo_v = 0, -1.0, 0.0
    for ax in range(6):
        lo, hi = box[ax], box[6 + ax]
        if hi - lo > best_ext:
            best_axis, best_ext, lo_v = ax, hi - lo, lo
    mid = (a + b) // 2
    if best_ext <= 0.0:
        return mid
    hist[:] = 0
    scale = BINS / best_ext
    for i in range(a, b):
        k = min(BINS - 1, int((pts[i, best_axis] - lo_v) * scale))
        hist[k] += 1
    acc, cut = 0, BINS - 1
    for k in range(BINS):
        acc += hist[k]
        if acc >= (b - a) // 2:
            cut = k
            break
    edge = lo_v + (cut + 1) / scale
    i, j = a, b - 1
    while i <= j:
        if pts[i, best_axis] < edge:
            i += 1
        else:
            order[i], order[j] = order[j], order[i]
            for ax in range(6):
                row[ax] = pts[i, ax]
                pts[i, ax] = pts[j, ax]
                pts[j, ax] = row[ax]
            j -= 1
    if a < i < b and abs((i - a) - (b - i)) <= (b - a) // 2:
        return i
    keys = pts[a:b, best_axis].copy()
    perm = np.argsort(keys, kind="mergesort")
    seg = order[a:b].copy()
    rows = pts[a:b].copy()
    for q in range(b - a):
        order[a + q] = seg[perm[q]]
        for ax in range(6):
            pts[a + q, ax] = rows[perm[q], ax]
    return mid


@njit(cache=True)
def _subtree_topology(pts, order, right, start, count, node0, a0, b0, box0, max_depth, tasks):
    """Builds the subtree of node0 over rows a0..b0-1 (bounds box0). With
    max_depth >= 0, nodes that deep are not split but appended to `tasks`
    (node, a, b, bounds) for later; returns the number of tasks."""
    hist = np.zeros(BINS, np.int64)
    row = np.empty(6)
    cap = 256
    st_node = np.empty(cap, np.int64)
    st_a = np.empty(cap, np.int64)
    st_b = np.empty(cap, np.int64)
    st_d = np.empty(cap, np.int64)
    st_box = np.empty((cap, 12))
    st_node[0], st_a[0], st_b[0], st_d[0] = node0, a0, b0, 0
    st_box[0] = box0
    sp = 1
    n_tasks = 0
    while sp > 0:
        sp -= 1
        node, a, b, d = st_node[sp], st_a[sp], st_b[sp], st_d[sp]
        start[node], count[node] = a, b - a
        if b - a == 1:
            continue
        if d == max_depth:
            tasks[n_tasks, 0], tasks[n_tasks, 1], tasks[n_tasks, 2] = node, a, b
            tasks[n_tasks, 3:] = st_box[sp]
            n_tasks += 1
            continue
        mid = _split(pts, order, a, b, st_box[sp], hist, row)
        if sp + 2 > cap:
            cap *= 2
            st_node = np.concatenate((st_node, np.empty_like(st_node)))
            st_a = np.concatenate((st_a, np.empty_like(st_a)))
            st_b = np.concatenate((st_b, np.empty_like(st_b)))
            st_d = np.concatenate((st_d, np.empty_like(st_d)))
            st_box = np.concatenate((st_box, np.empty_like(st_box)))
        left = node + 1                 # preorder: the left subtree's 2 (mid - a) - 1 nodes, then the right's
        rgt = node + 2 * (mid - a)
        right[node] = rgt
        st_node[sp], st_a[sp], st_b[sp], st_d[sp] = rgt, mid, b, d + 1
        _bounds(pts, mid, b, st_box, sp)
        st_node[sp + 1], st_a[sp + 1], st_b[sp + 1], st_d[sp + 1] = left, a, mid, d + 1
        _bounds(pts, a, mid, st_box, sp + 1)
        sp += 2
    return n_tasks


TOP_LEVELS = 4  # built one after another; the 16 subtrees below them in parallel


@njit(cache=True, parallel=True)
def _topology(points, order):
    """Depth-first nodes over points (n, 6) by balanced splits: returns
    right (m,) and the VPL range of each node in `order` (permuted in
    place): start (m,), count (m,).

    The points are copied and permuted along with `order`, so each split
    reads them in sequence, and each node's bounds are found once, as its
    parent splits. Node numbers follow from the counts (a left subtree of
    k VPLs has 2 k - 1 nodes), so the subtrees below the top levels are
    built in parallel into their own ranges: the same tree for any
    thread count."""
    n = points.shape[0]
    m = 2 * n - 1
    right = np.full(m, -1, np.int64)
    start = np.zeros(m, np.int64)
    count = np.zeros(m, np.int64)
    pts = points.copy()
    box = np.empty((1, 12))
    _bounds(pts, 0, n, box, 0)
    tasks = np.empty((1 << TOP_LEVELS, 15))
    n_tasks = _subtree_topology(pts, order, right, start, count, 0, 0, n, box[0], TOP_LEVELS, tasks)
    none = np.empty((0, 15))
    for t in prange(n_tasks):
        _subtree_topology(pts, order, right, start, count, int(tasks[t, 0]), int(tasks[t, 1]), int(tasks[t, 2]),
                          tasks[t, 3:], -1, none)
    return right, start, count


@njit(cache=True)
def _subtrees(right, count):
    """The roots of the subtrees below the top TOP_LEVELS levels (as
    _topology splits them): (k,) node numbers; subtree r spans nodes
    r .. r + 2 count[r] - 2."""
    out = np.empty(1 << TOP_LEVELS, np.int64)
    k = 0
    stack = [(0, 0)]
    while len(stack):
        node, d = stack.pop()
        if d == TOP_LEVELS or right[node] < 0:
            out[k] = node
            k += 1
        else:
            stack.append((right[node], d + 1))
            stack.append((node + 1, d + 1))
    return out[:k]


@njit(cache=True)
def _node_attributes(node, right, start, order, position, normal, power, lum_w, seed, base, lo, hi, axis, cosv, pw,
                     lum, rep):
    """One node's bounds, cone, power and representative from its
    children's (or its VPL's, for a leaf)."""
    if right[node] < 0:
        v = order[start[node]]
        for c in range(3):
            lo[node, c] = position[v, c]
            hi[node, c] = position[v, c]
            axis[node, c] = normal[v, c]
            pw[node, c] = power[v, c]
        cosv[node] = 1.0
        lum[node] = lum_w[0] * power[v, 0] + lum_w[1] * power[v, 1] + lum_w[2] * power[v, 2]
        rep[node] = v
        return
    l, r = node + 1, right[node]
    for c in range(3):
        lo[node, c] = min(lo[l, c], lo[r, c])
        hi[node, c] = max(hi[l, c], hi[r, c])
        pw[node, c] = pw[l, c] + pw[r, c]
    lum[node] = lum[l] + lum[r]
    # the cone holding both children's cones
    ax = axis[l, 0] * lum[l] + axis[r, 0] * lum[r] + 1e-300
    ay = axis[l, 1] * lum[l] + axis[r, 1] * lum[r]
    az = axis[l, 2] * lum[l] + axis[r, 2] * lum[r]
    ln = math.sqrt(ax * ax + ay * ay + az * az)
    if ln < 1e-12:
        ax, ay, az, ln = axis[l, 0], axis[l, 1], axis[l, 2], 1.0
    ax, ay, az = ax / ln, ay / ln, az / ln
    half = 0.0
    for ch in (l, r):
        d = min(1.0, max(-1.0, ax * axis[ch, 0] + ay * axis[ch, 1] + az * axis[ch, 2]))
        half = max(half, math.acos(d) + math.acos(min(1.0, max(-1.0, cosv[ch]))))
    axis[node, 0], axis[node, 1], axis[node, 2] = ax, ay, az
    cosv[node] = math.cos(half) if half < math.pi else -1.0
    # representative: the left's with probability lum_l / lum
    h = keyed(seed, base + node)
    u = float(h >> np.uint64(11)) / 9007199254740992.0
    rep[node] = rep[l] if (lum[node] > 0.0 and u * lum[node] < lum[l]) or lum[node] <= 0.0 else rep[r]


@njit(cache=True, parallel=True)
def _attributes(right, start, count, order, position, normal, power, lum_w, seed, base):
    """Every node's attributes, children before parents: the subtrees below
    the top levels in parallel, then the top (each node's values depend
    only on its own subtree and its number: the same for any thread
    count)."""
    m = right.shape[0]
    lo = np.empty((m, 3))
    hi = np.empty((m, 3))
    axis = np.empty((m, 3))
    cosv = np.empty(m)
    pw = np.empty((m, 3))
    lum = np.empty(m)
    rep = np.empty(m, np.int64)
    roots = _subtrees(right, count)
    covered = np.zeros(m, np.bool_)
    for t in prange(roots.shape[0]):
        r = roots[t]
        for node in range(r + 2 * count[r] - 2, r - 1, -1):
            _node_attributes(node, right, start, order, position, normal, power, lum_w, seed, base, lo, hi, axis,
                             cosv, pw, lum, rep)
            covered[node] = True
    for node in range(m - 1, -1, -1):
        if not covered[node]:
            _node_attributes(node, right, start, order, position, normal, power, lum_w, seed, base, lo, hi, axis,
                             cosv, pw, lum, rep)
    return lo, hi, axis, cosv, pw, lum, rep


def _subtree(vpls, index, seed, base, diag, kind) -> LightTree:
    """The tree over vpls[index], all of one kind."""
    pos = vpls.position[index]
    nor = vpls.normal[index]
    pts = np.concatenate([pos, nor * (NORMAL_WEIGHT * diag)], axis=1)
    if kind == KIND_DIRECTIONAL:
        pts[:, :3] = 0.0  # directions at infinity: split by direction only
    order = np.arange(len(index), dtype=np.int64)
    right, start, count = _topology(pts, order)
    lo, hi, axis, cosv, pw, lum, rep = _attributes(right, start, count, order, pos, nor, vpls.power[index], LUMINANCE,
                                                   seed, base)
    return LightTree(lo, hi, axis, cosv, pw, lum, index[rep], right, np.full(len(lum), kind, np.int8))


def _joined(a: LightTree, b: LightTree, seed) -> LightTree:
    """One tree over two: a new root over a's and b's roots (its
    representative a's with probability lum_a / lum, drawn from the seed),
    a then b depth-first below it."""
    root_lum = a.lum[0] + b.lum[0]
    rep = a.rep[0] if seed_unit(seed) * root_lum < a.lum[0] else b.rep[0]
    root = LightTree(np.minimum(a.lo[:1], b.lo[:1]), np.maximum(a.hi[:1], b.hi[:1]), np.array([[0.0, 1.0, 0.0]]),
                     np.array([-1.0]), a.power[:1] + b.power[:1], np.array([root_lum]), np.array([rep], np.int64),
                     np.array([1 + len(a)], np.int64), np.array([-1], np.int8))
    right_a = np.where(a.right >= 0, a.right + 1, -1)
    right_b = np.where(b.right >= 0, b.right + 1 + len(a), -1)
    return LightTree(*(np.concatenate([getattr(root, f), getattr(a, f), getattr(b, f)]) for f in
                       ("lo", "hi", "axis", "cos", "power", "lum", "rep")),
                     np.concatenate([root.right, right_a, right_b]), np.concatenate([root.kind, a.kind, b.kind]))


def build_tree(vpls, seed=0) -> LightTree:
    """The light tree of `vpls` (at least one): a subtree per kind (points,
    directions), joined under one root when there are both."""
    parts = []
    diag = 1.0
    area = np.nonzero(vpls.kind == KIND_AREA)[0]
    if len(area):
        diag = float(np.linalg.norm(np.ptp(vpls.position[area], axis=0))) or 1.0
    for kind in (KIND_AREA, KIND_DIRECTIONAL):
        idx = np.nonzero(vpls.kind == kind)[0].astype(np.int64)
        if len(idx):
            parts.append(_subtree(vpls, idx, seed, 0 if kind == KIND_AREA else 1 << 40, diag, kind))
    if not parts:
        raise ValueError("no VPLs to build a light tree over")
    return parts[0] if len(parts) == 1 else _joined(parts[0], parts[1], seed)
