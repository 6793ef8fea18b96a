"""Irradiance from the probe grid at any point and normal (the reference
of the viewer's shader: shaders/probes.glsl computes the same).

A point x with normal n reads the eight probes of the grid cell that
holds it (clamped to the grid), each weighted by
- its trilinear weight (DDGI's backface term, which favours the probes
  in front of the surface, is left out: the light field a moving object
  samples is the room's, which the probes behind its surface hold as
  well, and beside a lamp the term bent the Cornell sphere's sides 20%
  dark; what it was for, probes behind walls, the two tests below do);
- Chebyshev's visibility bound against the probe's distance moments in
  the direction of x (lifted BIAS spacings along n): 1 where x is nearer
  than the mean distance, else var / (var + (d - mean)^2), cubed, and 0
  under CRUSH (a probe behind a wall counts for nothing);
- 0 for an invalid probe.
Each probe's E(n) is its irradiance map read at n (bilinear over the
octahedral texels, across the map's folded edges as the octahedron
joins them); the result is the weighted mean of the probes, and 0 where
no probe counts. (probe_irradiance_sh reads the order-2 SH instead, as
clients that take SH do.) With ProbeLights, the sun, the punctual lights
and the lamps (lamps.py) come out of each probe's map read and in at the
point itself behind its own shadow rays: a probe grid cannot hold a
shadow's edge or a lamp's near field.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from collections import namedtuple
from dataclasses import dataclass

from ..kernels.bvh import STACK_SIZE
from ..kernels.traverse import transmittance
from .gather import from_map, light_towards, punctual_delta, to_map
from .lamps import LampArrays, lamp_above, lamp_arrays, lamp_factor, lamp_sees, lamps_rest

# the scene's punctual lights and sun as the kernels here read them (the fields of scene.surfaces' arrays)
LightArrays = namedtuple("LightArrays", "light_kind light_pos light_dir light_intensity light_cones")


def light_arrays(surf=None) -> LightArrays:
    """The punctual lights of surfaces' arrays `surf` (None: no light)."""
    if surf is None:
        return LightArrays(np.zeros(0, np.int32), np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 3)),
                           np.zeros((0, 2)))
    return LightArrays(surf.light_kind, surf.light_pos, surf.light_dir, surf.light_intensity, surf.light_cones)

BIAS = 0.05      # spacings along the normal, for the visibility test
CRUSH = 0.05     # visibility weights below this count for nothing
MIN_VAR = 1e-4   # spacing^2: the least variance the test assumes


def probe_irradiance_sh(sh, normals) -> np.ndarray:
    """(n, 3) E(normals) of SH radiance coefficients sh (n, 9, 3),
    unclamped."""
    from .gather import SH_BAND, sh_basis_np
    y = sh_basis_np(np.asarray(normals, np.float64)) * SH_BAND[None, :]
    return np.einsum("nc,nck->nk", y, sh.astype(np.float64))


def _wrap(row, col, size):
    """Texel (row, col), one beyond the map's edge at most, folded back:
    the octahedral map's edge texels meet their mirror images across each
    edge (DDGI's border), the corners meet the opposite corner."""
    out_r = (row < 0) | (row >= size)
    out_c = (col < 0) | (col >= size)
    r = np.where(out_c & ~out_r, size - 1 - row, row)
    c = np.where(out_r & ~out_c, size - 1 - col, col)
    r = np.where(out_r, np.where(row < 0, 0, size - 1), r)
    c = np.where(out_c, np.where(col < 0, 0, size - 1), c)
    both = out_r & out_c
    r = np.where(both, np.where(row < 0, size - 1, 0), r)
    c = np.where(both, np.where(col < 0, size - 1, 0), c)
    return r, c


def oct_uv(d):
    """Octahedral (u, v) in [0, 1]^2 of unit scene directions d (n, 3), in
    the maps' frame (gather.MAP_FRAME)."""
    from .gather import MAP_FRAME
    d = np.asarray(d, np.float64) @ MAP_FRAME.T
    s = np.abs(d).sum(axis=1)
    px, py = d[:, 0] / s, d[:, 1] / s
    neg = d[:, 2] < 0
    qx = (1 - np.abs(py)) * np.where(px >= 0, 1.0, -1.0)
    qy = (1 - np.abs(px)) * np.where(py >= 0, 1.0, -1.0)
    px, py = np.where(neg, qx, px), np.where(neg, qy, py)
    return 0.5 * (px + 1), 0.5 * (py + 1)


def irradiance_map_at(maps, normals) -> np.ndarray:
    """(n, 3): maps (n, S, S, 3) octahedral irradiance maps read at unit
    normals (n, 3), bilinear between texel centres."""
    size = maps.shape[1]
    u, v = oct_uv(np.asarray(normals, np.float64))
    x, y = u * size - 0.5, v * size - 0.5
    c0, r0 = np.floor(x).astype(np.int64), np.floor(y).astype(np.int64)
    fx, fy = x - c0, y - r0
    out = np.zeros((len(maps), 3))
    k = np.arange(len(maps))
    for dr, dc, w in ((0, 0, (1 - fx) * (1 - fy)), (0, 1, fx * (1 - fy)), (1, 0, (1 - fx) * fy), (1, 1, fx * fy)):
        r, c = _wrap(r0 + dr, c0 + dc, size)
        out += w[:, None] * maps[k, r, c].astype(np.float64)
    return out


