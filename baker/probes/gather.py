"""Irradiance probes for moving objects (docs/design.md, "Irradiance probes").

After the solve, probes are placed on a regular grid in the scene's
bounds. Each probe stores the radiance that reaches it as real spherical
harmonics to order 2 (9 RGB coefficients), gathered with exact
visibility. The light is split as the texels split it: rays from the
probe read the bounced light (the voxel solution's rho H / pi, the side
they hit, through thin glass tinted) where they land and the sky where
they escape; the area emitters are sampled (EMITTER_SAMPLES points by
power, stratified, each behind a shadow ray) and, with the punctual
lights and the sun, added as the deltas they are (a small lamp seen by a
few uniform rays would be noise). The rays are a spherical Fibonacci
set (ray_set), the same for every probe: quasi-uniform, so the sums
over them converge far faster than a Monte-Carlo estimate (a constant
radiance's irradiance within 0.07% at 768 rays).

Order 2 cannot hold a lamp's irradiance: a delta's order-2 irradiance
overshoots by 37% facing it and is 37% of the peak facing away. So each
probe also stores its irradiance itself, E(n) over an octahedral map of
IRR x IRR normals (the rays and deltas convolved with the clamped cosine
at each texel's normal), which is what our viewer reads; the SH are for
clients that take them (three.js's LightProbe).

Each probe also keeps what interpolation needs to stop leaks, as DDGI
does: the mean and mean square distance to the nearest surface over an
octahedral map of DEPTH x DEPTH directions, and a validity flag (false
where a quarter or more of its rays meet the back of a one-sided surface:
inside a wall, outside a building, in a closed volume).

A shading point x with normal n reads (probes/sample.py) the eight
probes of its grid cell, weighted by trilinear weights, a smooth
backface term and a Chebyshev visibility test against the probe's
distance moments toward x (a probe the test puts behind a surface counts
for nothing), then E(n) = sum_l A_l sum_m c_lm Y_lm(n), A = (pi, 2 pi / 3,
pi / 4): irradiance, clamped at 0 (order-2 ringing).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from ..errors import ConfigError
from ..kernels.bvh import PASS_GLASS, STACK_SIZE
from ..kernels.rng import STREAM_PROBE_EMITTERS, rand01
from ..kernels.traverse import closest_hit, hit_normal, transmittance
from ..scene.surfaces import (LIGHT_DIRECTIONAL, LIGHT_SPOT, emission_at, sample_emitter, sky_radiance, spot_falloff,
                              triangle_normal)
from ..solve.gather import GAP_STOP, GLASS_LAYERS, _read_at

SH = 9            # coefficients per channel (order 2)
IRR = 25          # the irradiance map's texels per side (octahedral, in MAP_FRAME): against the path tracer 86-87%
#                   of readings within 3% where 17 gave 67-75% (bench/results/probes.md), for twice the bytes
DEPTH = 8         # the distance map's texels per side (octahedral)
EMITTER_SAMPLES = 256   # points on the area emitters per probe
DEPTH_SUB = 2     # rays per texel per side for the distance map
BACKFACE_INVALID = 0.25   # share of backface hits that makes a probe invalid
MAX_PROBES = 1 << 20      # probes in a grid at most (a flag that asks more is refused before any work)
MAX_DIST = 4.0   # spacings: the distance map's rays are capped here
# The octahedral maps' frame: a map direction is MAP_FRAME @ d for a scene direction d, a turn of 67.5 degrees
# about the scene's z. The octahedral map is singular at its vertices and folds along the square's edges; a
# bilinear read beside them is off by up to half a texel's turn. In the scene's own frame its x and y axes, the
# normals of walls, floors and ceilings, lay on the vertices at the square's edges (a ceiling's +y read a normal
# 3.6 degrees off: the walkthrough's probes 8% bright under a lamp). Turned, they lie on the map's equator 22.5
# degrees from a vertex, and the cube's corner directions midway between folds; +z stays the map's centre.
# Measured as the map's read against the probe's own irradiance at the 14 cube normals (tests/test_probes.py),
# at 17 x 17: within 3% for 91% / 95% of them (Cornell box / walkthrough) against 82% / 89% unturned; a
# 60-degree turn about (1, 1, 1) gave 90% / 96% but bent -z, the Cornell box's view, 11% at its 95th
# percentile. At IRR = 25: 96% / 98%.
MAP_FRAME = np.array([[0.3826834323650898, -0.9238795325112867, 0.0], [0.9238795325112867, 0.3826834323650898, 0.0],
                      [0.0, 0.0, 1.0]])
SH_BAND = np.array([math.pi] + [2 * math.pi / 3] * 3 + [math.pi / 4] * 5)   # the cosine lobe per band


@dataclass(frozen=True)
class ProbeGrid:
    """origin (3,) the first probe, spacing (scene units), dims (3,) probes
    per axis (x fastest in every array); sh (N, 9, 3) float32 radiance SH
    (real, order 2, Y order: 00, 1-1, 10, 11, 2-2, 2-1, 20, 21, 22);
    irradiance (N, IRR, IRR, 3) float32 E at each octahedral texel's
    normal (row v, column u); depth (N, DEPTH, DEPTH, 2) float32 mean and
    mean square distance per octahedral texel; valid (N,) bool; rays per
    probe."""
    origin: np.ndarray
    spacing: float
    dims: np.ndarray
    sh: np.ndarray
    irradiance: np.ndarray
    depth: np.ndarray
    valid: np.ndarray
    rays: int

    @property
    def count(self) -> int:
        return int(np.prod(self.dims))

    def positions(self) -> np.ndarray:
        return probe_positions(self.origin, self.spacing, self.dims)


def probe_positions(origin, spacing, dims) -> np.ndarray:
    """(N, 3) float64, x fastest, then y, then z."""
    k = np.indices(tuple(int(d) for d in dims[::-1])).reshape(3, -1)[::-1].T   # (N, 3) as (i, j, l)
    return np.asarray(origin, np.float64) + spacing * k


def grid_for(lo, hi, spacing=None, budget=4096):
    """(origin, spacing, dims): probes `spacing` apart (None: about
    `budget` probes over the bounds, each axis counted as at least 1/16 of
    the longest), centred in the bounds, each at least a quarter spacing
    inside them. Refuses a grid over MAX_PROBES in one line."""
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    ext = np.maximum(hi - lo, 0.0)
    big = float(ext.max()) if ext.size else 0.0
    if big <= 0 or not np.isfinite(big):
        raise ConfigError("the scene has no extent to place probes in")
    if spacing is None:
        eff = np.maximum(ext, big / 16)
        spacing = float(np.prod(eff) / budget) ** (1 / 3)
    spacing = float(spacing)
    if not (np.isfinite(spacing) and spacing > 0):
        raise ConfigError(f"the probe spacing must be a positive number (got {spacing})")
    want = np.maximum(1, np.rint(ext / spacing))
    if float(np.prod(want)) > MAX_PROBES:
        raise ConfigError(f"a probe spacing of {spacing:g} gives {int(np.prod(want)):,} probes over the scene's "
                          f"bounds, over the limit of {MAX_PROBES:,}: give a larger --probe-spacing")
    dims = want.astype(np.int64)
    origin = lo + (ext - (dims - 1) * spacing) / 2
    return origin, spacing, dims


def ray_set(count: int) -> np.ndarray:
    """(count, 3) unit directions: a spherical Fibonacci set (equal areas
    by z, the golden angle around y). Quasi-uniform, so a probe's
    irradiance, whose integrand has the cosine's kink at the horizon and
    the room's edges, converges much faster than over random directions:
    against the path tracer in the walkthrough, 768 of them put 99% of
    probe readings within 3% (max 5.3%) where 64 randomly turned
    icosahedra (a union of spherical 5-designs, exact for order-2 SH
    only) put 90% (max 8.9-16%, by the seed). A constant radiance's
    irradiance is within 0.07% for every normal (768 rays) and its order-2
    SH within 2e-4 (192: 0.4% and 2e-3). The same set for every probe and
    seed: nothing in it is random."""
    i = np.arange(int(count)) + 0.5
    y = 1.0 - 2.0 * i / count
    phi = 2.0 * math.pi * i / ((1.0 + math.sqrt(5.0)) / 2.0)
    r = np.sqrt(np.maximum(1.0 - y * y, 0.0))
    return np.ascontiguousarray(np.stack([r * np.cos(phi), y, r * np.sin(phi)], axis=1))


@njit(cache=True, inline="always")
def sh_basis(x, y, z, out):
    out[0] = 0.28209479177387814
    out[1] = 0.4886025119029199 * y
    out[2] = 0.4886025119029199 * z
    out[3] = 0.4886025119029199 * x
    out[4] = 1.0925484305920792 * x * y
    out[5] = 1.0925484305920792 * y * z
    out[6] = 0.31539156525252005 * (3.0 * z * z - 1.0)
    out[7] = 1.0925484305920792 * x * z
    out[8] = 0.5462742152960396 * (x * x - y * y)


def sh_basis_np(d) -> np.ndarray:
    """(n, 9) the basis at unit directions d (n, 3)."""
    x, y, z = d[:, 0], d[:, 1], d[:, 2]
    c1, c2, c3, c4 = 0.4886025119029199, 1.0925484305920792, 0.31539156525252005, 0.5462742152960396
    return np.stack([np.full_like(x, 0.28209479177387814), c1 * y, c1 * z, c1 * x, c2 * x * y, c2 * y * z,
                     c3 * (3 * z * z - 1), c2 * x * z, c4 * (x * x - y * y)], axis=1)


@njit(cache=True, inline="always")
def to_map(x, y, z):
    """A scene direction in the maps' frame (MAP_FRAME @ d)."""
    return (0.3826834323650898 * x - 0.9238795325112867 * y, 0.9238795325112867 * x + 0.3826834323650898 * y, z)


