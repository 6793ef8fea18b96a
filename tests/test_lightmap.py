"""Lightmap stage on its own: charts, texel points, fill, quadtree packing,
single-colour maps and deduplication (docs/design.md section 8)."""
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.ndimage import distance_transform_cdt

from baker.lightmap import PAGE, build_atlas, pack_quadtree, per_triangle_charts
from baker.lightmap.charts import BORDER, MAX_SIZE, MIN_SIZE
from baker.lightmap.texels import FILL_DISTANCE, fill, open_edges, texel_points

POW2 = [8, 16, 32, 64, 128, 256, 512]


def paint(sizes, page, x, y, n_pages):
    """Cover counts per page texel (8-texel blocks suffice: every placement
    is a multiple of 8)."""
    b = PAGE // MIN_SIZE
    cover = np.zeros((n_pages, b, b), np.int32)
    for s, p, x0, y0 in zip(sizes, page, x, y):
        assert 0 <= p < n_pages and x0 % MIN_SIZE == 0 and y0 % MIN_SIZE == 0
        assert 0 <= x0 and 0 <= y0 and x0 + s <= PAGE and y0 + s <= PAGE  # inside its page
        cover[p, y0 // MIN_SIZE:(y0 + s) // MIN_SIZE, x0 // MIN_SIZE:(x0 + s) // MIN_SIZE] += 1
    return cover


@settings(max_examples=200, deadline=None)
@given(st.lists(st.sampled_from(POW2), min_size=1, max_size=300))
def test_quadtree_places_without_overlap_and_fills_pages(sizes):
    page, x, y, n = pack_quadtree(sizes)
    cover = paint(sizes, page, x, y, n)
    assert cover.max() == 1  # no two placements overlap
    area = sum(s * s for s in sizes)
    assert n == -(-area // PAGE ** 2)  # power-of-two squares: no page opened before the last one is full
    assert n == 1 or cover[:-1].min() == 1  # every page but the last is filled completely


def test_quadtree_page_of_512_and_many_small():
    page, x, y, n = pack_quadtree([8] * 4096 + [512])
    assert n == 2 and (page[:4096] == 1).all() and page[4096] == 0  # the large map first, the small ones fill page 2


def square_chart(size, tri=0):
    """A chart of a right triangle filling most of a size x size map."""
    corners = np.array([[[0, 0, 0], [size - 2 * BORDER, 0, 0], [0, 0, size - 2 * BORDER]]], float)
    return per_triangle_charts(corners, np.zeros(1, bool), 1.0)


def test_charts_are_power_of_two_squares_with_border():
    rng = np.random.default_rng(1)
    corners = rng.uniform(-3, 3, (200, 3, 3))
    corners[:5] *= 100  # larger than a page at this texel size: coarser texels
    corners[5:15] = corners[5:15, :1] + 0.03 * (corners[5:15] - corners[5:15, :1])  # smaller than a map: finer
    ch = per_triangle_charts(corners, rng.uniform(size=200) < 0.3, 0.1)
    assert len(ch) == 200 + int((ch.back).sum()) and ch.back.sum() > 20
    s = ch.size
    assert ((s & (s - 1)) == 0).all() and s.min() >= MIN_SIZE and s.max() <= MAX_SIZE
    assert (ch.corners2d.min(axis=(1, 2)) >= BORDER - 1e-9).all()           # the border is kept
    assert (ch.corners2d.max(axis=(1, 2)) <= s - BORDER + 1e-9).all()
    assert (ch.texel[:10] > 0.1).any()
    span = np.ptp(ch.corners2d * ch.texel[:, None, None], axis=1).max(axis=1)  # scene units
    big = (ch.tri >= 5) & (span >= 0.4)
    assert np.allclose(ch.texel[big], 0.1)
    small = span < 0.4  # smaller than the 8 x 8 map's interior: finer texels that fill it
    assert small.any() and np.allclose(ch.texel[small], np.maximum(span[small] / 4, 0.1 / 16))


def test_texel_points_lie_on_their_triangle():
    rng = np.random.default_rng(2)
    corners = rng.uniform(0, 4, (50, 3, 3))
    ch = per_triangle_charts(corners, np.zeros(50, bool), 0.25)
    pts, covered = texel_points(corners, ch.tri, ch.corners2d, ch.size, ch.offsets, 0.0, open_edges(corners))
    off = ch.offsets
    for c in range(len(ch)):
        t = corners[ch.tri[c]]
        p = pts[off[c]:off[c + 1]]
        n = np.cross(t[1] - t[0], t[2] - t[0])
        # on the plane, and inside the triangle (barycentrics >= 0)
        assert np.abs((p - t[0]) @ n).max() < 1e-9 * np.linalg.norm(n) * 10
        m = np.stack([t[1] - t[0], t[2] - t[0]], axis=1)
        b = np.linalg.lstsq(m, (p - t[0]).T, rcond=None)[0]
        assert b.min() > -1e-9 and (b.sum(axis=0)).max() < 1 + 1e-9
        # a covered texel's centre is near the triangle: at least the texels whose centre lies inside
        cov = covered[off[c]:off[c + 1]]
        assert cov.sum() >= 1


def test_fill_reaches_exactly_city_block_distance_below_four():
    rng = np.random.default_rng(3)
    s = 32
    filled = rng.uniform(size=(s, s)) < 0.02
    filled[5, 5] = True
    values = np.where(filled[..., None], rng.uniform(1, 2, (s, s, 3)), 0.0).reshape(-1, 3)
    before = values.copy()
    f = filled.reshape(-1).copy()
    fill(values, f, np.array([0, s * s]), np.array([s]))
    dist = distance_transform_cdt(~filled, metric="taxicab")
    assert np.array_equal(f.reshape(s, s), dist < FILL_DISTANCE)
    assert np.array_equal(values[filled.reshape(-1)], before[filled.reshape(-1)])  # filled texels kept
    assert (values[~f] == 0).all()
    # each filled texel's value lies within the range of the values around it: a mean, never an extrapolation
    new = f & ~filled.reshape(-1)
    assert values[new].min() >= 1 and values[new].max() <= 2


def tile_charts(n):
    """n identical tiles (a unit square as two triangles each), side by side."""
    corners = []
    for i in range(n):
        corners += [[[i, 0, 0], [i + 1, 0, 0], [i + 1, 0, 1]], [[i, 0, 0], [i + 1, 0, 1], [i, 0, 1]]]
    corners = np.array(corners, float)
    return per_triangle_charts(corners, np.zeros(len(corners), bool), 1 / 16)


def test_dedup_stores_one_map_per_distinct_lighting():
    """A grid of identical tiles, three distinct lightings (a gradient over
    the map, the same gradient twice as bright, a uniform light): three
    maps are stored (both triangles of a tile see the same gradient over
    their map), and the uniform ones become 8 x 8."""
    ch = tile_charts(12)
    off = ch.offsets
    values = np.zeros((off[-1], 3))
    for c in range(len(ch)):
        s = ch.size[c]
        j, i = np.divmod(np.arange(s * s), s)
        tile = ch.tri[c] // 2
        grad = 1.0 + 0.1 * i + 0.05 * j
        v = grad if tile % 3 == 0 else (2 * grad if tile % 3 == 1 else np.full(s * s, 0.7))
        values[off[c]:off[c + 1]] = v[:, None] * [1.0, 0.9, 0.8]
    filled = np.ones(off[-1], bool)
    maps = build_atlas(values, filled, ch, np.zeros(len(ch), bool))
    assert maps.counts["maps"] == 24
    assert maps.counts["unique"] == 3
    assert maps.counts["constant"] == 8
    assert maps.dedup_ratio == pytest.approx(24 / 3)
    # the uniform tiles' UVs all sit at the centre of their 8 x 8 map, which holds the value
    uv = maps.chart_uv[ch.tri // 2 % 3 == 2]
    assert np.ptp(uv, axis=(0, 1)).max() == 0
    x, y = (uv[0, 0] * PAGE).astype(int)
    assert np.allclose(maps.pages[maps.chart_page[2 * 2], y, x], [0.7, 0.63, 0.56], rtol=1e-3)


def test_atlas_pages_hold_each_map_where_its_uvs_point():
    rng = np.random.default_rng(4)
    corners = rng.uniform(0, 3, (40, 3, 3))
    ch = per_triangle_charts(corners, np.zeros(40, bool), 0.05)
    values = rng.uniform(0, 5, (ch.offsets[-1], 3))
    maps = build_atlas(values, np.ones(len(values), bool), ch, np.zeros(len(ch), bool))
    assert maps.counts["unique"] == 40
    off = ch.offsets
    for c in range(len(ch)):
        s = ch.size[c]
        # the chart's corner UVs map back to the corners2d in its block: the block's origin is uv * PAGE - corners2d
        o = maps.chart_uv[c] * PAGE - ch.corners2d[c]
        assert np.ptp(o, axis=0).max() < 1e-3
        x0, y0 = np.rint(o[0]).astype(int)
        block = maps.pages[maps.chart_page[c], y0:y0 + s, x0:x0 + s].reshape(-1, 3)
        assert np.allclose(block, values[off[c]:off[c + 1]].astype(np.float16), rtol=0, atol=0)
    assert (maps.page_scale >= maps.pages.reshape(len(maps.pages), -1).max(axis=1) * 0.999).all()


def _nearest_on_triangle_2d(p, q):
    """Nearest points (n, 2) of the 2D triangle q (3, 2) to points p (n, 2):
    p itself inside, else the nearest of the three edges' nearest points."""
    best = np.full(len(p), np.inf)
    out = p.copy()
    m = np.array([q[1] - q[0], q[2] - q[0]]).T
    b = np.linalg.solve(m, (p - q[0]).T).T
    inside = (b.min(axis=1) >= 0) & (b.sum(axis=1) <= 1)
    for e in range(3):
        a, c = q[e], q[(e + 1) % 3]
        t = np.clip(((p - a) @ (c - a)) / ((c - a) @ (c - a)), 0, 1)
        x = a + t[:, None] * (c - a)
        d = np.linalg.norm(p - x, axis=1)
        take = ~inside & (d < best)
        out[take], best[take] = x[take], d[take]
    return out


def test_texel_points_keep_their_centre_or_move_straight_in_from_an_open_edge():
    """A texel samples the point nearest its centre of its triangle with
    the open edges moved INSET texels in (at most half the inradius), then
    the 1e-4 nudge towards the centroid: a centre well inside is sampled
    there, whatever the rounding of the nearest-point search (a nonzero
    residue once moved ~40% of the inside texels half a texel towards the
    centroid); a centre on an open edge (every texel along an edge of a
    per-triangle map, whose corners sit on texel centres) or beyond it
    moves straight in from that edge, even in a sliver a texel wide (a
    move towards the centroid would slide it along the sliver and leave it
    on the edge, where a moulding meets the ceiling and its rays start on
    the ceiling's plane). Across the diagonal of a quad (two coplanar
    triangles sharing the edge) points stay where they are."""
    from baker.lightmap.texels import INSET, NUDGE
    rng = np.random.default_rng(5)
    corners = rng.uniform(0, 4, (42, 3, 3))
    corners[0] = [[0, 0, 0], [3, 0, 0], [3, 0.06, 0]]          # a sliver about one texel wide
    corners[40] = [[5, 0, 0], [7, 0, 0], [7, 0, 2]]            # a quad: its diagonal (5,0,0)-(7,0,2) is shared
    corners[41] = [[5, 0, 0], [7, 0, 2], [5, 0, 2]]
    edges = open_edges(corners)
    assert not edges[40, 1] and not edges[41, 2] and edges[40, [0, 2]].all() and edges[41, [0, 1]].all()
    assert edges[:40].all()
    ch = per_triangle_charts(corners, np.zeros(42, bool), 0.05)
    pts, covered = texel_points(corners, ch.tri, ch.corners2d, ch.size, ch.offsets, INSET, edges)
    checked = moved = on_diagonal = 0
    for c in range(len(ch)):
        t, s, q = corners[ch.tri[c]], int(ch.size[c]), ch.corners2d[c].astype(np.float64)
        i, j = np.meshgrid(np.arange(s), np.arange(s))
        cen2 = np.stack([i.ravel() + 0.5, j.ravel() + 0.5], axis=1)
        per = sum(np.linalg.norm(q[(e + 1) % 3] - q[(e + 2) % 3]) for e in range(3))
        e1, e2 = q[1] - q[0], q[2] - q[0]
        shrink = min(INSET, abs(e1[0] * e2[1] - e1[1] * e2[0]) / per / 2)
        # the open edges' lines moved in; the moved triangle's corners where they cross
        lines = []
        for e in range(3):
            a, d = q[(e + 1) % 3], q[(e + 2) % 3]
            n = np.array([d[1] - a[1], a[0] - d[0]]) / np.linalg.norm(d - a)
            n = n if (q[e] - a) @ n > 0 else -n
            lines.append((n, n @ a + (shrink if edges[ch.tri[c], e] else 0.0)))
        small = np.array([np.linalg.solve(np.array([lines[(v + 1) % 3][0], lines[(v + 2) % 3][0]]),
                                          [lines[(v + 1) % 3][1], lines[(v + 2) % 3][1]]) for v in range(3)])
        want2 = _nearest_on_triangle_2d(_nearest_on_triangle_2d(cen2, q), small)
        m = np.array([q[1] - q[0], q[2] - q[0]]).T
        b = np.linalg.solve(m, (want2 - q[0]).T).T
        want = np.column_stack([1 - b.sum(axis=1), b]) @ t
        want += NUDGE * (t.mean(axis=0) - want)
        got = pts[ch.offsets[c]:ch.offsets[c + 1]]
        cov = covered[ch.offsets[c]:ch.offsets[c + 1]]
        assert np.abs(got[cov] - want[cov]).max() < 1e-9, c
        for e, (n, h) in enumerate(lines):   # in from every open edge by `shrink`
            assert (want2[cov] @ n - h).min() > -1e-9
        moved += (np.linalg.norm(want2 - cen2, axis=1)[cov] > 1e-9).sum()
        if ch.tri[c] >= 40:   # texel centres on the quad's diagonal keep their place
            d = lines[1 if ch.tri[c] == 40 else 2]
            clear = np.all([cen2 @ n - h > 1e-9 for e, (n, h) in enumerate(lines) if edges[ch.tri[c], e]], axis=0)
            on = cov & (np.abs(cen2 @ d[0] - d[1]) < 1e-9) & clear   # on it, clear of the open edges
            on_diagonal += on.sum()
            assert np.abs(want2[on] - cen2[on]).max(initial=0) < 1e-9
        checked += cov.sum()
    assert checked > 10_000 and moved > 1_000 and on_diagonal > 10
    sliver = pts[ch.offsets[0]:ch.offsets[1]][covered[ch.offsets[0]:ch.offsets[1]]]
    assert sliver[:, 1].min() > 0.1 * 0.06 and sliver[:, 1].max() < 0.9 * 0.06


def test_open_edges_find_where_the_surface_stops():
    """An edge is open unless exactly one other triangle shares it (same
    endpoints, either order) with the same winding normal: a quad's
    diagonal is closed; a fold (a crease), an edge three triangles share
    and an edge whose neighbour's endpoint differs (a T-junction) are open."""
    quad = [[[0, 0, 0], [1, 0, 0], [1, 1, 0]], [[0, 0, 0], [1, 1, 0], [0, 1, 0]]]
    fold = [[[0, 0, 0], [1, 0, 0], [1, 1, 0]], [[0, 0, 0], [1, 1, 0], [0, 1, 1]]]
    three = quad + [[[1, 1, 0], [0, 0, 0], [0.5, 0.5, 1]]]
    tee = [[[0, 0, 0], [2, 0, 0], [1, 1, 0]], [[0, 0, 0], [1, 0, 0], [1, -1, 0]]]
    e = open_edges(np.array(quad, float))
    assert e.tolist() == [[True, False, True], [True, True, False]]
    assert open_edges(np.array(fold, float)).all()
    assert open_edges(np.array(three, float)).all()
    assert open_edges(np.array(tee, float)).all()
    assert open_edges(np.zeros((0, 3, 3))).shape == (0, 3)


def test_adaptive_shading_interpolates_only_between_agreeing_lattice_texels():
    """One level of between_lattice on an 8 x 8 map whose even texels
    (i, j both even) are known: a texel between two (same row or column)
    or four (diagonal) known texels that agree within the contrast takes
    their mean; one whose neighbours differ by more, or that misses one (off
    the map, or not known), or lies beyond `reach`, or faces another way,
    or whose neighbours' points' mean is more than `shift` from its own
    point (a neighbour's point kept in from an open edge), is left for
    shading."""
    from baker.lightmap.texels import between_lattice
    s = 8
    i, j = np.meshgrid(np.arange(s), np.arange(s))          # texel k = j * s + i
    i, j = i.ravel(), j.ravel()
    rng = np.random.default_rng(5)
    lum = np.where((i % 2 == 0) & (j % 2 == 0), rng.uniform(1.0, 1.04, s * s), np.nan)
    lum[(j == 4) & (i == 6)] = 2.0                           # a bright lattice texel: its neighbours differ
    values = np.repeat(lum[:, None], 3, axis=1) * [1.0, 0.5, 0.25]
    known = (i % 2 == 0) & (j % 2 == 0)
    known[(j == 0) & (i == 0)] = False                       # not shaded (say, inside geometry)
    target = ~((i % 2 == 0) & (j % 2 == 0))
    point = np.stack([i * 0.1, j * 0.1, np.zeros(s * s)], axis=1)
    point[(j == 7) & (i == 3)] = [5.0, 5.0, 5.0]             # far from its neighbours: another surface
    normal = np.tile([0.0, 0.0, 1.0], (s * s, 1))
    normal[(j == 1) & (i == 3)] = [0.0, 0.0, -1.0]           # facing away: the other face of a thin wall
    point[(j == 6) & (i == 2)] += [0.0, 0.05, 0.0]           # moved half a texel: its neighbours' means move by
    #                                                          0.025 (row), 0.0125 (diagonal)
    v = values.copy()
    got = between_lattice(v, np.nan_to_num(lum), known, target, point, normal, np.array([0]), np.array([s]), 0.5,
                          0.1, 1, np.array([0.02]))
    want = np.zeros(s * s, bool)
    for k in np.nonzero(target)[0]:
        di, dj = i[k] % 2, j[k] % 2
        nb = [(i[k] + a * di) + (j[k] + b * dj) * s for a in (-1, 1) for b in (-1, 1)]
        if min(i[k] - di, j[k] - dj) < 0 or max(i[k] + di, j[k] + dj) >= s or not known[nb].all():
            continue
        if k in (7 * s + 3, 1 * s + 3, 5 * s + 2, 6 * s + 1, 6 * s + 3) or np.ptp(lum[nb]) > 0.1 * lum[nb].max():
            continue
        want[k] = True
        assert np.allclose(v[k], values[nb].mean(axis=0), rtol=1e-12)
    assert np.array_equal(got, want)
    assert np.array_equal(v[~got], values[~got], equal_nan=True)       # the others untouched
    assert 10 <= want.sum() < target.sum() - 10
    # odd rows and columns at the map's far side (i or j = 7) have no neighbour beyond: never interpolated
    assert not got[(i == s - 1) | (j == s - 1)].any()
    # a bright texel's neighbours are shaded, not interpolated
    assert not got[(j == 4) & (i == 5)].any() and not got[(j == 3) & (i == 5)].any()
    # beside the moved point in its row or column, no; diagonally (its mean 0.0125 off), yes
    assert not got[[5 * s + 2, 6 * s + 1, 6 * s + 3]].any() and got[5 * s + 1] and got[5 * s + 3]


def _floor_map(tmp_path, wall=False, n=9):
    """A floor quad (z = 0, facing +z; with wall, a one-sided wall standing
    on it at x = 4.5 facing -x), its BVH, and one n x n map's texel points
    on it (centres 1 apart from the origin) with their normals."""
    from baker.scene import build_scene_bvh, load_scene
    from scenes.generate import GltfBuilder, quad
    b = GltfBuilder()
    w = b.material("w", (0.5,) * 3)
    b.mesh("floor", *quad((-1, -1, 0), (9, -1, 0), (9, 9, 0), (-1, 9, 0), facing=(0, 0, 1)), w)
    if wall:
        b.mesh("wall", *quad((4.5, -1, -1), (4.5, 9, -1), (4.5, 9, 1), (4.5, -1, 1), facing=(-1, 0, 0)), w)
    b.save(tmp_path / "f.glb")
    bvh = build_scene_bvh(load_scene(tmp_path / "f.glb"))
    j, i = np.divmod(np.arange(n * n), n)
    point = np.stack([i, j, np.zeros(n * n)], axis=1).astype(np.float64)
    return bvh, point, np.tile([0.0, 0.0, 1.0], (n * n, 1))


def test_sparse_bounced_light_is_exact_on_a_linear_field_and_stops_at_a_wall(tmp_path):
    """sparse_bounced on one 9 x 9 map of a floor (texel centres 1 apart,
    z = 0) with a one-sided wall standing on it at x = 4.5: a bounced light
    linear in the point (1 + x + 2y) left of the wall and 0 right of it.
    Left of the wall the texels between lattice texels read the field
    exactly (bilinear reproduces a linear field); right of it every texel
    reads exactly 0 (the texel at x = 5 lies between the lattice columns 4
    and 6, but the wall hides column 4 from it: it is shaded itself); and
    fewer points are shaded than there are texels."""
    from baker.lightmap.values import sparse_bounced
    n = 9
    bvh, point, normals = _floor_map(tmp_path, wall=True, n=n)
    shaded = []

    def field(p, nrm, floor):
        shaded.append(len(p))
        return np.where((p[:, 0] < 4.5)[:, None], (1 + p[:, 0] + 2 * p[:, 1])[:, None], 0.0) * np.ones(3)

    ok = np.ones(n * n, bool)
    out = sparse_bounced(field, bvh.arrays, np.zeros((n * n, 3)), point, normals, ok, ok, np.array([0]),
                         np.array([n]), 2, 0.1)
    left, right = point[:, 0] < 4.5, point[:, 0] > 4.5
    np.testing.assert_allclose(out[left, 0], 1 + point[left, 0] + 2 * point[left, 1], rtol=1e-12)
    assert out[right].max() == 0.0
    assert sum(shaded) < 0.6 * n * n


def _step_field(tmp_path, n=9):
    """One n x n map of an open plane under a smooth light of 1 with a step
    to 3 from x = 4.5 on: (n, texel points, the light as sparse_bounced's
    shade function, the points it was asked for, sparse_bounced's
    arguments after the shade function)."""
    bvh, point, normals = _floor_map(tmp_path, n=n)
    shaded = []

    def field(p, nrm, floor):
        shaded.append(p.copy())
        return np.where((p[:, 0] > 4.5)[:, None], 3.0, 1.0) * np.ones(3)

    ok = np.ones(n * n, bool)
    return n, point, field, shaded, (bvh.arrays, np.zeros((n * n, 3)), point, normals, ok, ok, np.array([0]),
                                     np.array([n]), 2, 0.1)


def test_sparse_smooth_light_shades_the_texels_where_its_lattice_disagrees(tmp_path):
    """sparse_bounced with agree > 0 on one 9 x 9 map of an open plane: a
    light of 1 with a step to 3 from x = 4.5 on. The texels whose lattice
    texels span the step (x = 5, between columns 4 and 6) are shaded
    themselves and read the field exactly; the texels between agreeing
    lattice texels are interpolated (the field is constant there: exact
    too); without the check (agree 0) the texels at x = 5 take the
    lattice's mean, 2."""
    from baker.lightmap.values import sparse_bounced
    n, point, field, shaded, args = _step_field(tmp_path)
    out = sparse_bounced(field, *args, agree=0.2)
    np.testing.assert_array_equal(out[:, 0], np.where(point[:, 0] > 4.5, 3.0, 1.0))
    got = np.concatenate(shaded)
    assert np.isin(5.0, got[:, 0]) and len(got) < 0.8 * n * n
    shaded.clear()
    plain = sparse_bounced(field, *args)
    assert np.all(plain[point[:, 0] == 5, 0] == 2.0)


def test_a_second_sparse_pass_shades_only_what_its_agreement_test_adds(tmp_path):
    """The gather's two passes (values.lightcuts_texels): a first
    sparse_bounced with no agreement test records what it shaded in
    `known`; the second, with the test, shades only the texels its test
    adds (those at x = 5, across the step) and gives what one pass with
    the test gives."""
    from baker.lightmap.values import sparse_bounced
    n, point, field, shaded, args = _step_field(tmp_path)
    one = sparse_bounced(field, *args, agree=0.2)
    shaded.clear()
    known = (np.full(n * n, -1, np.int32), [])
    first = sparse_bounced(field, *args, known=known)
    n_first = len(np.concatenate(shaded))
    assert (known[0] >= 0).sum() == n_first and np.all(first[point[:, 0] == 5, 0] == 2.0)
    shaded.clear()
    second = sparse_bounced(field, *args, agree=0.2, known=known)
    again = np.concatenate(shaded)
    assert len(again) > 0 and np.all(again[:, 0] == 5.0)
    np.testing.assert_array_equal(second, one)

def test_single_colour_maps_are_found_as_a_loop_over_maps_finds_them():
    """atlas._single_colour (all maps at once) against the rule map by map:
    a map is one colour when its filled texels spread within CONSTANT_REL
    of its brightest channel's mean, or when none is filled."""
    from baker.lightmap.atlas import CONSTANT_REL, _single_colour, to_stored
    rng = np.random.default_rng(9)
    sizes = rng.choice([8, 16, 32], 300)
    off = np.r_[0, np.cumsum(sizes ** 2)]
    values = np.zeros((off[-1], 3))
    filled = rng.random(off[-1]) < 0.7
    for c in range(300):
        n = sizes[c] ** 2
        kind = c % 5
        base = rng.uniform(0.1, 3.0, 3)
        if kind == 0:
            values[off[c]:off[c + 1]] = base                                   # one colour
        elif kind == 1:
            values[off[c]:off[c + 1]] = base * (1 + rng.uniform(-0.4, 0.4, (n, 1)) * CONSTANT_REL)   # just within
        elif kind == 2:
            values[off[c]:off[c + 1]] = base * (1 + rng.uniform(-3, 3, (n, 1)) * CONSTANT_REL)       # just beyond
        elif kind == 3:
            filled[off[c]:off[c + 1]] = False                                   # nothing filled
        # kind 4: all zero
    stored = to_stored(values)
    mean, constant = _single_colour(stored, filled, off)
    for c in range(300):
        f = filled[off[c]:off[c + 1]]
        v = stored[off[c]:off[c + 1]][f].astype(np.float64)
        if not len(v):
            assert constant[c] and not mean[c].any()
            continue
        want = np.ptp(v, axis=0).max() <= CONSTANT_REL * v.mean(axis=0).max()
        assert constant[c] == want, c
        assert np.allclose(mean[c], v.mean(axis=0), rtol=1e-12)
    assert 0 < constant.sum() < 300


def test_a_map_capped_at_a_page_says_its_texels_are_coarser():
    """A triangle 10 units across at 0.01 a texel would need a map of 1000
    texels; it stops at a page (512) with coarser texels, and the bake says
    so in one sentence. A triangle that fits, or an xatlas layout, says
    nothing."""
    from baker.lightmap.charts import MAX_SIZE, per_triangle_charts
    from baker.lightmap.values import capped_note
    big = np.array([[[0, 0, 0], [10, 0, 0], [0, 0, 10]]], float)
    small = np.array([[[0, 0, 0], [1, 0, 0], [0, 0, 1]]], float)
    charts = per_triangle_charts(np.concatenate([big, small]), np.zeros(2, bool), 0.01)
    assert charts.size.max() == MAX_SIZE and charts.texel.max() > 0.019
    note = capped_note(charts, 0.01)
    assert note.startswith("1 of 2 triangle maps reached a page's size (512x512): their texels are up to 0.0")
    assert capped_note(per_triangle_charts(small, np.zeros(1, bool), 0.01), 0.01) is None
    assert capped_note(object(), 0.01) is None


def _dense_floor(tmp_path, step, wall=False):
    """_floor_map's floor (with wall: and its one-sided wall at x = 4.5)
    with texel points `step` apart over x, y in [0, 8], half a step off
    the wall's foot (a point under a wall is inside geometry: no bake
    shades it)."""
    bvh, _, _ = _floor_map(tmp_path, wall=wall)
    g = np.arange(0.5 * step, 8.0, step)
    x, y = np.meshgrid(g, g, indexing="ij")
    point = np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], axis=1)
    return bvh, point, np.tile([0.0, 0.0, 1.0], (len(point), 1))


def test_the_gather_cache_gathers_once_a_cell_and_interpolates_smoothly(tmp_path):
    """SmoothCache on a floor with texel points 0.1 apart, records a unit
    apart, a gathered light 1 + 0.5 x: about one gather per unit cell (81
    cells, 6,561 points; the same at points 0.05 apart); away from the
    floor's edges (where the records stop short) the field is read within
    0.2% (a linear fit reproduces it but for its slope's ridge);
    neighbouring points 0.1 apart differ by at most 5% more than the
    field does (0.05; a cache of one value per cell jumps by 0.5, a
    weighted mean of the records by up to 0.11); a constant light is read
    exactly everywhere."""
    from baker.lightmap.smooth_cache import SmoothCache
    bvh, point, normals = _dense_floor(tmp_path, 0.1)
    asked = []

    def linear(p, n):
        asked.append(len(p))
        return (1 + 0.5 * p[:, 0])[:, None] * np.ones(3)

    c = SmoothCache(bvh.arrays, linear, point, normals, 1.0, 0.01)
    assert c.gathered == 64 and not c.own.any()
    v = c.values[:, 0]
    inner = np.all((point[:, :2] >= 1.0) & (point[:, :2] <= 7.0), axis=1)
    np.testing.assert_allclose(v[inner], 1 + 0.5 * point[inner, 0], rtol=2e-3)
    n = int(round(np.sqrt(len(point))))
    grid = v.reshape(n, n)
    assert np.abs(np.diff(grid, axis=0)).max() <= 1.05 * 0.1 * 0.5
    assert np.abs(np.diff(grid, axis=1)).max() <= 1.05 * 0.1 * 0.5
    bvh, fine, fn = _dense_floor(tmp_path, 0.05)
    assert SmoothCache(bvh.arrays, linear, fine, fn, 1.0, 0.01).gathered == c.gathered
    flat = SmoothCache(bvh.arrays, lambda p, n: np.full((len(p), 3), 0.7), point, normals, 1.0, 0.01)
    np.testing.assert_allclose(flat.values, 0.7, rtol=1e-14)


def test_the_gather_cache_does_not_reach_through_a_wall_nor_across_a_thin_wall(tmp_path):
    """A one-sided wall at x = 4.5 on the floor: a gathered light of 1 left
    of it and 0 right of it. Every point right of the wall reads exactly
    0 and every point left of it exactly 1 (the records beyond the wall
    are out of sight). The two faces of a thin wall (points at one place
    facing apart, light 2 on one face and 0 on the other) each read only
    their own side."""
    from baker.lightmap.smooth_cache import SmoothCache
    bvh, point, normals = _dense_floor(tmp_path, 0.1, wall=True)
    c = SmoothCache(bvh.arrays, lambda p, n: np.where((p[:, 0] < 4.5)[:, None], 1.0, 0.0) * np.ones(3), point,
                    normals, 1.0, 0.01)
    left = point[:, 0] < 4.5
    assert np.all(c.values[left] == 1.0) and np.all(c.values[~left] == 0.0)
    g = np.arange(0.0, 3.0 + 1e-9, 0.1)
    y, z = np.meshgrid(g, g, indexing="ij")
    face = np.stack([np.full(y.size, 20.0), y.ravel(), z.ravel()], axis=1)
    both = np.concatenate([face, face])
    nrm = np.concatenate([np.tile([1.0, 0, 0], (len(face), 1)), np.tile([-1.0, 0, 0], (len(face), 1))])
    c = SmoothCache(bvh.arrays, lambda p, n: np.where((n[:, 0] > 0)[:, None], 2.0, 0.0) * np.ones(3), both, nrm,
                    1.0, 0.01)
    assert np.all(c.values[:len(face)] == 2.0) and np.all(c.values[len(face):] == 0.0)


def test_the_gather_cache_gathers_where_its_records_disagree(tmp_path):
    """A gathered light of 1 with a step to 3 from x = 4.45 on (a contact's
    edge): with refine(agree 0.2), the points whose records straddle the
    step are gathered themselves and read the field exactly; the rest
    (records all one side) are exact too, and only points within the
    records' reach of the step are added. Without refine, the points
    beside the step read a blend of the two."""
    from baker.lightmap.smooth_cache import RADIUS, SmoothCache
    bvh, point, normals = _dense_floor(tmp_path, 0.1)

    def step(p, n):
        return np.where((p[:, 0] > 4.45)[:, None], 3.0, 1.0) * np.ones(3)

    c = SmoothCache(bvh.arrays, step, point, normals, 1.0, 0.01)
    exact = np.where(point[:, 0] > 4.45, 3.0, 1.0)
    assert np.any(np.abs(c.values[:, 0] - exact) > 0.5)
    before = c.gathered
    added = c.refine(np.zeros(len(point)), 0.2)
    np.testing.assert_array_equal(c.values[:, 0], exact)
    assert added == c.gathered - before > 0
    assert np.all(np.abs(point[c.own, 0] - 4.45) <= 2 * RADIUS)


@pytest.mark.parametrize("height", [0.2, 0.8])
def test_the_gather_cache_does_not_share_under_a_low_overhang(tmp_path, height):
    """A thin slab `height` over the floor for 3 < x < 6 (a low step,
    facing down; records 1 apart): a gathered light of 0.1 under it and 1
    beside it. Points the slab's height or more from its edges read
    exactly 0.1 under it and exactly 1 beside it, with no refine: a
    segment between each point and a record, raised to half its
    clearance, crosses a low slab, and a point whose clearance differs by
    more than a factor of two from a record's does not read it. (With the
    lift alone, 2,320 points of the low slab's read a blend, up to 0.85 of
    a spacing from its edges. Nearer an edge the light itself blends: a
    point there sees part of the room.)"""
    from baker.lightmap.smooth_cache import SmoothCache
    from baker.scene import build_scene_bvh, load_scene
    from scenes.generate import GltfBuilder, quad
    b = GltfBuilder()
    w = b.material("w", (0.5,) * 3)
    b.mesh("floor", *quad((-1, -1, 0), (9, -1, 0), (9, 9, 0), (-1, 9, 0), facing=(0, 0, 1)), w)
    b.mesh("slab", *quad((3, -1, height), (6, -1, height), (6, 9, height), (3, 9, height), facing=(0, 0, -1)), w)
    b.save(tmp_path / "s.glb")
    bvh = build_scene_bvh(load_scene(tmp_path / "s.glb"))
    g = np.arange(0.05, 8.0, 0.1)
    x, y = np.meshgrid(g, g, indexing="ij")
    point = np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], axis=1)
    under = (point[:, 0] > 3) & (point[:, 0] < 6)
    c = SmoothCache(bvh.arrays, lambda p, n: np.where(((p[:, 0] > 3) & (p[:, 0] < 6))[:, None], 0.1, 1.0) * np.ones(3),
                    point, np.tile([0.0, 0.0, 1.0], (len(point), 1)), 1.0, 0.01)
    deep = np.minimum(np.abs(point[:, 0] - 3), np.abs(point[:, 0] - 6)) >= height
    assert np.all(c.values[under & deep] == 0.1) and np.all(c.values[~under & deep] == 1.0)


