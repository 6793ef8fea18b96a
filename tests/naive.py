"""Slow, obviously-correct references for the fast kernels (STYLE.md)."""
import numpy as np


def ray_triangles(origin, direction, corners, tmin=0.0, tmax=np.inf):
    """Brute force: one ray against every triangle (nt, 3, 3) with the
    watertight test of Woop et al. 2013 written out in numpy; returns
    (t, triangle) of the closest hit, (inf, -1) on a miss."""
    d = np.asarray(direction, float)
    kz = int(np.argmax(np.abs(d)))
    kx, ky = (kz + 1) % 3, (kz + 2) % 3
    if d[kz] < 0:
        kx, ky = ky, kx
    sx, sy, sz = d[kx] / d[kz], d[ky] / d[kz], 1.0 / d[kz]
    rel = corners - np.asarray(origin, float)
    x = rel[:, :, kx] - sx * rel[:, :, kz]
    y = rel[:, :, ky] - sy * rel[:, :, kz]
    z = sz * rel[:, :, kz]
    (ax, bx, cx), (ay, by, cy) = x.T, y.T
    eu, ev, ew = cx * by - cy * bx, ax * cy - ay * cx, bx * ay - by * ax
    inside = ~(((eu < 0) | (ev < 0) | (ew < 0)) & ((eu > 0) | (ev > 0) | (ew > 0)))
    det = eu + ev + ew
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (eu * z[:, 0] + ev * z[:, 1] + ew * z[:, 2]) / det
    ok = inside & (det != 0) & (t > tmin) & (t < tmax)
    if not ok.any():
        return np.inf, -1
    i = np.nonzero(ok)[0]
    k = i[np.argmin(t[i])]
    return float(t[k]), int(k)


def rectangle_form_factor(a, b, h):
    """Point-to-rectangle form factor: differential area at height h below
    the corner of an a x b rectangle, parallel to it (closed form)."""
    A, B = a / np.hypot(a, h), b / np.hypot(b, h)
    return (A * np.arctan(b / np.hypot(a, h)) + B * np.arctan(a / np.hypot(b, h))) / (2 * np.pi)


def irradiance_under_rectangle(L, x0, x1, z0, z1, h, px=0.0, pz=0.0):
    """Irradiance at (px, 0, pz) from a Lambertian rectangle [x0,x1]x[z0,z1]
    at height h of radiance L (facing down): L * pi * F, F by corner sums."""
    def corner(a, b):
        sa, sb = np.sign(a), np.sign(b)
        return sa * sb * rectangle_form_factor(abs(a), abs(b), h)
    f = corner(x1 - px, z1 - pz) - corner(x0 - px, z1 - pz) - corner(x1 - px, z0 - pz) + corner(x0 - px, z0 - pz)
    return L * np.pi * f
