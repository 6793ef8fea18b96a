"""Stage 5, lightmaps: charts (one square map per lit triangle side, or
xatlas charts on pages), texels (sample points, inside-geometry test,
fill), texel values (the preview tier: the voxel solution reconstructed at
each texel) and atlases (single-colour maps, deduplication, quadtree
pages)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .atlas import PAGE, Lightmaps, build_atlas, pack_quadtree
from .charts import Charts, per_triangle_charts
from .texels import INSET, fill, inside_geometry, texel_points
from .voxel_irradiance import reconstruct
from .xatlas_charts import XatlasLayout, xatlas_layout, xatlas_texels

LIFT = 0.25   # cells (or texels, the smaller): texel points are lifted this far off their surface for rays


@dataclass(frozen=True)
class TexelSet:
    """The texels of every map, flat: map m (a per-triangle chart or an
    xatlas page) is the square map_size[m]^2 at map_offsets[m].
    layout: Charts or XatlasLayout; texel_tri (N,) int32 the triangle a
    texel samples (-1: none) and texel_back (N,) bool its back side;
    point (N, 3) float64 sample points; covered (N,) bool; inside (N,)
    bool covered texels hidden inside geometry; values (N, 3) float64 H
    after the fill; filled (N,) bool."""
    layout: object
    map_offsets: np.ndarray
    map_size: np.ndarray
    texel_tri: np.ndarray
    texel_back: np.ndarray
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


def layout_for(scene, texel_size, uv="per-triangle"):
    """Charts (per-triangle) or XatlasLayout (xatlas)."""
    if uv == "xatlas":
        return xatlas_layout(scene.vertices, scene.triangles, scene.double_sided[scene.material_ids], texel_size)
    return charts_for(scene, texel_size)


def sample_points(layout, corners, inset=0.0):
    """(map_offsets, map_size, point, covered, texel_tri, texel_back);
    points clamped onto an edge move `inset` texels inward (texels.inset)."""
    if isinstance(layout, XatlasLayout):
        point, covered, tri, back = xatlas_texels(layout, corners, inset)
        size = np.full(layout.n_pages, PAGE, np.int64)
        off = np.arange(layout.n_pages + 1, dtype=np.int64) * PAGE * PAGE
        return off, size, point, covered, tri, back
    off = layout.offsets
    size = layout.size.astype(np.int64)
    point, covered = texel_points(corners, layout.tri, layout.corners2d, layout.size, off, float(inset))
    per = np.repeat(np.arange(len(layout)), size ** 2)
    return off, size, point, covered, layout.tri[per].astype(np.int32), layout.back[per]


def preview_texels(scene, solution, bvh, surfaces, layout, seed=0) -> TexelSet:
    """The preview tier: texel values from the voxel solution."""
    vox = solution.voxels
    h = float(vox.cell_size)
    corners = surfaces.arrays.corners
    off, size, point, covered, ttri, tback = sample_points(layout, corners)
    texel = float(np.min(layout.texel)) if isinstance(layout, Charts) else layout.texel
    lift = LIFT * min(h, texel)
    inside = inside_geometry(bvh.arrays, surfaces.arrays.double_sided, surfaces.arrays.tri_material, corners, ttri,
                             tback, point, covered, lift, np.inf, seed)
    values, found = reconstruct(bvh.arrays, corners, ttri, tback, point, covered,
                                np.ascontiguousarray(solution.irradiance), vox.key, vox.cell, vox.centroid,
                                vox.normal, vox.area, vox.cut_plane, vox.cut_sign, vox.piece_key, vox.piece_voxel,
                                vox.piece_plane, vox.piece_sign, vox.side_start, vox.back_side, vox.origin, h,
                                vox.dims, lift)
    return finish(layout, off, size, ttri, tback, point, covered, inside, values, found)


def side_normals(corners, texel_tri, texel_back):
    """(N, 3) unit normal of each texel's triangle side (0 where none)."""
    n = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    out = n[np.maximum(texel_tri, 0)]
    out[texel_back] *= -1
    out[texel_tri < 0] = 0
    return out