def _plan(scene, cell, **kw):
    from baker.lightmap.values import plan_texels
    return plan_texels(scene, cell, **kw)


def test_the_default_texel_follows_the_scene_not_the_voxel_cell(cornell):
    """The presets' texel size: the walkthrough (a 3 m high house whose
    default voxel cell is 0.144 m) gets texels of 5 cm or less (its height
    over 64) and xatlas charts (its per-triangle maps would be ~47x the
    texels: a floor of 2 cm triangles); the Cornell box keeps at least one
    texel per cell (0.00877) and its per-triangle maps; a density asked for
    is taken as asked, and texels_across 0 is one texel per cell."""
    from baker.presets import PRESETS
    import baker
    across = PRESETS["default"].texels_across
    walk = baker.load_scene("walkthrough")
    plan = _plan(walk, 0.1439, texels_across=across, uv="auto")
    assert plan.texel_size <= 0.05 and plan.uv == "xatlas", plan
    assert 0.99 * 3.0 / 64 <= plan.texel_size
    cell = 0.5560 / 64 * 1.01   # the Cornell box's default cell (a texel per cell before the presets asked more)
    plan = _plan(cornell, cell, texels_across=across, uv="auto")
    assert plan.texel_size <= cell and plan.uv == "per-triangle", plan
    assert _plan(cornell, cell, texel_density=40, uv="auto").texel_size == 1 / 40
    assert _plan(cornell, cell, texels_across=0).texel_size == cell
    assert PRESETS["preview"].texels_across == 0   # the preview's texels follow its voxels


