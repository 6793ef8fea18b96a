"""Area lamps taken exactly at a moving object's points.

A probe grid cannot hold a lamp's near field: between probes 4 cm (the
Cornell box) or 57 cm (the walkthrough) apart, the irradiance beside a
lamp changes by orders of magnitude, and a point 2 mm beside the Cornell
lamp's edge read 6x its path-traced light from its probes. So, as the
punctual lights (sample.ProbeLights), the brightest untextured emitter
triangles come out of the probes and in at each shading point:

- unshadowed, a triangle of constant radiance L gives a point x with
  normal n exactly E = L / 2 |sum_i theta_i (g_i . n)| (Lambert's
  formula over the triangle clipped to x's upper half-space: theta_i the
  angle each edge subtends at x, g_i the unit normal of the plane through
  x and that edge: lights/lightcuts.corners_cosine, the same sum the
  bake's texels take for the emitters), 0 behind a one-sided emitter;
- its shadow is the share of LampArrays.marks (fixed points spread over
  the triangle) whose shadow rays from x arrive (glass tints), times the
  unshadowed E (the ratio estimator of analytic direct light with
  stochastic shadows: exact wherever the lamp is wholly seen or hidden).

Where the triangle lies wholly above the point's horizon and farther
than FAR times its longest edge, the kernels take it as a point, A cos_e
cos_n / d^2; between MID and FAR times, as the four points of its
halved-edge quarters: each within 0.8% of the triangle's peak A cos_e /
d^2 there (against Lambert's formula, tests/test_probes.py), for one or
four dot products a normal instead of four arc tangents. Cut by the
horizon it takes the clipped sum at any distance (points there would
clamp each one's cosine: up to 18% off the lamp's light at a Cornell
probe's grazing normal).

Textured emitters stay in the probes (their radiance is not one L), as do
all but the MAX_LAMPS brightest triangles (a glowing mesh of thousands
would cost thousands of shadow rays a point).
"""
from __future__ import annotations

import math
from collections import namedtuple

import numpy as np
from numba import njit, prange

from ..kernels.bvh import STACK_SIZE
from ..kernels.sampling import triangle_point
from ..kernels.traverse import transmittance
from ..lights.lightcuts import corners_cosine

MAX_LAMPS = 64     # emitter triangles taken exactly, by power
MARKS = 16         # points on each lamp triangle for its shadow (the first k of them for fewer rays)
FAR = 5.0          # longest edges away, a lamp triangle is a point
MID = 2.5          # ... and from here to FAR the four centroids of its quarters

# corners (m, 3, 3) float64, front by the winding; radiance (m, 3) float64; double (m,) float64 1 where
# double-sided, else 0; marks (MARKS, 2)
# barycentrics (b1, b2); edge (m,) float64 the longest edge; centroid (m, 3); area (m,); normal (m, 3);
# quarters (m, 3, 3) the centroids of the three corner quarters (the middle one's is the triangle's)
LampArrays = namedtuple("LampArrays", "corners radiance double marks edge centroid area normal quarters")


def _marks(count: int) -> np.ndarray:
    """(count, 2) barycentrics: the R2 sequence mapped onto a triangle
    (area-uniform, stratified for every prefix)."""
    g = 1.32471795724474602596
    i = np.arange(count) + 0.5
    u = np.stack([(0.5 + i / g) % 1.0, (0.5 + i / (g * g)) % 1.0], axis=1)
    out = np.empty((count, 2))
    for k in range(count):
        out[k] = triangle_point(u[k, 0], u[k, 1])
    return out


def lamp_arrays(surf=None, limit: int = MAX_LAMPS) -> LampArrays:
    """The lamps of surfaces' arrays `surf`: its untextured emitter
    triangles, the `limit` brightest (power, sides counted); none where
    surf is None."""
    if surf is None or limit <= 0 or len(surf.emitters) == 0:
        tris = np.zeros(0, np.int64)
    else:
        tris = np.asarray(surf.emitters, np.int64)
        mats = surf.tri_material[tris]
        tris = tris[(surf.emit_offset[mats] < 0) & (surf.tri_area[tris] > 0)]
        sides = np.where(surf.double_sided[surf.tri_material[tris]], 2.0, 1.0)
        power = (surf.tri_emission[tris].sum(axis=1) * surf.tri_area[tris] * sides) if len(tris) else np.zeros(0)
        tris = tris[np.argsort(-power, kind="stable")[:limit]]
    if len(tris) == 0:
        return lamps_of(np.zeros((0, 3, 3)), np.zeros((0, 3)), np.zeros(0))
    mats = surf.tri_material[tris]
    return lamps_of(surf.corners[tris], surf.emission[mats], surf.double_sided[mats])


