"""The baked geometry: one triangle per chart (a two-sided triangle's back
becomes a triangle of its own, wound the other way, so that each face of a
thin wall shows its own light), with the lightmap UVs and page of its
chart."""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ..scene.model import Scene


@dataclass(frozen=True)
class Bake:
    """scene: the baked geometry as a Scene (unshared corners, one-sided
    materials; vertices (3m, 3), triangle k = corners 3k .. 3k + 2); uv1
    (m, 3, 2) float32 lightmap UVs (u right, v down); page (m,) int32 each
    triangle's lightmap page; pages (P, 512, 512, 3) float32 irradiance H
    (W/m^2); page_scale (P,) float32 the 8-bit pages' intensity; meta: the
    bake's settings, counts, versions and timings; vpls: the ordered VPL
    list of the viewer's progressive preview (lights/ordered.py), or None;
    probes: the irradiance probe grid (probes.ProbeGrid), or None."""
    scene: Scene
    uv1: np.ndarray
    page: np.ndarray
    pages: np.ndarray
    page_scale: np.ndarray
    meta: dict = field(default_factory=dict)
    vpls: object = None
    probes: object = None

    @property
    def triangle_count(self) -> int:
        return len(self.page)


def baked_scene(scene, charts, lightmaps, meta=None, vpls=None, probes=None) -> Bake:
    """Scene + charts + lightmaps -> Bake, its triangles in the file's
    order: by material, then page (one primitive each), then chart."""
    order = np.lexsort((lightmaps.chart_page, scene.material_ids[charts.tri]))
    tri, back = charts.tri[order], charts.back[order]
    swap = np.where(back[:, None], np.array([0, 2, 1]), np.array([0, 1, 2]))          # backs: reversed winding
    front = scene.triangle_corners()[tri]
    corners = np.take_along_axis(front, swap[:, :, None], axis=1)
    uv1 = np.take_along_axis(lightmaps.chart_uv[order], swap[:, :, None], axis=1)
    uvs = None
    if scene.uvs is not None:
        uvs = np.take_along_axis(scene.uvs[scene.triangles[tri]], swap[:, :, None], axis=1).reshape(-1, 2)
    if scene.normals is not None:
        normals = scene.normals[scene.triangles[tri]].astype(np.float64)
    else:
        n = np.cross(front[:, 1] - front[:, 0], front[:, 2] - front[:, 0])
        normals = np.repeat(n[:, None, :], 3, axis=1)
    normals = np.where(back[:, None, None], -normals, normals)
    normals = np.take_along_axis(normals, swap[:, :, None], axis=1)
    normals /= np.maximum(np.linalg.norm(normals, axis=2, keepdims=True), 1e-30)
    materials = tuple(replace(m, double_sided=False) for m in scene.materials)
    m = len(tri)
    baked = Scene(vertices=corners.reshape(-1, 3).astype(np.float32),
                  triangles=np.arange(3 * m, dtype=np.int32).reshape(-1, 3),
                  material_ids=scene.material_ids[tri].astype(np.int32), materials=materials,
                  normals=normals.reshape(-1, 3).astype(np.float32),
                  uvs=None if uvs is None else uvs.astype(np.float32), cameras=tuple(scene.cameras),
                  lights=tuple(scene.lights), sky=scene.sky, path=scene.path, dynamic=tuple(scene.dynamic))
    return Bake(baked, uv1.astype(np.float32), lightmaps.chart_page[order].astype(np.int32), lightmaps.pages,
                lightmaps.page_scale.astype(np.float32), dict(meta or {}), vpls, probes)