@njit(cache=True, inline="always")
def from_map(x, y, z):
    """A direction of the maps' frame in the scene's (MAP_FRAME.T @ d)."""
    return (0.3826834323650898 * x + 0.9238795325112867 * y, -0.9238795325112867 * x + 0.3826834323650898 * y, z)


@njit(cache=True, inline="always")
def oct_encode(x, y, z):
    """Unit scene direction -> octahedral (u, v) in [0, 1]^2 (in the maps'
    frame)."""
    x, y, z = to_map(x, y, z)
    s = abs(x) + abs(y) + abs(z)
    px, py = x / s, y / s
    if z < 0.0:
        qx = (1.0 - abs(py)) * (1.0 if px >= 0.0 else -1.0)
        qy = (1.0 - abs(px)) * (1.0 if py >= 0.0 else -1.0)
        px, py = qx, qy
    return 0.5 * (px + 1.0), 0.5 * (py + 1.0)


@njit(cache=True, inline="always")
def oct_decode(u, v):
    px, py = 2.0 * u - 1.0, 2.0 * v - 1.0
    pz = 1.0 - abs(px) - abs(py)
    if pz < 0.0:
        qx = (1.0 - abs(py)) * (1.0 if px >= 0.0 else -1.0)
        qy = (1.0 - abs(px)) * (1.0 if py >= 0.0 else -1.0)
        px, py = qx, qy
    n = math.sqrt(px * px + py * py + pz * pz)
    return from_map(px / n, py / n, pz / n)


