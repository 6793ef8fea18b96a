"""Coplanar triangles that overlap (docs/design.md section 2, "Which
geometry is handled how").

Two triangles in one plane, facing the same way, that overlap in part are
one surface there: a file that tiles a floor twice, a decal or a lamp
modelled on the ceiling's own plane, a face repeated with other corners.
Each would count in the voxels' area, the emitters' power and the
lightmaps, so the overlap would be lit (or emit) twice. `cut_overlaps`
cuts the overlapping part out of all but one of them, at loading, so the
union of the surface counts once:

- triangles are grouped by plane (normal within 1e-4, offset within 1e-5
  of the scene's size) and ranked: emitters first (a lamp on the ceiling's
  plane stays a lamp), then two-sided, then file order;
- each triangle loses the parts that a higher-ranked triangle of its
  plane covers on every face it has: a one-sided triangle is covered by
  a higher one facing the same way or by a two-sided one; a two-sided
  triangle only by a two-sided one (a one-sided lamp on a two-sided
  ceiling is left as it is, and the audit reports it);
- what remains of it is split into convex pieces (P minus a triangle:
  at most three convex parts), each fanned into triangles whose corners
  interpolate the original's normals and texture coordinates.

Triangles that only touch (share an edge, meet along a line) do not
overlap: an overlap under OVERLAP_FRAC of the smaller triangle's area is
rounding, left alone.
"""
from __future__ import annotations

import numpy as np
from numba import njit

OVERLAP_FRAC = 1e-6   # overlaps below this fraction of a triangle's area are rounding
SLIVER_FRAC = 1e-7    # remaining pieces below this fraction of the triangle's area are dropped
MAX_PIECES = 256      # a triangle whose remainder would need more convex pieces is left whole (with a warning)


@njit(cache=True)
def clip_half(px, py, m, x0, y0, x1, y1, keep_left):
    """The convex polygon (px, py)[:m] clipped to the half-plane left of
    (keep_left) or right of the directed line (x0, y0) -> (x1, y1)."""
    # a convex polygon gains at most one corner, but one that rounding left slightly non-convex can gain one
    # per edge: room for two per edge, never a write past the end
    qx = np.empty(2 * m + 1)
    qy = np.empty(2 * m + 1)
    n = 0
    sgn = 1.0 if keep_left else -1.0
    for i in range(m):
        j = (i + 1) % m
        si = sgn * ((x1 - x0) * (py[i] - y0) - (y1 - y0) * (px[i] - x0))
        sj = sgn * ((x1 - x0) * (py[j] - y0) - (y1 - y0) * (px[j] - x0))
        if si >= 0:
            qx[n] = px[i]
            qy[n] = py[i]
            n += 1
        if (si >= 0) != (sj >= 0):
            t = si / (si - sj)
            qx[n] = px[i] + t * (px[j] - px[i])
            qy[n] = py[i] + t * (py[j] - py[i])
            n += 1
    return qx, qy, n


@njit(cache=True)
def polygon_area(px, py, m):
    a = 0.0
    for k in range(m):
        a += px[k] * py[(k + 1) % m] - px[(k + 1) % m] * py[k]
    return 0.5 * a


@njit(cache=True)
def overlap_area(uv, ti, tj):
    """Area of triangle ti inside triangle tj (uv (nt, 3, 2), counter-clockwise)."""
    px = np.array([uv[ti, 0, 0], uv[ti, 1, 0], uv[ti, 2, 0]])
    py = np.array([uv[ti, 0, 1], uv[ti, 1, 1], uv[ti, 2, 1]])
    m = 3
    for k in range(3):
        px, py, m = clip_half(px, py, m, uv[tj, k, 0], uv[tj, k, 1], uv[tj, (k + 1) % 3, 0],
                              uv[tj, (k + 1) % 3, 1], True)
        if m == 0:
            return 0.0
    return polygon_area(px, py, m)


