"""Per-triangle lightmap charts: the thesis's texture method (docs/design.md
section 8).

Each lit side of a triangle gets its own square map: the triangle is
projected on the plane of its dominant axis, its bounding rectangle is
taken in texel units (texel size = one voxel cell by default), BORDER
texels are added on every side and the square is rounded up to a power of
two (at least MIN_SIZE, at most MAX_SIZE: a triangle too large for a page
gets coarser texels, one smaller than the smallest map's interior finer
ones that fill it). A two-sided triangle has two charts (front and
back): the two faces of a thin wall see different light.

Charts are flat arrays: chart c belongs to triangle `tri[c]` (its back if
`back[c]`), projects along `axis[c]`, and its texel (i, j) (column i, row
j) has its centre at 2D point `(origin[c] + (i + 0.5, j + 0.5)) *
texel[c]` in the projection plane's coordinates (u, v) = the two other
axes in increasing order.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

BORDER = 2        # texels around the triangle's bounding rectangle
MIN_SIZE = 8      # the smallest map (and the quadtree's smallest node)
MAX_SIZE = 512    # a page: no map is larger
MAX_REFINE = 16   # a small triangle's texels are at most this much finer than the texel size asked for
SUBTEXEL_SPAN = 2  # texels: triangles no wider are shaded at their corners (Charts.subtexel)
CENTROID_SPAN = 0.5  # texels: triangles no wider are shaded once, at their centroid (Charts.centroid)


@dataclass(frozen=True)
class Charts:
    """tri (nc,) int32; back (nc,) bool; axis (nc,) int8 dominant axis;
    origin (nc, 2) float64 lower corner in texel units; size (nc,) int32
    power-of-two side; texel (nc,) float64 texel size in scene units;
    corners2d (nc, 3, 2) float64 the triangle's corners in the chart's
    texel units (0 .. size), the per-triangle UVs times size; subtexel
    (nc,) bool: the triangle is no wider than SUBTEXEL_SPAN texels of the
    size asked for (a scan's or a dense mesh's triangle), so its light is
    sampled at its three corners and interpolated over its map, not texel
    by texel (lightmap/values.py: corner_values): at that density its own texels
    would sample it at no more than about SUBTEXEL_SPAN^2 / 2 = 2 points;
    span (nc,) float64: the triangle's extent in texels of the size asked
    for (on its projection plane)."""
    tri: np.ndarray
    back: np.ndarray
    axis: np.ndarray
    origin: np.ndarray
    size: np.ndarray
    texel: np.ndarray
    corners2d: np.ndarray
    subtexel: np.ndarray
    span: np.ndarray

    per_triangle = True  # the Layout protocol (lightmap/values.py): maps follow triangles

    def __len__(self):
        return len(self.tri)

    @property
    def chart_count(self) -> int:
        return len(self.tri)

    @property
    def min_texel(self) -> float:
        return float(np.min(self.texel))

    def subtexel_charts(self) -> np.ndarray:
        """The charts shaded at their corners (lightmap/values.py: corner_values)."""
        return np.nonzero(self.subtexel)[0]

    @property
    def centroid(self) -> np.ndarray:
        """(nc,) bool: sub-texel triangles no wider than CENTROID_SPAN
        texels (a dense mesh's, a scan's), shaded once at their centroid:
        the light over a triangle that small is the light of a point (its
        map is constant), and three corner points would triple the cost."""
        return self.subtexel & (self.span <= CENTROID_SPAN)

    def sample(self, corners, inset=0.0, bvh=None, lift=0.0, open_edge=None):
        """The Layout protocol's texel points (lightmap/values.py: sample_points)."""
        from .texels import onto_coplanar, open_edges, texel_points
        off = self.offsets
        size = self.size.astype(np.int64)
        if open_edge is None:
            open_edge = open_edges(corners) if inset > 0 else np.zeros((len(corners), 3), bool)   # (unread at 0)
        point, covered = texel_points(corners, self.tri, self.corners2d, self.size, off, float(inset), open_edge)
        if bvh is not None:
            onto_coplanar(bvh.arrays, corners, self.tri, self.back, self.axis, self.origin, self.texel,
                          self.size, off, point, covered, float(lift), self.centroid)
        per = np.repeat(np.arange(len(self), dtype=np.int32), size ** 2)
        return off, size, point, covered, self.tri[per].astype(np.int32), self.back[per], per, self.corners2d

    def pages(self, texels, emits):
        """The Layout protocol's atlas: maps deduplicated and packed
        (atlas.build_atlas)."""
        from .atlas import build_atlas
        return build_atlas(texels.values, texels.filled, self, emits[self.tri])

    @property
    def texel_count(self) -> int:
        return int((self.size.astype(np.int64) ** 2).sum())

    @property
    def offsets(self) -> np.ndarray:
        """(nc + 1,) int64 first texel of each chart in a flat texel array."""
        return np.concatenate([[0], np.cumsum(self.size.astype(np.int64) ** 2)])


