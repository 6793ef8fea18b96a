"""Texels of the charts: where each one samples the scene, which ones lie
inside geometry, and how empty texels are filled (docs/design.md section 8).

- Sample points: texel (i, j) of a chart has its centre at (i + 0.5,
  j + 0.5) in the chart's texel units; its sample point is the point of the
  triangle shrunk by INSET texels (at most half its inradius) nearest to
  that centre: the centre itself well inside, moved straight in from the
  edge where the centre lies on or near an edge or beyond it (`inset`). A texel is *covered* when its centre lies within COVER
  texels of the triangle: those are the texels a bilinear lookup anywhere
  on the triangle reads (a lookup at x reads the centres within Chebyshev
  distance 1 of x, hence within Euclidean distance sqrt 2 < COVER).
- Inside geometry: a covered texel whose point lies where the surface is
  hidden inside a closed object (a floor under a box, a wall's end inside
  the next wall) sees the back faces of the object around it. PROBES rays
  over the hemisphere tell it (the nearest surface each meets, at any
  distance: a box's lid may be many texels above the floor under it); a texel with at least PROBE_BACK of
  them on back faces is *invalid*: its own value (the dark inside) would
  bleed into the visible texels beside it through bilinear filtering, so
  the first ring of them (the texels a bilinear lookup at the object's
  outline reads) takes its valid neighbours' mean instead; deeper ones keep
  their own value (refilling them further would carry light under a thick
  wall into the dark room beyond it).
- Fill: empty texels take the mean of their filled 4-neighbours, layer by
  layer: exactly the texels within city-block distance < FILL_DISTANCE of
  a filled texel are filled.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ..kernels.bvh import STACK_SIZE
from ..kernels.rng import keyed
from ..kernels.sampling import frame
from ..kernels.traverse import any_hit, back_hit, closest_hit, hit_normal

COVER = 1.5           # texels: centres this near the triangle are sampled
OUTSIDE = 1e-6        # texels: a centre farther than this from its triangle lies outside it (inside, the nearest
#                       point is the centre itself up to rounding, ~1e-15)
NUDGE = 1e-4          # fraction of the way towards the centroid a sample point moves
INSET = 0.5           # texels: sample points keep this far in from every edge (at most half the inradius)
FILL_DISTANCE = 4     # city-block: texels nearer than this to a filled one are filled
SAME_FACING = 0.9     # adaptive shading interpolates only between texels whose normals' cosine is at least this
PROBES = 16           # rays per texel for the inside-geometry test
PROBE_BACK = 0.6      # fraction of probes on back faces that marks a texel inside geometry (a floor texel at the
#                       foot of a one-sided wall seen from behind sees its back in half the hemisphere: not inside)
PROBE_NEAR = 0.25     # ... of which this fraction of all probes on one-sided triangles or near two-sided ones


@njit(cache=True, inline="always")
def closest_on_triangle(px, py, ax, ay, bx, by, cx, cy):
    """Barycentrics (wa, wb, wc) of the point of 2D triangle abc nearest to
    p (Ericson, Real-Time Collision Detection 5.1.5)."""
    abx, aby, acx, acy = bx - ax, by - ay, cx - ax, cy - ay
    apx, apy = px - ax, py - ay
    d1 = abx * apx + aby * apy
    d2 = acx * apx + acy * apy
    if d1 <= 0.0 and d2 <= 0.0:
        return 1.0, 0.0, 0.0
    bpx, bpy = px - bx, py - by
    d3 = abx * bpx + aby * bpy
    d4 = acx * bpx + acy * bpy
    if d3 >= 0.0 and d4 <= d3:
        return 0.0, 1.0, 0.0
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        v = d1 / (d1 - d3)
        return 1.0 - v, v, 0.0
    cpx, cpy = px - cx, py - cy
    d5 = abx * cpx + aby * cpy
    d6 = acx * cpx + acy * cpy
    if d6 >= 0.0 and d5 <= d6:
        return 0.0, 0.0, 1.0
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        w = d2 / (d2 - d6)
        return 1.0 - w, 0.0, w
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        return 0.0, 1.0 - w, w
    denom = 1.0 / (va + vb + vc)
    v = vb * denom
    w = vc * denom
    return 1.0 - v - w, v, w


@njit(cache=True, inline="always")
def inset(wa, wb, wc, q, amount, oa, ob, oc):
    """Barycentrics of a sample point moved inward: to the nearest point of
    the triangle whose open edges (oa, ob, oc: the edges opposite corners
    0, 1, 2 where no coplanar triangle continues the surface, open_edges)
    are moved `amount` texels in (at most half the inradius: a sliver
    keeps its length), then a hair towards the centroid (never exactly on
    an edge). A point on or beyond an open edge moves straight in from it;
    points deeper inside, or by an edge the surface continues across (a
    quad's diagonal, the next tile of a floor), stay where they are. At an
    open edge another surface may meet the triangle at distance 0 (a
    moulding's top flush with the ceiling: rays from a point on that line
    start on the ceiling's plane and pass it into the sky above), and
    point lights are least accurate there (the near field of a VPL); a
    bilinear lookup at the edge reads this texel half and the one inside
    half, so the edge still shows light from within half a texel.
    `amount`: INSET for lightcuts' texels; 0 for the voxel
    reconstruction's (smooth across an edge: the clamped point keeps seams
    closest)."""
    third = 1.0 / 3.0
    if amount > 0.0 and (oa or ob or oc):
        la = math.hypot(q[1, 0] - q[2, 0], q[1, 1] - q[2, 1])
        lb = math.hypot(q[2, 0] - q[0, 0], q[2, 1] - q[0, 1])
        lc = math.hypot(q[0, 0] - q[1, 0], q[0, 1] - q[1, 1])
        area2 = abs((q[1, 0] - q[0, 0]) * (q[2, 1] - q[0, 1]) - (q[2, 0] - q[0, 0]) * (q[1, 1] - q[0, 1]))
        if area2 > 0.0:
            s = min(amount, 0.5 * area2 / (la + lb + lc))
            # a point h_e in from edge e has barycentric l_e h_e / (2 area) for the corner opposite e
            fa = la * s / area2 if oa else 0.0
            fb = lb * s / area2 if ob else 0.0
            fc = lc * s / area2 if oc else 0.0
            a0, a1, a2 = 1.0 - fb - fc, fb, fc           # the moved triangle's corners, in barycentrics
            b0, b1, b2 = fa, 1.0 - fa - fc, fc
            c0, c1, c2 = fa, fb, 1.0 - fa - fb
            px = wa * q[0, 0] + wb * q[1, 0] + wc * q[2, 0]
            py = wa * q[0, 1] + wb * q[1, 1] + wc * q[2, 1]
            sa, sb, sc = closest_on_triangle(
                px, py, a0 * q[0, 0] + a1 * q[1, 0] + a2 * q[2, 0], a0 * q[0, 1] + a1 * q[1, 1] + a2 * q[2, 1],
                b0 * q[0, 0] + b1 * q[1, 0] + b2 * q[2, 0], b0 * q[0, 1] + b1 * q[1, 1] + b2 * q[2, 1],
                c0 * q[0, 0] + c1 * q[1, 0] + c2 * q[2, 0], c0 * q[0, 1] + c1 * q[1, 1] + c2 * q[2, 1])
            wa = sa * a0 + sb * b0 + sc * c0
            wb = sa * a1 + sb * b1 + sc * c1
            wc = 1.0 - wa - wb
    wa = wa + (third - wa) * NUDGE
    wb = wb + (third - wb) * NUDGE
    return wa, wb, 1.0 - wa - wb


def open_edges(corners):
    """(nt, 3) bool: the edges (opposite corners 0, 1, 2) of triangles
    corners (nt, 3, 3) across which no coplanar triangle continues the
    surface: edges used by one triangle, or by more than two (a wall
    meeting a floor along a shared edge), or by two whose winding normals
    differ (a crease). Endpoints match by their exact coordinates (a mesh's
    shared vertices); an edge whose neighbour's vertices differ, a
    T-junction, counts as open (its texels move in a little for nothing)."""
    c = np.ascontiguousarray(corners, np.float64)
    nt = len(c)
    if nt == 0:
        return np.zeros((0, 3), bool)
    n = np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1), 1e-300)[:, None]
    ends = np.stack([c[:, [1, 2]], c[:, [2, 0]], c[:, [0, 1]]], axis=1).reshape(-1, 2, 3)  # edge e: opposite e
    # order each edge's endpoints lexicographically so both triangles name it alike
    d = ends[:, 0] - ends[:, 1]
    key0 = np.where(d[:, 0] != 0, d[:, 0], np.where(d[:, 1] != 0, d[:, 1], d[:, 2]))
    lo = np.where((key0 > 0)[:, None], ends[:, 1], ends[:, 0])
    hi = np.where((key0 > 0)[:, None], ends[:, 0], ends[:, 1])
    keys = np.concatenate([lo, hi], axis=1)
    order = np.lexsort(keys.T[::-1])
    k = keys[order]
    same = np.all(k[1:] == k[:-1], axis=1)
    start = np.concatenate([[True], ~same])
    group = np.cumsum(start) - 1
    count = np.bincount(group)
    tri = order // 3
    out = np.ones(len(keys), bool)
    two = count[group] == 2
    pair = np.nonzero(two & start)[0]            # the first of each pair, sorted
    ta, tb = tri[pair], tri[pair + 1]
    cont = (np.einsum("ij,ij->i", n[ta], n[tb]) > COPLANAR_COS) & (ta != tb)
    out[order[pair[cont]]] = False
    out[order[pair[cont] + 1]] = False
    return out.reshape(nt, 3)


@njit(cache=True, parallel=True)
def texel_points(corners, chart_tri, corners2d, size, offsets, amount, open_edge):
    """Sample point (N, 3) float64 (kept `amount` texels in from the open
    edges, open_edge (nt, 3) bool: `inset`) and covered flag (N,) bool of
    every texel of every chart (flat, chart c at offsets[c] .., row-major
    (row j, column i))."""
    total = offsets[-1]
    point = np.zeros((total, 3))
    covered = np.zeros(total, np.bool_)
    for c in prange(len(size)):
        t = chart_tri[c]
        s = size[c]
        q = corners2d[c]
        for j in range(s):
            for i in range(s):
                px, py = i + 0.5, j + 0.5
                wa, wb, wc = closest_on_triangle(px, py, q[0, 0], q[0, 1], q[1, 0], q[1, 1], q[2, 0], q[2, 1])
                dx = wa * q[0, 0] + wb * q[1, 0] + wc * q[2, 0] - px
                dy = wa * q[0, 1] + wb * q[1, 1] + wc * q[2, 1] - py
                k = offsets[c] + j * s + i
                covered[k] = dx * dx + dy * dy <= COVER * COVER
                wa, wb, wc = inset(wa, wb, wc, q, amount, open_edge[t, 0], open_edge[t, 1], open_edge[t, 2])
                for a in range(3):
                    point[k, a] = wa * corners[t, 0, a] + wb * corners[t, 1, a] + wc * corners[t, 2, a]
    return point, covered


@njit(cache=True)
def side_normal(corners, t, back):
    """Unit normal of triangle t's side (its winding normal, negated for the back)."""
    ax, ay, az = corners[t, 1, 0] - corners[t, 0, 0], corners[t, 1, 1] - corners[t, 0, 1], \
        corners[t, 1, 2] - corners[t, 0, 2]
    bx, by, bz = corners[t, 2, 0] - corners[t, 0, 0], corners[t, 2, 1] - corners[t, 0, 1], \
        corners[t, 2, 2] - corners[t, 0, 2]
    nx, ny, nz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
    ln = math.sqrt(nx * nx + ny * ny + nz * nz)
    s = -1.0 / ln if back else 1.0 / ln
    return nx * s, ny * s, nz * s


CHUNK = 1024  # texels per parallel work item


@njit(cache=True, parallel=True)
def inside_geometry(bvh, double, mat_of, corners, texel_tri, texel_back, point, covered, offset, reach, near, seed):
    """(N,) bool: covered texels whose point is hidden inside geometry: of
    PROBES cosine-distributed rays, started `offset` off the surface, at
    least PROBE_BACK first hit a triangle from behind (against its winding)
    within `reach`, and at least PROBE_NEAR of them a one-sided triangle,
    or a two-sided one within `near`. Real scenes are often
    two-sided throughout (every one of the big scenes is), their closed
    objects still wound outward: a wall's texels inside a step that runs
    into it see the step's inner faces from behind, close by, and their
    darkness would bleed around the step's end; a sheet's back seen from
    afar (a ceiling wound upward) is no closed object's inside (close by,
    across a gap, it may be taken for one: the ceiling over a lamp hung
    just under it; the texels marked there are hidden by the lamp, and
    the ring at its outline takes the light beside it: unlike the
    voxels', voxels/buried.py, this test moves no light). Where everything is
    one-sided this is the plain test (PROBE_BACK of the rays on back
    faces). Stratified directions, rotated per texel by a hash.
    texel_tri (N,) int32 the triangle a texel samples (-1: none),
    texel_back (N,) bool its back side."""
    total = point.shape[0]
    out = np.zeros(total, np.bool_)
    side = int(math.sqrt(PROBES))
    for ch in prange((total + CHUNK - 1) // CHUNK):
        stack = np.empty(STACK_SIZE, np.int32)
        for k in range(ch * CHUNK, min(total, (ch + 1) * CHUNK)):
            t = texel_tri[k]
            if not covered[k] or t < 0:
                continue
            nx, ny, nz = side_normal(corners, t, texel_back[k])
            tx, bx = frame(nx, ny, nz)
            h = keyed(seed, k)
            r1 = float(h >> np.uint64(40)) / 16777216.0
            r2 = float((h >> np.uint64(16)) & np.uint64(0xFFFFFF)) / 16777216.0
            ox = point[k, 0] + offset * nx
            oy = point[k, 1] + offset * ny
            oz = point[k, 2] + offset * nz
            backs = close = 0
            for p in range(side * side):
                u1 = ((p // side) + r1) / side
                u1 = u1 - 1.0 if u1 >= 1.0 else u1
                u2 = ((p % side) + r2) / side
                u2 = u2 - 1.0 if u2 >= 1.0 else u2
                rr = math.sqrt(u1)
                phi = 2.0 * math.pi * u2
                x, y, z = rr * math.cos(phi), rr * math.sin(phi), math.sqrt(max(0.0, 1.0 - u1))
                dx = x * tx[0] + y * bx[0] + z * nx
                dy = x * tx[1] + y * bx[1] + z * ny
                dz = x * tx[2] + y * bx[2] + z * nz
                what = back_hit(bvh, stack, double, mat_of, ox, oy, oz, dx, dy, dz, reach, near)
                backs += what > 0
                close += what > 1
                left = side * side - 1 - p
                if backs + left < PROBE_BACK * side * side or close + left < PROBE_NEAR * side * side:
                    break   # the rest cannot reach the shares (most texels: open air)
            out[k] = backs >= PROBE_BACK * side * side and close >= PROBE_NEAR * side * side
    return out


@njit(cache=True, inline="always")
def neighbour(o, s, i, j, e):
    """Flat index of 4-neighbour e (0: +i, 1: -i, 2: +j, 3: -j) of texel
    (i, j) of the s x s map at offset o; -1 off the map."""
    ii = i + (1 if e == 0 else (-1 if e == 1 else 0))
    jj = j + (1 if e == 2 else (-1 if e == 3 else 0))
    if ii < 0 or jj < 0 or ii >= s or jj >= s:
        return -1
    return o + jj * s + ii


@njit(cache=True, parallel=True)
def fill(values, filled, offsets, size, layers=FILL_DISTANCE - 1, target=None):
    """Fills, in place, the empty texels within city-block distance <=
    `layers` of a filled one (default: < FILL_DISTANCE): layer d takes the
    mean of its filled 4-neighbours of layers < d. values (N, 3) float64,
    filled (N,) bool (updated); target (N,) bool: only these may be filled
    (None: any)."""
    for c in prange(len(size)):
        s = size[c]
        o = offsets[c]
        for d in range(1, layers + 1):
            new = np.zeros(s * s, np.bool_)
            for j in range(s):
                for i in range(s):
                    k = o + j * s + i
                    if filled[k] or (target is not None and not target[k]):
                        continue
                    a0 = a1 = a2 = 0.0
                    m = 0
                    for e in range(4):
                        kk = neighbour(o, s, i, j, e)
                        if kk >= 0 and filled[kk]:
                            a0 += values[kk, 0]
                            a1 += values[kk, 1]
                            a2 += values[kk, 2]
                            m += 1
                    if m:
                        values[k, 0] = a0 / m
                        values[k, 1] = a1 / m
                        values[k, 2] = a2 / m
                        new[j * s + i] = True
            for q in range(s * s):
                if new[q]:
                    filled[o + q] = True


@njit(cache=True, parallel=True)
def sub_texel_points(bvh, corners, texels, owner, q_all, map_off, map_size, texel_tri, texel_back, point, side,
                     amount, open_edge, lift, chart_axis, chart_origin, chart_texel, coplanar):
    """Anti-aliasing points of the texels `texels` (m,): a side x side grid
    of sub-texel centres over each texel's square, each taken to the point
    of the texel's triangle nearest to it (moved inward as the texel's own
    point, `inset`), or to the sub-centre itself where it lies beyond the
    triangle on a coplanar one that continues the surface (continues_at:
    as the texel's own point, onto_coplanar): with `coplanar` (per-triangle
    charts: owner[k]'s axis, origin and texel size in chart_axis,
    chart_origin, chart_texel) on the chart's plane, else (an xatlas page)
    by the face's own map extended past its edge. owner (N,) indexes q_all (n, 3, 2): the triangle's
    corners in its map's texel units; map_off (m,) and map_size (m,): the
    first texel and the side of each texel's map. Returns points
    (m * side^2, 3) and ok (m * side^2,) bool: False where the segment from
    the texel's own point to the sub-point (both lifted `lift` along the
    side's normal) is blocked, a sub-point under a box standing on the
    floor or beyond a wall meeting the surface, which a viewer never shows
    on this side: such points are left out of the texel's mean."""
    m = texels.shape[0]
    n_sub = side * side
    pts = np.zeros((m * n_sub, 3))
    ok = np.zeros(m * n_sub, np.bool_)
    for e in prange(m):
        stack = np.empty(STACK_SIZE, np.int32)
        k = texels[e]
        t = texel_tri[k]
        q = q_all[owner[k]]
        s = map_size[e]
        local = k - map_off[e]
        i, j = local % s, local // s
        nx, ny, nz = side_normal(corners, t, texel_back[k])
        ox, oy, oz = point[k, 0] + lift * nx, point[k, 1] + lift * ny, point[k, 2] + lift * nz
        for sub in range(n_sub):
            px = i + (sub % side + 0.5) / side
            py = j + (sub // side + 0.5) / side
            wa, wb, wc = closest_on_triangle(px, py, q[0, 0], q[0, 1], q[1, 0], q[1, 1], q[2, 0], q[2, 1])
            dx = wa * q[0, 0] + wb * q[1, 0] + wc * q[2, 0] - px
            dy = wa * q[0, 1] + wb * q[1, 1] + wc * q[2, 1] - py
            outside = dx * dx + dy * dy > OUTSIDE * OUTSIDE
            r = e * n_sub + sub
            found = False
            if outside:
                if coplanar:
                    c = owner[k]
                    cx, cy, cz = plane_point(corners, t, chart_axis[c], chart_origin[c], chart_texel[c], px, py)
                else:   # an xatlas chart is flat where it continues: the face's own map, extrapolated
                    ea, eb, ec = plane_bary(px, py, q)
                    cx = ea * corners[t, 0, 0] + eb * corners[t, 1, 0] + ec * corners[t, 2, 0]
                    cy = ea * corners[t, 0, 1] + eb * corners[t, 1, 1] + ec * corners[t, 2, 1]
                    cz = ea * corners[t, 0, 2] + eb * corners[t, 1, 2] + ec * corners[t, 2, 2]
                found = continues_at(bvh, stack, corners, t, texel_back[k], cx, cy, cz, lift)
                if found:
                    pts[r, 0], pts[r, 1], pts[r, 2] = cx, cy, cz
            if not found:
                wa, wb, wc = inset(wa, wb, wc, q, amount, open_edge[t, 0], open_edge[t, 1], open_edge[t, 2])
                for a in range(3):
                    pts[r, a] = wa * corners[t, 0, a] + wb * corners[t, 1, a] + wc * corners[t, 2, a]
            ex, ey, ez = pts[r, 0] + lift * nx - ox, pts[r, 1] + lift * ny - oy, pts[r, 2] + lift * nz - oz
            d = math.sqrt(ex * ex + ey * ey + ez * ez)
            ok[r] = d <= 0.0 or not any_hit(bvh, stack, ox, oy, oz, ex / d, ey / d, ez / d, 0.0, d)
    return pts, ok


@njit(cache=True, parallel=True)
def contrast_texels(lum, scale, valid, point, map_off, map_size, reach, contrast):
    """(N,) bool: valid texels whose luminance lum differs from a valid
    4-neighbour's in their map (whose point lies within `reach` scene units:
    a neighbour across a chart boundary on an xatlas page is another
    surface) by more than `contrast` of the larger of the two texels'
    `scale` (the luminance of all their light, of which lum may be a part):
    the texels where a shadow's edge or a contact crosses the texel, which
    a single point per texel aliases."""
    out = np.zeros(lum.shape[0], np.bool_)
    r2 = reach * reach
    for c in prange(map_size.shape[0]):
        s = map_size[c]
        o = map_off[c]
        for j in range(s):
            for i in range(s):
                k = o + j * s + i
                if not valid[k]:
                    continue
                for e in range(4):
                    kk = neighbour(o, s, i, j, e)
                    if kk < 0 or not valid[kk]:
                        continue
                    d = 0.0
                    for a in range(3):
                        d += (point[k, a] - point[kk, a]) ** 2
                    if d > r2:
                        continue
                    if abs(lum[k] - lum[kk]) > contrast * max(scale[k], scale[kk]):
                        out[k] = True
                        break
    return out


@njit(cache=True, parallel=True)
def interpolate_corners(corners, tri, first, size, at_corners, point, corner_in, values):
    """values[k] for every texel k of the maps at first[c] (size[c]^2
    texels, triangle tri[c]): linear in point[k] through the three values
    at_corners[c] (3, 3) taken at the corners moved corner_in of the way to
    the centroid; never below 0."""
    for c in prange(tri.shape[0]):
        t = tri[c]
        e1 = corners[t, 1] - corners[t, 0]
        e2 = corners[t, 2] - corners[t, 0]
        d00, d01, d11 = np.dot(e1, e1), np.dot(e1, e2), np.dot(e2, e2)
        den = d00 * d11 - d01 * d01
        for k in range(first[c], first[c] + size[c] * size[c]):
            d20 = d21 = 0.0
            for a in range(3):
                d = point[k, a] - corners[t, 0, a]
                d20 += d * e1[a]
                d21 += d * e2[a]
            b1 = (d11 * d20 - d01 * d21) / den
            b2 = (d00 * d21 - d01 * d20) / den
            w = ((1.0 - b1 - b2 - corner_in / 3) / (1.0 - corner_in), (b1 - corner_in / 3) / (1.0 - corner_in),
                 (b2 - corner_in / 3) / (1.0 - corner_in))
            for ch in range(3):
                values[k, ch] = max(0.0, w[0] * at_corners[c, 0, ch] + w[1] * at_corners[c, 1, ch]
                                    + w[2] * at_corners[c, 2, ch])


COPLANAR_COS = 0.9999   # a neighbour this parallel (same winding) whose plane the texel's centre lies on continues the surface


@njit(cache=True)
def plane_point(corners, t, a, origin, texel, x, y):
    """The point at (x, y), in the texel units of triangle t's chart
    (dominant axis a, origin (2,), texel size), on the triangle's plane."""
    wx, wy, wz = side_normal(corners, t, False)
    d = wx * corners[t, 0, 0] + wy * corners[t, 0, 1] + wz * corners[t, 0, 2]
    ua = 1 if a == 0 else 0
    va = 1 if a == 2 else 2
    wn = (wx, wy, wz)
    p = np.empty(3)
    p[ua] = (origin[0] + x) * texel
    p[va] = (origin[1] + y) * texel
    p[a] = (d - wn[ua] * p[ua] - wn[va] * p[va]) / wn[a]
    return p[0], p[1], p[2]


@njit(cache=True, inline="always")
def plane_bary(px, py, q):
    """Barycentrics of (px, py) with respect to the 2D triangle q (3, 2),
    unclamped (negative beyond an edge)."""
    e1x, e1y, e2x, e2y = q[1, 0] - q[0, 0], q[1, 1] - q[0, 1], q[2, 0] - q[0, 0], q[2, 1] - q[0, 1]
    det = e1x * e2y - e1y * e2x
    if det == 0.0:
        return 1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0
    dx, dy = px - q[0, 0], py - q[0, 1]
    b = (dx * e2y - dy * e2x) / det
    c = (e1x * dy - e1y * dx) / det
    return 1.0 - b - c, b, c


@njit(cache=True)
def continues_at(bvh, stack, corners, t, back, px, py, pz, lift):
    """True where the surface of triangle t continues at p (on its plane):
    the first surface a ray down the side's normal from p lifted `lift`
    meets, at the plane, is a triangle wound the same way in the same plane
    (the other half of a quad, the next tile of a floor)."""
    wx, wy, wz = side_normal(corners, t, False)          # the winding normal
    sg = -1.0 if back else 1.0
    nx, ny, nz = sg * wx, sg * wy, sg * wz               # the side's
    tt, h, u, v = closest_hit(bvh, stack, px + lift * nx, py + lift * ny, pz + lift * nz, -nx, -ny, -nz, 0.0,
                              2.0 * lift)
    if h < 0 or abs(tt - lift) > 0.05 * lift:          # float32 triangles: t is good to ~1e-7 of the scene
        return False
    hx, hy, hz = hit_normal(bvh, h)
    return hx * wx + hy * wy + hz * wz > COPLANAR_COS


@njit(cache=True, parallel=True)
def onto_coplanar(bvh, corners, chart_tri, chart_back, axis, origin, texel, size, offsets, point, covered, lift, skip):
    """Moves, in place, the sample point of each covered texel whose centre
    lies outside its triangle onto the centre itself (on the triangle's
    plane) where the surface continues there (continues_at). A texel
    across a shared edge then holds the light at its own centre, as its
    neighbour across the edge does, and bilinear filtering shows no seam
    along the edge. Where the surface ends (a box's edge, a wall meeting
    the floor) the point stays clamped and inset (texel_points), unless
    another surface separates it from its triangle's centroid: a segment
    lifted off the side, from the point to the centroid, meets something.
    Such a point lies past a surface that cuts the triangle near its edge
    (a moulding's strip poking a tenth of a millimetre through the ceiling
    it meets, a floor running on under a wall): it sees what is beyond
    (the sky over the roof), and bilinear filtering would show that on the
    visible side. Its texel is left uncovered (not shaded, filled from its
    neighbours); an edge texel cut off by an object standing on its
    triangle takes its neighbours' light, a texel away, likewise.
    Charts where skip[c] are left as they are: a triangle shaded once, at
    its centroid, has one value over its map, wherever its texels' points
    lie (two thirds of the walkthrough's texels at 14 cm, each a ray here)."""
    for c in prange(chart_tri.shape[0]):
        if skip[c]:
            continue
        stack = np.empty(STACK_SIZE, np.int32)
        s = size[c]
        for j in range(s):
            for i in range(s):
                k = offsets[c] + j * s + i
                if not covered[k]:
                    continue
                px, py, pz = plane_point(corners, chart_tri[c], axis[c], origin[c], texel[c], i + 0.5, j + 0.5)
                moved = (px - point[k, 0]) ** 2 + (py - point[k, 1]) ** 2 + (pz - point[k, 2]) ** 2
                if moved <= (1e-3 * texel[c]) ** 2:
                    continue                                  # inside its triangle: already at its centre
                if continues_at(bvh, stack, corners, chart_tri[c], chart_back[c], px, py, pz, lift):
                    point[k, 0], point[k, 1], point[k, 2] = px, py, pz
                    continue
                t = chart_tri[c]
                dx = (corners[t, 0, 0] + corners[t, 1, 0] + corners[t, 2, 0]) / 3.0 - point[k, 0]
                dy = (corners[t, 0, 1] + corners[t, 1, 1] + corners[t, 2, 1]) / 3.0 - point[k, 1]
                dz = (corners[t, 0, 2] + corners[t, 1, 2] + corners[t, 2, 2]) / 3.0 - point[k, 2]
                reach = math.sqrt(dx * dx + dy * dy + dz * dz)
                if reach <= 0.0:
                    continue
                dx, dy, dz = dx / reach, dy / reach, dz / reach
                nx, ny, nz = side_normal(corners, t, chart_back[c])
                _, h, _, _ = closest_hit(bvh, stack, point[k, 0] + lift * nx, point[k, 1] + lift * ny,
                                         point[k, 2] + lift * nz, dx, dy, dz, 0.0, reach)
                if h >= 0:
                    covered[k] = False


@njit(cache=True, parallel=True)
def between_lattice(values, lum, known, target, point, normal, map_off, map_size, reach, contrast, step, shift):
    """One level of adaptive shading: texels of `target` on the lattice of
    spacing `step` but not on that of 2 step (i or j an odd multiple of
    step) whose neighbours on the coarser lattice (the two `step` away in
    their row or column, or the four diagonal ones) are all `known`, lie
    within `reach` scene units, face within SAME_FACING of its own normal
    (on an xatlas page a neighbour may be another surface: the other face
    of a thin wall) and agree within `contrast` of the largest
    luminance, and whose points' mean lies within shift[map] scene units of
    its own point (a point kept in from an open edge, texels.inset, is not
    where its texel's centre is: the mean of it and a point a texel further
    in is not the light between them): their value is set, in place, to
    those neighbours' mean (the bilinear interpolation at their centre).
    Returns (N,) bool, the texels so set; the others in `target` need
    shading of their own."""
    out = np.zeros(lum.shape[0], np.bool_)
    r2 = reach * reach
    two = 2 * step
    for c in prange(map_size.shape[0]):
        s = map_size[c]
        o = map_off[c]
        for j in range(0, s, step):
            for i in range(0, s, step):
                k = o + j * s + i
                di, dj = i % two, j % two
                if not target[k] or (di == 0 and dj == 0):
                    continue
                lo, hi = np.inf, 0.0
                a0 = a1 = a2 = 0.0
                m0 = m1 = m2 = 0.0
                ok = True
                for e in range(4):
                    ii = i + (di if e & 1 else -di)
                    jj = j + (dj if e & 2 else -dj)
                    if ii < 0 or jj < 0 or ii >= s or jj >= s:
                        ok = False
                        break
                    kk = o + jj * s + ii
                    d = 0.0
                    for a in range(3):
                        d += (point[k, a] - point[kk, a]) ** 2
                    f = normal[k, 0] * normal[kk, 0] + normal[k, 1] * normal[kk, 1] + normal[k, 2] * normal[kk, 2]
                    if not known[kk] or d > r2 or f < SAME_FACING:
                        ok = False
                        break
                    lo = min(lo, lum[kk])
                    hi = max(hi, lum[kk])
                    a0 += values[kk, 0]
                    a1 += values[kk, 1]
                    a2 += values[kk, 2]
                    m0 += point[kk, 0]
                    m1 += point[kk, 1]
                    m2 += point[kk, 2]
                if ok:
                    m0, m1, m2 = 0.25 * m0 - point[k, 0], 0.25 * m1 - point[k, 1], 0.25 * m2 - point[k, 2]
                    ok = m0 * m0 + m1 * m1 + m2 * m2 <= shift[c] * shift[c]
                if ok and hi - lo <= contrast * hi:
                    values[k, 0], values[k, 1], values[k, 2] = 0.25 * a0, 0.25 * a1, 0.25 * a2
                    out[k] = True
    return out