def oct_texel(d, size):
    """(row, col) of unit directions d (n, 3) in a size x size octahedral map."""
    u, v = oct_uv(d)
    col = np.clip((u * size).astype(np.int64), 0, size - 1)
    row = np.clip((v * size).astype(np.int64), 0, size - 1)
    return row, col


@njit(cache=True)
def _transmitted(bvh, a, u, dist, out):
    """out[i] the largest channel of the light that crosses from a[i]
    along u[i] for dist[i]; one thread: an object's few dozen rays per
    frame must not leave numba's workers spinning beside the viewer's
    software rasterizer."""
    stack = np.empty(STACK_SIZE, np.int32)
    for i in range(a.shape[0]):
        t0, t1, t2 = transmittance(bvh, stack, a[i, 0], a[i, 1], a[i, 2], u[i, 0], u[i, 1], u[i, 2], 0.0, dist[i])
        out[i] = max(t0, t1, t2)


def _sees(bvh, a, b) -> np.ndarray:
    """(n,) 1.0 where nothing opaque lies between a[i] and b[i], else 0."""
    d = b - a
    dist = np.linalg.norm(d, axis=1)
    u = d / np.maximum(dist, 1e-300)[:, None]
    t = np.zeros(len(a))
    _transmitted(bvh, np.ascontiguousarray(a, np.float64), np.ascontiguousarray(u), np.ascontiguousarray(dist), t)
    return np.where((dist <= 0) | (t > 0), 1.0, 0.0)


def interpolate(grid, points, normals, anchors=None, bvh=None, lights=None) -> np.ndarray:
    """(n, 3) irradiance at points (n, 3) with unit normals (n, 3).
    anchors (n, 3) with bvh (the scene's BVHArrays): each point belongs
    to an object whose centre is its anchor, and a probe that the anchor
    does not see (a ray from it meets a surface first) counts for
    nothing: the exact test the distance moments only approximate, which
    keeps an object beside a wall lit by its own side alone. lights
    (ProbeLights): the punctual lights and sun taken out of each probe's
    map and added at each point behind its own shadow ray."""
    points = np.asarray(points, np.float64)
    normals = np.asarray(normals, np.float64)
    dims = np.asarray(grid.dims, np.int64)
    s = float(grid.spacing)
    g = (points - grid.origin) / s
    base = np.clip(np.floor(g).astype(np.int64), 0, np.maximum(dims - 2, 0))
    frac = np.clip(g - base, 0.0, 1.0)
    frac = np.where(dims[None, :] > 1, frac, 0.0)
    lifted = points + BIAS * s * normals
    total = np.zeros((len(points), 3))
    weight = np.zeros(len(points))
    size = grid.depth.shape[1]
    for corner in range(8):
        off = np.array([(corner >> a) & 1 for a in range(3)])
        idx = np.minimum(base + off, dims - 1)
        w = np.prod(np.where(off == 1, frac, 1.0 - frac), axis=1)
        flat = idx[:, 0] + dims[0] * (idx[:, 1] + dims[1] * idx[:, 2])
        p = grid.origin + s * idx
        v = lifted - p
        d = np.linalg.norm(v, axis=1)
        row, col = oct_texel(v / np.maximum(d, 1e-12)[:, None], size)
        mean = grid.depth[flat, row, col, 0].astype(np.float64)
        mean2 = grid.depth[flat, row, col, 1].astype(np.float64)
        var = np.maximum(mean2 - mean * mean, MIN_VAR * s * s)
        cheb = np.where(d <= mean, 1.0, var / (var + (d - mean) ** 2)) ** 3
        cheb = np.where(cheb < CRUSH, 0.0, cheb)
        w = w * cheb * grid.valid[flat]
        if anchors is not None:
            w = w * _sees(bvh, np.asarray(anchors, np.float64), p)
        total += w[:, None] * irradiance_map_at(_maps(grid, lights)[flat], normals)
        weight += w
    out = np.maximum(np.where(weight[:, None] > 0, total / np.where(weight > 0, weight, 1.0)[:, None], 0.0), 0.0)
    if lights is not None and lights.count:
        _points_lights(lights.bvh, lights.lights, lights.lamps, lights.rays, np.ascontiguousarray(points),
                       np.ascontiguousarray(normals), out)
    return out