def lamps_of(corners, radiance, double) -> LampArrays:
    """LampArrays of triangles corners (m, 3, 3) (front by the winding)
    emitting radiance (m, 3), double-sided where double (m,)."""
    corners = np.ascontiguousarray(corners, np.float64).reshape(-1, 3, 3)
    edges = np.linalg.norm(corners - np.roll(corners, 1, axis=1), axis=2).max(axis=1) if len(corners) \
        else np.zeros(0)
    cross = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    twice = np.linalg.norm(cross, axis=1)
    normal = cross / np.where(twice > 0, twice, 1.0)[:, None]
    return LampArrays(corners, np.ascontiguousarray(radiance, np.float64).reshape(-1, 3),
                      np.ascontiguousarray(double, np.float64).reshape(-1), _marks(MARKS), edges,
                      np.ascontiguousarray(corners.mean(axis=1)), 0.5 * twice, np.ascontiguousarray(normal),
                      quarters(corners))


def quarters(corners) -> np.ndarray:
    """(m, 3, 3): the centroid of each corner's quarter of each triangle
    (halved edges): (4 a + b + c) / 6 for corner a."""
    c = np.asarray(corners, np.float64)
    return np.ascontiguousarray((3 * c + c.sum(axis=1, keepdims=True)) / 6)


@njit(cache=True, inline="always")
def _point_term(mx, my, mz, double, cx, cy, cz, nx, ny, nz):
    """cos_e cos_n / d^2 of a point at c (from the shading point) on a lamp
    of unit normal m for normal n; 0 below the horizon or behind a one-sided
    lamp (double 0). Branchless: it runs per texel and lamp."""
    cn = max(nx * cx + ny * cy + nz * cz, 0.0)
    side = -(mx * cx + my * cy + mz * cz)
    side = max(side, -double * side)
    d2 = cx * cx + cy * cy + cz * cz
    return side * cn / (d2 * d2)


@njit(cache=True, inline="always")
def lamp_factor(lamps, t, x, y, z, nx, ny, nz):
    """E / L of lamp triangle t at point (x, y, z) with unit normal n,
    unshadowed: Lambert's formula over the triangle clipped to the point's
    upper half-space (corners_cosine; wholly above it, as one point
    beyond FAR of its longest edges, four beyond MID); 0 behind a
    one-sided lamp."""
    # every field read before any branch: a namedtuple's array first read inside a branch of an inlined kernel
    # cost 90 ns a call here (numba 0.68), against 1-7 ns
    corners, quarters, double = lamps.corners, lamps.quarters, lamps.double[t]
    mx, my, mz = lamps.normal[t, 0], lamps.normal[t, 1], lamps.normal[t, 2]
    area, edge = lamps.area[t], lamps.edge[t]
    cx, cy, cz = lamps.centroid[t, 0] - x, lamps.centroid[t, 1] - y, lamps.centroid[t, 2] - z
    side = -(mx * cx + my * cy + mz * cz)   # > 0: in front
    if side <= 0.0 and double == 0.0:
        return 0.0
    d2 = cx * cx + cy * cy + cz * cz
    hmin, hmax = np.inf, -np.inf   # the corners' heights over the point's tangent plane
    for k in range(3):
        h = (corners[t, k, 0] - x) * nx + (corners[t, k, 1] - y) * ny + (corners[t, k, 2] - z) * nz
        hmin, hmax = min(hmin, h), max(hmax, h)
    if hmax <= 0.0:
        return 0.0
    if hmin <= 0.0:   # the horizon cuts it: the clipped sum (points would clamp each one's cosine instead)
        return corners_cosine(corners, t, x, y, z, nx, ny, nz)
    if d2 > FAR * FAR * edge * edge:
        return area * _point_term(mx, my, mz, double, cx, cy, cz, nx, ny, nz)
    if d2 > MID * MID * edge * edge:
        f = _point_term(mx, my, mz, double, cx, cy, cz, nx, ny, nz)
        for k in range(3):
            f += _point_term(mx, my, mz, double, quarters[t, k, 0] - x, quarters[t, k, 1] - y, quarters[t, k, 2] - z,
                             nx, ny, nz)
        return 0.25 * area * f
    return corners_cosine(corners, t, x, y, z, nx, ny, nz)


