"""The scene as the kernels read it, and the formulas every method shares.

`pack(scene)` flattens a Scene into `SurfaceArrays`, a namedtuple of
arrays that numba kernels take whole (fields by name). The numba helpers
below are the one place where "the surface at a hit" and "the light a
source gives" are defined: the path tracer (the yardstick), the photons
(the product) and later the VPLs call the same functions, so they cannot
drift apart.

Light kinds (kernel codes): area emitters (triangles with emission),
point, spot (glTF's cone falloff), directional (a sun: irradiance on a
surface facing it) and a uniform sky over the upper hemisphere or the
whole sphere (docs/design.md section 1).
"""
from __future__ import annotations

import math
from collections import namedtuple
from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from ..kernels.geometry import unit_cross
from ..kernels.sampling import sample_cdf, triangle_point
from ..kernels.traverse import closest_hit
from .model import UP, LightKind

# the kernels' names for model.LightKind's codes (plain ints: numba folds them as constants)
LIGHT_AREA, LIGHT_POINT, LIGHT_SPOT, LIGHT_DIRECTIONAL, LIGHT_SKY = (
    int(LightKind.AREA), int(LightKind.POINT), int(LightKind.SPOT), int(LightKind.DIRECTIONAL), int(LightKind.SKY))
SKY_NONE, SKY_HEMISPHERE, SKY_SPHERE = 0, 1, 2
# Thin glass that lets at least this share of light through is left out of the voxels (their lines are
# opaque or empty, not partly clear): photons go through it (tinted), and the light it would reflect,
# (1 - t) albedo, is not propagated. Below it the glass is a voxel of reflectance (1 - t) albedo that
# stops the lines. Shadow rays and the path tracer take the exact transmittance either way.
VOXEL_PASS = 0.5
MAX_PANES = 64   # panes of such glass a camera ray sees through

SurfaceArrays = namedtuple("SurfaceArrays", [
    "tri_material",     # (nt,) int32 material of each triangle
    "albedo",           # (nm, 3) float64 albedo factor
    "emission",         # (nm, 3) float64 emitted radiance L_e (the factor: times emit_texture where there is one)
    "tri_emission",     # (nt, 3) float64 each triangle's mean L_e over its area (the emissive texture averaged)
    "double_sided",     # (nm,) bool
    "transmission",     # (nm,) float64 thin-glass transmission factor t (tint: t x albedo factor)
    "corners",          # (nt, 3, 3) float64 triangle corners
    "tri_area",         # (nt,) float64
    "tri_normal",       # (nt, 3) float64 unit normal, front by the winding (triangle_normal of corners)
    "emitters",         # (ne,) int32 triangles that emit
    "emitter_cdf",      # (ne,) float64 cumulative emitted power over `emitters` (inclusive)
    "emitter_prob",     # (nt,) float64 probability of drawing each triangle by power (0: not an emitter)
    "tex_offset",       # (nm,) int64 first texel of a material's texture in tex_data (-1: none)
    "tex_size",         # (nm, 2) int64 texture width, height
    "emit_offset",      # (nm,) int64 first texel of a material's emissive texture in tex_data (-1: none)
    "emit_size",        # (nm, 2) int64 emissive texture width, height
    "tex_data",         # (texels, 3) float32 linear texels of every albedo and emissive texture
    "uvs",              # (nt, 3, 2) float64 texture coordinates of the corners
    "light_kind",       # (nl,) int32 LIGHT_POINT | LIGHT_SPOT | LIGHT_DIRECTIONAL
    "light_pos",        # (nl, 3) float64
    "light_dir",        # (nl, 3) float64 unit, where the light points
    "light_intensity",  # (nl, 3) float64 W/sr, or W/m^2 for directional
    "light_cones",      # (nl, 2) float64 cos of the spot's inner and outer cone angles
    "sky_radiance",     # (3,) float64 W m^-2 sr^-1
    "sky_mode",         # int: SKY_NONE | SKY_HEMISPHERE | SKY_SPHERE
    "sky_up",           # (3,) float64 unit zenith
])


@dataclass(frozen=True)
class Surfaces:
    """Kernel-side view of a Scene: `arrays` (SurfaceArrays), the area
    emitters' total power (3,) W and the scene's scale (largest |coordinate|,
    for ray offsets)."""
    arrays: SurfaceArrays
    emitted_power: np.ndarray
    scale: float

    @property
    def n_emitters(self) -> int:
        return len(self.arrays.emitters)


