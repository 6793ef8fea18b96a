import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from baker.scene import bvh as bvh_mod
from tests.naive import ray_triangles


def random_soup(rng, n, spread=1.0, size=0.2):
    centres = rng.random((n, 1, 3)) * spread
    # float32-exact corners: the BVH stores float32 (exact for scene vertices)
    return (centres + (rng.random((n, 3, 3)) - 0.5) * size).astype(np.float32).astype(float)


def check_against_brute_force(corners, origins, dirs):
    tree = bvh_mod.build(corners, leaf_max=2)
    t, tri, u, v = tree.closest(origins, dirs)
    occl = tree.occluded(origins, dirs, tmax=np.full(len(origins), 0.5))
    for i in range(len(origins)):
        tr, kr = ray_triangles(origins[i], dirs[i], corners)
        if kr < 0:
            assert tri[i] == -1 and t[i] == np.inf
        else:
            # equal t on shared edges may pick either triangle: compare t, then the hit point
            assert t[i] == pytest.approx(tr, rel=1e-12, abs=1e-12)
            assert tri[i] >= 0
        ts, _ = ray_triangles(origins[i], dirs[i], corners, tmax=0.5)
        assert occl[i] == (ts < np.inf)


def test_random_soup_matches_brute_force():
    rng = np.random.default_rng(3)
    corners = random_soup(rng, 400)
    o = rng.random((600, 3)) * 1.4 - 0.2
    d = rng.normal(size=(600, 3))
    check_against_brute_force(corners, o, d)


def test_rays_through_vertices_and_edges():
    """A grid of triangles sharing edges and vertices; rays aimed exactly at
    vertices and edge midpoints, and grazing along the plane."""
    n = 6
    xs = np.linspace(0, 1, n + 1)
    corners = []
    for i in range(n):
        for j in range(n):
            a, b = (xs[i], 0, xs[j]), (xs[i + 1], 0, xs[j])
            c, d = (xs[i + 1], 0, xs[j + 1]), (xs[i], 0, xs[j + 1])
            corners += [(a, b, c), (a, c, d)]
    corners = np.array(corners, float)
    targets = np.concatenate([corners.reshape(-1, 3), (corners[:, 0] + corners[:, 1]) / 2,
                              (corners[:, 0] + corners[:, 2]) / 2])
    rng = np.random.default_rng(5)
    origins = targets + np.array([0.0, 1.0, 0.0]) + rng.normal(scale=0.2, size=targets.shape) * [1, 0, 1]
    dirs = targets - origins
    tree = bvh_mod.build(corners)
    t, tri, _, _ = tree.closest(origins, dirs)
    # every ray aimed at a vertex or an edge of the closed grid hits it (no cracks), at t = 1
    assert (tri >= 0).all()
    np.testing.assert_allclose(t, 1.0, rtol=1e-9)
    check_against_brute_force(corners, origins, dirs)
    # rays in the plane of the grid (grazing) do not crash and agree with brute force
    o = np.column_stack([np.full(50, -0.5), np.zeros(50), rng.random(50)])
    check_against_brute_force(corners, o, np.tile([1.0, 0.0, 0.0], (50, 1)))


@settings(max_examples=25, deadline=None)
@given(st.integers(1, 300), st.integers(0, 2**31 - 1), st.floats(0.01, 1.0))
def test_property_bvh_equals_brute_force(n, seed, size):
    rng = np.random.default_rng(seed)
    corners = random_soup(rng, n, size=size)
    o = rng.random((40, 3)) * 1.4 - 0.2
    d = rng.normal(size=(40, 3))
    check_against_brute_force(corners, o, d)


def test_bvh_structure_invariants():
    rng = np.random.default_rng(7)
    corners = random_soup(rng, 1000).astype(np.float32).astype(float)
    tree = bvh_mod.build(corners)
    # every triangle in exactly one leaf, inside every box on its path
    seen = np.zeros(1000, int)
    stack = [(0, [tree.root_box])]
    while stack:
        node, boxes = stack.pop()
        if tree.count[node] > 0:
            for j in range(tree.first[node], tree.first[node] + tree.count[node]):
                seen[tree.tri_index[j]] += 1
                pts = corners[tree.tri_index[j]]
                np.testing.assert_array_equal(tree.tris[j].reshape(3, 3), pts)
                for b in boxes:
                    assert (pts >= b[:3]).all() and (pts <= b[3:]).all()
        else:
            cb = tree.child_box[node].astype(float)
            stack += [(node + 1, boxes + [cb[:6]]), (tree.right[node], boxes + [cb[6:]])]
    assert (seen == 1).all()


