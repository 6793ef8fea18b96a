"""Stage 5, lightmaps: charts (one square map per lit triangle side),
texels (sample points, inside-geometry test, fill), texel values (the
preview tier: the voxel solution reconstructed at each texel) and atlases
(single-colour maps, deduplication, quadtree pages)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .atlas import PAGE, Lightmaps, build_atlas, pack_quadtree
from .charts import Charts, per_triangle_charts
from .texels import fill, inside_geometry, texel_points
from .voxel_irradiance import reconstruct

LIFT = 0.05   # cells: texel points are lifted this far off their surface for the visibility rays


@dataclass(frozen=True)
class TexelSet:
    """charts; point (N, 3) float64 sample points; covered (N,) bool;
    inside (N,) bool covered texels hidden inside geometry; values (N, 3)
    float64 H after the fill; filled (N,) bool."""
    charts: Charts
    point: np.ndarray
    covered: np.ndarray
    inside: np.ndarray
    values: np.ndarray
    filled: np.ndarray


def texel_size_for(solution, texel_density=None) -> float:
    """Scene units per texel: one voxel cell, or 1 / texel_density."""
    if texel_density:
        return 1.0 / float(texel_density)
    return float(solution.voxels.cell_size)


def charts_for(scene, texel_size) -> Charts:
    return per_triangle_charts(scene.triangle_corners(), scene.double_sided[scene.material_ids], texel_size)


def preview_texels(scene, solution, bvh, surfaces, charts: Charts, seed=0) -> TexelSet:
    """The preview tier: texel values from the voxel solution."""
    vox = solution.voxels
    h = float(vox.cell_size)
    corners = surfaces.arrays.corners
    off = charts.offsets
    point, covered = texel_points(corners, charts.tri, charts.corners2d, charts.size, off)
    lift = LIFT * min(h, float(charts.texel.min()))
    reach = np.inf
    inside = inside_geometry(bvh.arrays, surfaces.arrays.double_sided, surfaces.arrays.tri_material, corners,
                             charts.tri, charts.back, off, point, covered, lift, reach, seed)
    values, found = reconstruct(bvh.arrays, corners, charts.tri, charts.back, off, point, covered,
                                np.ascontiguousarray(solution.irradiance), vox.key, vox.cell, vox.centroid,
                                vox.normal, vox.area, vox.cut_plane, vox.cut_sign, vox.piece_key, vox.piece_voxel,
                                vox.piece_plane, vox.piece_sign, vox.side_start, vox.back_side, vox.origin, h,
                                vox.dims, lift)
    return finish(charts, point, covered, inside, values, found)


def finish(charts, point, covered, inside, values, found) -> TexelSet:
    """Texels inside geometry next to a valid one take their valid
    neighbours' mean (one ring: what bilinear filtering at the object's
    outline reads), the other covered ones keep their own value, and the
    texels around the triangle are filled from them (texels.py)."""
    valid = covered & found & ~inside
    values = np.where((covered & found)[:, None], values, 0.0)
    off = charts.offsets
    size = charts.size.astype(np.int64)
    filled = valid.copy()
    fill(values, filled, off, size, 1, covered & found & inside)
    filled |= covered & found  # deeper inside texels: their own value
    fill(values, filled, off, size)
    return TexelSet(charts, point, covered, inside, values, filled)


def atlas_for(scene, texels: TexelSet) -> Lightmaps:
    emits = scene.emission.max(axis=1)[scene.material_ids] > 0
    return build_atlas(texels.values, texels.filled, texels.charts, emits[texels.charts.tri])


__all__ = ["PAGE", "Charts", "Lightmaps", "TexelSet", "atlas_for", "build_atlas", "charts_for", "finish",
           "pack_quadtree", "per_triangle_charts", "preview_texels", "texel_size_for"]
