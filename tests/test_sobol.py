"""The path tracer's sampler (kernels/sobol.py): Sobol's generator matrices,
the stratification that Owen scrambling keeps, and uniform points."""
import numpy as np
import pytest
from numba import njit

from baker.kernels.sobol import DIMS, _T, sample4


@njit(cache=True)
def _points(seed, pixel, n, group):
    out = np.empty((n, 4))
    for i in range(n):
        out[i] = sample4(seed, pixel, i, group)
    return out


@njit(cache=True)
def _first_points(seed, pixels, group):
    out = np.empty((pixels, 4))
    for p in range(pixels):
        out[p] = sample4(seed, p, 0, group)
    return out


def _unscrambled(n):
    """(n, DIMS) the plain Sobol points from the byte tables."""
    out = np.zeros((n, DIMS))
    for i in range(n):
        for d in range(DIMS):
            x = 0
            for k in range(4):
                x ^= int(_T[d, k, (i >> (8 * k)) & 255])
            out[i, d] = int(format(x, "032b")[::-1], 2) / 2.0 ** 32
    return out


def test_generator_matrices_are_sobols():
    """The same point sets as scipy's Sobol sequence (Joe and Kuo's numbers)
    in every dimension, for every power of two up to 1024."""
    qmc = pytest.importorskip("scipy.stats.qmc")
    ours = _unscrambled(1024)
    ref = qmc.Sobol(DIMS, scramble=False, bits=32).random(1024)
    for m in (1, 4, 7, 10):
        a = ours[:2 ** m]
        b = ref[:2 ** m]
        assert np.array_equal(a[np.lexsort(a.T[::-1])], b[np.lexsort(b.T[::-1])]), m


def _is_net(pts, m):
    """Every elementary interval of area 2^-m (2^a by 2^(m-a) cells) holds
    exactly one of the 2^m points: a (0, m, 2)-net in base 2."""
    for a in range(m + 1):
        cx = np.floor(pts[:, 0] * 2 ** a).astype(np.int64)
        cy = np.floor(pts[:, 1] * 2 ** (m - a)).astype(np.int64)
        if len(np.unique(cx * 2 ** (m - a) + cy)) != 2 ** m:
            return False
    return True


@pytest.mark.parametrize("group", [0, 1, 9])
def test_scrambled_pairs_stay_stratified(group):
    """Each pixel's first 2^m samples (and the next 2^m) are a (0, m, 2)-net
    in the pixel position pair and in the emitter pair: the scramble keeps
    Sobol's stratification, which is where the low noise comes from."""
    for pixel in (0, 7, 123457):
        pts = _points(np.uint64(5), pixel, 512, group)
        for m in (4, 8):
            for block in (pts[:2 ** m], pts[2 ** m:2 ** (m + 1)]):
                assert _is_net(block[:, :2], m) and _is_net(block[:, 2:], m), (pixel, m)
    # a plain hash would fail this: 256 independent points almost never form a net
    rng = np.random.default_rng(0)
    assert not _is_net(rng.random((256, 2)), 8)


@pytest.mark.parametrize("group", [0, 2, 7])
def test_points_are_uniform_and_independent_across_pixels(group):
    """Sample 0 of 200,000 pixels: each coordinate uniform (chi-square over 64
    bins below its 99.99th percentile), coordinates uncorrelated, and the
    seed changes them: the estimator is unbiased and pixels do not share
    noise."""
    n = 200_000
    pts = _first_points(np.uint64(3), n, group)
    assert pts.min() >= 0.0 and pts.max() < 1.0
    for d in range(4):
        counts = np.bincount(np.floor(pts[:, d] * 64).astype(int), minlength=64)
        chi2 = ((counts - n / 64) ** 2 / (n / 64)).sum()
        assert chi2 < 120, (d, chi2)  # 63 degrees of freedom: P(chi2 > 120) ~ 2e-5
    corr = np.corrcoef(pts.T)
    assert np.abs(corr - np.eye(4)).max() < 0.015
    other = _first_points(np.uint64(4), 1000, group)
    assert not np.array_equal(other, pts[:1000])
