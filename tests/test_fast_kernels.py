"""The path tracer's fast paths: kernels/inline.py's inlined kernel copies
and borrowed (owner-less) views compute the same as the originals, share
their memory, and leave the owners' reference counts as they were; and
kernels/sampling.py's turn() (cos and sin of a turn without libm) and the
cosine-weighted directions built on it."""
import sys
from collections import namedtuple

import numpy as np
from numba import njit

from baker.kernels.inline import borrowed, inlined
from baker.kernels.sampling import cosine_hemisphere, turn
from baker.kernels.traverse import any_hit, closest_hit
from baker.scene import build_scene_bvh, load_scene

Pair = namedtuple("Pair", ["a", "b", "k"])


@njit
def _sum_borrowed(x):
    v = borrowed(x)
    s = 0.0
    for i in range(v.shape[0]):
        for j in range(v.shape[1]):
            s += v[i, j]
    return s


@njit
def _write_borrowed(x):
    v = borrowed(x)
    v[1, 2] = 7.0
    return v.shape[0] * 100 + v.shape[1]


@njit
def _pair_borrowed(p):
    q = borrowed(p)
    return q.a[2] + q.b[1, 1] + q.k


def test_borrowed_views_read_and_write_the_same_memory():
    x = np.arange(12.0).reshape(3, 4)[:, ::-1].copy()
    assert _sum_borrowed(x) == x.sum()  # same order of summation as numpy here: small integers, exact
    assert _write_borrowed(x) == 304 and x[1, 2] == 7.0
    strided = np.arange(24.0).reshape(4, 6)[::2, 1::2]  # a view with strides: kept as they are
    assert _sum_borrowed(strided) == strided.sum()


def test_borrowed_tuples_keep_their_members_and_the_owners_counts():
    p = Pair(np.array([1.0, 2.0, 3.0]), np.eye(2) * 5.0, 4)
    before = sys.getrefcount(p.a), sys.getrefcount(p.b)
    for _ in range(1000):
        assert _pair_borrowed(p) == 3.0 + 5.0 + 4
    # a borrowed view that took a count and never gave it back (or the reverse) would move these
    assert (sys.getrefcount(p.a), sys.getrefcount(p.b)) == before
    assert p.a.tolist() == [1.0, 2.0, 3.0]


_closest, _any = inlined(closest_hit), inlined(any_hit)


@njit
def _both(bvh, stack, rays):
    out = np.empty((rays.shape[0], 6))
    for i in range(rays.shape[0]):
        o, d = rays[i, :3], rays[i, 3:]
        t, j, _, _ = closest_hit(bvh, stack, o[0], o[1], o[2], d[0], d[1], d[2], 0.0, np.inf)
        t2, j2, _, _ = _closest(bvh, stack, o[0], o[1], o[2], d[0], d[1], d[2], 0.0, np.inf)
        out[i, 0], out[i, 1], out[i, 4], out[i, 5] = t, j, t2, j2
        out[i, 2] = any_hit(bvh, stack, o[0], o[1], o[2], d[0], d[1], d[2], 0.0, 1.0)
        out[i, 3] = _any(bvh, stack, o[0], o[1], o[2], d[0], d[1], d[2], 0.0, 1.0)
    return out


def test_inlined_copies_answer_as_the_kernels():
    assert _closest.targetoptions["inline"] == "always"
    assert _closest.targetoptions["error_model"] == closest_hit.targetoptions["error_model"]
    tree = build_scene_bvh(load_scene("cornell_box"))
    rng = np.random.default_rng(3)
    lo, hi = tree.arrays.root_box[:3], tree.arrays.root_box[3:]
    o = lo + (hi - lo) * rng.random((500, 3))
    d = rng.normal(size=(500, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    out = _both(tree.arrays, np.empty(1024, np.int32), np.hstack([o, d]))
    assert np.array_equal(out[:, :2], out[:, 4:])  # misses (the open front) are inf in both
    assert np.isinf(out[:, 0]).any() and np.isfinite(out[:, 0]).any()
    assert np.array_equal(out[:, 2], out[:, 3]) and 0 < out[:, 2].sum() < 500  # both outcomes occur


@njit
def _turns(u):
    out = np.empty((u.shape[0], 2))
    for i in range(u.shape[0]):
        out[i, 0], out[i, 1] = turn(u[i])
    return out


@njit
def _hemisphere(u, n):
    out = np.empty((u.shape[0], 4))
    for i in range(u.shape[0]):
        out[i, 0], out[i, 1], out[i, 2], out[i, 3] = cosine_hemisphere(u[i, 0], u[i, 1], n[0], n[1], n[2])
    return out


def test_turn_is_cos_and_sin_of_a_full_turn_to_a_few_ulps():
    # the quarter and eighth turns (where the reduction switches branch) and their neighbours, then random
    edges = np.array([k / 8 for k in range(9)])
    u = np.concatenate([edges, np.nextafter(edges, 2.0), np.nextafter(edges, -1.0),
                        np.random.default_rng(0).random(100_000)])
    u = u[(u >= 0.0) & (u <= 1.0)]
    got = _turns(u)
    want = np.stack([np.cos(2 * np.pi * u), np.sin(2 * np.pi * u)], axis=1)
    assert np.abs(got - want).max() < 4e-16 * 4  # 2 pi u itself rounds (1 ulp of 2 pi), the polynomials add ~2
    assert np.abs(np.hypot(got[:, 0], got[:, 1]) - 1.0).max() < 1e-15


def test_cosine_hemisphere_directions_are_unit_with_the_cosine_law():
    n = np.array([0.48, -0.6, 0.64])
    u = np.random.default_rng(1).random((200_000, 2))
    d = _hemisphere(u, n)
    assert np.abs(np.linalg.norm(d[:, :3], axis=1) - 1.0).max() < 1e-14
    assert np.allclose(d[:, :3] @ n, d[:, 3], atol=1e-14) and d[:, 3].min() >= 0.0
    # E[cos] = 2/3 and E[cos^2] = 1/2 under pdf cos/pi; 200k samples: standard errors 5e-4 and 6e-4
    assert abs(d[:, 3].mean() - 2 / 3) < 3e-3 and abs((d[:, 3] ** 2).mean() - 0.5) < 3e-3
    # the azimuth is uniform: the mean of the direction's tangent part vanishes (std error ~1e-3)
    tangent = d[:, :3] - d[:, 3:4] * n
    assert np.abs(tangent.mean(axis=0)).max() < 6e-3