def object_map(grid, center, bvh, lights=None) -> np.ndarray:
    """(S, S, 3) float32: the irradiance map of a small object at
    `center`: the probes' maps weighted as interpolate weighs them at the
    centre itself (trilinear, Chebyshev toward the centre, valid, seen
    from it). Read at a normal n it is interpolate(grid, center, n) (the
    read is linear in the maps): what the viewer shades an object no
    larger than a probe cell with, one map read per pixel. With `lights`
    the punctual lights and sun come out of the probes' maps and in as
    seen from the centre, at each texel's normal."""
    c = np.asarray(center, np.float64)[None]
    dims = np.asarray(grid.dims, np.int64)
    s = float(grid.spacing)
    g = (c - grid.origin) / s
    base = np.clip(np.floor(g).astype(np.int64), 0, np.maximum(dims - 2, 0))
    frac = np.where(dims[None, :] > 1, np.clip(g - base, 0.0, 1.0), 0.0)
    size = grid.depth.shape[1]
    out = np.zeros(grid.irradiance.shape[1:], np.float64)
    total = 0.0
    for corner in range(8):
        off = np.array([(corner >> a) & 1 for a in range(3)])
        idx = np.minimum(base + off, dims - 1)
        flat = int((idx[:, 0] + dims[0] * (idx[:, 1] + dims[1] * idx[:, 2]))[0])
        p = grid.origin + s * idx
        w = float(np.prod(np.where(off == 1, frac, 1.0 - frac)))
        v = c - p
        d = float(np.linalg.norm(v))
        row, col = oct_texel(v / max(d, 1e-12), size)
        mean, mean2 = (float(x) for x in grid.depth[flat, row[0], col[0]])
        var = max(mean2 - mean * mean, MIN_VAR * s * s)
        cheb = 1.0 if d <= mean else (var / (var + (d - mean) ** 2)) ** 3
        cheb = 0.0 if cheb < CRUSH else cheb
        w *= cheb * float(grid.valid[flat]) * float(_sees(bvh, c, p)[0])
        out += w * _maps(grid, lights)[flat].astype(np.float64)
        total += w
    out = out / total if total > 0 else out
    if lights is not None and lights.count:
        out = np.maximum(out, 0.0)
        texdirs = lights.texdirs
        add = np.zeros((len(texdirs), 3))
        _center_lights(lights.bvh, lights.lights, lights.lamps, lights.rays, c[0], np.ascontiguousarray(texdirs),
                       add)
        out = out + add.reshape(out.shape)
    return out.astype(np.float32)


@njit(cache=True, inline="always")
def _oct_col_row(x, y, z, size):
    """Octahedral (u, v) * size of unit direction (x, y, z) (oct_uv)."""
    x, y, z = to_map(x, y, z)
    s = abs(x) + abs(y) + abs(z)
    px, py = x / s, y / s
    if z < 0.0:
        px, py = (1.0 - abs(py)) * (1.0 if px >= 0.0 else -1.0), (1.0 - abs(px)) * (1.0 if py >= 0.0 else -1.0)
    return 0.5 * (px + 1.0) * size, 0.5 * (py + 1.0) * size


@njit(cache=True, inline="always")
def _wrap1(row, col, size):
    """_wrap for one texel."""
    out_r = row < 0 or row >= size
    out_c = col < 0 or col >= size
    r = size - 1 - row if (out_c and not out_r) else row
    c = size - 1 - col if (out_r and not out_c) else col
    if out_r:
        r = 0 if row < 0 else size - 1
    if out_c:
        c = 0 if col < 0 else size - 1
    if out_r and out_c:
        r = size - 1 if row < 0 else 0
        c = size - 1 if col < 0 else 0
    return r, c