@njit(cache=True)
def _radiance_along(bvh, surf, stack, double, mat_of, vnormal, vcentroid, vcut, pieces, bounced, ox, oy, oz, dx,
                    dy, dz, ray_density, n_emit):
    """(r, g, b, distance to the first surface, hit its one-sided back):
    the radiance a ray from o along d brings: the bounced light
    (`bounced` / pi of the voxel where it lands), an emitter's own light
    under its MIS weight against the emitter samples (balance heuristic:
    ray_density = rays / 4 pi, n_emit samples by power), through thin
    glass tinted; the sky where it escapes."""
    w0 = w1 = w2 = 1.0
    a0 = a1 = a2 = 0.0
    first = np.inf
    back = False
    run = 0.0
    for layer in range(GLASS_LAYERS):
        t, j, u, v = closest_hit(bvh, stack, ox, oy, oz, dx, dy, dz, 0.0, np.inf)
        if j < 0:
            s0, s1, s2 = sky_radiance(surf, dx, dy, dz)
            a0 += w0 * s0
            a1 += w1 * s1
            a2 += w2 * s2
            break
        tri = bvh.tri_index[j]
        hx, hy, hz = hit_normal(bvh, j)
        cos_in = -(hx * dx + hy * dy + hz * dz)
        facing = cos_in > 0.0 or double[mat_of[tri]]
        if layer == 0:
            first = t
            back = not facing
        mat = mat_of[tri]
        e = surf.emission
        if facing and (e[mat, 0] > 0.0 or e[mat, 1] > 0.0 or e[mat, 2] > 0.0) and bvh.tri_pass[j] != PASS_GLASS:
            er, eg, eb = emission_at(surf, tri, u, v)
            r = run + t
            p_e = surf.emitter_prob[tri] / surf.tri_area[tri] * r * r / max(abs(cos_in), 1e-300)
            w = ray_density / (ray_density + n_emit * p_e) if n_emit > 0 else 1.0
            a0 += w0 * er * w
            a1 += w1 * eg * w
            a2 += w2 * eb * w
        vi = _read_at(bvh, stack, double, mat_of, vnormal, vcentroid, vcut, pieces, 0.0, -dx, -dy, -dz, ox, oy, oz,
                      dx, dy, dz, t, j)
        if vi == GAP_STOP:
            break
        if vi >= 0:
            a0 += w0 * bounced[vi, 0] / math.pi
            a1 += w1 * bounced[vi, 1] / math.pi
            a2 += w2 * bounced[vi, 2] / math.pi
        if bvh.tri_pass[j] != PASS_GLASS:
            break
        g = bvh.glass_tint[bvh.tri_mat[j]]
        w0, w1, w2 = w0 * g[0], w1 * g[1], w2 * g[2]
        if w0 <= 0.0 and w1 <= 0.0 and w2 <= 0.0:
            break
        step = 1e-6 * max(1.0, t)
        run += t + step
        ox, oy, oz = ox + t * dx + step * dx, oy + t * dy + step * dy, oz + t * dz + step * dz
    return a0, a1, a2, first, back


