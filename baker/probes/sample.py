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
clients that take SH do.)
"""
from __future__ import annotations

import numpy as np
from numba import njit

from ..kernels.bvh import STACK_SIZE
from ..kernels.traverse import transmittance

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
    """Octahedral (u, v) in [0, 1]^2 of unit directions d (n, 3)."""
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


def interpolate(grid, points, normals, anchors=None, bvh=None) -> np.ndarray:
    """(n, 3) irradiance at points (n, 3) with unit normals (n, 3).
    anchors (n, 3) with bvh (the scene's BVHArrays): each point belongs
    to an object whose centre is its anchor, and a probe that the anchor
    does not see (a ray from it meets a surface first) counts for
    nothing: the exact test the distance moments only approximate, which
    keeps an object beside a wall lit by its own side alone."""
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
        total += w[:, None] * irradiance_map_at(grid.irradiance[flat], normals)
        weight += w
    out = np.where(weight[:, None] > 0, total / np.where(weight > 0, weight, 1.0)[:, None], 0.0)
    return np.maximum(out, 0.0)


def object_map(grid, center, bvh) -> np.ndarray:
    """(S, S, 3) float32: the irradiance map of a small object at
    `center`: the probes' maps weighted as interpolate weighs them at the
    centre itself (trilinear, Chebyshev toward the centre, valid, seen
    from it). Read at a normal n it is interpolate(grid, center, n) (the
    read is linear in the maps): what the viewer shades an object no
    larger than a probe cell with, one map read per pixel."""
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
        out += w * grid.irradiance[flat]
        total += w
    return (out / total if total > 0 else out).astype(np.float32)