@njit(cache=True)
def _boxes_apart(uv, ti, tj):
    for c in range(2):
        if max(uv[ti, 0, c], uv[ti, 1, c], uv[ti, 2, c]) <= min(uv[tj, 0, c], uv[tj, 1, c], uv[tj, 2, c]) or \
                max(uv[tj, 0, c], uv[tj, 1, c], uv[tj, 2, c]) <= min(uv[ti, 0, c], uv[ti, 1, c], uv[ti, 2, c]):
            return True
    return False


@njit(cache=True)
def overlap_pairs(uv, order, starts, min_frac):
    """Pairs (a, b) of triangles of one group (order[starts[g]:starts[g+1]],
    in rank order) that overlap by more than min_frac of the smaller's
    area, a ranked before b; and each pair's overlap area. A sweep along u
    in each group: O(n log n + pairs whose u-extents meet)."""
    cap = 16
    pa = np.empty(cap, np.int64)
    pb = np.empty(cap, np.int64)
    ar = np.empty(cap)
    n = 0
    for g in range(starts.shape[0] - 1):
        lo, hi = starts[g], starts[g + 1]
        members = order[lo:hi]
        umin = np.empty(hi - lo)
        umax = np.empty(hi - lo)
        for i in range(hi - lo):
            t = members[i]
            umin[i] = min(uv[t, 0, 0], uv[t, 1, 0], uv[t, 2, 0])
            umax[i] = max(uv[t, 0, 0], uv[t, 1, 0], uv[t, 2, 0])
        sweep = np.argsort(umin, kind="mergesort")
        for x in range(hi - lo):
            i = sweep[x]
            for y in range(x + 1, hi - lo):
                j = sweep[y]
                if umin[j] >= umax[i]:
                    break
                if i > j:  # rank order: the group's earlier member first
                    ti, tj = members[j], members[i]
                else:
                    ti, tj = members[i], members[j]
                if _boxes_apart(uv, ti, tj):
                    continue
                a = overlap_area(uv, ti, tj)
                ai = abs(polygon_area(uv[ti, :, 0], uv[ti, :, 1], 3))
                aj = abs(polygon_area(uv[tj, :, 0], uv[tj, :, 1], 3))
                if a > min_frac * min(ai, aj):
                    if n == cap:
                        cap *= 2
                        pa2 = np.empty(cap, np.int64)
                        pb2 = np.empty(cap, np.int64)
                        ar2 = np.empty(cap)
                        pa2[:n] = pa[:n]
                        pb2[:n] = pb[:n]
                        ar2[:n] = ar[:n]
                        pa, pb, ar = pa2, pb2, ar2
                    pa[n] = ti
                    pb[n] = tj
                    ar[n] = a
                    n += 1
    return pa[:n], pb[:n], ar[:n]