@njit(cache=True, inline="always")
def lamp_above(lamps, t, x, y, z, nx, ny, nz):
    """Whether lamp triangle t can light (x, y, z) with normal n at all:
    a corner above its tangent plane, and the point before a one-sided
    lamp (lamp_factor > 0 but for a lamp seen edge-on)."""
    corners, double = lamps.corners, lamps.double[t]
    cx, cy, cz = lamps.centroid[t, 0] - x, lamps.centroid[t, 1] - y, lamps.centroid[t, 2] - z
    if double == 0.0 and lamps.normal[t, 0] * cx + lamps.normal[t, 1] * cy + lamps.normal[t, 2] * cz >= 0.0:
        return False
    for k in range(3):
        if (corners[t, k, 0] - x) * nx + (corners[t, k, 1] - y) * ny + (corners[t, k, 2] - z) * nz > 0.0:
            return True
    return False


@njit(cache=True, inline="always")
def lamp_sees(bvh, stack, lamps, t, x, y, z, rays):
    """(r, g, b): the mean transmittance of the shadow rays from (x, y, z)
    to the first `rays` marks on lamp triangle t (stopped short of it: its
    own triangle is not in the way)."""
    s0 = s1 = s2 = 0.0
    for j in range(rays):
        b1, b2 = lamps.marks[j, 0], lamps.marks[j, 1]
        b0 = 1.0 - b1 - b2
        dx = b0 * lamps.corners[t, 0, 0] + b1 * lamps.corners[t, 1, 0] + b2 * lamps.corners[t, 2, 0] - x
        dy = b0 * lamps.corners[t, 0, 1] + b1 * lamps.corners[t, 1, 1] + b2 * lamps.corners[t, 2, 1] - y
        dz = b0 * lamps.corners[t, 0, 2] + b1 * lamps.corners[t, 1, 2] + b2 * lamps.corners[t, 2, 2] - z
        dist = math.sqrt(dx * dx + dy * dy + dz * dz)
        if dist <= 0.0:
            s0 += 1.0
            s1 += 1.0
            s2 += 1.0
            continue
        t0, t1, t2 = transmittance(bvh, stack, x, y, z, dx / dist, dy / dist, dz / dist, 0.0, dist * (1.0 - 1e-6))
        s0 += t0
        s1 += t1
        s2 += t2
    return s0 / rays, s1 / rays, s2 / rays


@njit(cache=True, parallel=True)
def lamps_rest(bvh, lamps, points, texdirs, rays, irr, out):
    """out[i] = irr[i] (S, S, 3) less each lamp's light at probe points[i]
    for the normals texdirs (S^2, 3): what the probe holds once the lamps
    are put back at each shading point (each probe its own: any thread
    count gives the same bits)."""
    size = irr.shape[1]
    for i in prange(points.shape[0]):
        stack = np.empty(STACK_SIZE, np.int32)
        x, y, z = points[i, 0], points[i, 1], points[i, 2]
        for r in range(size):
            for c in range(size):
                for ch in range(3):
                    out[i, r, c, ch] = irr[i, r, c, ch]
        for t in range(lamps.corners.shape[0]):
            v0, v1, v2 = lamp_sees(bvh, stack, lamps, t, x, y, z, rays)
            if v0 == 0.0 and v1 == 0.0 and v2 == 0.0:
                continue
            for q in range(texdirs.shape[0]):
                f = lamp_factor(lamps, t, x, y, z, texdirs[q, 0], texdirs[q, 1], texdirs[q, 2])
                if f > 0.0:
                    out[i, q // size, q % size, 0] -= lamps.radiance[t, 0] * f * v0
                    out[i, q // size, q % size, 1] -= lamps.radiance[t, 1] * f * v1
                    out[i, q // size, q % size, 2] -= lamps.radiance[t, 2] * f * v2