def lightcuts_texels(scene, solution, bvh, surfaces, layout, lights, epsilon=0.02, cap=1000, seed=0,
                     progress=None) -> TexelSet:
    """The default and high tiers: each texel's irradiance by lightcuts over
    the VPLs (direct light from the emitters' VPLs with shadow rays, the
    indirect from the voxels'), at its sample point, on its side."""
    from ..lights import irradiance
    from ..startup import checkpoint
    h = float(solution.voxels.cell_size)
    corners = surfaces.arrays.corners
    off, size, point, covered, ttri, tback = sample_points(layout, corners, INSET)
    texel = float(np.min(layout.texel)) if isinstance(layout, Charts) else layout.texel
    lift = LIFT * min(h, texel)
    inside = inside_geometry(bvh.arrays, surfaces.arrays.double_sided, surfaces.arrays.tri_material, corners, ttri,
                             tback, point, covered, lift, np.inf, seed)
    normals = side_normals(corners, ttri, tback)
    todo = np.nonzero(covered & (ttri >= 0))[0]
    values = np.zeros((len(point), 3))
    cuts = np.zeros(len(point), np.int64)
    rays = np.zeros(len(point), np.int64)
    batch = 1 << 15
    for a in range(0, len(todo), batch):
        idx = todo[a:a + batch]
        values[idx], cuts[idx], rays[idx] = irradiance(lights, bvh, surfaces, point[idx], normals[idx], None, lift,
                                                       epsilon, cap)
        checkpoint()
        if progress is not None:
            progress(len(idx))
    found = covered & (ttri >= 0)
    ts = finish(layout, off, size, ttri, tback, point, covered, inside, values, found)
    shaded = found & ~inside
    stats = {"cut_mean": float(cuts[shaded].mean()) if shaded.any() else 0.0, "cut_max": int(cuts.max(initial=0)),
             "shadow_rays": int(rays.sum()), "texels_shaded": int(found.sum())}
    return ts, stats


def finish(layout, off, size, ttri, tback, point, covered, inside, values, found) -> TexelSet:
    """Texels inside geometry next to a valid one take their valid
    neighbours' mean (one ring: what bilinear filtering at the object's
    outline reads), the other covered ones keep their own value, and the
    texels around the triangles are filled from them (texels.py)."""
    valid = covered & found & ~inside
    values = np.where((covered & found)[:, None], values, 0.0)
    filled = valid.copy()
    fill(values, filled, off, size, 1, covered & found & inside)
    filled |= covered & found  # deeper inside texels: their own value
    fill(values, filled, off, size)
    return TexelSet(layout, off, size, ttri, tback, point, covered, inside, values, filled)


def atlas_for(scene, texels: TexelSet) -> Lightmaps:
    emits = scene.emission.max(axis=1)[scene.material_ids] > 0
    layout = texels.layout
    if isinstance(layout, XatlasLayout):
        return pages_for(layout, texels, emits)
    return build_atlas(texels.values, texels.filled, layout, emits[layout.tri])


def pages_for(layout, texels, emits) -> Lightmaps:
    """xatlas pages as they are (charts are not deduplicated); each page's
    scale from its non-emitter texels."""
    from .atlas import to_stored
    n = layout.n_pages
    pages = to_stored(texels.values).astype(np.float32).reshape(n, PAGE, PAGE, 3)
    lit = (texels.texel_tri >= 0) & ~emits[np.maximum(texels.texel_tri, 0)]
    scale = np.array([float(pages[p].reshape(-1, 3)[lit.reshape(n, -1)[p]].max(initial=0.0)) or
                      float(pages[p].max()) for p in range(n)], np.float32)
    counts = {"maps": int(layout.charts), "unique": int(layout.charts), "constant": 0,
              "texels": int(n * PAGE * PAGE), "texels_stored": int(texels.covered.sum()), "pages": int(n)}
    return Lightmaps(pages, layout.page.astype(np.int32), (layout.uv / PAGE).astype(np.float32), scale, counts)


__all__ = ["PAGE", "Charts", "Lightmaps", "TexelSet", "XatlasLayout", "atlas_for", "build_atlas", "charts_for",
           "finish", "layout_for", "lightcuts_texels", "pack_quadtree", "per_triangle_charts", "preview_texels", "texel_size_for"]
