"""Charted lightmap UVs by xatlas (`--uv xatlas`, docs/design.md section 8):
charts over connected triangles, packed at a texel density (texels per
scene unit) into 512 x 512 pages, as many as needed, with PADDING texels
between charts for bilinear filtering. A two-sided triangle's back is
charted as a triangle of its own (wound the other way).

Texels: each page texel belongs to the triangle whose UV triangle is
nearest its centre (within COVER texels: the texels bilinear lookups on
the triangles read); its sample point is that triangle's point nearest the
centre, moved inward (texels.inset). The rest of the page is filled from them (dilation
into the padding).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from .atlas import PAGE
from .texels import COVER, closest_on_triangle, inset, open_edges

PADDING = 2


@dataclass(frozen=True)
class XatlasLayout:
    """tri (m,) int32 and back (m,) bool: the charted triangle sides;
    page (m,) int32; uv (m, 3, 2) float64 the triangle's corners (in the
    scene's order, backs too) in page texels (0..PAGE, v down); n_pages; texel: scene units per texel; charts: xatlas charts;
    utilization: mean share of a page's texels the charts cover;
    borrowed (m,) bool: sides xatlas left out of every chart (it drops
    faces whose area it rounds to nothing), which read a neighbour's
    texel (borrowed_uv) and own none."""
    tri: np.ndarray
    back: np.ndarray
    page: np.ndarray
    uv: np.ndarray
    n_pages: int
    texel: float
    charts: int
    utilization: float
    borrowed: np.ndarray | None = None

    per_triangle = False  # the Layout protocol (lightmap/values.py): a page's neighbour may be another chart

    def __len__(self):
        return len(self.tri)

    @property
    def chart_count(self) -> int:
        return int(self.charts)

    @property
    def min_texel(self) -> float:
        return float(self.texel)

    def subtexel_charts(self) -> np.ndarray:
        return np.zeros(0, np.int64)  # texels follow the surface's area, not its triangles

    def sample(self, corners, inset=0.0, bvh=None, lift=0.0, open_edge=None):
        """The Layout protocol's texel points (lightmap/values.py: sample_points)."""
        point, covered, tri, back, face = xatlas_texels(self, corners, inset, open_edge)
        size = np.full(self.n_pages, PAGE, np.int64)
        off = np.arange(self.n_pages + 1, dtype=np.int64) * PAGE * PAGE
        return off, size, point, covered, tri, back, face, self.uv

    def pages(self, texels, emits):
        """The Layout protocol's atlas: the pages as they are (charts are
        not deduplicated); each page's scale from its non-emitter texels."""
        from .atlas import Lightmaps, to_stored
        n = self.n_pages
        pages = to_stored(texels.values).astype(np.float32).reshape(n, PAGE, PAGE, 3)
        lit = (texels.texel_tri >= 0) & ~emits[np.maximum(texels.texel_tri, 0)]
        scale = np.array([float(pages[p].reshape(-1, 3)[lit.reshape(n, -1)[p]].max(initial=0.0)) or
                          float(pages[p].max()) for p in range(n)], np.float32)
        counts = {"maps": int(self.charts), "unique": int(self.charts), "constant": 0,
                  "texels": int(n * PAGE * PAGE), "texels_stored": int(texels.covered.sum()), "pages": int(n)}
        return Lightmaps(pages, self.page.astype(np.int32), (self.uv / PAGE).astype(np.float32), scale, counts)


