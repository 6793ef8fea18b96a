"""Virtual point lights (docs/design.md section 6): the voxel solution and
the scene's lights as a flat list the light tree, lightcuts and instant
radiosity share.

Kinds:
- KIND_AREA, oriented cosine emitters: direct VPLs (points on the area
  emitters, drawn by power, stratified) and indirect VPLs (one per voxel
  with bounced radiosity B_ind = rho H > 0, at its photon-weighted
  centroid, with its normal). power = Phi (W); the irradiance at p is the
  bounded disc form Phi cos_l cos_p / (pi r^2 + A), A = the VPL's area
  (emitter area / n_direct, or the voxel's area): the point form at a
  distance, finite at r = 0.
- KIND_DIRECTIONAL: the sky as directions (stratified over its domain),
  each with irradiance E = L_sky Omega / n at normal incidence: E cos_p.
  normal = the direction towards the sky.
Punctual lights (point, spot, directional) stay the scene's own and are
summed exactly at every shading point (a handful, no tree needed).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from ..kernels.rng import rand01
from ..voxels.tolerances import SKIN_COS
from ..scene.model import LightKind
from ..scene.surfaces import (SKY_HEMISPHERE, SKY_NONE, emission_at, sample_emitter, sky_solid_angle,
                              triangle_normal)

KIND_AREA, KIND_DIRECTIONAL = int(LightKind.AREA), int(LightKind.DIRECTIONAL)  # a VPL is a point or a direction
STREAM_VPL = 0x7F1  # rand01 index of the direct VPLs' stream (dims 0..3 per VPL: see kernels/rng.py's table)


@dataclass(frozen=True)
class VPLs:
    """kind (n,) int8; position (n, 3) float64; normal (n, 3) unit (the
    emitting side's normal, or the direction towards the sky); power (n, 3)
    float64 (Phi in W, or E in W/m^2); area (n,) float64 (the near-field
    A; 0 for directions); indirect (n,) bool."""
    kind: np.ndarray
    position: np.ndarray
    normal: np.ndarray
    power: np.ndarray
    area: np.ndarray
    indirect: np.ndarray

    def __len__(self):
        return len(self.kind)

    def subset(self, m: int) -> "VPLs":
        """The first m VPLs."""
        return VPLs(*(getattr(self, f)[:m] for f in ("kind", "position", "normal", "power", "area", "indirect")))

    def select(self, mask) -> "VPLs":
        """The VPLs where mask (n,) bool is set, in their order."""
        return VPLs(*(getattr(self, f)[mask] for f in ("kind", "position", "normal", "power", "area", "indirect")))

    def counts(self) -> dict:
        d = (self.kind == KIND_AREA) & ~self.indirect
        return {"vpls": len(self), "vpls_direct": int(d.sum()), "vpls_indirect": int(self.indirect.sum()),
                "vpls_sky": int((self.kind == KIND_DIRECTIONAL).sum()),
                "vpl_power_direct": self.power[d].sum(axis=0).tolist(),
                "vpl_power_indirect": self.power[self.indirect].sum(axis=0).tolist()}


@njit(cache=True)
def _direct(surf, n, seed):
    pos = np.empty((n, 3))
    nor = np.empty((n, 3))
    power = np.empty((n, 3))
    for i in range(n):
        u0 = (i + rand01(seed, STREAM_VPL + i, 0)) / n  # stratified over the emitters' power
        tri, px, py, pz, p_tri, b1, b2 = sample_emitter(surf, u0, rand01(seed, STREAM_VPL + i, 1),
                                                        rand01(seed, STREAM_VPL + i, 2))
        nx, ny, nz = triangle_normal(surf.corners, tri)
        sides = 1.0
        if surf.double_sided[surf.tri_material[tri]]:
            sides = 2.0
            if rand01(seed, STREAM_VPL + i, 3) < 0.5:
                nx, ny, nz = -nx, -ny, -nz  # a two-sided emitter: either face, each with half its power
        er, eg, eb = emission_at(surf, tri, b1, b2)
        f = math.pi * surf.tri_area[tri] * sides / (p_tri * n)
        pos[i, 0], pos[i, 1], pos[i, 2] = px, py, pz
        nor[i, 0], nor[i, 1], nor[i, 2] = nx, ny, nz
        power[i, 0], power[i, 1], power[i, 2] = er * f, eg * f, eb * f
    return pos, nor, power


def direct_vpls(surfaces, n, seed=0):
    """n points on the area emitters, their triangles drawn by power: each
    carries pi L_e(point) area / (n p_tri) (an emissive texture's pattern;
    total / n where the emission is uniform and of one colour) and the
    area of the emitters / n."""
    if n <= 0 or surfaces.n_emitters == 0:
        return _empty()
    pos, nor, power = _direct(surfaces.arrays, int(n), int(seed))
    a = surfaces.arrays
    sides = np.where(a.double_sided[a.tri_material[a.emitters]], 2.0, 1.0)
    total_area = float((a.tri_area[a.emitters] * sides).sum())
    return VPLs(np.zeros(n, np.int8), pos, nor, power, np.full(n, total_area / n), np.zeros(n, bool))


PLANAR_SKIN = 1e-3   # a planar voxel's VPL under a surface by less than this x its side is under its own plane
SKIN = 0.5        # a voxel's VPL under its surface by less than this x the voxel's side is moved onto it,


def on_surface(bvh, surfaces, position, normal, side, voxels=None, index=None):
    """Voxel VPL positions (n, 3) put on their surface. A voxel's
    photon-weighted centroid on a convex curved surface (a column, a
    sphere, a scan) lies under it by the sagitta of the voxel's patch, so
    every shadow ray to it would leave through that surface from behind
    and its light would be lost (5% of the walkthrough's bounced power at
    the default preset). A ray from the centroid along the VPL's normal
    that meets, within SKIN x side, a surface from behind (one-sided: its
    winding normal within 60 degrees of the VPL's; two-sided: either way)
    has found that skin: the VPL moves onto it, a hair past. A surface met
    from the front (a box standing over a floor's voxel) leaves it where it
    is. Given the voxels (and each position's voxel, `index`), a planar
    voxel (its centroid lies on its plane) moves only past its own plane,
    met within rounding (PLANAR_SKIN x side): a ceiling's voxel just above
    a lamp meets the lamp's back, and must not carry its light into the
    room."""
    if bvh is None or len(position) == 0:
        return position
    t, tri, _, _ = bvh.closest(position, normal, tmax=SKIN * side)
    hit = np.nonzero(np.isfinite(t) & (t > 1e-6 * side))[0]  # (not the VPL's own flat surface, met at rounding)
    if len(hit) == 0:
        return position
    a = surfaces.arrays
    c = a.corners[tri[hit]]
    fn = np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0])
    fn /= np.maximum(np.linalg.norm(fn, axis=1, keepdims=True), 1e-300)
    cos = np.einsum("ij,ij->i", fn, normal[hit])
    two = a.double_sided[a.tri_material[tri[hit]]]
    ok = (cos > SKIN_COS) | (two & (np.abs(cos) > SKIN_COS))
    if voxels is not None:
        ok &= ~voxels.planar[np.asarray(index, np.int64)[hit]] | (t[hit] < PLANAR_SKIN * side[hit])
    skin = hit[ok]
    out = position.copy()
    out[skin] += normal[skin] * (t[skin] + 1e-4 * side[skin])[:, None]
    return out


def indirect_vpls(solution, bvh=None, surfaces=None):
    """One VPL per voxel with bounced light: Phi = B_ind * area, at the
    voxel's photon-weighted centroid (put on its surface where it lies
    under it: on_surface, given the scene's BVH)."""
    vox = solution.voxels
    b_ind = solution.radiosity - vox.emission
    power = b_ind * vox.area[:, None]
    keep = power.max(axis=1) > 0
    n = int(keep.sum())
    normal = vox.normal[keep].astype(np.float64)
    area = vox.area[keep].astype(np.float64)
    position = on_surface(bvh, surfaces, solution.photon_centroid[keep].astype(np.float64), normal,
                          np.sqrt(area), vox, np.nonzero(keep)[0])
    return VPLs(np.zeros(n, np.int8), position, normal, power[keep], area, np.ones(n, bool))


def sky_vpls(surfaces, n, seed=0):
    """The sky as n directions, stratified over its domain (a Fibonacci
    lattice on the sphere or the upper hemisphere), E = L Omega / n each."""
    a = surfaces.arrays
    if a.sky_mode == SKY_NONE or n <= 0 or float(np.max(a.sky_radiance)) <= 0:
        return _empty()
    omega = sky_solid_angle(a.sky_mode)
    k = np.arange(n) + 0.5
    z = 1.0 - k / n if a.sky_mode == SKY_HEMISPHERE else 1.0 - 2.0 * k / n  # uniform in solid angle
    phi = k * math.pi * (3.0 - math.sqrt(5.0)) + 2 * math.pi * rand01(seed, STREAM_VPL - 1, 0)
    r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    local = np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)
    up = np.asarray(a.sky_up, float)
    t = np.cross(up, [1.0, 0.0, 0.0] if abs(up[0]) < 0.9 else [0.0, 0.0, 1.0])
    t /= np.linalg.norm(t)
    b = np.cross(up, t)
    dirs = local[:, :1] * t + local[:, 1:2] * b + local[:, 2:] * up
    power = np.broadcast_to(np.asarray(a.sky_radiance, float) * omega / n, (n, 3)).copy()
    return VPLs(np.full(n, KIND_DIRECTIONAL, np.int8), np.zeros((n, 3)), dirs, power, np.zeros(n), np.zeros(n, bool))


def _empty():
    return VPLs(np.zeros(0, np.int8), np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0),
                np.zeros(0, bool))


def concat(*sets) -> VPLs:
    return VPLs(*(np.concatenate([getattr(s, f) for s in sets]) for f in
                  ("kind", "position", "normal", "power", "area", "indirect")))


def make_vpls(scene, solution, surfaces, n_direct, n_sky, seed=0, bvh=None) -> VPLs:
    """Direct + indirect + sky VPLs of a solved scene (bvh: the scene's,
    to put the voxels' VPLs on their surfaces)."""
    return concat(direct_vpls(surfaces, n_direct, seed), indirect_vpls(solution, bvh, surfaces),
                  sky_vpls(surfaces, n_sky, seed))
