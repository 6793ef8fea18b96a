"""Owen-scrambled Sobol points, padded in pairs: a counter-based
low-discrepancy sampler.

Sample i of a pixel draws each of its two-dimensional pairs (the position
in the pixel, the emitter point of a vertex, its next direction, ...) from
the first two dimensions of the Sobol sequence. Those two form a (0, 2)
sequence in base 2: any 2^m consecutive aligned points put one point in
each of the 2^m elementary intervals of every shape, so a pixel's samples
are stratified in every pair at once. The pairs are decorrelated from one
another by shuffling the index (a nested uniform scramble of its bits,
which keeps aligned blocks of 2^m indices together) with a seed of their
own, and each coordinate is Owen-scrambled (a random permutation of every
binary digit that depends on the digits above it), which keeps the
stratification and makes each point uniform, so estimates stay unbiased
(Owen 1995; the hash form of Laine and Karras 2011 as improved by Burley
2020, "Practical hash-based Owen scrambling"; padding pairs as pbrt-v4's
padded Sobol sampler does).

Sobol's first DIMS dimensions are kept (tested against scipy's) although
the sampler draws only from the first two: one Sobol point across all of
a path's dimensions (their joint stratification) measured no better than
the two-seed noise on the Cornell box, and its later pairs are not (0, 2)
sequences.

Everything is a pure function of (seed, pixel, sample index, pair): no
state, so the image does not depend on the thread count or on how the
samples are split into passes.
"""
import numpy as np
from numba import njit

from .rng import keyed, mix64

_M32 = np.uint64(0xFFFFFFFF)
_INV32 = 1.0 / 4294967296.0


# Sobol's dimensions 2-24 (the first is the van der Corput sequence): degree
# s, coefficients a and initial m_k of their primitive polynomials, from
# Joe and Kuo's table (2008, new-joe-kuo-6.21201).
_POLYNOMIALS = (
    (1, 0, (1,)), (2, 1, (1, 3)), (3, 1, (1, 3, 1)), (3, 2, (1, 1, 1)), (4, 1, (1, 1, 3, 3)),
    (4, 4, (1, 3, 5, 13)), (5, 2, (1, 1, 5, 5, 17)), (5, 4, (1, 1, 5, 5, 5)), (5, 7, (1, 1, 7, 11, 19)),
    (5, 11, (1, 1, 5, 1, 1)), (5, 13, (1, 1, 1, 3, 11)), (5, 14, (1, 3, 5, 5, 31)),
    (6, 1, (1, 3, 3, 9, 7, 49)), (6, 13, (1, 1, 1, 15, 21, 21)), (6, 16, (1, 3, 1, 13, 27, 49)),
    (6, 19, (1, 1, 1, 15, 7, 5)), (6, 22, (1, 3, 1, 15, 13, 25)), (6, 25, (1, 1, 5, 5, 19, 61)),
    (7, 1, (1, 3, 7, 11, 23, 15, 103)), (7, 4, (1, 3, 7, 13, 13, 15, 69)), (7, 7, (1, 1, 3, 13, 7, 35, 63)),
    (7, 8, (1, 3, 5, 9, 1, 25, 53)), (7, 14, (1, 3, 1, 13, 9, 35, 107)))
DIMS = len(_POLYNOMIALS) + 1


def _direction_numbers():
    """(DIMS, 32) uint64: the generator columns v_k of each dimension, as
    32-bit fractions (v_k = m_k / 2^k), by Bratley and Fox's recurrence."""
    v = np.zeros((DIMS, 32), np.uint64)
    for k in range(32):
        v[0, k] = 1 << (31 - k)
    for d, (deg, a, m) in enumerate(_POLYNOMIALS, start=1):
        w = [0] * 32
        for k in range(deg):
            w[k] = m[k] << (31 - k)
        for k in range(deg, 32):
            x = w[k - deg] ^ (w[k - deg] >> deg)
            for j in range(1, deg):
                if (a >> (deg - 1 - j)) & 1:
                    x ^= w[k - j]
            w[k] = x
        v[d] = w
    return v