@njit(cache=True, inline="always")
def _first_hit(bvh, stack, double, mat_of, ox, oy, oz, dx, dy, dz):
    """(distance to the first surface (inf: none), hit its one-sided
    back): what _radiance_along says of a ray's first hit, without its
    light (the distance map's rays need no more)."""
    t, j, _, _ = closest_hit(bvh, stack, ox, oy, oz, dx, dy, dz, 0.0, np.inf)
    if j < 0:
        return np.inf, False
    hx, hy, hz = hit_normal(bvh, j)
    return t, not (-(hx * dx + hy * dy + hz * dz) > 0.0 or double[mat_of[bvh.tri_index[j]]])


@njit(cache=True, inline="always")
def _halton(i, base, rot):
    f = 1.0 / base
    r = 0.0
    inv = f
    while i > 0:
        r += f * (i % base)
        i //= base
        f *= inv
    r += rot
    return r - math.floor(r)


@njit(cache=True)
def _deltas(bvh, surf, stack, ox, oy, oz, seed, probe, n_emit, ray_density, out):
    """The lights a probe sees as deltas: rows (dx, dy, dz, r, g, b) of
    out, the direction and the irradiance at normal incidence, each behind
    its shadow ray (glass tints). First n_emit points on the area emitters
    (by power, stratified by a rotated Halton sequence; each carries L_e
    cos_e / (d^2 n p_A) under its MIS weight against the rays, p_A the
    point's area density), then every punctual light and sun. Returns the
    rows used."""
    k = 0
    ne = surf.emitters.shape[0]
    if ne > 0 and n_emit > 0:
        key = np.uint64(seed) ^ np.uint64(STREAM_PROBE_EMITTERS)
        r0, r1, r2 = rand01(key, probe, 0), rand01(key, probe, 1), rand01(key, probe, 2)
        for j in range(n_emit):
            tri, px, py, pz, p_tri, b1, b2 = sample_emitter(surf, (j + r0) / n_emit - math.floor((j + r0) / n_emit),
                                                            _halton(j + 1, 2, r1), _halton(j + 1, 3, r2))
            dx, dy, dz = px - ox, py - oy, pz - oz
            d2 = dx * dx + dy * dy + dz * dz
            if d2 <= 0.0 or p_tri <= 0.0:
                continue
            dist = math.sqrt(d2)
            dx, dy, dz = dx / dist, dy / dist, dz / dist
            nx, ny, nz = triangle_normal(surf.corners, tri)
            ce = -(nx * dx + ny * dy + nz * dz)   # the emitter's cosine toward the probe
            if ce < 0.0:
                if not surf.double_sided[surf.tri_material[tri]]:
                    continue
                ce = -ce
            er, eg, eb = emission_at(surf, tri, b1, b2)
            p_a = p_tri / surf.tri_area[tri]
            p_e = p_a * d2 / max(ce, 1e-300)
            f = ce / (d2 * n_emit * p_a) * (n_emit * p_e / (ray_density + n_emit * p_e))
            # short of the emitter: its own triangle is not in the way
            t0, t1, t2 = transmittance(bvh, stack, ox, oy, oz, dx, dy, dz, 0.0, dist * (1.0 - 1e-6))
            out[k, 0], out[k, 1], out[k, 2] = dx, dy, dz
            out[k, 3], out[k, 4], out[k, 5] = er * f * t0, eg * f * t1, eb * f * t2
            k += 1
    for li in range(surf.light_kind.shape[0]):
        dx, dy, dz, r, g, b = punctual_delta(bvh, surf, stack, ox, oy, oz, li)
        if r == 0.0 and g == 0.0 and b == 0.0:
            continue
        out[k, 0], out[k, 1], out[k, 2] = dx, dy, dz
        out[k, 3], out[k, 4], out[k, 5] = r, g, b
        k += 1
    return k