def plane_groups(corners, rank=None, canonical=False):
    """Triangles grouped by plane: (uv (nt, 3, 2) corners projected on the
    plane's dominant axis, counter-clockwise seen from the front of each
    triangle (canonical=False) or of its plane's canonical side, order
    (nt,) triangles sorted by group then rank, starts (ng + 1,) of the
    groups with more than one triangle in order, flipped (nt,) bool: the
    triangle faces against its plane's canonical side)."""
    corners = np.asarray(corners, np.float64)
    nt = len(corners)
    cross = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    norm = np.linalg.norm(cross, axis=1)
    n = np.where((norm > 0)[:, None], cross / np.maximum(norm, 1e-300)[:, None], 0.0)
    flipped = np.zeros(nt, bool)
    if canonical:  # one side of each plane: the largest component of the normal positive
        ax = np.argmax(np.abs(n), axis=1)
        flipped = n[np.arange(nt), ax] < 0
        n = np.where(flipped[:, None], -n, n)
    scale = float(np.abs(corners).max()) or 1.0
    d = np.einsum("ij,ij->i", n, corners[:, 0])
    key = np.concatenate([np.round(n * 1e4), np.round(d / scale * 1e5)[:, None]], axis=1).astype(np.int64)
    rank = np.arange(nt) if rank is None else np.asarray(rank)
    order = np.lexsort(np.vstack([rank[None], key.T[::-1]]))
    ks = key[order]
    new = np.ones(nt, bool)
    new[1:] = (ks[1:] != ks[:-1]).any(axis=1)
    starts = np.append(np.flatnonzero(new), nt).astype(np.int64)
    big = np.diff(starts) > 1
    keep = np.zeros(nt, bool)
    for s, e in zip(starts[:-1][big], starts[1:][big]):
        keep[s:e] = True
    order = order[keep].astype(np.int64)
    sizes = np.diff(starts)[big]
    starts = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    axis = np.argmax(np.abs(n), axis=1)
    u_ax, v_ax = (axis + 1) % 3, (axis + 2) % 3
    idx = np.arange(nt)
    uv = np.stack([corners[idx[:, None], [0, 1, 2], u_ax[:, None]], corners[idx[:, None], [0, 1, 2], v_ax[:, None]]],
                  axis=2)
    ccw = n[idx, axis] > 0  # the projection keeps the winding seen from +axis
    if canonical:
        ccw = ~flipped
    uv[~ccw] = uv[~ccw][:, [0, 2, 1]]
    return np.ascontiguousarray(uv), order, starts, flipped, ~ccw


def _subtract(poly, tri):
    """Convex polygon (k, 2) minus the counter-clockwise triangle tri (3, 2):
    a list of convex polygons (the part outside edge 0; inside 0, outside 1;
    inside 0 and 1, outside 2)."""
    out = []
    px, py, m = poly[:, 0].copy(), poly[:, 1].copy(), len(poly)
    for k in range(3):
        a, b = tri[k], tri[(k + 1) % 3]
        ox, oy, mo = clip_half(px, py, m, a[0], a[1], b[0], b[1], False)
        if mo >= 3:
            out.append(np.stack([ox[:mo], oy[:mo]], axis=1))
        px, py, m = clip_half(px, py, m, a[0], a[1], b[0], b[1], True)
        if m < 3:
            break
    return out