def xatlas_layout(vertices, triangles, two_sided, texel_size) -> XatlasLayout:
    """vertices (nv, 3), triangles (nt, 3) (shared corners: charts follow
    connectivity), two_sided (nt,) bool."""
    import xatlas
    corners = vertices[triangles].astype(np.float64)
    good = np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1) > 0
    front = np.nonzero(good)[0]
    backs = np.nonzero(good & two_sided)[0]
    nv = len(vertices)
    pos = np.concatenate([vertices, vertices]).astype(np.float32)  # backs use the second copy: their own charts
    faces = np.concatenate([triangles[front], triangles[backs][:, ::-1] + nv]).astype(np.uint32)
    tri = np.concatenate([front, backs]).astype(np.int32)
    back = np.concatenate([np.zeros(len(front), bool), np.ones(len(backs), bool)])
    texel = float(texel_size)
    for _ in range(16):
        atlas = xatlas.Atlas()
        atlas.add_mesh(pos, faces)
        po = xatlas.PackOptions()
        po.resolution = PAGE
        po.texels_per_unit = 1.0 / texel
        po.padding = PADDING
        po.bilinear = True
        atlas.generate(xatlas.ChartOptions(), po)
        if atlas.width <= PAGE and atlas.height <= PAGE:
            break
        texel *= max(atlas.width, atlas.height) / PAGE * 1.05  # a chart too large for a page: coarser texels
    vmap, idx, uvs = atlas[0]
    page_of_vertex, _ = atlas.get_mesh_vertex_assignment(0)
    idx = idx.reshape(-1, 3)
    uv = uvs[idx].astype(np.float64) * [atlas.width, atlas.height]
    uv[back] = uv[back][:, [0, 2, 1]]  # backs were charted wound the other way: back to the triangle's order
    page = page_of_vertex[idx[:, 0]].astype(np.int32)
    borrowed = page < 0
    if borrowed.any():
        page, uv = borrowed_uv(triangles, corners, tri, back, page, uv)
    return XatlasLayout(tri, back, page, uv, int(atlas.atlas_count), texel, int(atlas.chart_count),
                        float(atlas.utilization if np.isscalar(atlas.utilization) else np.mean(atlas.utilization)),
                        borrowed)