def pack(scene) -> Surfaces:
    corners = scene.triangle_corners()
    area = scene.triangle_areas()
    mids = scene.material_ids
    emission = scene.emission.astype(np.float64)
    # textures: one flat texel array, an offset and size per material (albedo, then emissive)
    nm = len(scene.materials)
    tex_offset, emit_offset = np.full(nm, -1, np.int64), np.full(nm, -1, np.int64)
    tex_size, emit_size = np.zeros((nm, 2), np.int64), np.zeros((nm, 2), np.int64)
    chunks, off = [], 0
    for which, offsets, sizes in (("texture", tex_offset, tex_size), ("emission_texture", emit_offset, emit_size)):
        for i, m in enumerate(scene.materials):
            t = getattr(m, which)
            if t is not None and scene.uvs is not None and (which == "texture" or emission[i].max() > 0):
                h, w = t.shape[:2]
                offsets[i], sizes[i] = off, (w, h)
                chunks.append(t.reshape(-1, 3).astype(np.float32))
                off += w * h
    tex_data = np.concatenate(chunks) if chunks else np.zeros((1, 3), np.float32)
    uvs = scene.uvs[scene.triangles].astype(np.float64) if scene.uvs is not None \
        else np.zeros((len(area), 3, 2))
    tri_emission = emission[mids]
    textured = np.nonzero((emit_offset[mids] >= 0) & (area > 0))[0]
    if len(textured):
        tri_emission = tri_emission.copy()
        tri_emission[textured] = _mean_emission(tri_emission[textured], emit_offset[mids[textured]],
                                                emit_size[mids[textured]], tex_data, uvs[textured])
    sides = np.where(scene.double_sided[mids], 2.0, 1.0)
    power = np.pi * tri_emission * (area * sides)[:, None]           # (nt, 3)
    weight = power.sum(axis=1)
    emitters = np.nonzero(weight > 0)[0].astype(np.int32)
    cdf = np.cumsum(weight[emitters]) if len(emitters) else np.zeros(1)
    prob = np.zeros(len(area))
    if len(emitters):
        prob[emitters] = weight[emitters] / cdf[-1]
    lights = scene.lights
    sky = scene.sky
    sky_mode = SKY_NONE if sky is None else (SKY_HEMISPHERE if sky.hemisphere else SKY_SPHERE)
    arrays = SurfaceArrays(
        tri_material=mids.astype(np.int32), albedo=scene.albedo.astype(np.float64), emission=emission,
        tri_emission=np.ascontiguousarray(tri_emission),
        double_sided=scene.double_sided, transmission=scene.transmission, corners=np.ascontiguousarray(corners), tri_area=area,
        tri_normal=_unit_normals(corners), emitters=emitters,
        emitter_cdf=cdf.astype(np.float64), emitter_prob=prob, tex_offset=tex_offset, tex_size=tex_size,
        emit_offset=emit_offset, emit_size=emit_size, tex_data=tex_data, uvs=np.ascontiguousarray(uvs),
        light_kind=np.array([LightKind.of(l.kind) for l in lights], np.int32),
        light_pos=np.array([l.position for l in lights], np.float64).reshape(-1, 3),
        light_dir=np.array([l.direction for l in lights], np.float64).reshape(-1, 3),
        light_intensity=np.array([l.intensity for l in lights], np.float64).reshape(-1, 3),
        light_cones=np.array([(math.cos(l.inner_cone), math.cos(l.outer_cone)) for l in lights],
                             np.float64).reshape(-1, 2),
        sky_radiance=np.zeros(3) if sky is None else np.asarray(sky.radiance, np.float64).reshape(3),
        sky_mode=sky_mode, sky_up=UP.astype(np.float64))
    return Surfaces(arrays, power.sum(axis=0), float(np.abs(scene.vertices).max()) or 1.0)


def _unit_normals(corners):
    """(nt, 3) float64 unit normals by the winding, the formula of
    kernels/geometry.unit_cross; a zero vector for a degenerate triangle."""
    n = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    length = np.linalg.norm(n, axis=1, keepdims=True)
    return np.ascontiguousarray(np.divide(n, length, out=np.zeros_like(n), where=length > 0))


@njit(cache=True, inline="always")
def _textured(surf, factor, offset, size, tri, b1, b2):
    """factor[mat] (r, g, b) of scene triangle `tri`'s material times its
    texture at tex_data[offset[mat]:] (size[mat]: width, height; offset
    -1: none), nearest texel, wrapped, at barycentrics (b1, b2)."""
    mat = surf.tri_material[tri]
    r, g, b = factor[mat, 0], factor[mat, 1], factor[mat, 2]
    off = offset[mat]
    if off >= 0:
        w, h = size[mat, 0], size[mat, 1]
        uv = surf.uvs
        b0 = 1.0 - b1 - b2
        u = b0 * uv[tri, 0, 0] + b1 * uv[tri, 1, 0] + b2 * uv[tri, 2, 0]
        v = b0 * uv[tri, 0, 1] + b1 * uv[tri, 1, 1] + b2 * uv[tri, 2, 1]
        x = int(math.floor((u - math.floor(u)) * w)) % w
        y = int(math.floor((v - math.floor(v)) * h)) % h
        t = surf.tex_data[off + y * w + x]
        r, g, b = r * t[0], g * t[1], b * t[2]
    return r, g, b