@njit(cache=True, inline="always")
def _oct_bilinear(x, y, z, size):
    """(ra, ca, rb, cb, rc, cc, rd, cd, wa, wb, wc, wd): the four texels
    (row, column) of a size x size octahedral map around unit direction
    (x, y, z), folded across its edges (_wrap1), and their bilinear
    weights: irradiance_map_at's read."""
    u, v = _oct_col_row(x, y, z, size)
    fx, fy = u - 0.5, v - 0.5
    c0, r0 = int(np.floor(fx)), int(np.floor(fy))
    fx, fy = fx - c0, fy - r0
    ra, ca = _wrap1(r0, c0, size)
    rb, cb = _wrap1(r0, c0 + 1, size)
    rc, cc = _wrap1(r0 + 1, c0, size)
    rd, cd = _wrap1(r0 + 1, c0 + 1, size)
    return ra, ca, rb, cb, rc, cc, rd, cd, (1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy


@njit(cache=True, inline="always")
def _point_irradiance(irr, depth, seen, origin, spacing, dims, x, n, base, frac):
    """(r, g, b): interpolate's sum at point x (3,) with unit normal n
    (3,), its probes weighted by seen[probe] (the anchor test, made
    beforehand); base (3,) int64 and frac (3,) scratch; irr the probes'
    maps (or ProbeLights.rest)."""
    isz, dsz = irr.shape[1], depth.shape[1]
    for k in range(3):
        g = (x[k] - origin[k]) / spacing
        b = min(max(int(np.floor(g)), 0), max(dims[k] - 2, 0))
        base[k] = b
        frac[k] = min(max(g - b, 0.0), 1.0) if dims[k] > 1 else 0.0
    lx, ly, lz = x[0] + BIAS * spacing * n[0], x[1] + BIAS * spacing * n[1], x[2] + BIAS * spacing * n[2]
    # the normal's texel in the probes' irradiance maps, as irradiance_map_at reads it
    ra, ca, rb, cb, rc, cc, rd, cd, wa, wb, wc, wd = _oct_bilinear(n[0], n[1], n[2], isz)
    t0 = t1 = t2 = 0.0
    total = 0.0
    for corner in range(8):
        i0 = min(base[0] + (corner & 1), dims[0] - 1)
        i1 = min(base[1] + ((corner >> 1) & 1), dims[1] - 1)
        i2 = min(base[2] + ((corner >> 2) & 1), dims[2] - 1)
        flat = i0 + dims[0] * (i1 + dims[1] * i2)
        if seen[flat] == 0:
            continue
        w = (frac[0] if corner & 1 else 1.0 - frac[0]) * (frac[1] if (corner >> 1) & 1 else 1.0 - frac[1]) \
            * (frac[2] if (corner >> 2) & 1 else 1.0 - frac[2])
        vx = lx - (origin[0] + spacing * i0)
        vy = ly - (origin[1] + spacing * i1)
        vz = lz - (origin[2] + spacing * i2)
        d = np.sqrt(vx * vx + vy * vy + vz * vz)
        dd = max(d, 1e-12)
        du, dv = _oct_col_row(vx / dd, vy / dd, vz / dd, dsz)
        dc, dr = min(max(int(du), 0), dsz - 1), min(max(int(dv), 0), dsz - 1)
        mean, mean2 = float(depth[flat, dr, dc, 0]), float(depth[flat, dr, dc, 1])
        var = max(mean2 - mean * mean, MIN_VAR * spacing * spacing)
        cheb = 1.0 if d <= mean else var / (var + (d - mean) * (d - mean))
        cheb = cheb * cheb * cheb
        if cheb < CRUSH:
            continue
        w *= cheb
        e0 = wa * irr[flat, ra, ca, 0] + wb * irr[flat, rb, cb, 0] + wc * irr[flat, rc, cc, 0] + wd * irr[flat, rd, cd, 0]
        e1 = wa * irr[flat, ra, ca, 1] + wb * irr[flat, rb, cb, 1] + wc * irr[flat, rc, cc, 1] + wd * irr[flat, rd, cd, 1]
        e2 = wa * irr[flat, ra, ca, 2] + wb * irr[flat, rb, cb, 2] + wc * irr[flat, rc, cc, 2] + wd * irr[flat, rd, cd, 2]
        t0 += w * e0
        t1 += w * e1
        t2 += w * e2
        total += w
    if total > 0.0:
        return max(t0 / total, 0.0), max(t1 / total, 0.0), max(t2 / total, 0.0)
    return 0.0, 0.0, 0.0


@njit(cache=True, inline="always")
def _lights_at(surf, lamps, x, n, vis_r, vis_g, vis_b):
    """(r, g, b): the punctual lights', sun's and lamps' irradiance at x
    (3,) with normal n (3,), each times its transmittance vis_*[l] from x
    (the punctual lights first, then the lamps)."""
    r = g = b = 0.0
    n_punctual = surf.light_kind.shape[0]
    for li in range(n_punctual):
        dx, dy, dz, dist, e = light_towards(surf, li, x[0], x[1], x[2])
        cos = n[0] * dx + n[1] * dy + n[2] * dz
        if cos <= 0.0 or e <= 0.0:
            continue
        f = e * cos
        r += surf.light_intensity[li, 0] * f * vis_r[li]
        g += surf.light_intensity[li, 1] * f * vis_g[li]
        b += surf.light_intensity[li, 2] * f * vis_b[li]
    for t in range(lamps.corners.shape[0]):
        k = n_punctual + t
        if vis_r[k] == 0.0 and vis_g[k] == 0.0 and vis_b[k] == 0.0:
            continue
        f = lamp_factor(lamps, t, x[0], x[1], x[2], n[0], n[1], n[2])
        r += lamps.radiance[t, 0] * f * vis_r[k]
        g += lamps.radiance[t, 1] * f * vis_g[k]
        b += lamps.radiance[t, 2] * f * vis_b[k]
    return r, g, b


@njit(cache=True, inline="always")
def _sees_lights(bvh, surf, lamps, rays, stack, x, n, lift, vis_r, vis_g, vis_b):
    """vis_*[l]: the transmittance from x (lifted `lift` along n) towards
    each punctual light and the sun (0 behind an opaque surface), then
    each lamp (the mean over `rays` shadow rays to it; 0 where it is below
    x's horizon)."""
    ox, oy, oz = x[0] + lift * n[0], x[1] + lift * n[1], x[2] + lift * n[2]
    n_punctual = surf.light_kind.shape[0]
    for li in range(n_punctual):
        dx, dy, dz, dist, e = light_towards(surf, li, ox, oy, oz)
        if e <= 0.0:
            vis_r[li] = vis_g[li] = vis_b[li] = 0.0
            continue
        t0, t1, t2 = transmittance(bvh, stack, ox, oy, oz, dx, dy, dz, 0.0, dist)
        vis_r[li], vis_g[li], vis_b[li] = t0, t1, t2
    for t in range(lamps.corners.shape[0]):
        k = n_punctual + t
        if not lamp_above(lamps, t, x[0], x[1], x[2], n[0], n[1], n[2]):
            vis_r[k] = vis_g[k] = vis_b[k] = 0.0
            continue
        vis_r[k], vis_g[k], vis_b[k] = lamp_sees(bvh, stack, lamps, t, ox, oy, oz, rays)


@njit(cache=True, inline="always")
def _sphere_point(row, col, size, center, radius, x, nn):
    """nn (3,): the normal at the centre of texel (row, col) of a size x
    size octahedral map (the inverse of oct_uv); x (3,): the sphere's
    point with that normal."""
    px, py = 2.0 * (col + 0.5) / size - 1.0, 2.0 * (row + 0.5) / size - 1.0
    nz = 1.0 - abs(px) - abs(py)
    nx, ny = px, py
    if nz < 0.0:
        nx, ny = (1.0 - abs(py)) * (1.0 if px >= 0.0 else -1.0), (1.0 - abs(px)) * (1.0 if py >= 0.0 else -1.0)
    ln = np.sqrt(nx * nx + ny * ny + nz * nz)
    n = from_map(nx / ln, ny / ln, nz / ln)
    for k in range(3):
        nn[k] = n[k]
        x[k] = center[k] + radius * n[k]


@njit(cache=True, fastmath=True, error_model="numpy")
def _sphere_map(irr, depth, seen, origin, spacing, dims, center, radius, lights, lamps, vis, lamp_map, out):
    """out (S, S, 3): the sphere's map; vis (V, V, L, 3) the lights'
    visibility map (sphere_visibility); lamp_map (V, V, 3) a map of the
    lamps' light already summed (none where V is 0: the lamps, if any,
    taken at each texel through vis)."""
    size = out.shape[0]
    vsz = vis.shape[0]
    lsz = lamp_map.shape[0]
    n_lights = vis.shape[2]
    base = np.empty(3, np.int64)
    frac = np.empty(3)
    x = np.empty(3)
    nn = np.empty(3)
    vr, vg, vb = np.empty(n_lights), np.empty(n_lights), np.empty(n_lights)
    for row in range(size):
        for col in range(size):
            _sphere_point(row, col, size, center, radius, x, nn)
            r, g, b = _point_irradiance(irr, depth, seen, origin, spacing, dims, x, nn, base, frac)
            if n_lights:
                # the lights' visibility read bilinearly from its coarser map over the same normals
                ra, ca, rb, cb, rc, cc, rd, cd, wa, wb, wc, wd = _oct_bilinear(nn[0], nn[1], nn[2], vsz)
                for li in range(n_lights):
                    vr[li] = wa * vis[ra, ca, li, 0] + wb * vis[rb, cb, li, 0] + wc * vis[rc, cc, li, 0] \
                        + wd * vis[rd, cd, li, 0]
                    vg[li] = wa * vis[ra, ca, li, 1] + wb * vis[rb, cb, li, 1] + wc * vis[rc, cc, li, 1] \
                        + wd * vis[rd, cd, li, 1]
                    vb[li] = wa * vis[ra, ca, li, 2] + wb * vis[rb, cb, li, 2] + wc * vis[rc, cc, li, 2] \
                        + wd * vis[rd, cd, li, 2]
                dr, dg, db = _lights_at(lights, lamps, x, nn, vr, vg, vb)
                r, g, b = r + dr, g + dg, b + db
            if lsz:
                ra, ca, rb, cb, rc, cc, rd, cd, wa, wb, wc, wd = _oct_bilinear(nn[0], nn[1], nn[2], lsz)
                r += wa * lamp_map[ra, ca, 0] + wb * lamp_map[rb, cb, 0] + wc * lamp_map[rc, cc, 0] \
                    + wd * lamp_map[rd, cd, 0]
                g += wa * lamp_map[ra, ca, 1] + wb * lamp_map[rb, cb, 1] + wc * lamp_map[rc, cc, 1] \
                    + wd * lamp_map[rd, cd, 1]
                b += wa * lamp_map[ra, ca, 2] + wb * lamp_map[rb, cb, 2] + wc * lamp_map[rc, cc, 2] \
                    + wd * lamp_map[rd, cd, 2]
            out[row, col, 0] = r
            out[row, col, 1] = g
            out[row, col, 2] = b


@njit(cache=True, fastmath=True, error_model="numpy")
def _sphere_visibility(bvh, lights, lamps, rays, center, radius, out):
    """out (S, S, L, 3): the transmittance towards each light (then each
    lamp, over `rays` shadow rays) from the sphere's point at each texel
    normal of an S x S octahedral map."""
    size = out.shape[0]
    stack = np.empty(STACK_SIZE, np.int32)
    x = np.empty(3)
    nn = np.empty(3)
    n_lights = out.shape[2]
    vr, vg, vb = np.empty(n_lights), np.empty(n_lights), np.empty(n_lights)
    for row in range(size):
        for col in range(size):
            _sphere_point(row, col, size, center, radius, x, nn)
            _sees_lights(bvh, lights, lamps, rays, stack, x, nn, 0.0, vr, vg, vb)
            for li in range(n_lights):
                out[row, col, li, 0], out[row, col, li, 1], out[row, col, li, 2] = vr[li], vg[li], vb[li]


@njit(cache=True, fastmath=True, error_model="numpy")
def _sphere_lamp_map(bvh, lamps, rays, center, radius, out):
    """out (S, S, 3): the lamps' light at the sphere's point of each texel
    normal, their shadow rays traced once from the centre."""
    size = out.shape[0]
    stack = np.empty(STACK_SIZE, np.int32)
    x = np.empty(3)
    nn = np.empty(3)
    m = lamps.corners.shape[0]
    vis = np.empty((m, 3))
    for t in range(m):
        vis[t, 0], vis[t, 1], vis[t, 2] = lamp_sees(bvh, stack, lamps, t, center[0], center[1], center[2], rays)
    for row in range(size):
        for col in range(size):
            _sphere_point(row, col, size, center, radius, x, nn)
            r = g = b = 0.0
            for t in range(m):
                f = lamp_factor(lamps, t, x[0], x[1], x[2], nn[0], nn[1], nn[2])
                r += lamps.radiance[t, 0] * f * vis[t, 0]
                g += lamps.radiance[t, 1] * f * vis[t, 1]
                b += lamps.radiance[t, 2] * f * vis[t, 2]
            out[row, col, 0], out[row, col, 1], out[row, col, 2] = r, g, b


@njit(cache=True, fastmath=True, error_model="numpy")
def _points_irradiance(irr, depth, seen, origin, spacing, dims, points, normals, out):
    base = np.empty(3, np.int64)
    frac = np.empty(3)
    for i in range(points.shape[0]):
        r, g, b = _point_irradiance(irr, depth, seen, origin, spacing, dims, points[i], normals[i], base, frac)
        out[i, 0] = r
        out[i, 1] = g
        out[i, 2] = b


@njit(cache=True, fastmath=True, error_model="numpy")
def _points_lights(bvh, lights, lamps, rays, points, normals, out):
    """out[i] += the punctual lights, sun and lamps at points[i] with
    normals[i], each behind its shadow rays from the point (`rays` to
    each lamp)."""
    stack = np.empty(STACK_SIZE, np.int32)
    n_lights = lights.light_kind.shape[0] + lamps.corners.shape[0]
    vr, vg, vb = np.empty(n_lights), np.empty(n_lights), np.empty(n_lights)
    for i in range(points.shape[0]):
        _sees_lights(bvh, lights, lamps, rays, stack, points[i], normals[i], 0.0, vr, vg, vb)
        r, g, b = _lights_at(lights, lamps, points[i], normals[i], vr, vg, vb)
        out[i, 0] += r
        out[i, 1] += g
        out[i, 2] += b


@njit(cache=True, fastmath=True, error_model="numpy")
def _points_lights_from(bvh, lights, lamps, rays, anchor, points, normals, out):
    """_points_lights with the lamps' shadow rays traced once, from
    `anchor`, for every point (the punctual lights' still one a point)."""
    stack = np.empty(STACK_SIZE, np.int32)
    n_punctual = lights.light_kind.shape[0]
    n_lights = n_punctual + lamps.corners.shape[0]
    vr, vg, vb = np.empty(n_lights), np.empty(n_lights), np.empty(n_lights)
    for t in range(lamps.corners.shape[0]):
        vr[n_punctual + t], vg[n_punctual + t], vb[n_punctual + t] = lamp_sees(
            bvh, stack, lamps, t, anchor[0], anchor[1], anchor[2], rays)
    for i in range(points.shape[0]):
        x, nn = points[i], normals[i]
        for li in range(n_punctual):
            dx, dy, dz, dist, e = light_towards(lights, li, x[0], x[1], x[2])
            vr[li] = vg[li] = vb[li] = 0.0
            if e > 0.0 and nn[0] * dx + nn[1] * dy + nn[2] * dz > 0.0:
                vr[li], vg[li], vb[li] = transmittance(bvh, stack, x[0], x[1], x[2], dx, dy, dz, 0.0, dist)
        r, g, b = _lights_at(lights, lamps, x, nn, vr, vg, vb)
        out[i, 0] += r
        out[i, 1] += g
        out[i, 2] += b


@njit(cache=True, fastmath=True, error_model="numpy")
def _center_lights(bvh, lights, lamps, rays, center, normals, out):
    """out[q] += the punctual lights, sun and lamps at `center` for each
    of normals[q], their shadow rays traced once from the centre (a small
    object's one visibility for all its normals)."""
    stack = np.empty(STACK_SIZE, np.int32)
    n_punctual = lights.light_kind.shape[0]
    n_lights = n_punctual + lamps.corners.shape[0]
    vr, vg, vb = np.empty(n_lights), np.empty(n_lights), np.empty(n_lights)
    for li in range(n_punctual):
        dx, dy, dz, dist, e = light_towards(lights, li, center[0], center[1], center[2])
        vr[li] = vg[li] = vb[li] = 0.0
        if e > 0.0:
            vr[li], vg[li], vb[li] = transmittance(bvh, stack, center[0], center[1], center[2], dx, dy, dz, 0.0,
                                                   dist)
    for t in range(lamps.corners.shape[0]):
        vr[n_punctual + t], vg[n_punctual + t], vb[n_punctual + t] = lamp_sees(
            bvh, stack, lamps, t, center[0], center[1], center[2], rays)
    for q in range(normals.shape[0]):
        r, g, b = _lights_at(lights, lamps, center, normals[q], vr, vg, vb)
        out[q, 0] += r
        out[q, 1] += g
        out[q, 2] += b


LAMP_RAYS = 16   # shadow rays from a probe or a shading point to each lamp triangle (lamps.MARKS at most)


@dataclass(frozen=True)
class ProbeLights:
    """The punctual lights, the sun and the lamps (lamps.py: the brightest
    untextured emitter triangles) taken out of the probes and put back
    exactly at each shading point, behind its own shadow rays: a probe
    grid cannot hold a sun shadow's edge between its probes (a point in
    the sun's patch 18 cm over the walkthrough's floor read half its
    light), nor a lamp's near field. The probes hold each punctual light
    as the delta the bake added (gather.punctual_delta: its direction from
    the probe and its irradiance behind the probe's own shadow ray), so it
    comes out of the maps exactly, texel by texel; each lamp comes out as
    Lambert's formula at the probe times its shadow rays' share (the bake's
    sampled estimate of it, less its expectation). Once: rest (count, S,
    S, 3) float32 the maps without them (what every read then reads).
    direction, irradiance (count, L, 3) the deltas; texdirs (S^2, 3) the
    maps' texel normals; bvh, lights, lamps: the scene's arrays for the
    shading points' shadow rays; rays: shadow rays to each lamp from a
    shading point."""
    direction: np.ndarray
    irradiance: np.ndarray
    texdirs: np.ndarray
    rest: np.ndarray
    bvh: object
    lights: LightArrays
    lamps: LampArrays
    rays: int = LAMP_RAYS

    @property
    def count(self) -> int:
        """The lights put back at each point: punctual, then lamps."""
        return int(self.direction.shape[1]) + int(self.lamps.corners.shape[0])


@njit(cache=True)
def _probe_lights(bvh, surf, points, direction, irradiance):
    stack = np.empty(STACK_SIZE, np.int32)
    for i in range(points.shape[0]):
        for li in range(surf.light_kind.shape[0]):
            dx, dy, dz, r, g, b = punctual_delta(bvh, surf, stack, points[i, 0], points[i, 1], points[i, 2], li)
            direction[i, li, 0], direction[i, li, 1], direction[i, li, 2] = dx, dy, dz
            irradiance[i, li, 0], irradiance[i, li, 1], irradiance[i, li, 2] = r, g, b


def probe_lights(grid, prepared, rays: int = LAMP_RAYS, lamps: bool = True) -> ProbeLights:
    """ProbeLights of `grid` in the scene `prepared` (its punctual lights
    and sun as the bake saw them from each probe: one shadow ray each; its
    lamps, unless `lamps` is false: LAMP_RAYS shadow rays each from each
    probe), `rays` shadow rays to each lamp from each shading point."""
    from .gather import IRR, texel_directions
    from .lamps import MARKS
    surf, bvh = prepared.surfaces.arrays, prepared.bvh.arrays
    n_lights = int(surf.light_kind.shape[0])
    direction = np.zeros((grid.count, n_lights, 3))
    irradiance = np.zeros((grid.count, n_lights, 3))
    texdirs = texel_directions(IRR)
    rest = grid.irradiance
    if n_lights:
        _probe_lights(bvh, surf, np.ascontiguousarray(grid.positions(), np.float64), direction, irradiance)
        rest = np.empty_like(grid.irradiance, np.float32)
        for a in range(0, grid.count, 1024):   # in blocks: (block, L, S^2) cosines at a time
            b = min(a + 1024, grid.count)
            cos = np.maximum(np.einsum("qk,nlk->nlq", texdirs, direction[a:b]), 0.0)
            delta = np.einsum("nlq,nlc->nqc", cos, irradiance[a:b]).reshape(rest[a:b].shape)
            rest[a:b] = grid.irradiance[a:b] - delta
    held = lamp_arrays(surf if lamps else None)
    if len(held.corners):
        out = np.empty(rest.shape, np.float64)
        lamps_rest(bvh, held, np.ascontiguousarray(grid.positions(), np.float64), texdirs, LAMP_RAYS,
                   np.ascontiguousarray(rest, np.float64), out)
        rest = out
    return ProbeLights(direction, irradiance, texdirs, np.ascontiguousarray(rest, np.float32), bvh,
                       light_arrays(surf), held, int(min(max(rays, 1), MARKS)))


def _maps(grid, lights):
    """The maps the kernels read: the probes', or without the punctual
    lights (ProbeLights.rest) where they are put back at each point."""
    return grid.irradiance if lights is None or lights.count == 0 else lights.rest


VISIBILITY_MAP = 16   # normals a side of a large sphere's light-visibility map (bilinear between them)


def sphere_map(grid, center, radius, seen, size, lights: ProbeLights | None = None, coarse=False) -> np.ndarray:
    """(size, size, 3) float32: the irradiance over a sphere's surface as
    an octahedral map of its normals: texel n holds interpolate at the
    point center + radius n with normal n, the probes weighted by
    seen (count,) (1 where a probe is valid and seen from the centre,
    viewer/objects.probe_mask: interpolate's anchor test, once per probe
    instead of once per point). A sphere's point is a function of its
    normal, so the map read at a pixel's normal is that pixel's
    interpolate to the map's resolution: what the viewer shades a sphere
    larger than a probe cell with, one read a pixel. With `lights`, the
    punctual lights and the sun come out of the probes and in at each
    point, their visibility from a VISIBILITY_MAP squared map of the
    sphere's points (shadow rays) read bilinearly; coarse: the lamps'
    light summed on that coarser map instead, their shadow rays traced
    once from the centre, and read bilinearly (the window's moving
    sphere: the walkthrough's 64 x 64 map 1.6 ms, against 2.8 with the
    lamps at each texel and their shadow rays from each of 16 x 16 points). One thread: it runs every frame an object moves, beside the
    viewer's software rasterizer."""
    out = np.zeros((size, size, 3), np.float32)
    lamp_map = np.zeros((0, 0, 3))
    if lights is not None and lights.count:
        arrays, lamps = lights.lights, lights.lamps
        if coarse and len(lamps.corners):
            lamp_map = np.zeros((VISIBILITY_MAP, VISIBILITY_MAP, 3))
            _sphere_lamp_map(lights.bvh, lamps, lights.rays, np.asarray(center, np.float64), float(radius), lamp_map)
            lamps = lamp_arrays()
        vis = np.zeros((VISIBILITY_MAP, VISIBILITY_MAP, len(arrays.light_kind) + len(lamps.corners), 3))
        _sphere_visibility(lights.bvh, arrays, lamps, lights.rays, np.asarray(center, np.float64), float(radius),
                           vis)
    else:
        vis, arrays, lamps = np.zeros((1, 1, 0, 3)), light_arrays(), lamp_arrays()
    _sphere_map(_maps(grid, lights), grid.depth, np.ascontiguousarray(seen, np.uint8),
                np.asarray(grid.origin, np.float64), float(grid.spacing), np.asarray(grid.dims, np.int64),
                np.asarray(center, np.float64), float(radius), arrays, lamps, vis, lamp_map, out)
    return out


def points_irradiance(grid, points, normals, seen, lights: ProbeLights | None = None, anchor=None) -> np.ndarray:
    """(n, 3) float32: interpolate at points (n, 3) with unit normals
    (n, 3), the probes weighted by seen (count,) uint8 (probe_seen: valid
    and seen from the object's anchor) instead of a ray per point: what the
    viewer lights a dynamic mesh's vertices with when it moves; with
    `lights`, the punctual lights, sun and lamps out of the probes and in
    at each point behind its own shadow rays, or with `anchor` (3,) the
    lamps' shadow rays traced once from there for every point (the
    window's moving mesh: 2,562 vertices under the walkthrough's eight
    lamp triangles take 12 ms with 4 rays a lamp a vertex, 0.2 ms from the
    anchor). One thread, as sphere_map."""
    out = np.zeros((len(points), 3), np.float32)
    p = np.ascontiguousarray(points, np.float64)
    n = np.ascontiguousarray(normals, np.float64)
    _points_irradiance(_maps(grid, lights), grid.depth, np.ascontiguousarray(seen, np.uint8),
                       np.asarray(grid.origin, np.float64), float(grid.spacing), np.asarray(grid.dims, np.int64),
                       p, n, out)
    if lights is not None and lights.count:
        if anchor is None:
            _points_lights(lights.bvh, lights.lights, lights.lamps, lights.rays, p, n, out)
        else:
            _points_lights_from(lights.bvh, lights.lights, lights.lamps, lights.rays,
                                np.asarray(anchor, np.float64), p, n, out)
    return out