def cut_overlaps(vertices, triangles, material_ids, emits, two_sided, normals=None, uvs=None):
    """Cut from each triangle what a higher-ranked coplanar triangle covers
    (module docstring). vertices (nv, 3) float64; triangles (nt, 3);
    material_ids (nt,); emits, two_sided (nm,) bool per material; normals
    (nv, 3), uvs (nv, 2) or None. Returns (vertices, triangles,
    material_ids, normals, uvs, cut) with the new corners appended and
    each cut triangle replaced by its remaining pieces (at the end), and
    cut = (number of triangles cut, overlapping area removed, number of
    triangles left whole because their pieces would exceed MAX_PIECES)."""
    corners = vertices[triangles].astype(np.float64)
    em = np.asarray(emits, bool)[material_ids]
    ds = np.asarray(two_sided, bool)[material_ids]
    nt = len(triangles)
    rank = np.lexsort([np.arange(nt), ~ds, ~em])  # emitters, then two-sided, then file order
    pos = np.empty(nt, np.int64)
    pos[rank] = np.arange(nt)
    uv, order, starts, flipped, mirrored = plane_groups(corners, pos, canonical=True)
    if len(order) == 0:
        return vertices, triangles, material_ids, normals, uvs, (0, 0.0, 0)
    a, b, _ = overlap_pairs(uv, order, starts, OVERLAP_FRAC)
    # b loses what a covers where a has every face b has
    covers = ds[a] | (~ds[b] & (flipped[a] == flipped[b]))
    a, b = a[covers], b[covers]
    if len(b) == 0:
        return vertices, triangles, material_ids, normals, uvs, (0, 0.0, 0)
    sort = np.argsort(b, kind="stable")
    a, b = a[sort], b[sort]
    cut_tris, first = np.unique(b, return_index=True)
    last = np.append(first[1:], len(b))  # b sorted: triangle cut_tris[i]'s coverers are a[first[i]:last[i]]
    new_v, new_n, new_uv, new_t, new_m = [], [], [], [], []
    base = len(vertices)  # index of the next new corner
    removed = 0.0
    drop = np.zeros(nt, bool)
    too_many = 0
    for t, lo, hi in zip(cut_tris, first, last):
        tri_uv = uv[t]
        area = _area2(tri_uv)
        polys = [tri_uv.copy()]
        for s in a[lo:hi]:
            # only the pieces s overlaps are split: the others stay whole (a floor under many pot bases)
            polys = [q for p in polys for q in (_subtract(p, uv[s]) if _overlap(p, uv[s], SLIVER_FRAC * area)
                                                 else (p,))]
            if len(polys) > MAX_PIECES:
                break
        if len(polys) > MAX_PIECES:  # a pathological case: keep the triangle as it is
            too_many += 1
            continue
        polys = [p for p in polys if _area2(p) > SLIVER_FRAC * area]
        kept = sum(_area2(p) for p in polys)
        removed += (area - kept) / max(area, 1e-300) * _area3(corners[t])
        drop[t] = True
        # barycentric coordinates in the (projected) triangle: affine, so exact on its plane
        t0, t1, t2 = tri_uv
        m = np.array([[t1[0] - t0[0], t2[0] - t0[0]], [t1[1] - t0[1], t2[1] - t0[1]]])
        inv = np.linalg.inv(m)
        order_c = [0, 2, 1] if mirrored[t] else [0, 1, 2]  # uv corners in the triangle's own corner order
        src = triangles[t][order_c]
        for p in polys:
            w12 = (p - t0) @ inv.T
            w = np.column_stack([1 - w12.sum(axis=1), w12])
            new_v.append(w @ vertices[src].astype(np.float64))
            if normals is not None:
                nn = w @ normals[src].astype(np.float64)
                new_n.append(nn / np.maximum(np.linalg.norm(nn, axis=1, keepdims=True), 1e-30))
            if uvs is not None:
                new_uv.append(w @ uvs[src].astype(np.float64))
            k = len(p)
            fan = np.array([[base, base + i, base + i + 1] for i in range(1, k - 1)], np.int64)
            if mirrored[t]:  # the polygon runs against the triangle's winding
                fan = fan[:, [0, 2, 1]]
            new_t.append(fan)
            new_m.append(np.full(len(fan), material_ids[t]))
            base += k
    keep = ~drop
    vertices = np.concatenate([vertices] + new_v) if new_v else vertices
    if normals is not None and new_n:
        normals = np.concatenate([normals] + new_n)
    if uvs is not None and new_uv:
        uvs = np.concatenate([uvs] + new_uv)
    triangles = np.concatenate([triangles[keep]] + new_t) if new_t else triangles[keep]
    material_ids = np.concatenate([material_ids[keep]] + new_m) if new_m else material_ids[keep]
    return vertices, triangles, material_ids, normals, uvs, (int(drop.sum()), float(removed), too_many)


def _overlap(poly, tri, min_area) -> bool:
    """Does the counter-clockwise triangle tri (3, 2) cover more than
    min_area of the convex polygon poly (k, 2)?"""
    if (poly.max(axis=0) <= tri.min(axis=0)).any() or (tri.max(axis=0) <= poly.min(axis=0)).any():
        return False
    px, py, m = poly[:, 0].copy(), poly[:, 1].copy(), len(poly)
    for k in range(3):
        a, b = tri[k], tri[(k + 1) % 3]
        px, py, m = clip_half(px, py, m, a[0], a[1], b[0], b[1], True)
        if m < 3:
            return False
    return abs(polygon_area(px, py, m)) > min_area


def _area2(p):
    """Area of a convex polygon (k, 2)."""
    return abs(polygon_area(p[:, 0].copy(), p[:, 1].copy(), len(p)))


def _area3(c):
    return 0.5 * float(np.linalg.norm(np.cross(c[1] - c[0], c[2] - c[0])))