@njit(cache=True)
def albedo_at(surf, tri, b1, b2):
    """Albedo (r, g, b) at barycentrics (b1, b2) of scene triangle `tri`:
    the material factor times its texture (nearest texel, wrapped)."""
    return _textured(surf, surf.albedo, surf.tex_offset, surf.tex_size, tri, b1, b2)


@njit(cache=True)
def emission_at(surf, tri, b1, b2):
    """Emitted radiance L_e (r, g, b) at barycentrics (b1, b2) of scene
    triangle `tri`: the material's emissive factor times its emissive
    texture (nearest texel, wrapped), the one definition the photons, the
    direct VPLs, the path tracer and the views share."""
    return _textured(surf, surf.emission, surf.emit_offset, surf.emit_size, tri, b1, b2)


@njit(cache=True, parallel=True)
def _mean_emission(factor, offset, size, tex_data, uvs):
    """(n, 3) mean of factor x the nearest texel over each triangle (its
    corners' texture coordinates uvs (n, 3, 2)): the R2 sequence mapped
    onto the triangle, about 4 points per texel the triangle covers (256 to
    65,536). The mean only weighs the triangles for sampling; each
    sampled point carries its own texel's value over the triangle's
    probability, so the emitted light is unbiased whatever its error."""
    n = factor.shape[0]
    out = np.zeros((n, 3))
    for k in prange(n):
        w, h = size[k, 0], size[k, 1]
        du1, dv1 = uvs[k, 1, 0] - uvs[k, 0, 0], uvs[k, 1, 1] - uvs[k, 0, 1]
        du2, dv2 = uvs[k, 2, 0] - uvs[k, 0, 0], uvs[k, 2, 1] - uvs[k, 0, 1]
        texels = 0.5 * abs(du1 * dv2 - du2 * dv1) * w * h
        m = int(min(max(4.0 * texels, 256.0), 65536.0))
        s0 = s1 = s2 = 0.0
        for i in range(m):
            ra = 0.5 + i * 0.7548776662466927
            rb = 0.5 + i * 0.5698402909980532
            b1, b2 = triangle_point(ra - math.floor(ra), rb - math.floor(rb))
            b0 = 1.0 - b1 - b2
            u = b0 * uvs[k, 0, 0] + b1 * uvs[k, 1, 0] + b2 * uvs[k, 2, 0]
            v = b0 * uvs[k, 0, 1] + b1 * uvs[k, 1, 1] + b2 * uvs[k, 2, 1]
            x = int(math.floor((u - math.floor(u)) * w)) % w
            y = int(math.floor((v - math.floor(v)) * h)) % h
            t = tex_data[offset[k] + y * w + x]
            s0 += t[0]
            s1 += t[1]
            s2 += t[2]
        out[k, 0], out[k, 1], out[k, 2] = factor[k, 0] * s0 / m, factor[k, 1] * s1 / m, factor[k, 2] * s2 / m
    return out


@njit(cache=True)
def triangle_normal(corners, tri):
    """Unit normal of triangle `tri` of corners (nt, 3, 3), front by its
    winding (counter-clockwise seen from the front)."""
    c = corners
    return unit_cross(c[tri, 1, 0] - c[tri, 0, 0], c[tri, 1, 1] - c[tri, 0, 1], c[tri, 1, 2] - c[tri, 0, 2],
                      c[tri, 2, 0] - c[tri, 0, 0], c[tri, 2, 1] - c[tri, 0, 1], c[tri, 2, 2] - c[tri, 0, 2])


@njit(cache=True)
def _on_emitter(surf, k, u1, u2):
    """(tri, px, py, pz, p_tri, b1, b2): emitter k's triangle, the point
    (u1, u2) places uniformly on it, that triangle's probability and the
    point's barycentrics (for emission_at)."""
    tri = surf.emitters[k]
    b1, b2 = triangle_point(u1, u2)
    c = surf.corners
    b0 = 1.0 - b1 - b2
    px = b0 * c[tri, 0, 0] + b1 * c[tri, 1, 0] + b2 * c[tri, 2, 0]
    py = b0 * c[tri, 0, 1] + b1 * c[tri, 1, 1] + b2 * c[tri, 2, 1]
    pz = b0 * c[tri, 0, 2] + b1 * c[tri, 1, 2] + b2 * c[tri, 2, 2]
    return tri, px, py, pz, surf.emitter_prob[tri], b1, b2


