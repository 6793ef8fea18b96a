"""The scene model: triangles as flat arrays and what they are made of.

A `Scene` is what every later stage reads: indexed float32 vertices, one
material index per triangle, materials (albedo, emitted radiance,
double-sidedness, optional albedo texture), cameras, punctual lights and an
optional uniform sky. Units (docs/design.md section 1): emitted radiance
L_e in W m^-2 sr^-1; point and spot intensity in W/sr; directional
irradiance in W/m^2 on a surface facing the light; sky radiance in
W m^-2 sr^-1.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from enum import IntEnum

import numpy as np


class LightKind(IntEnum):
    """Every kind of light under one code, as the kernels, the bake file's
    VPL rows and the shaders (as #defines KIND_AREA ...) read it: AREA an
    area emitter, or a VPL at a point with a normal; DIRECTIONAL a sun, or a
    VPL of the sky (a direction); POINT and SPOT glTF's punctual lights;
    SKY a uniform sky."""
    AREA = 0
    DIRECTIONAL = 1
    POINT = 2
    SPOT = 3
    SKY = 4

    @classmethod
    def of(cls, name: str) -> "LightKind":
        """The kind of a punctual light's glTF name ('point', 'spot',
        'directional')."""
        return cls[name.upper()]

    @classmethod
    def defines(cls) -> dict:
        return {f"KIND_{k.name}": int(k) for k in cls}


LIGHT_KINDS = tuple(k.name.lower() for k in (LightKind.POINT, LightKind.SPOT, LightKind.DIRECTIONAL))  # punctual
UP = np.array([0.0, 1.0, 0.0])  # glTF's up axis: the sky's zenith


@dataclass(frozen=True)
class Material:
    """A diffuse surface. Thin glass: `transmission` t of the light goes
    straight through, tinted by the base colour (glTF
    KHR_materials_transmission), the rest is diffuse: reflectance
    (1 - t) albedo, transmittance t albedo. Alpha mask (glTF alphaMode
    MASK): where alpha x opacity(uv) < alpha_cutoff the surface is not
    there at all (light and rays pass the cut-out texels)."""
    name: str
    albedo: np.ndarray            # (3,) float32, linear base colour factor
    emission: np.ndarray          # (3,) float32, emitted radiance L_e
    double_sided: bool = False
    texture: np.ndarray | None = None   # (h, w, 3) float32 linear albedo, multiplied by `albedo`
    transmission: float = 0.0     # thin-glass transmission factor in [0, 1]
    alpha_cutoff: float | None = None   # masked: alpha below it is cut out; None: opaque
    alpha: float = 1.0            # the base colour factor's alpha
    opacity: np.ndarray | None = None   # (h, w) float32 texture alpha, multiplied by `alpha`
    emission_texture: np.ndarray | None = None  # (h, w, 3) float32 linear, multiplied by `emission`

    @property
    def masked(self) -> bool:
        return self.alpha_cutoff is not None


def make_material(name, albedo=(0.8, 0.8, 0.8), emission=(0, 0, 0), double_sided=False, texture=None,
                  transmission=0.0, alpha_cutoff=None, alpha=1.0, opacity=None, emission_texture=None) -> Material:
    t = float(transmission)
    if not 0.0 <= t <= 1.0:
        raise ValueError(f"transmission {t} outside [0, 1]")
    return Material(name, np.asarray(albedo, np.float32)[:3], np.asarray(emission, np.float32)[:3],
                    bool(double_sided), texture, t, None if alpha_cutoff is None else float(alpha_cutoff),
                    float(alpha), opacity, emission_texture)


@dataclass(frozen=True)
class Camera:
    name: str
    position: np.ndarray          # (3,) float64
    forward: np.ndarray           # (3,) unit
    up: np.ndarray                # (3,) unit, orthogonal to forward
    yfov: float                   # vertical field of view, radians
    aspect: float | None = None   # width / height, None: from the image


def make_camera(name, position, forward, up, yfov, aspect=None) -> Camera:
    """A camera with `up` made orthogonal to `forward` (any up not parallel
    to forward will do; a parallel one is replaced)."""
    f = np.asarray(forward, float)
    f = f / np.linalg.norm(f)
    u = np.asarray(up, float)
    r = np.cross(f, u)
    if np.linalg.norm(r) < 1e-9:
        r = np.cross(f, [1.0, 0.0, 0.0] if abs(f[0]) < 0.9 else [0.0, 0.0, 1.0])
    r /= np.linalg.norm(r)
    u = np.cross(r, f)
    return Camera(name, np.asarray(position, float), f, u, float(yfov), aspect)


@dataclass(frozen=True)
class PunctualLight:
    name: str
    kind: str                     # one of LIGHT_KINDS
    intensity: np.ndarray         # (3,) W/sr (point, spot) or W/m^2 (directional), colour included
    position: np.ndarray          # (3,)
    direction: np.ndarray         # (3,) unit, where the light points
    inner_cone: float = 0.0       # radians (spot)
    outer_cone: float = np.pi / 4


def sun(azimuth_deg: float, elevation_deg: float, irradiance, name="sun") -> PunctualLight:
    """A directional light from azimuth (degrees from +Z towards +X) and
    elevation (degrees above the horizon, +Y up), giving `irradiance` W/m^2
    (a number or RGB) on a surface facing it."""
    az, el = np.radians(azimuth_deg), np.radians(elevation_deg)
    towards = np.array([np.cos(el) * np.sin(az), np.sin(el), np.cos(el) * np.cos(az)])
    e = np.broadcast_to(np.asarray(irradiance, np.float64), (3,)).copy()
    return PunctualLight(name, "directional", e, np.zeros(3), -towards)


@dataclass(frozen=True)
class Sky:
    """Uniform sky light: radiance (3,) W m^-2 sr^-1 arriving from every
    direction w with w . UP > 0 (hemisphere) or from all directions."""
    radiance: np.ndarray
    hemisphere: bool = True


@dataclass(frozen=True)
class DynamicMesh:
    """A mesh of the file marked dynamic (`voxbake bake --dynamic NODE`):
    it moves at run time, so it is not baked: no lightmap, no shadow, no
    light bounced off it; a viewer lights it from the irradiance probes.
    name: the node's; pivot (3,) float64 its world position (where a
    viewer moves it from); vertices (nv, 3) float32 in world space;
    triangles (nt, 3) int32; material_ids (nt,) int32 into the scene's
    materials; normals (nv, 3) float32 unit; uvs (nv, 2) float32 or None."""
    name: str
    pivot: np.ndarray
    vertices: np.ndarray
    triangles: np.ndarray
    material_ids: np.ndarray
    normals: np.ndarray
    uvs: np.ndarray | None = None

    @property
    def radius(self) -> float:
        """The largest distance of a vertex from the pivot."""
        d = self.vertices.astype(np.float64) - self.pivot
        return float(np.sqrt((d * d).sum(axis=1).max())) if len(d) else 0.0


@dataclass(frozen=True)
class Scene:
    """Triangles and what they are made of.

    vertices (nv, 3) float32; triangles (nt, 3) int32; material_ids (nt,) int32;
    normals (nv, 3) float32 or None; uvs (nv, 2) float32 or None.
    """
    vertices: np.ndarray
    triangles: np.ndarray
    material_ids: np.ndarray
    materials: tuple
    normals: np.ndarray | None = None
    uvs: np.ndarray | None = None
    cameras: tuple = ()
    lights: tuple = ()
    sky: Sky | None = None
    path: str = ""
    warnings: tuple = field(default=())
    dynamic: tuple = ()   # DynamicMesh: the file's moving meshes, not part of the bake

    # -- flat material arrays for kernels ----------------------------------
    @property
    def albedo(self) -> np.ndarray:
        """(nm, 3) float32 albedo factors."""
        return np.array([m.albedo for m in self.materials], np.float32).reshape(-1, 3)

    @property
    def emission(self) -> np.ndarray:
        """(nm, 3) float32 emitted radiance."""
        return np.array([m.emission for m in self.materials], np.float32).reshape(-1, 3)

    @property
    def double_sided(self) -> np.ndarray:
        """(nm,) bool."""
        return np.array([m.double_sided for m in self.materials], np.bool_)

    @property
    def transmission(self) -> np.ndarray:
        """(nm,) float64 thin-glass transmission factors."""
        return np.array([m.transmission for m in self.materials], np.float64).reshape(-1)

    def triangle_corners(self) -> np.ndarray:
        """(nt, 3, 3) float64 corner positions."""
        return self.vertices[self.triangles].astype(np.float64)

    def triangle_areas(self) -> np.ndarray:
        c = self.triangle_corners()
        return 0.5 * np.linalg.norm(np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0]), axis=1)

    def emitter_triangles(self) -> np.ndarray:
        """Indices of triangles whose material emits."""
        return np.nonzero(self.emission.max(axis=1)[self.material_ids] > 0)[0].astype(np.int32)

    def emitted_power(self) -> np.ndarray:
        """(3,) total power of the area emitters, W: pi L_e area per emitting
        side, L_e averaged over each triangle (emissive textures)."""
        from .surfaces import pack
        return pack(self).emitted_power

    def has_light(self) -> bool:
        """Does anything emit: an area emitter, a punctual light, a sky?"""
        sky = self.sky is not None and float(np.max(self.sky.radiance)) > 0
        return bool(len(self.emitter_triangles()) or self.lights or sky)

    def bounds(self):
        return self.vertices.min(axis=0).astype(np.float64), self.vertices.max(axis=0).astype(np.float64)

    def with_lights(self, lights=(), sky: Sky | None = None) -> "Scene":
        """This scene with more punctual lights and (if given) a sky."""
        return replace(self, lights=tuple(self.lights) + tuple(lights), sky=sky if sky is not None else self.sky)