def test_a_flat_scene_takes_its_width_not_its_thickness(make_scene):
    """A lone floor (zero thickness): its thinnest extent that is not flat
    is its width, so the texel is width / texels_across, not zero."""
    from scenes.generate import GltfBuilder, quad
    b = GltfBuilder()
    grey = b.material("grey", (0.5,) * 3)
    b.mesh("floor", *quad((-2, 0, -1), (2, 0, -1), (2, 0, 1), (-2, 0, 1), facing=(0, 1, 0)), grey)
    scene = make_scene(b, "plan_flat_floor")
    assert _plan(scene, 1.0, texels_across=64).texel_size == pytest.approx(2.0 / 64)


def test_the_default_texel_is_coarsened_to_the_memory_budget(cornell):
    """Under a memory budget the preset's texel grows until its layout's
    texels fit (BYTES_PER_TEXEL each), by no more than the few percent one
    step adds; a density asked for is not coarsened (the bake refuses it
    before any work instead: test_cli)."""
    from baker.lightmap.values import BYTES_PER_TEXEL, texel_estimate
    budget = 4.0   # MiB
    limit = budget * 2 ** 20 / BYTES_PER_TEXEL
    plan = _plan(cornell, 0.02, texels_across=256, uv="xatlas", memory_budget_mb=budget)
    assert plan.texels <= limit and texel_estimate(cornell, plan.texel_size, "xatlas") == plan.texels
    assert texel_estimate(cornell, plan.texel_size / 1.1, "xatlas") > limit   # not coarser than it had to be
    assert "memory budget" in plan.why
    free = _plan(cornell, 0.02, texels_across=256, uv="xatlas")
    assert free.texel_size < plan.texel_size and free.texels > limit