@njit(cache=True, inline="always")
def light_towards(surf, li, ox, oy, oz):
    """(dx, dy, dz, dist, e): the unit direction from o towards punctual
    light (or sun) li, its distance (inf: the sun) and the factor of its
    intensity that arrives at normal incidence, unshadowed (1 / d^2, a
    spot's falloff; 1 for the sun; e = 0: nothing arrives)."""
    kind = surf.light_kind[li]
    if kind == LIGHT_DIRECTIONAL:
        return -surf.light_dir[li, 0], -surf.light_dir[li, 1], -surf.light_dir[li, 2], np.inf, 1.0
    dx = surf.light_pos[li, 0] - ox
    dy = surf.light_pos[li, 1] - oy
    dz = surf.light_pos[li, 2] - oz
    dist = math.sqrt(dx * dx + dy * dy + dz * dz)
    if dist <= 0.0:
        return 0.0, 1.0, 0.0, 0.0, 0.0
    dx, dy, dz = dx / dist, dy / dist, dz / dist
    e = 1.0 / (dist * dist)
    if kind == LIGHT_SPOT:
        e *= spot_falloff(-(dx * surf.light_dir[li, 0] + dy * surf.light_dir[li, 1] + dz * surf.light_dir[li, 2]),
                          surf.light_cones[li, 0], surf.light_cones[li, 1])
    return dx, dy, dz, dist, e


@njit(cache=True, inline="always")
def punctual_delta(bvh, surf, stack, ox, oy, oz, li):
    """(dx, dy, dz, r, g, b): punctual light (or sun) li seen from o: the
    unit direction towards it and the irradiance it brings at normal
    incidence, behind its shadow ray (glass tints; 0 where shadowed): the
    delta a probe at o holds of it."""
    dx, dy, dz, dist, e = light_towards(surf, li, ox, oy, oz)
    if e <= 0.0:
        return dx, dy, dz, 0.0, 0.0, 0.0
    t0, t1, t2 = transmittance(bvh, stack, ox, oy, oz, dx, dy, dz, 0.0, dist)
    return (dx, dy, dz, surf.light_intensity[li, 0] * e * t0, surf.light_intensity[li, 1] * e * t1,
            surf.light_intensity[li, 2] * e * t2)


