"""The area emitters' direct light at a point, lamp by lamp.

A lamp is a connected set of emitter triangles (sharing a vertex). At a
point p (normal n) each lamp gives its exact unoccluded irradiance A (the
clipped cosine integral of each triangle, lightcuts.emitter_cosine)
times its visibility V: the share of that integral that reaches p unblocked
(through glass, tinted). V is estimated by shadow rays towards points drawn
over the lamp in proportion to the light they send (a triangle by its share
of A, a direction in it uniformly over its solid angle, or over its area
where it is far and small), each ray weighted by its direction's cosine over
the triangle's mean:

    V = sum_j w_j T_j / sum_j w_j,  w_j = cos_p(j) Omega_t / G_t   (solid angle)
                                         = cos_p cos_l / r^2 Area_t / G_t  (area)

with G_t the triangle's cosine integral. A lamp that nothing blocks gets V =
1 exactly, one wholly hidden V = 0 exactly. A lamp's rays: FIRST, then, when
they disagree (a penumbra), as many as its share of the point's light asks
for out of BUDGET; a lamp with under a quarter of the point's light starts
with fewer rays in proportion (FIRST_MIN at least): 13 lamps at FIRST each
cost the modern hall as many rays as the cut did. Every point draws the same scrambled Sobol points per
lamp (mapped onto the lamp as that point sees it): neighbouring texels'
rays move together, so a penumbra is smooth, not speckled (a scramble per
point doubled the texels the bake anti-aliases for their contrast).

Why not a lightcut over the emitters' VPLs: beside a large lamp (a window's
light panel a few centimetres away) the cut's bounds never meet epsilon,
the cut stops at its cap with coarse nodes over the lamp's far parts, and
its visibility read 0.15 where rays over the solid angle read 0.70 (and
hemisphere rays from the same origin 0.695): the modern hall's window bays.

The rays leave a tenth of the texel point's lift off the surface (LAMP_LIFT):
from the full lift (a quarter texel, 3.9 cm in the hall) a lamp that grazes
a wall's end face or a contact is seen more than from the surface (0.70
against 0.50 at the point above), and the hall's worst block read 1.145.
"""
from __future__ import annotations

import math
from collections import namedtuple

import numpy as np
from numba import njit

from ..kernels.colour import LUM_B, LUM_G, LUM_R
from ..kernels.sobol import sample2
from ..kernels.traverse import transmittance
from .lightcuts import COS_MIN, SHADOW_EPS, emitter_cosine

# lamp l's triangles (scene numbering) are tris[start[l]:start[l + 1]]
LampArrays = namedtuple("LampArrays", ["start", "tris"])

FIRST = 24       # rays a lamp with a quarter or more of a point's light gets first (16 missed a 3 cm bar's band)
FIRST_MIN = 4    # ... and one with little of it: fewer in proportion, at least these
FULL_SHARE = 0.25
BUDGET = 128     # rays a point spends on lamps whose first rays disagree, split by their share of its light
LAMP_LIFT = 0.1  # the lamps' rays leave this fraction of the point's lift off its surface (shade.shade_points)