_V = _direction_numbers()


def _byte_tables(v):
    """(DIMS, 4, 256) uint64: for dimension d and byte k of an index, the
    xor of the columns its set bits select, bit-reversed (so that the
    scramble needs one reversal, not two)."""
    t = np.zeros((v.shape[0], 4, 256), np.uint64)
    for d in range(v.shape[0]):
        for k in range(4):
            for b in range(256):
                x = 0
                for j in range(8):
                    if (b >> j) & 1:
                        x ^= int(v[d, 8 * k + j])
                t[d, k, b] = int(format(x, "032b")[::-1], 2)
    return t


_T = _byte_tables(_V)


@njit(cache=True, inline="always")
def reverse32(x):
    """The 32 low bits of x in reverse order."""
    x = ((x >> np.uint64(1)) & np.uint64(0x55555555)) | ((x & np.uint64(0x55555555)) << np.uint64(1))
    x = ((x >> np.uint64(2)) & np.uint64(0x33333333)) | ((x & np.uint64(0x33333333)) << np.uint64(2))
    x = ((x >> np.uint64(4)) & np.uint64(0x0F0F0F0F)) | ((x & np.uint64(0x0F0F0F0F)) << np.uint64(4))
    x = ((x >> np.uint64(8)) & np.uint64(0x00FF00FF)) | ((x & np.uint64(0x00FF00FF)) << np.uint64(8))
    return ((x >> np.uint64(16)) | (x << np.uint64(16))) & _M32


@njit(cache=True, inline="always")
def _laine_karras(x, seed):
    """A random bijection of 32-bit x in which each bit depends only on the
    bits below it (multiplications by even numbers and additions carry
    upwards only)."""
    x = (x ^ (x * np.uint64(0x3D20ADEA))) & _M32
    x = (x + seed) & _M32
    x = (x * ((seed >> np.uint64(16)) | np.uint64(1))) & _M32
    x = (x ^ (x * np.uint64(0x05526C56))) & _M32
    return (x ^ (x * np.uint64(0x53A22864))) & _M32


@njit(cache=True, inline="always")
def owen32(x, seed):
    """Nested uniform (Owen) scramble of 32-bit x: each bit flipped by a
    hash of the bits above it."""
    return reverse32(_laine_karras(reverse32(x), seed & _M32))


@njit(cache=True, inline="always")
def _sobol_reversed(i, d):
    """Dimension d (0 to DIMS - 1) of Sobol point i (32-bit), as a 32-bit
    fraction with its bits reversed."""
    return (_T[d, 0, i & np.uint64(255)] ^ _T[d, 1, (i >> np.uint64(8)) & np.uint64(255)]
            ^ _T[d, 2, (i >> np.uint64(16)) & np.uint64(255)] ^ _T[d, 3, (i >> np.uint64(24)) & np.uint64(255)])


@njit(cache=True, inline="always")
def _coordinate(i, d, seed):
    """Dimension d of point i, Owen-scrambled with `seed`, in [0, 1)."""
    return float(reverse32(_laine_karras(_sobol_reversed(i, d), seed & _M32))) * _INV32


@njit(cache=True, inline="always")
def _seed(seed, pixel, group):
    return mix64(keyed(seed, pixel) + np.uint64(group))


@njit(cache=True, inline="always")
def sample2(seed, pixel, index, pair):
    """Point `index` of the scrambled (0, 2) sequence of (seed, pixel,
    pair): two uniform doubles in [0, 1)."""
    h = _seed(seed, pixel, pair)
    i = owen32(np.uint64(index) & _M32, h)
    h0 = mix64(h)
    return _coordinate(i, 0, h0), _coordinate(i, 1, mix64(h0))


@njit(cache=True, inline="always")
def sample4(seed, pixel, index, group):
    """Pairs 2 group and 2 group + 1 of sample2: four uniform doubles."""
    x0, x1 = sample2(seed, pixel, index, 2 * group)
    x2, x3 = sample2(seed, pixel, index, 2 * group + 1)
    return x0, x1, x2, x3