def borrowed_uv(triangles, corners, tri, back, page, uv):
    """(page, uv) where every side xatlas left uncharted (page -1: slivers
    whose area it rounds to nothing, far under a texel) takes the page and
    the UV centroid of a charted side of the same facing, one sharing a
    corner vertex where there is one, else the one whose centroid is
    nearest: it reads that texel's light (its UV triangle is a point, so
    it covers no texel of its own)."""
    page, uv = page.copy(), uv.copy()
    lost = np.nonzero(page < 0)[0]
    kept = np.nonzero(page >= 0)[0]
    if not len(kept):
        raise ValueError("xatlas charted no triangle")
    donor = np.full(len(lost), -1, np.int64)
    key = (triangles[tri[kept]].astype(np.int64) * 2 + back[kept, None]).ravel()   # (vertex, facing) -> a side
    order = np.argsort(key, kind="stable")
    skey = key[order]
    for k in range(3):
        want = triangles[tri[lost], k].astype(np.int64) * 2 + back[lost]
        at = np.minimum(np.searchsorted(skey, want), len(skey) - 1)
        hit = (skey[at] == want) & (donor < 0)
        donor[hit] = kept[order[at[hit]] // 3]
    centre = corners[tri].mean(axis=1)
    for facing in (False, True):   # isolated slivers: the nearest charted side of the same facing
        alone = np.nonzero((donor < 0) & (back[lost] == facing))[0]
        if not len(alone):
            continue
        pool = kept[back[kept] == facing]
        pool = pool if len(pool) else kept
        order = np.argsort(centre[pool, 0], kind="stable")
        donor[alone] = pool[order[_nearest(np.ascontiguousarray(centre[pool[order]]),
                                           np.ascontiguousarray(centre[lost[alone]]))]]
    page[lost] = page[donor]
    uv[lost] = uv[donor].mean(axis=1, keepdims=True)
    return page, uv


@njit(cache=True)
def _nearest(points, queries):
    """For each query (m, 3), the index of the nearest of `points` (k, 3),
    sorted by x: a sweep outwards from the query's x that stops once the x
    gap alone exceeds the best distance (ties: the lower index)."""
    out = np.zeros(queries.shape[0], np.int64)
    xs = points[:, 0]
    for i in range(queries.shape[0]):
        qx, qy, qz = queries[i, 0], queries[i, 1], queries[i, 2]
        start = np.searchsorted(xs, qx)
        best, at = np.inf, 0
        for step in (-1, 1):
            j = start if step == 1 else start - 1
            while 0 <= j < xs.shape[0]:
                gap = xs[j] - qx
                if gap * gap > best:
                    break
                d = gap * gap + (points[j, 1] - qy) ** 2 + (points[j, 2] - qz) ** 2
                if d < best or (d == best and j < at):
                    best, at = d, j
                j += step
        out[i] = at
    return out


@njit(cache=True)
def _rasterize(uv, page, n_pages, size, amount, tri, open_edge):
    """Per texel of every page: the face nearest its centre within COVER
    (-1: none) and the barycentrics of that face's point nearest it, kept
    `amount` texels in from the open edges of its triangle tri[face]
    (open_edge (nt, 3) bool: texels.inset)."""
    n = n_pages * size * size
    face = np.full(n, -1, np.int32)
    best = np.full(n, np.inf)
    bary = np.zeros((n, 3))
    for f in range(uv.shape[0]):
        if page[f] < 0:
            continue
        q = uv[f]
        x0 = max(0, int(np.floor(min(q[0, 0], q[1, 0], q[2, 0]) - COVER)))
        x1 = min(size - 1, int(np.ceil(max(q[0, 0], q[1, 0], q[2, 0]) + COVER)))
        y0 = max(0, int(np.floor(min(q[0, 1], q[1, 1], q[2, 1]) - COVER)))
        y1 = min(size - 1, int(np.ceil(max(q[0, 1], q[1, 1], q[2, 1]) + COVER)))
        base = page[f] * size * size
        for j in range(y0, y1 + 1):
            for i in range(x0, x1 + 1):
                px, py = i + 0.5, j + 0.5
                wa, wb, wc = closest_on_triangle(px, py, q[0, 0], q[0, 1], q[1, 0], q[1, 1], q[2, 0], q[2, 1])
                dx = wa * q[0, 0] + wb * q[1, 0] + wc * q[2, 0] - px
                dy = wa * q[0, 1] + wb * q[1, 1] + wc * q[2, 1] - py
                d = dx * dx + dy * dy
                k = base + j * size + i
                if d <= COVER * COVER and d < best[k]:
                    best[k] = d
                    face[k] = f
                    t = tri[f]
                    bary[k, 0], bary[k, 1], bary[k, 2] = inset(wa, wb, wc, q, amount, open_edge[t, 0],
                                                               open_edge[t, 1], open_edge[t, 2])
    return face, bary


def xatlas_texels(layout: XatlasLayout, corners, amount=0.0, open_edge=None):
    """Sample points (N, 3), covered (N,), texel_tri (N,) int32, texel_back
    (N,) bool and face (N,) int32 (the layout's triangle side, -1: none) of
    every texel of every page (page-major, row-major)."""
    page = layout.page
    if layout.borrowed is not None and layout.borrowed.any():
        page = np.where(layout.borrowed, -1, page).astype(np.int32)   # a borrowing side owns no texel
    if open_edge is None:
        open_edge = open_edges(corners) if amount > 0 else np.zeros((len(corners), 3), bool)   # (unread at 0)
    face, bary = _rasterize(layout.uv, page, layout.n_pages, PAGE, float(amount), layout.tri.astype(np.int64),
                            open_edge)
    covered = face >= 0
    f = np.where(covered, face, 0)
    tri = layout.tri[f]
    c = corners[tri]
    point = np.einsum("nk,nkc->nc", bary, c)
    texel_tri = np.where(covered, tri, -1).astype(np.int32)
    texel_back = np.where(covered, layout.back[f], False)
    return point, covered, texel_tri, texel_back, face