def test_a_budget_no_texel_size_fits_is_refused_in_one_line(cornell):
    """Per-triangle maps keep 8 x 8 texels however coarse the texel: a
    budget under the Cornell box's 32 smallest maps (2,048 texels, 0.3
    MiB) cannot be met by coarsening, and the plan says so (BudgetError,
    naming the file, the texels and the way out) instead of baking past
    it."""
    from baker.errors import BudgetError
    with pytest.raises(BudgetError) as e:
        _plan(cornell, 0.02, texels_across=64, uv="per-triangle", memory_budget_mb=0.1)
    msg = e.value.one_line()
    assert "cornell_box" in msg and "--memory-budget" in msg and "\n" not in msg
    assert _plan(cornell, 0.02, texels_across=64, uv="per-triangle", memory_budget_mb=1.0).texels <= 2 ** 20 / 160


@pytest.mark.parametrize("shared", [False, True])
def test_slivers_xatlas_drops_read_a_neighbours_texel(shared):
    """xatlas leaves faces it rounds to zero area out of its charts (page
    -1: a bake file would name a page that does not exist). Such a sliver
    takes a charted side's page and a point UV inside it: one sharing a
    corner vertex where there is one, else the nearest; it owns no texel
    (the texels are those of the layout without it)."""
    from baker.lightmap.xatlas_charts import xatlas_layout, xatlas_texels
    at = np.array([1, 0, 0]) if shared else np.array([-0.5, 0, 1.2])   # the quad's corner, or apart by side 1
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 0, 1], [0, 0, 1], at + [1e-4, 0, 0], at + [0, 0, 1e-4], at],
                 np.float32)
    t = np.array([[0, 1, 2], [0, 2, 3], [1 if shared else 6, 5, 4]], np.int32)
    lay = xatlas_layout(v, t, np.zeros(3, bool), 0.05)
    assert lay.borrowed.tolist() == [False, False, True]
    assert (lay.page >= 0).all()
    donor = 0 if shared else 1   # shared: the side at vertex 1; apart: the side with the nearest centroid
    u = lay.uv[2]
    assert np.ptp(u, axis=0).max() == 0   # a point
    np.testing.assert_allclose(u[0], lay.uv[donor].mean(axis=0))
    corners = v[t].astype(np.float64)
    _, covered, tri, _, face = xatlas_texels(lay, corners)
    assert covered.any() and not (face == 2).any()


