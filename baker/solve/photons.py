"""First bounce by photons (docs/design.md section 5).

Photons leave the lights (area emitters by power, uniform on the triangle,
cosine-distributed; punctual lights by power and profile; a sun across the
scene's bounding disc; a sky from every direction of its domain), are
traced through the BVH to their first hit and deposit their power in the
voxel of the hit cell whose facing matches the side they hit:
H_1(x) = deposited power / area(x). They are stored, never reflected.
Where a light's photons start and with which power is defined by the
shared formulas of scene/surfaces.py, the same ones the path tracer uses.

Sampling is quasi-random and counter-based: photon i picks its light by a
stratified sample of the power CDF ((i + rotation) / n) and its point and
direction from the Halton sequence at index i (bases 2, 3, 5, 7, 11, 13),
each dimension shifted by a seeded rotation (Cranley-Patterson). The
photon set is a function of (seed, i) only: the same for any thread count
and any batch size, and far less noisy than independent random photons.
Photons are shot in fixed blocks of BLOCK indices (pure tasks an executor
may run anywhere: bake/executor.py); each block's deposits are summed in
photon order into its own partial sums, and the partials are added to
the voxels' in block order: the same sums for any thread or worker count.

Directional lights (a sun) cover the scene's whole bounding disc, and over
a building most of that lands on the outside of one-sided walls and is
lost. A pilot pass (1/16 of the photons, directional lights only) learns,
on a 64 x 64 grid across each light, where photons reach a voxel; the
light then sends 90% of its photons there and 10% evenly over the disc,
each weighted by the inverse of its probability (unbiased). In the
walkthrough this lands 754k of 1M photons instead of 89k.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from ..kernels.bvh import STACK_SIZE
from ..kernels.rng import STREAM_PHOTON_GLASS, STREAM_PHOTON_ROTATION, rand01
from ..kernels.sampling import cosine_hemisphere, frame, sample_cdf
from ..kernels.traverse import closest_hit, hit_normal
from ..scene.model import LightKind
from ..tasks import run_tasks
from ..scene.surfaces import (VOXEL_PASS, LIGHT_AREA, LIGHT_DIRECTIONAL, LIGHT_SKY, LIGHT_SPOT, emission_at,
                              sample_emitter, sky_solid_angle, spot_falloff, triangle_normal)
from ..voxels.lookup import voxel_of_hit

BLOCK = 1 << 16         # photons per block (a task, and a progress step); fixed: it sets the sums' order
GUIDE_CELLS = 64        # directional lights: G x G cells across the light
GUIDE_FLOOR = 0.1       # share of a directional light's photons spread evenly over its disc
MAX_GLASS = 64          # panes a photon goes through before it is dropped
PILOT_SHARE = 1 / 16    # pilot photons, as a share of the photon count (directional lights only)


@njit(cache=True, inline="always")
def radical_inverse(base, i):
    inv = 1.0 / base
    f = inv
    r = 0.0
    while i > 0:
        r += f * (i % base)
        i //= base
        f *= inv
    return r


@njit(cache=True, inline="always")
def _qmc(i, dim, base, rot):
    v = radical_inverse(base, i) + rot[dim]
    return v - math.floor(v)


@njit(cache=True)
def _emit(surf, i, rot, kind, j, power, eps, center, radius, guide, G):
    """Where photon i of light (kind, j) of power (3,) starts, where it
    goes, its power before the selection of the light (an area emitter:
    pi L_e at its point times its triangle's area over the triangle's
    probability; a guided sun: over its cell's; a spot: times its
    falloff) and the guide cell a sun photon left from (-1 otherwise).
    Returns (ox, oy, oz, dx, dy, dz, r, g, b, cell)."""
    if kind == LIGHT_AREA:
        # an area emitter triangle chosen by power, a point uniform on it, cosine-distributed
        tri, ox, oy, oz, p_tri, b1, b2 = sample_emitter(surf, _qmc(i, 1, 2, rot), _qmc(i, 2, 3, rot),
                                                        _qmc(i, 3, 5, rot))
        nx, ny, nz = triangle_normal(surf.corners, tri)
        mat = surf.tri_material[tri]
        sides = 2.0 if surf.double_sided[mat] else 1.0
        if sides == 2.0 and _qmc(i, 6, 13, rot) >= 0.5:
            nx, ny, nz = -nx, -ny, -nz
        dx, dy, dz, cos = cosine_hemisphere(_qmc(i, 4, 7, rot), _qmc(i, 5, 11, rot), nx, ny, nz)
        # pi L_e(point) area (x2 sides) over the triangle's probability: an emissive texture's pattern
        er, eg, eb = emission_at(surf, tri, b1, b2)
        f = math.pi * surf.tri_area[tri] * sides / p_tri
        return ox + eps * nx, oy + eps * ny, oz + eps * nz, dx, dy, dz, er * f, eg * f, eb * f, -1
    if kind == LIGHT_DIRECTIONAL:
        # from the square [-radius, radius]^2 across the light, cell c of G x G drawn by the guide
        # table, the power divided by G^2 times its probability (unbiased where the table is positive)
        dx, dy, dz = surf.light_dir[j, 0], surf.light_dir[j, 1], surf.light_dir[j, 2]
        t, b = frame(dx, dy, dz)
        u1 = _qmc(i, 2, 3, rot)
        c = sample_cdf(guide, u1)
        g0 = guide[c - 1] if c > 0 else 0.0
        pc = (guide[c] - g0) / guide[-1]
        fx = min(max((u1 * guide[-1] - g0) / (guide[c] - g0), 0.0), 1.0)
        a1 = radius * (-1.0 + 2.0 * ((c % G) + fx) / G)
        a2 = radius * (-1.0 + 2.0 * ((c // G) + _qmc(i, 3, 5, rot)) / G)
        ox = center[0] - 2.0 * radius * dx + a1 * t[0] + a2 * b[0]
        oy = center[1] - 2.0 * radius * dy + a1 * t[1] + a2 * b[1]
        oz = center[2] - 2.0 * radius * dz + a1 * t[2] + a2 * b[2]
        f = 1.0 / (G * G * pc)
        return ox, oy, oz, dx, dy, dz, power[0] * f, power[1] * f, power[2] * f, c
    if kind == LIGHT_SKY:
        # a direction w towards the sky uniform over its domain, then a point on the disc of
        # radius `radius` across w, 2 radius from the centre: every photon carries L pi R^2 Omega / n
        up = surf.sky_up
        ct = _qmc(i, 2, 3, rot) if surf.sky_mode == 1 else 1.0 - 2.0 * _qmc(i, 2, 3, rot)
        st = math.sqrt(max(0.0, 1.0 - ct * ct))
        phi = 2.0 * math.pi * _qmc(i, 3, 5, rot)
        t, b = frame(up[0], up[1], up[2])
        wx = st * math.cos(phi) * t[0] + st * math.sin(phi) * b[0] + ct * up[0]
        wy = st * math.cos(phi) * t[1] + st * math.sin(phi) * b[1] + ct * up[1]
        wz = st * math.cos(phi) * t[2] + st * math.sin(phi) * b[2] + ct * up[2]
        t, b = frame(wx, wy, wz)
        r = radius * math.sqrt(_qmc(i, 4, 7, rot))
        psi = 2.0 * math.pi * _qmc(i, 5, 11, rot)
        a1, a2 = r * math.cos(psi), r * math.sin(psi)
        ox = center[0] + 2.0 * radius * wx + a1 * t[0] + a2 * b[0]
        oy = center[1] + 2.0 * radius * wy + a1 * t[1] + a2 * b[1]
        oz = center[2] + 2.0 * radius * wz + a1 * t[2] + a2 * b[2]
        return ox, oy, oz, -wx, -wy, -wz, power[0], power[1], power[2], -1
    # point and spot: uniform over the sphere, or over the spot's outer cone, weighted by its falloff
    ox, oy, oz = surf.light_pos[j, 0], surf.light_pos[j, 1], surf.light_pos[j, 2]
    cmin = surf.light_cones[j, 1] if kind == LIGHT_SPOT else -1.0
    ct = 1.0 - _qmc(i, 2, 3, rot) * (1.0 - cmin)
    st = math.sqrt(max(0.0, 1.0 - ct * ct))
    phi = 2.0 * math.pi * _qmc(i, 3, 5, rot)
    ax, ay, az = 0.0, 0.0, 1.0
    f = 1.0
    if kind == LIGHT_SPOT:
        ax, ay, az = surf.light_dir[j, 0], surf.light_dir[j, 1], surf.light_dir[j, 2]
        f = spot_falloff(ct, surf.light_cones[j, 0], surf.light_cones[j, 1])
    t, b = frame(ax, ay, az)
    lx, ly = st * math.cos(phi), st * math.sin(phi)
    return ox, oy, oz, lx * t[0] + ly * b[0] + ct * ax, lx * t[1] + ly * b[1] + ct * ay, \
        lx * t[2] + ly * b[2] + ct * az, power[0] * f, power[1] * f, power[2] * f, -1


@njit(cache=True, parallel=True)
def shoot(bvh, surf, light_cdf, light_kind, light_ref, light_power, i0, i1, n, rot, eps, center, radius, guide,
          guide_row):
    """Traces photons i0 .. i1 - 1 of n. light_kind: LIGHT_AREA (all area
    emitters, light_ref unused) or a punctual kind or LIGHT_SKY, light_ref
    the light's index; light_power (nl, 3) the power of each entry; guide
    (rows, G*G) cumulative cell tables of directional lights, guide_row
    their row per entry. Returns, per photon: hit point (m, 3), power
    (m, 3), ok (m,) (False: escaped or absorbed by a one-sided back), the
    triangle hit and whether its back, the guide cell it left from (-1:
    not a sun) and its light's entry. Thin glass (transmission t): the
    photon goes through glass the voxels leave out (t >= VOXEL_PASS)
    tinted by t x albedo; at glass that is a voxel it lands with
    probability 1 - t (power / (1 - t): the glass's irradiance) and else
    goes through tinted by its albedo."""
    m = i1 - i0
    glass_key = np.uint64(rot[0] * 9007199254740992.0) ^ np.uint64(STREAM_PHOTON_GLASS)
    point = np.zeros((m, 3))
    power = np.zeros((m, 3))
    ok = np.zeros(m, np.bool_)
    hit_tri = np.full(m, -1, np.int32)
    hit_back = np.zeros(m, np.bool_)
    cell = np.full(m, -1, np.int64)
    source = np.empty(m, np.int32)
    G = int(math.sqrt(guide.shape[1]) + 0.5)
    total = light_cdf[-1]
    chunk = 1024
    for c in prange((m + chunk - 1) // chunk):
        stack = np.empty(STACK_SIZE, np.int32)
        for k in range(c * chunk, min(m, (c + 1) * chunk)):
            i = i0 + k
            u = (i + rot[0]) / n
            u = u - math.floor(u)
            li = sample_cdf(light_cdf, u)
            source[k] = li
            p_sel = (light_cdf[li] - (light_cdf[li - 1] if li > 0 else 0.0)) / total
            kind = light_kind[li]
            ox, oy, oz, dx, dy, dz, pr, pg, pb, cl = _emit(surf, i, rot, kind, light_ref[li], light_power[li], eps,
                                                           center, radius, guide[guide_row[li]], G)
            cell[k] = cl
            f = 1.0 / (p_sel * n)
            pr, pg, pb = pr * f, pg * f, pb * f
            th, jh, uh, vh = closest_hit(bvh, stack, ox, oy, oz, dx, dy, dz, 0.0, np.inf)
            passes = 0
            while jh >= 0 and passes < MAX_GLASS:   # thin glass: through it, tinted
                gm = surf.tri_material[bvh.tri_index[jh]]
                tt = surf.transmission[gm]
                if tt <= 0.0:
                    break
                if tt < VOXEL_PASS:   # a voxel: it lands there with probability 1 - t, else goes through
                    if rand01(glass_key, i, passes) >= tt:
                        f = 1.0 / (1.0 - tt)
                        pr, pg, pb = pr * f, pg * f, pb * f
                        break
                    tt = 1.0
                pr, pg, pb = pr * tt * surf.albedo[gm, 0], pg * tt * surf.albedo[gm, 1], pb * tt * surf.albedo[gm, 2]
                ox, oy, oz = ox + (th + eps) * dx, oy + (th + eps) * dy, oz + (th + eps) * dz
                th, jh, uh, vh = closest_hit(bvh, stack, ox, oy, oz, dx, dy, dz, 0.0, np.inf)
                passes += 1
            if jh < 0 or passes == MAX_GLASS or (pr <= 0.0 and pg <= 0.0 and pb <= 0.0):
                continue
            tri_h = bvh.tri_index[jh]
            hx, hy, hz = hit_normal(bvh, jh)
            if hx * dx + hy * dy + hz * dz > 0.0:
                if not surf.double_sided[surf.tri_material[tri_h]]:
                    continue  # the back of a one-sided surface absorbs
                hit_back[k] = True
            hit_tri[k] = tri_h
            point[k, 0], point[k, 1], point[k, 2] = ox + th * dx, oy + th * dy, oz + th * dz
            power[k, 0], power[k, 1], power[k, 2] = pr, pg, pb
            ok[k] = True
    return point, power, ok, hit_tri, hit_back, cell, source


@njit(cache=True, parallel=True)
def find_voxels(points, ok, hit_tri, hit_back, pieces):
    """Voxel of each photon hit (the piece of the side it hit), -1 if none."""
    n = points.shape[0]
    out = np.full(n, -1, np.int64)
    for i in prange(n):
        if ok[i]:
            out[i] = voxel_of_hit(hit_tri[i], hit_back[i], points[i, 0], points[i, 1], points[i, 2], pieces)
    return out


@njit(cache=True)
def deposit(vi, power, points, dep, cen):
    """Adds each landed photon's power to its voxel (dep) and its point
    times its power (summed over channels) to the centroid sums (cen), in
    photon order: the same sums for any batch size and thread count."""
    landed = 0
    for k in range(vi.shape[0]):
        v = vi[k]
        if v < 0:
            continue
        landed += 1
        lum = power[k, 0] + power[k, 1] + power[k, 2]
        for c in range(3):
            dep[v, c] += power[k, c]
            cen[v, c] += points[k, c] * lum
    return landed


def light_table(scene, surfaces):
    """The lights photons are drawn from: area emitters (one entry), each
    punctual light and the sky, with their kind code, index and power (W,
    RGB; the area entry's row is its total power, each photon takes its own
    triangle's radiance). Also the scene's centre and bounding radius."""
    kinds, refs, powers = [], [], []
    if surfaces.n_emitters:
        kinds.append(LIGHT_AREA)
        refs.append(-1)
        powers.append(surfaces.emitted_power)
    lo, hi = scene.bounds()
    radius = float(np.linalg.norm(hi - lo)) / 2 or 1.0
    for j, light in enumerate(scene.lights):
        i = np.asarray(light.intensity, np.float64)
        if light.kind == "point":
            p = 4 * np.pi * i
        elif light.kind == "spot":
            p = 2 * np.pi * (1 - np.cos(light.outer_cone)) * i  # falloff applied per photon
        else:
            p = 4.0 * radius * radius * i  # over the square the photons leave from
        kinds.append(int(LightKind.of(light.kind)))
        refs.append(j)
        powers.append(p)
    sky = surfaces.arrays.sky_mode
    if sky and surfaces.arrays.sky_radiance.max() > 0:
        # radiance L over solid angle Omega through a disc of radius R across each direction
        kinds.append(LIGHT_SKY)
        refs.append(-1)
        powers.append(surfaces.arrays.sky_radiance * np.pi * radius ** 2 * sky_solid_angle(sky))
    powers = np.array(powers, np.float64).reshape(-1, 3)
    return np.array(kinds, np.int32), np.array(refs, np.int32), powers, (lo + hi) / 2, radius


def _disc_cells(g):
    """(g*g,) bool: the cells of the light's square that meet the disc the
    scene's bounding sphere casts (nothing outside it can be hit)."""
    c = (np.arange(g) + 0.5) / g * 2 - 1
    x, y = np.meshgrid(c, c)  # y: rows (cell // g), x: columns (cell % g)
    half = 1.0 / g
    near = np.hypot(np.maximum(np.abs(x) - half, 0), np.maximum(np.abs(y) - half, 0))
    return (near <= 1.0).reshape(-1)


def _voxels_hit(voxels, pts, ok, tri, back):
    return find_voxels(pts, ok, tri, back, voxels.lookup())


def _guides(surfaces, bvh, voxels, kinds, refs, powers, center, radius, n, rot, eps):
    """Per light, the cumulative cell table directional photons are drawn
    from. A pilot pass (directional lights only, uniform over the disc)
    finds where photons reach a voxel; each directional light then sends
    (1 - GUIDE_FLOOR) of its photons in proportion to the power that landed
    per cell and GUIDE_FLOOR evenly over its disc (so that no cell that can
    light the scene has probability 0: the estimate stays unbiased). A sun
    over a building with a few windows lands 5-20x more of its photons."""
    g = GUIDE_CELLS
    disc = _disc_cells(g).astype(np.float64)
    uniform = np.cumsum(disc)[None, :]
    rows = np.zeros(len(kinds), np.int32)
    sun = np.nonzero(kinds == LIGHT_DIRECTIONAL)[0]
    if len(sun) == 0:
        return uniform, rows
    m = max(4096, int(n * PILOT_SHARE))
    cdf = np.cumsum(powers[sun].sum(axis=1))
    prot = (rot + 0.5) % 1.0  # another rotation of the same sequence: the pilot's own photons
    pts, pw, ok, tri, back, cell, which = shoot(bvh.arrays, surfaces.arrays, cdf, kinds[sun], refs[sun], powers[sun],
                                                0, int(m), int(m), prot, eps, center, radius, uniform,
                                                np.zeros(len(sun), np.int32))
    landed = _voxels_hit(voxels, pts, ok, tri, back) >= 0
    tables = [uniform[0]]
    for r, li in enumerate(sun, start=1):
        sel = landed & (which == r - 1)
        # float64 even when no pilot photon landed (bincount of nothing is integer)
        w = np.bincount(cell[sel], weights=pw[sel].sum(axis=1), minlength=g * g).astype(np.float64)
        w *= disc
        rows[li] = r
        if w.sum() <= 0:
            tables.append(uniform[0])
            continue
        mix = (1 - GUIDE_FLOOR) * w / w.sum() + GUIDE_FLOOR * disc / disc.sum()
        tables.append(np.cumsum(mix))
    return np.array(tables), rows


@dataclass(frozen=True)
class PhotonShot:
    """What every block of a photon pass shares: the kernels' BVH,
    surfaces and voxel lookup, the light table (cdf, kinds, refs,
    powers), the photon count n, the sequence's rotation, the ray offset,
    the lights' disc (center, radius) and the directional lights' guide
    tables (guide, rows)."""
    bvh: object
    surf: object
    lookup: object
    cdf: np.ndarray
    kinds: np.ndarray
    refs: np.ndarray
    powers: np.ndarray
    n: int
    rot: np.ndarray
    eps: float
    center: np.ndarray
    radius: float
    guide: np.ndarray
    rows: np.ndarray


@dataclass(frozen=True)
class PhotonBlock:
    """Photons i0 .. i1 - 1: one task."""
    number: int
    i0: int
    i1: int

    def describe(self) -> str:
        return f"photon block {self.number} (photons {self.i0:,} to {self.i1 - 1:,})"


@dataclass(frozen=True)
class PhotonPart:
    """A block's deposits: the voxels it reached (sorted), the power
    (k, 3) and power-weighted point sums (k, 3) it left in each, summed in
    photon order, and the photons that landed."""
    voxels: np.ndarray
    power: np.ndarray
    centroid: np.ndarray
    landed: int


def shoot_block(block: PhotonBlock, shot: PhotonShot) -> PhotonPart:
    """The pure task: a block's photons traced and deposited."""
    pts, pw, ok, tri, back, _, _ = shoot(shot.bvh, shot.surf, shot.cdf, shot.kinds, shot.refs, shot.powers, block.i0,
                                         block.i1, shot.n, shot.rot, shot.eps, shot.center, shot.radius, shot.guide,
                                         shot.rows)
    vi = find_voxels(pts, ok, tri, back, shot.lookup)
    reached, row = np.unique(vi[vi >= 0], return_inverse=True)
    rows = np.full(len(vi), -1, np.int64)
    rows[vi >= 0] = row
    dep, cen = np.zeros((len(reached), 3)), np.zeros((len(reached), 3))
    landed = deposit(rows, pw, pts, dep, cen)
    return PhotonPart(reached.astype(np.int64), dep, cen, int(landed))


def shoot_photons(scene, surfaces, bvh, voxels, n, seed=0, progress=None, executor=None):
    """Returns (deposited power (nv, 3), photon-weighted centroid sums (nv, 3),
    photons landed, emitted power (3,)). `progress(k)` after each block of
    k photons; the blocks on `executor` (bake/executor.py; None: here)."""
    kinds, refs, powers, center, radius = light_table(scene, surfaces)
    nv = len(voxels)
    dep, cen = np.zeros((nv, 3)), np.zeros((nv, 3))
    if len(kinds) == 0 or n == 0 or powers.sum() <= 0:
        return dep, cen, 0, np.zeros(3)
    cdf = np.cumsum(powers.sum(axis=1))
    rot = np.array([rand01(seed, STREAM_PHOTON_ROTATION, d) for d in range(8)])
    eps = 1e-7 * float(np.abs(scene.vertices).max() or 1.0)
    guide, rows = _guides(surfaces, bvh, voxels, kinds, refs, powers, center, radius, n, rot, eps)
    shot = PhotonShot(bvh.arrays, surfaces.arrays, voxels.lookup(), cdf, kinds, refs, powers, int(n), rot, eps,
                      np.asarray(center, np.float64), float(radius), guide, rows)
    blocks = [PhotonBlock(b, i0, min(int(n), i0 + BLOCK)) for b, i0 in enumerate(range(0, int(n), BLOCK))]

    parts = run_tasks(executor, shoot_block, blocks, shot, "photons",
                      None if progress is None else lambda j, _: progress(blocks[j].i1 - blocks[j].i0))
    landed = 0
    for part in parts:   # in block order: the same sums wherever the blocks ran
        dep[part.voxels] += part.power
        cen[part.voxels] += part.centroid
        landed += part.landed
    return dep, cen, landed, powers.sum(axis=0)