def lamp_groups(surf) -> LampArrays:
    """The emitter triangles of SurfaceArrays `surf` grouped into lamps:
    connected components of triangles that share a corner (positions equal
    to the bit)."""
    e = np.asarray(surf.emitters, np.int64)
    if len(e) == 0:
        return LampArrays(np.zeros(1, np.int64), np.zeros(0, np.int64))
    corners = np.ascontiguousarray(surf.corners[e].reshape(-1, 3))
    _, vid = np.unique(corners, axis=0, return_inverse=True)
    vid = vid.reshape(-1, 3)
    parent = np.arange(len(e))

    def find(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    first_of = {}
    for t in range(len(e)):
        for v in vid[t]:
            o = first_of.setdefault(int(v), t)
            a, b = find(t), find(o)
            if a != b:
                parent[max(a, b)] = min(a, b)
    root = np.array([find(t) for t in range(len(e))])
    order = np.argsort(root, kind="stable")
    _, counts = np.unique(root[order], return_counts=True)
    return LampArrays(np.concatenate([[0], np.cumsum(counts)]).astype(np.int64), e[order])


@njit(cache=True, inline="always")
def _unit(x, y, z):
    s = math.sqrt(x * x + y * y + z * z)
    return x / s, y / s, z / s


@njit(cache=True, inline="always")
def solid_angle(ax, ay, az, bx, by, bz, cx, cy, cz):
    """Solid angle of the spherical triangle of unit vectors a, b, c (Van
    Oosterom and Strackee 1983)."""
    trip = ax * (by * cz - bz * cy) + ay * (bz * cx - bx * cz) + az * (bx * cy - by * cx)
    den = 1.0 + ax * bx + ay * by + az * bz + bx * cx + by * cy + bz * cz + cx * ax + cy * ay + cz * az
    return 2.0 * math.atan2(abs(trip), den)


@njit(cache=True, inline="always")
def spherical_sample(ax, ay, az, bx, by, bz, cx, cy, cz, omega, u1, u2):
    """A direction uniform over the spherical triangle of unit vectors a, b,
    c (solid angle omega) for (u1, u2) in [0, 1)^2: Arvo 1995, "Stratified
    sampling of spherical triangles". ok False: degenerate."""
    n1x, n1y, n1z = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
    n2x, n2y, n2z = ay * cz - az * cy, az * cx - ax * cz, ax * cy - ay * cx
    l1 = math.sqrt(n1x * n1x + n1y * n1y + n1z * n1z)
    l2 = math.sqrt(n2x * n2x + n2y * n2y + n2z * n2z)
    if l1 <= 0.0 or l2 <= 0.0 or omega <= 1e-12:
        return 0.0, 0.0, 0.0, False
    ca = max(-1.0, min(1.0, (n1x * n2x + n1y * n2y + n1z * n2z) / (l1 * l2)))   # the angle at a
    alpha = math.acos(ca)
    sa = math.sin(alpha)
    if sa <= 1e-12:
        return 0.0, 0.0, 0.0, False
    s, t = math.sin(u1 * omega - alpha), math.cos(u1 * omega - alpha)
    u = t - ca
    v = s + sa * (ax * bx + ay * by + az * bz)
    den = (v * s + u * t) * sa
    if den == 0.0:
        return 0.0, 0.0, 0.0, False
    q = max(-1.0, min(1.0, ((v * t - u * s) * ca - v) / den))
    d = cx * ax + cy * ay + cz * az
    ex, ey, ez = cx - d * ax, cy - d * ay, cz - d * az
    le = math.sqrt(ex * ex + ey * ey + ez * ez)
    if le <= 0.0:
        return 0.0, 0.0, 0.0, False
    r = math.sqrt(max(0.0, 1.0 - q * q)) / le
    hx, hy, hz = q * ax + r * ex, q * ay + r * ey, q * az + r * ez   # the sub-triangle's third corner
    hb = hx * bx + hy * by + hz * bz
    z = 1.0 - u2 * (1.0 - hb)
    fx, fy, fz = hx - hb * bx, hy - hb * by, hz - hb * bz
    lf = math.sqrt(fx * fx + fy * fy + fz * fz)
    if lf <= 0.0:
        return bx, by, bz, True
    r = math.sqrt(max(0.0, 1.0 - z * z)) / lf
    return z * bx + r * fx, z * by + r * fy, z * bz + r * fz, True


@njit(cache=True)
def lamps_light(bvh, stack, surf, lamps, g, far, cum, px, py, pz, nx, ny, nz, offset, floor, first, budget):
    """Irradiance (r, g, b) at p (normal n) from every lamp (LampArrays),
    and the shadow rays cast; shadow rays leave from p + offset n. g, far,
    cum: scratch of one slot per lamp triangle. floor: the luminance p gets
    from elsewhere (a lamp's share of the point's light, which sets its
    rays, counts it)."""
    c = surf.corners
    n_lamps = lamps.start.shape[0] - 1
    total = floor
    for q in range(lamps.tris.shape[0]):
        t = lamps.tris[q]
        g[q], far[q] = emitter_cosine(surf, t, px, py, pz, nx, ny, nz)
        total += g[q] * (LUM_R * surf.tri_emission[t, 0] + LUM_G * surf.tri_emission[t, 1]
                         + LUM_B * surf.tri_emission[t, 2])
    ox, oy, oz = px + offset * nx, py + offset * ny, pz + offset * nz
    h0 = h1 = h2 = 0.0
    rays = 0
    for lamp in range(n_lamps):
        a0 = a1 = a2 = 0.0
        run = 0.0
        for q in range(lamps.start[lamp], lamps.start[lamp + 1]):
            t = lamps.tris[q]
            a0 += g[q] * surf.tri_emission[t, 0]
            a1 += g[q] * surf.tri_emission[t, 1]
            a2 += g[q] * surf.tri_emission[t, 2]
            run += g[q] * (surf.tri_emission[t, 0] + surf.tri_emission[t, 1] + surf.tri_emission[t, 2])
            cum[q] = run
        if run <= 0.0:
            continue
        share = (LUM_R * a0 + LUM_G * a1 + LUM_B * a2) / total if total > 0.0 else 1.0
        # a lamp's first rays in proportion to its share of the point's light: one that it misjudges
        # altogether errs by that share at most
        m = max(FIRST_MIN, min(first, int(math.ceil(first * share / FULL_SHARE))))
        n_rays = max(m, min(budget, int(math.ceil(budget * share))))
        s0 = s1 = s2 = sw = 0.0
        f0 = -1.0
        f1 = f2 = 0.0
        agree = True
        j = 0
        while j < m:
            u1, u2 = sample2(lamp, 0, j, 0)
            j += 1
            # the triangle by its share of the lamp's light; u1 rescaled within it keeps the stratification
            x = u1 * run
            lo, hi = lamps.start[lamp], lamps.start[lamp + 1] - 1
            while lo < hi:
                mid = (lo + hi) // 2
                if cum[mid] > x:
                    hi = mid
                else:
                    lo = mid + 1
            q = lo
            t = lamps.tris[q]
            below = cum[q - 1] if q > lamps.start[lamp] else 0.0
            width = cum[q] - below
            u1 = min(max((x - below) / width, 0.0), 0.9999999999) if width > 0.0 else 0.5
            ok = False
            w = dist = dx = dy = dz = 0.0
            if width <= 0.0:
                pass
            elif far[q]:
                s = math.sqrt(u1)
                wa, wb = s * (1.0 - u2), s * u2
                qx = c[t, 0, 0] + wa * (c[t, 1, 0] - c[t, 0, 0]) + wb * (c[t, 2, 0] - c[t, 0, 0])
                qy = c[t, 0, 1] + wa * (c[t, 1, 1] - c[t, 0, 1]) + wb * (c[t, 2, 1] - c[t, 0, 1])
                qz = c[t, 0, 2] + wa * (c[t, 1, 2] - c[t, 0, 2]) + wb * (c[t, 2, 2] - c[t, 0, 2])
                dx, dy, dz = qx - ox, qy - oy, qz - oz
                dist = math.sqrt(dx * dx + dy * dy + dz * dz)
                if dist > 0.0:
                    dx, dy, dz = dx / dist, dy / dist, dz / dist
                    cl = -(surf.tri_normal[t, 0] * dx + surf.tri_normal[t, 1] * dy + surf.tri_normal[t, 2] * dz)
                    if surf.double_sided[surf.tri_material[t]]:
                        cl = abs(cl)
                    cp = nx * dx + ny * dy + nz * dz
                    w = cp * cl / (dist * dist) * surf.tri_area[t] / g[q]
                    ok = cl > COS_MIN and cp > COS_MIN
            else:
                ax, ay, az = _unit(c[t, 0, 0] - ox, c[t, 0, 1] - oy, c[t, 0, 2] - oz)
                bx, by, bz = _unit(c[t, 1, 0] - ox, c[t, 1, 1] - oy, c[t, 1, 2] - oz)
                cx, cy, cz = _unit(c[t, 2, 0] - ox, c[t, 2, 1] - oy, c[t, 2, 2] - oz)
                omega = solid_angle(ax, ay, az, bx, by, bz, cx, cy, cz)
                dx, dy, dz, ok = spherical_sample(ax, ay, az, bx, by, bz, cx, cy, cz, omega, u1, u2)
                if ok:
                    cp = nx * dx + ny * dy + nz * dz
                    mx, my, mz = surf.tri_normal[t, 0], surf.tri_normal[t, 1], surf.tri_normal[t, 2]
                    den = mx * dx + my * dy + mz * dz
                    dist = (mx * (c[t, 0, 0] - ox) + my * (c[t, 0, 1] - oy) + mz * (c[t, 0, 2] - oz)) / den \
                        if den != 0.0 else -1.0
                    w = cp * omega / g[q]
                    ok = cp > COS_MIN and dist > 0.0 and dist < np.inf
            if ok:
                tr, tg, tb = transmittance(bvh, stack, ox, oy, oz, dx, dy, dz, 0.0, dist * (1.0 - SHADOW_EPS))
                rays += 1
                if f0 < 0.0:
                    f0, f1, f2 = tr, tg, tb
                elif tr != f0 or tg != f1 or tb != f2:
                    agree = False
                s0 += w * tr
                s1 += w * tg
                s2 += w * tb
                sw += w
            # disagreeing first rays (a penumbra), or none that reached the lamp (all of them under p's
            # horizon, the lamp mostly below it): the lamp's whole share
            if j == m and m < n_rays and (not agree or f0 < 0.0):
                m = n_rays
        if sw > 0.0:
            h0 += a0 * (s0 / sw)
            h1 += a1 * (s1 / sw)
            h2 += a2 * (s2 / sw)
    return h0, h1, h2, rays
