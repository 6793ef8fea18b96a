"""Flat per-triangle and per-material arrays that the kernels read, and the
numba helpers that interpret them (albedo lookup, emitter sampling, punctual
light irradiance). One place for what "the surface at a hit" means, so the
path tracer, the photons and later the VPL shading agree.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from .kernels.rng import rand01
from .kernels.sampling import sample_cdf, triangle_point

LIGHT_POINT, LIGHT_SPOT, LIGHT_DIRECTIONAL = 0, 1, 2
_KINDS = {"point": LIGHT_POINT, "spot": LIGHT_SPOT, "directional": LIGHT_DIRECTIONAL}


@dataclass(frozen=True)
class Surfaces:
    """Kernel-side view of a Scene. `.arrays` is the tuple kernels take:

    0 tri_material (nt,) int32   1 albedo (nm, 3) f64     2 emission (nm, 3) f64
    3 double_sided (nm,) bool    4 corners (nt, 3, 3) f64 5 tri_area (nt,) f64
    6 emitters (ne,) int32       7 emitter_cdf (ne,) f64  8 emitter_prob (nt,) f64
    9 tex_offset (nm,) int64     10 tex_size (nm, 2) int64 11 tex_data (n, 3) f32
    12 uvs (nt, 3, 2) f64        13 light_kind (nl,) i32  14 light_pos (nl, 3)
    15 light_dir (nl, 3)         16 light_intensity (nl, 3) 17 light_cones (nl, 2) cos inner/outer
    """
    arrays: tuple
    emitted_power: np.ndarray   # (3,) W, area emitters
    scale: float                # largest |coordinate|, for ray offsets

    @property
    def n_emitters(self) -> int:
        return len(self.arrays[6])

    @property
    def n_lights(self) -> int:
        return len(self.arrays[13])


def pack(scene) -> Surfaces:
    corners = scene.triangle_corners()
    area = scene.triangle_areas()
    mids = scene.material_ids
    emission = scene.emission.astype(np.float64)
    sides = np.where(scene.double_sided[mids], 2.0, 1.0)
    power = np.pi * emission[mids] * (area * sides)[:, None]           # (nt, 3)
    weight = power.sum(axis=1)
    emitters = np.nonzero(weight > 0)[0].astype(np.int32)
    cdf = np.cumsum(weight[emitters]) if len(emitters) else np.zeros(1)
    prob = np.zeros(len(area))
    if len(emitters):
        prob[emitters] = weight[emitters] / cdf[-1]
    # textures: one flat texel array, an offset and size per material
    tex_offset = np.full(len(scene.materials), -1, np.int64)
    tex_size = np.zeros((len(scene.materials), 2), np.int64)
    chunks, off = [], 0
    for i, m in enumerate(scene.materials):
        if m.texture is not None and scene.uvs is not None:
            h, w = m.texture.shape[:2]
            tex_offset[i], tex_size[i] = off, (w, h)
            chunks.append(m.texture.reshape(-1, 3).astype(np.float32))
            off += w * h
    tex_data = np.concatenate(chunks) if chunks else np.zeros((1, 3), np.float32)
    uvs = scene.uvs[scene.triangles].astype(np.float64) if scene.uvs is not None \
        else np.zeros((len(area), 3, 2))
    lights = scene.lights
    arrays = (
        mids.astype(np.int32), scene.albedo.astype(np.float64), emission, scene.double_sided,
        np.ascontiguousarray(corners), area, emitters, cdf.astype(np.float64), prob,
        tex_offset, tex_size, tex_data, np.ascontiguousarray(uvs),
        np.array([_KINDS[l.kind] for l in lights], np.int32),
        np.array([l.position for l in lights], np.float64).reshape(-1, 3),
        np.array([l.direction for l in lights], np.float64).reshape(-1, 3),
        np.array([l.intensity for l in lights], np.float64).reshape(-1, 3),
        np.array([(math.cos(l.inner_cone), math.cos(l.outer_cone)) for l in lights], np.float64).reshape(-1, 2),
    )
    return Surfaces(arrays, power.sum(axis=0), float(np.abs(scene.vertices).max()) or 1.0)


@njit(cache=True)
def albedo_at(surf, tri, b1, b2):
    """Albedo (r, g, b) at barycentrics (b1, b2) of scene triangle `tri`:
    the material factor times its texture (nearest texel, wrapped)."""
    mat = surf[0][tri]
    alb = surf[1]
    r, g, b = alb[mat, 0], alb[mat, 1], alb[mat, 2]
    off = surf[9][mat]
    if off >= 0:
        uv = surf[12]
        w, h = surf[10][mat, 0], surf[10][mat, 1]
        b0 = 1.0 - b1 - b2
        u = b0 * uv[tri, 0, 0] + b1 * uv[tri, 1, 0] + b2 * uv[tri, 2, 0]
        v = b0 * uv[tri, 0, 1] + b1 * uv[tri, 1, 1] + b2 * uv[tri, 2, 1]
        x = int(math.floor((u - math.floor(u)) * w)) % w
        y = int(math.floor((v - math.floor(v)) * h)) % h
        t = surf[11][off + y * w + x]
        r, g, b = r * t[0], g * t[1], b * t[2]
    return r, g, b


@njit(cache=True)
def geometric_normal(surf, tri):
    """Unit normal of scene triangle `tri` by its winding (front side)."""
    c = surf[4]
    ax, ay, az = c[tri, 1, 0] - c[tri, 0, 0], c[tri, 1, 1] - c[tri, 0, 1], c[tri, 1, 2] - c[tri, 0, 2]
    bx, by, bz = c[tri, 2, 0] - c[tri, 0, 0], c[tri, 2, 1] - c[tri, 0, 1], c[tri, 2, 2] - c[tri, 0, 2]
    nx, ny, nz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
    ln = math.sqrt(nx * nx + ny * ny + nz * nz)
    return nx / ln, ny / ln, nz / ln


@njit(cache=True)
def sample_emitter(surf, seed, index, dim):
    """A point on the area emitters, triangle chosen by power, uniform on it.
    Returns (tri, px, py, pz, b1, b2, pdf_area): pdf_area = P(tri) / area."""
    emitters, cdf = surf[6], surf[7]
    k = sample_cdf(cdf, rand01(seed, index, dim))
    tri = emitters[k]
    b1, b2 = triangle_point(rand01(seed, index, dim + 1), rand01(seed, index, dim + 2))
    c = surf[4]
    b0 = 1.0 - b1 - b2
    px = b0 * c[tri, 0, 0] + b1 * c[tri, 1, 0] + b2 * c[tri, 2, 0]
    py = b0 * c[tri, 0, 1] + b1 * c[tri, 1, 1] + b2 * c[tri, 2, 1]
    pz = b0 * c[tri, 0, 2] + b1 * c[tri, 1, 2] + b2 * c[tri, 2, 2]
    return tri, px, py, pz, b1, b2, surf[8][tri] / surf[5][tri]


@njit(cache=True)
def punctual_irradiance(surf, i, px, py, pz, nx, ny, nz):
    """Irradiance (r, g, b) from punctual light i at p with normal n, and the
    shadow ray (dx, dy, dz, distance) to test; zero if it faces away.
    Point: I cos / r^2; spot: times glTF's cone falloff; directional: E cos."""
    kind = surf[13][i]
    pos, ldir, inten, cones = surf[14], surf[15], surf[16], surf[17]
    if kind == LIGHT_DIRECTIONAL:
        dx, dy, dz = -ldir[i, 0], -ldir[i, 1], -ldir[i, 2]
        cos = nx * dx + ny * dy + nz * dz
        if cos <= 0.0:
            return 0.0, 0.0, 0.0, dx, dy, dz, 0.0
        return inten[i, 0] * cos, inten[i, 1] * cos, inten[i, 2] * cos, dx, dy, dz, np.inf
    dx, dy, dz = pos[i, 0] - px, pos[i, 1] - py, pos[i, 2] - pz
    d2 = dx * dx + dy * dy + dz * dz
    dist = math.sqrt(d2)
    if dist == 0.0:
        return 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0
    dx, dy, dz = dx / dist, dy / dist, dz / dist
    cos = nx * dx + ny * dy + nz * dz
    if cos <= 0.0:
        return 0.0, 0.0, 0.0, dx, dy, dz, 0.0
    f = cos / d2
    if kind == LIGHT_SPOT:
        cd = -(dx * ldir[i, 0] + dy * ldir[i, 1] + dz * ldir[i, 2])
        ci, co = cones[i, 0], cones[i, 1]
        a = (cd - co) / max(ci - co, 1e-4)
        a = min(max(a, 0.0), 1.0)
        f *= a * a
    return inten[i, 0] * f, inten[i, 1] * f, inten[i, 2] * f, dx, dy, dz, dist