def tree_depth(tree):
    depth, stack = 0, [(0, 0)]
    while stack:
        node, d = stack.pop()
        depth = max(depth, d)
        if tree.count[node] == 0:
            stack += [(node + 1, d + 1), (tree.right[node], d + 1)]
    return depth


@pytest.mark.parametrize("kind", ["sizes", "coincident"])
def test_degenerate_inputs_keep_the_tree_within_the_traversal_stack(kind):
    """Triangles along a line whose sizes shrink over 200 orders of magnitude
    (the smaller half rounds to zero area in float32): binned SAH keeps
    peeling a sliver off the big end, and without a depth bound the tree
    grew to depth 129, past the traversal's fixed stack (which the
    traversal would have written past). Many coincident triangles, plus a
    few far apart, split by count. Either way the depth stays under the
    stack and every ray finds what brute force finds."""
    from baker.kernels.bvh import MAX_SAH_DEPTH, STACK_SIZE
    rng = np.random.default_rng(5)
    if kind == "sizes":
        n = 100_000
        k = np.arange(n)
        size = 1e3 * 10.0 ** (-200.0 * k / n)
        base = np.array([[-0.5, -0.5, 0], [0.5, -0.5, 0], [0, 0.5, 0]])
        corners = base[None] * size[:, None, None] + np.stack([k / n, np.zeros(n), np.zeros(n)], 1)[:, None]
    else:
        one = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
        corners = np.concatenate([np.repeat(one[None], 3000, axis=0), random_soup(rng, 5, spread=10)])
    corners = corners.astype(np.float32).astype(float)
    tree = bvh_mod.build(corners)
    depth = tree_depth(tree)
    assert tree.depth == depth and 3 * (depth + 1) <= STACK_SIZE  # 3 pending nodes a level at most
    if kind == "sizes":
        assert depth > MAX_SAH_DEPTH  # the median split had to take over: the input is degenerate as meant
    o = np.column_stack([rng.uniform(-0.2, 1.2, 60), rng.uniform(-0.3, 0.3, 60), np.full(60, -1.0)])
    d = np.tile([0.0, 0.0, 1.0], (60, 1)) + rng.normal(0, 0.05, (60, 3))
    check_against_brute_force(corners, o, d)


def test_wide_tree_holds_every_triangle_once_inside_its_boxes():
    """The 8-wide tree the traversal reads: slots fill from the first, each
    triangle sits in exactly one leaf slot, inside the box of every slot on
    its path; at most a third as many nodes as the binary tree's inner
    nodes (a full 8-wide node replaces 7)."""
    from baker.kernels.bvh import WIDE_CHILD, WIDE_COUNT, WIDE_HI, WIDE_LO, WIDTH
    rng = np.random.default_rng(8)
    corners = random_soup(rng, 1000).astype(np.float32).astype(float)
    tree = bvh_mod.build(corners)
    w, wi = tree.wide, tree.wide.view(np.int32)
    seen = np.zeros(1000, int)
    stack = [(0, [tree.root_box])]
    visited = 0
    while stack:
        node, boxes = stack.pop()
        visited += 1
        counts = wi[node, WIDE_COUNT:WIDE_COUNT + WIDTH]
        used = counts >= 0
        assert used[0] and not (~used[:-1] & used[1:]).any()  # filled from slot 0
        for s in np.nonzero(used)[0]:
            box = np.array([w[node, WIDE_LO + WIDTH * q + s] for q in range(3)]
                           + [w[node, WIDE_HI + WIDTH * q + s] for q in range(3)], float)
            c = wi[node, WIDE_CHILD + s]
            if counts[s] > 0:
                for j in range(c, c + counts[s]):
                    seen[tree.tri_index[j]] += 1
                    pts = corners[tree.tri_index[j]]
                    for b in boxes + [box]:
                        assert (pts >= b[:3]).all() and (pts <= b[3:]).all()
            else:
                stack.append((c, boxes + [box]))
    assert (seen == 1).all() and visited == len(w)
    inner = int((tree.count == 0).sum())
    assert len(w) < 0.34 * inner


@pytest.mark.parametrize("n", [0, 1, 3])
def test_tiny_trees(n):
    """No triangle (every ray misses), one (the root is a leaf), three."""
    one = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    corners = np.repeat(one[None], n, axis=0) + np.arange(n)[:, None, None] * np.array([0, 0, 1.0])
    tree = bvh_mod.build(corners.reshape(n, 3, 3))
    o = np.tile([0.2, 0.2, -1.0], (4, 1))
    d = np.tile([0.0, 0.0, 1.0], (4, 1))
    t, tri, _, _ = tree.closest(o, d)
    assert (tri == (0 if n else -1)).all() and (np.isfinite(t) == bool(n)).all()
    assert (tree.occluded(o, d) == bool(n)).all()