@njit(cache=True)
def sample_emitter(surf, u_tri, u1, u2):
    """A point on the area emitters from three uniform numbers: the triangle
    drawn by power (u_tri), the point uniform on it (u1, u2). Returns
    (tri, px, py, pz, p_tri, b1, b2): p_tri the probability of that
    triangle (the point's density is p_tri / area), (b1, b2) the point's
    barycentrics. A point's power is pi emission_at(point) area / p_tri
    per emitting side: an emissive texture's pattern, unbiased."""
    return _on_emitter(surf, sample_cdf(surf.emitter_cdf, u_tri), u1, u2)


@njit(cache=True)
def emitter_point(surf, u1, u2):
    """sample_emitter from two uniform numbers: u1 picks the triangle by
    power and, rescaled within that triangle's share, places the point
    with u2, so a stratified pair stays stratified over all the emitters."""
    cdf = surf.emitter_cdf
    k = sample_cdf(cdf, u1)
    lo = cdf[k - 1] if k > 0 else 0.0
    u = min(max((u1 * cdf[-1] - lo) / (cdf[k] - lo), 0.0), 1.0 - 1e-16)
    return _on_emitter(surf, k, u, u2)


@njit(cache=True)
def spot_falloff(cos_axis, cos_inner, cos_outer):
    """glTF KHR_lights_punctual's spot attenuation at cos_axis (the cosine
    between the light's axis and the direction to the point): a smooth
    step from the outer cone to the inner one, squared."""
    a = (cos_axis - cos_outer) / max(cos_inner - cos_outer, 1e-4)
    a = min(max(a, 0.0), 1.0)
    return a * a


@njit(cache=True)
def punctual_irradiance(surf, i, px, py, pz, nx, ny, nz):
    """Irradiance (r, g, b) from punctual light i at p with normal n, and the
    shadow ray (dx, dy, dz, distance) to test; zero if it faces away.
    Point: I cos / r^2; spot: times spot_falloff; directional: E cos."""
    kind = surf.light_kind[i]
    pos, ldir, inten, cones = surf.light_pos, surf.light_dir, surf.light_intensity, surf.light_cones
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
        f *= spot_falloff(-(dx * ldir[i, 0] + dy * ldir[i, 1] + dz * ldir[i, 2]), cones[i, 0], cones[i, 1])
    return inten[i, 0] * f, inten[i, 1] * f, inten[i, 2] * f, dx, dy, dz, dist


@njit(cache=True)
def sky_radiance(surf, wx, wy, wz):
    """Radiance (r, g, b) the sky sends along -w, w the unit direction towards
    the sky: its radiance where w lies in its domain, else 0."""
    mode = surf.sky_mode
    if mode == SKY_NONE:
        return 0.0, 0.0, 0.0
    if mode == SKY_HEMISPHERE:
        up = surf.sky_up
        if wx * up[0] + wy * up[1] + wz * up[2] <= 0.0:
            return 0.0, 0.0, 0.0
    L = surf.sky_radiance
    return L[0], L[1], L[2]


def sky_solid_angle(sky_mode: int) -> float:
    """Solid angle the sky covers, sr."""
    return {SKY_NONE: 0.0, SKY_HEMISPHERE: 2 * np.pi, SKY_SPHERE: 4 * np.pi}[sky_mode]


@njit(cache=True, inline="always")
def hit_past_glass(bvh, surf, stack, ox, oy, oz, dx, dy, dz, cull_back=False):
    """The closest hit of a camera ray past the thin glass the voxels leave
    out (t >= VOXEL_PASS): (t, j, u, v) as closest_hit, and the tint (r, g,
    b) of the panes it went through (t x albedo factor each). The glass's
    own diffuse part, (1 - t) albedo, is not shown (the bake and the
    solution hold no light for it)."""
    tr, tg, tb = 1.0, 1.0, 1.0
    tmin = 0.0
    for _ in range(MAX_PANES):
        t, j, u, v = closest_hit(bvh, stack, ox, oy, oz, dx, dy, dz, tmin, np.inf, cull_back)
        if j < 0:
            return t, j, u, v, tr, tg, tb
        m = surf.tri_material[bvh.tri_index[j]]
        tt = surf.transmission[m]
        if tt < VOXEL_PASS:
            return t, j, u, v, tr, tg, tb
        tr, tg, tb = tr * tt * surf.albedo[m, 0], tg * tt * surf.albedo[m, 1], tb * tt * surf.albedo[m, 2]
        tmin = t * (1.0 + 1e-9) + 1e-12
    return np.inf, -1, 0.0, 0.0, 0.0, 0.0, 0.0
