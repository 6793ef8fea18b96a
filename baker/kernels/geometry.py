"""Small geometric primitives shared by the kernels."""
import math

from numba import njit


@njit(cache=True, inline="always")
def unit_cross(ax, ay, az, bx, by, bz):
    """(a x b) / |a x b|: the unit normal of a triangle with edges a, b from
    its first corner, front by the winding (counter-clockwise seen from the
    front). The one formula every kernel uses for a triangle's normal."""
    nx, ny, nz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
    ln = math.sqrt(nx * nx + ny * ny + nz * nz)
    return nx / ln, ny / ln, nz / ln