@njit(cache=True, parallel=True, error_model="numpy")
def probe_kernel(bvh, surf, double, mat_of, vnormal, vcentroid, vcut, pieces, bounced, points, first, dirs,
                 irr_dirs, depth_dirs, max_dist, n_emit, seed, sh, irr, depth, backs):
    """Per probe i at points[i] (its index in the grid: first + i):
    sh[i] (9, 3) the radiance's projection: the rays `dirs` reading the
    bounced light (4 pi / K sum L Y) plus the deltas (_deltas: E Y);
    irr[i] (IRR, IRR, 3) the irradiance at the normals irr_dirs (texel
    major) from the same rays and deltas; depth[i] (DEPTH, DEPTH, 2) the
    mean and mean square distance (capped at max_dist) over the
    depth_dirs rays of each texel (DEPTH_SUB^2 of them, texel-major);
    backs[i] the share of all its rays whose first hit is a one-sided
    surface's back."""
    n = points.shape[0]
    k_n = dirs.shape[0]
    per = DEPTH_SUB * DEPTH_SUB
    n_irr = irr_dirs.shape[0]
    ix = np.ascontiguousarray(irr_dirs[:, 0])
    iy = np.ascontiguousarray(irr_dirs[:, 1])
    iz = np.ascontiguousarray(irr_dirs[:, 2])
    for i in prange(n):
        stack = np.empty(STACK_SIZE, np.int32)
        y = np.empty(SH)
        acc = np.zeros((SH, 3))
        e0 = np.zeros(n_irr)
        e1 = np.zeros(n_irr)
        e2 = np.zeros(n_irr)
        delta = np.empty((n_emit + surf.light_kind.shape[0], 6))
        ox, oy, oz = points[i, 0], points[i, 1], points[i, 2]
        nb = 0
        f = 4.0 * math.pi / k_n
        density = k_n / (4.0 * math.pi)
        for k in range(k_n):
            dx, dy, dz = dirs[k, 0], dirs[k, 1], dirs[k, 2]
            r, g, b, t, back = _radiance_along(bvh, surf, stack, double, mat_of, vnormal, vcentroid, vcut, pieces,
                                               bounced, ox, oy, oz, dx, dy, dz, density, n_emit)
            if back:
                nb += 1
            if r == 0.0 and g == 0.0 and b == 0.0:
                continue
            sh_basis(dx, dy, dz, y)
            for c in range(SH):
                acc[c, 0] += r * y[c]
                acc[c, 1] += g * y[c]
                acc[c, 2] += b * y[c]
            # clamped rather than skipped, one channel an array: the loop over the normals vectorizes, and
            # adding r x 0 leaves each sum's bits as the skip did
            for q in range(n_irr):
                cq = max(dx * ix[q] + dy * iy[q] + dz * iz[q], 0.0)
                e0[q] += r * cq
                e1[q] += g * cq
                e2[q] += b * cq
        for c in range(SH):
            for ch in range(3):
                acc[c, ch] *= f
        for q in range(n_irr):
            e0[q] *= f
            e1[q] *= f
            e2[q] *= f
        m = _deltas(bvh, surf, stack, ox, oy, oz, seed, first + i, n_emit, density, delta)
        for k in range(m):
            dx, dy, dz = delta[k, 0], delta[k, 1], delta[k, 2]
            sh_basis(dx, dy, dz, y)
            for c in range(SH):
                for ch in range(3):
                    acc[c, ch] += delta[k, 3 + ch] * y[c]
            d0, d1, d2 = delta[k, 3], delta[k, 4], delta[k, 5]
            for q in range(n_irr):
                cq = max(dx * ix[q] + dy * iy[q] + dz * iz[q], 0.0)
                e0[q] += d0 * cq
                e1[q] += d1 * cq
                e2[q] += d2 * cq
        for c in range(SH):
            for ch in range(3):
                sh[i, c, ch] = acc[c, ch]
        for q in range(n_irr):
            irr[i, q // IRR, q % IRR, 0] = e0[q]
            irr[i, q // IRR, q % IRR, 1] = e1[q]
            irr[i, q // IRR, q % IRR, 2] = e2[q]
        for tex in range(DEPTH * DEPTH):
            s1 = s2 = 0.0
            for q in range(per):
                dd = depth_dirs[tex * per + q]
                t, back = _first_hit(bvh, stack, double, mat_of, ox, oy, oz, dd[0], dd[1], dd[2])
                if back:
                    nb += 1
                t = min(t, max_dist)
                s1 += t
                s2 += t * t
            depth[i, tex // DEPTH, tex % DEPTH, 0] = s1 / per
            depth[i, tex // DEPTH, tex % DEPTH, 1] = s2 / per
        backs[i] = nb / (k_n + DEPTH * DEPTH * per)


def texel_directions(size: int, sub: int = 1) -> np.ndarray:
    """(size^2 sub^2, 3): per octahedral texel (row v, column u), sub^2
    unit directions at the centres of its sub-texels."""
    out = np.empty((size * size * sub * sub, 3))
    k = 0
    for row in range(size):
        for col in range(size):
            for a in range(sub):
                for b in range(sub):
                    out[k] = oct_decode((col + (b + 0.5) / sub) / size, (row + (a + 0.5) / sub) / size)
                    k += 1
    return out


@dataclass(frozen=True)
class ProbeShot:
    """What every block of probes shares (sent to a worker once)."""
    bvh: object
    surf: object
    voxels: object          # solve.gather.GatherVoxels
    bounced: np.ndarray     # (n, 3) the voxels' bounced radiosity rho H
    dirs: np.ndarray
    irr_dirs: np.ndarray
    depth_dirs: np.ndarray
    max_dist: float
    n_emit: int
    seed: int


@dataclass(frozen=True)
class ProbeBlock:
    number: int
    first: int
    points: np.ndarray

    def describe(self) -> str:
        return f"probe block {self.number} ({len(self.points):,} probes)"


@dataclass(frozen=True)
class ProbePart:
    sh: np.ndarray
    irradiance: np.ndarray
    depth: np.ndarray
    backs: np.ndarray


PROBE_BLOCK = 1024   # probes per task (each its own: any split gives the same bits)


def probe_block(block: ProbeBlock, shot: ProbeShot) -> ProbePart:
    """The pure task: a block's probes gathered."""
    n = len(block.points)
    sh = np.zeros((n, SH, 3))
    irr = np.zeros((n, IRR, IRR, 3))
    depth = np.zeros((n, DEPTH, DEPTH, 2))
    backs = np.zeros(n)
    g = shot.voxels
    probe_kernel(shot.bvh, shot.surf, g.double, g.mat_of, g.normal, g.centroid, g.cut, g.pieces, shot.bounced,
                 np.ascontiguousarray(block.points, np.float64), int(block.first), shot.dirs, shot.irr_dirs,
                 shot.depth_dirs, shot.max_dist, int(shot.n_emit), int(shot.seed), sh, irr, depth, backs)
    return ProbePart(sh, irr, depth, backs)


def bake_probes(prepared, solution, grid, rays: int, seed: int = 0, executor=None, progress=None) -> ProbeGrid:
    """The probes of `grid` ((origin, spacing, dims): grid_for) gathered
    from the solution with `rays` rays each (ray_set)."""
    from ..solve.gather import GatherVoxels
    from ..tasks import run_tasks
    origin, spacing, dims = grid
    points = probe_positions(origin, spacing, dims)
    vox = solution.voxels
    bounced = np.ascontiguousarray(solution.radiosity - vox.emission, np.float64)   # the emitters: sampled
    shot = ProbeShot(prepared.bvh.arrays, prepared.surfaces.arrays, GatherVoxels.of(prepared, vox),
                     np.maximum(bounced, 0.0), ray_set(int(rays)), texel_directions(IRR),
                     texel_directions(DEPTH, DEPTH_SUB), MAX_DIST * spacing, EMITTER_SAMPLES, int(seed))
    blocks = [ProbeBlock(j, a, points[a:a + PROBE_BLOCK]) for j, a in enumerate(range(0, len(points), PROBE_BLOCK))]

    parts = run_tasks(executor, probe_block, blocks, shot, "probes",
                      None if progress is None else lambda j, _: progress(len(blocks[j].points)))
    sh = np.concatenate([p.sh for p in parts])
    irr = np.concatenate([p.irradiance for p in parts])
    depth = np.concatenate([p.depth for p in parts])
    backs = np.concatenate([p.backs for p in parts])
    return ProbeGrid(np.asarray(origin, np.float64), float(spacing), np.asarray(dims, np.int64),
                     sh.astype(np.float32), half_exact(np.maximum(irr, 0.0)), depth.astype(np.float32),
                     backs < BACKFACE_INVALID, int(rays))


HALF_MAX = 60000.0


def half_scale(values) -> float:
    """A power of two that brings values under HALF_MAX (1 where they are)."""
    peak = float(np.max(values)) if np.size(values) else 0.0
    return 1.0 if peak <= HALF_MAX else float(2.0 ** -np.ceil(np.log2(peak / HALF_MAX)))


def half_exact(values) -> np.ndarray:
    """float32 values as the bake file's float16 (times half_scale) holds
    them: what is baked is what is read back, bit for bit."""
    k = half_scale(values)
    return ((np.asarray(values, np.float64) * k).astype(np.float16).astype(np.float64) / k).astype(np.float32)
