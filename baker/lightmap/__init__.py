"""Stage 5, lightmaps: charts (one square map per lit triangle side, or
xatlas charts on pages), texels (sample points, inside-geometry test,
fill), texel values (values.py: the preview tier from the voxel solution,
the lightcuts tier) and atlases (single-colour maps, deduplication,
quadtree pages)."""
from .atlas import PAGE, Lightmaps, build_atlas, pack_quadtree
from .charts import Charts, per_triangle_charts
from .values import (AA_CONTRAST, TexelSet, TexelStats, atlas_for, charts_for, finish, layout_for, lightcuts_texels,
                     preview_texels, sample_points, texel_size_for)
from .xatlas_charts import XatlasLayout

__all__ = ["AA_CONTRAST", "PAGE", "Charts", "Lightmaps", "TexelSet", "TexelStats", "XatlasLayout", "atlas_for",
           "build_atlas", "charts_for", "finish", "layout_for", "lightcuts_texels", "pack_quadtree",
           "per_triangle_charts", "preview_texels", "sample_points", "texel_size_for"]