PLANE_AXES = np.array([[1, 2], [0, 2], [0, 1]])  # the projection plane's (u, v) axes for dominant axis 0, 1, 2


def _pow2(n):
    return (1 << np.ceil(np.log2(np.maximum(n, 1))).astype(np.int64)).astype(np.int64)


def per_triangle_charts(corners: np.ndarray, two_sided: np.ndarray, texel_size: float) -> Charts:
    """corners (nt, 3, 3) float64; two_sided (nt,) bool (a back chart too);
    texel_size in scene units. Degenerate triangles (zero area) get no
    chart."""
    e1 = corners[:, 1] - corners[:, 0]
    e2 = corners[:, 2] - corners[:, 0]
    n = np.cross(e1, e2)
    good = np.linalg.norm(n, axis=1) > 0
    front = np.nonzero(good)[0]
    backs = np.nonzero(good & two_sided)[0]
    tri = np.concatenate([front, backs]).astype(np.int32)
    back = np.concatenate([np.zeros(len(front), bool), np.ones(len(backs), bool)])
    order = np.lexsort((back, tri))  # a triangle's front, then its back
    tri, back = tri[order], back[order]
    axis = np.abs(n[tri]).argmax(axis=1).astype(np.int8)
    uv_axes = PLANE_AXES[axis]                                   # (nc, 2)
    c = corners[tri]                                             # (nc, 3, 3)
    p2 = np.take_along_axis(c, uv_axes[:, None, :].repeat(3, axis=1), axis=2)  # (nc, 3, 2) scene units
    texel = np.full(len(tri), float(texel_size))
    # a triangle smaller than the smallest map's interior gets finer texels that fill it: the map's texels cost
    # nothing more, and the light varies across the triangle as it does across its neighbours (at one texel per
    # triangle a finely tessellated floor shows every triangle as a flat tile)
    span = np.ptp(p2, axis=1).max(axis=1)
    fine = float(MIN_SIZE - 2 * BORDER)
    small = span < fine * texel
    subtexel = span <= SUBTEXEL_SPAN * texel
    span_texels = span / float(texel_size)
    texel[small] = np.maximum(span[small] / fine, texel[small] / MAX_REFINE)
    for _ in range(64):  # coarser texels for triangles too large for a page
        lo = p2.min(axis=1) / texel[:, None]
        hi = p2.max(axis=1) / texel[:, None]
        extent = np.ceil((hi - lo).max(axis=1) - 1e-9) + 2 * BORDER
        big = extent > MAX_SIZE
        if not big.any():
            break
        texel[big] *= extent[big] / MAX_SIZE * 1.0001
    size = np.clip(_pow2(extent), MIN_SIZE, MAX_SIZE).astype(np.int32)
    # centre the rectangle in its square, at least BORDER texels from each side
    pad = (size[:, None] - (hi - lo)) / 2
    origin = lo - pad
    corners2d = p2 / texel[:, None, None] - origin[:, None, :]
    return Charts(tri, back, axis, origin, size, texel, corners2d, subtexel, span_texels)
