"""Sampling helpers: orthonormal frames, cosine hemisphere, triangles, CDFs."""
import math

import numpy as np
from numba import njit


@njit(cache=True)
def frame(nx, ny, nz):
    """Two unit tangents (t, b) completing unit n to a right-handed frame
    (Duff et al. 2017, "Building an orthonormal basis, revisited")."""
    s = 1.0 if nz >= 0.0 else -1.0
    a = -1.0 / (s + nz)
    b = nx * ny * a
    return (1.0 + s * nx * nx * a, s * b, -s * nx), (b, s + ny * ny * a, -ny)


# Taylor coefficients of sin x / x and (cos x - 1) / x^2 in x^2, to x^14 and
# x^16: on |x| <= pi/4 the first term left out is below 5e-17 (x^17 / 17!).
_SIN = (1.0, -1.0 / 6.0, 1.0 / 120.0, -1.0 / 5040.0, 1.0 / 362880.0, -1.0 / 39916800.0, 1.0 / 6227020800.0,
        -1.0 / 1307674368000.0)
_COS = (-0.5, 1.0 / 24.0, -1.0 / 720.0, 1.0 / 40320.0, -1.0 / 3628800.0, 1.0 / 479001600.0, -1.0 / 87178291200.0,
        1.0 / 20922789888000.0)


@njit(cache=True, inline="always")
def turn(u):
    """(cos 2 pi u, sin 2 pi u) for u in [0, 1], to a few ulps: u is reduced
    exactly to the nearest quarter turn q / 4 and a remainder of at most an
    eighth, whose sine and cosine are polynomials; the quarter turns rotate
    them. Cheaper than libm's sin and cos, which reduce any argument and
    showed in the path tracer's time."""
    q = math.floor(4.0 * u + 0.5)
    x = 2.0 * math.pi * (u - 0.25 * q)  # |x| <= pi / 4; u - q / 4 is exact
    x2 = x * x
    sp = ((((((_SIN[7] * x2 + _SIN[6]) * x2 + _SIN[5]) * x2 + _SIN[4]) * x2 + _SIN[3]) * x2 + _SIN[2]) * x2
          + _SIN[1]) * x2 + _SIN[0]
    cp = ((((((_COS[7] * x2 + _COS[6]) * x2 + _COS[5]) * x2 + _COS[4]) * x2 + _COS[3]) * x2 + _COS[2]) * x2
          + _COS[1]) * x2 + _COS[0]
    s, c = x * sp, 1.0 + x2 * cp
    k = int(q)
    if k & 1:  # a quarter turn
        c, s = -s, c
    if k & 2:  # a half turn
        c, s = -c, -s
    return c, s


@njit(cache=True)
def cosine_hemisphere(u1, u2, nx, ny, nz):
    """Direction about n with pdf cos(theta)/pi; returns (dx, dy, dz, cos)."""
    r = math.sqrt(u1)
    cphi, sphi = turn(u2)
    x, y = r * cphi, r * sphi
    z = math.sqrt(max(0.0, 1.0 - u1))
    t, b = frame(nx, ny, nz)
    return (x * t[0] + y * b[0] + z * nx, x * t[1] + y * b[1] + z * ny, x * t[2] + y * b[2] + z * nz, z)


@njit(cache=True)
def triangle_point(u1, u2):
    """Uniform barycentrics (b1, b2) on a triangle (square-root mapping)."""
    su = math.sqrt(u1)
    return su * (1.0 - u2), su * u2


@njit(cache=True)
def sample_cdf(cdf, u):
    """Index i with cdf[i-1] <= u * cdf[-1] < cdf[i] (cdf inclusive, increasing)."""
    x = u * cdf[-1]
    lo, hi = 0, len(cdf) - 1
    while lo < hi:
        mid = (lo + hi) // 2
        if cdf[mid] <= x:
            lo = mid + 1
        else:
            hi = mid
    return lo


def spiral_hemisphere(k: int) -> np.ndarray:
    """k cosine-distributed unit directions about +z (k, 3): a Fibonacci
    spiral lifted onto the hemisphere, fixed, so what they measure is
    deterministic."""
    i = np.arange(k) + 0.5
    r = np.sqrt(i / k)
    phi = i * np.pi * (3.0 - np.sqrt(5.0))
    x, y = r * np.cos(phi), r * np.sin(phi)
    return np.ascontiguousarray(np.stack([x, y, np.sqrt(np.maximum(0.0, 1.0 - x * x - y * y))], 1))
