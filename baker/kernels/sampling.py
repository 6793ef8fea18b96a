"""Sampling helpers: orthonormal frames, cosine hemisphere, triangles, CDFs."""
import math

from numba import njit


@njit(cache=True)
def frame(nx, ny, nz):
    """Two unit tangents (t, b) completing unit n to a right-handed frame
    (Duff et al. 2017, "Building an orthonormal basis, revisited")."""
    s = 1.0 if nz >= 0.0 else -1.0
    a = -1.0 / (s + nz)
    b = nx * ny * a
    return (1.0 + s * nx * nx * a, s * b, -s * nx), (b, s + ny * ny * a, -ny)


@njit(cache=True)
def cosine_hemisphere(u1, u2, nx, ny, nz):
    """Direction about n with pdf cos(theta)/pi; returns (dx, dy, dz, cos)."""
    r = math.sqrt(u1)
    phi = 2.0 * math.pi * u2
    x, y = r * math.cos(phi), r * math.sin(phi)
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