def test_the_nearest_charted_side_by_sweep_matches_brute_force():
    """xatlas_charts._nearest (a sweep over points sorted by x) finds the
    same nearest point as comparing every pair, including queries outside
    the points' span and points sharing an x."""
    from baker.lightmap.xatlas_charts import _nearest
    rng = np.random.default_rng(5)
    pts = rng.uniform(-1, 1, (400, 3))
    pts[:40, 0] = 0.25   # a column of equal x
    pts = pts[np.argsort(pts[:, 0], kind="stable")]
    q = rng.uniform(-2, 2, (300, 3))
    want = np.argmin(((q[:, None, :] - pts[None]) ** 2).sum(axis=2), axis=1)
    np.testing.assert_array_equal(_nearest(np.ascontiguousarray(pts), np.ascontiguousarray(q)), want)


def test_half_value_reads_every_half_float_exactly():
    """atlas.half_value (numba has no float16) against numpy's conversion
    for all 65,536 bit patterns (NaNs: NaN)."""
    from numba import njit

    from baker.lightmap.atlas import half_value

    @njit
    def values(bits, out):
        for i in range(len(bits)):
            out[i] = half_value(bits[i])

    bits = np.arange(1 << 16).astype(np.uint16)
    got = np.zeros(len(bits))
    values(bits, got)
    want = bits.view(np.float16).astype(np.float64)
    nan = np.isnan(want)
    assert np.array_equal(np.isnan(got), nan)
    assert np.array_equal(got[~nan], want[~nan])
    assert np.array_equal(np.signbit(got[~nan]), np.signbit(want[~nan]))   # -0.0 stays -0.0


def test_texel_coords_are_each_texels_column_and_row():
    from baker.lightmap.values import texel_coords
    size = np.array([8, 16, 8, 32], np.int64)
    off = np.r_[0, np.cumsum(size ** 2)].astype(np.int64)
    qi, qj = texel_coords(off, size, int(off[-1]))
    for m in range(len(size)):
        j, i = np.divmod(np.arange(size[m] ** 2), size[m])
        assert np.array_equal(qi[off[m]:off[m + 1]], i) and np.array_equal(qj[off[m]:off[m + 1]], j)
