"""VPLs, the light tree and lightcuts (docs/design.md sections 6-7)."""
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tests import naive
from baker.presets import solver_config
from baker.lights import KIND_AREA, KIND_DIRECTIONAL, VPLs, build_lights, build_tree, irradiance
from baker.presets import lightcuts_config
from baker.scene import Prepared, build_scene_bvh, pack
from baker.solve import solve
from baker.scene import camera_for

LUM = np.array([0.2126, 0.7152, 0.0722])


def random_vpls(rng, n, directional=0):
    kind = np.zeros(n, np.int8)
    kind[:directional] = KIND_DIRECTIONAL
    nor = rng.normal(size=(n, 3))
    nor /= np.linalg.norm(nor, axis=1)[:, None]
    return VPLs(kind, rng.uniform(-1, 1, (n, 3)), nor, rng.uniform(0, 2, (n, 3)) ** 3, rng.uniform(0, 0.01, n),
                np.zeros(n, bool))


def leaves_of(tree, node):
    out, stack = [], [node]
    while stack:
        k = stack.pop()
        if tree.right[k] < 0:
            out.append(int(tree.rep[k]))
        else:
            stack += [k + 1, int(tree.right[k])]
    return out


@settings(max_examples=40, deadline=None)
@given(st.integers(1, 300), st.integers(0, 40), st.integers(0, 2 ** 31))
def test_tree_invariants(n, n_dir, seed):
    """Every VPL is one leaf; a node's power is its leaves' sum; its box
    and normal cone hold its leaves; its representative is one of them;
    depth-first layout (left child = node + 1)."""
    rng = np.random.default_rng(seed)
    v = random_vpls(rng, n + n_dir, n_dir)
    t = build_tree(v, seed)
    assert len(t) == 2 * len(v) - 1  # a binary tree, the two kinds' subtrees joined under one root
    assert sorted(leaves_of(t, 0)) == list(range(len(v)))
    for node in range(len(t)):
        leaves = leaves_of(t, node)
        assert t.rep[node] in leaves
        assert np.allclose(t.power[node], v.power[leaves].sum(axis=0), rtol=1e-9, atol=1e-12)
        if t.kind[node] == KIND_AREA:
            assert (v.position[leaves] >= t.lo[node] - 1e-12).all() and (v.position[leaves] <= t.hi[node] + 1e-12).all()
        if t.cos[node] > -1:
            assert (v.normal[leaves] @ t.axis[node] >= t.cos[node] - 1e-9).all()
        if t.right[node] >= 0:
            assert t.right[node] > node + 1 or t.right[node] == node + 2


@settings(max_examples=30, deadline=None)
@given(st.integers(2, 200), st.floats(0.02, 2.0), st.integers(0, 2 ** 31))
def test_node_bound_holds_every_leaf_below_it(n, spread, seed):
    """A node's bound at a point p (normal n) is at least what its VPLs
    give p without visibility, sum of lum x cos_l cos_p / (pi r^2 + A)
    over its leaves (over a leaf's patch where p is near it); at most the
    bound without cosines, lum / (pi d^2), where no patch can be nearer
    than the box (beyond 3 sqrt(A) of the largest VPL's area);
    and the cosines do prune: with the VPLs' normals spread `spread`
    around one axis, some nodes are bounded well below lum / (pi d^2)
    (p beside or behind their cone, or their box below p's plane): a
    ninth point faces away from every VPL's box, where each node's bound
    must be well under it (eight random points alone may find no such
    node with two VPLs)."""
    from baker.lights import tree_arrays
    from baker.lights.lightcuts import COS_MIN, node_bound, node_patches
    rng = np.random.default_rng(seed)
    axis = rng.normal(size=3)
    nor = axis / np.linalg.norm(axis) + spread * rng.normal(size=(n, 3))
    nor /= np.linalg.norm(nor, axis=1)[:, None]
    v = VPLs(np.zeros(n, np.int8), rng.uniform(-1, 1, (n, 3)), nor, rng.uniform(0, 2, (n, 3)) ** 3,
             rng.uniform(0, 0.01, n), rng.uniform(size=n) < 0.7)
    t = build_tree(v, seed)
    patch = np.where(v.indirect, v.area, 0.0)
    node_patch = node_patches(t.rep, t.right, patch)
    tree = tree_arrays(t, node_patch)
    lum = v.power @ LUM
    pruned = near = 0
    lo, hi = v.position.min(axis=0), v.position.max(axis=0)
    for k in range(9):
        pn = rng.normal(size=3)
        pn /= np.linalg.norm(pn)
        # the ninth: twice the boxes' diagonal out along pn, facing on: every box lies below its plane
        p = rng.uniform(-1.5, 1.5, 3) if k < 8 else 0.5 * (lo + hi) + 2 * max(np.linalg.norm(hi - lo), 0.5) * pn
        d = v.position - p
        r2 = (d * d).sum(axis=1)
        u = d / np.sqrt(r2)[:, None]
        cp, cl = u @ pn, -(u * v.normal).sum(axis=1)
        g = np.where((cp > COS_MIN) & (cl > COS_MIN), cl * cp / (np.pi * r2 + v.area), 0.0)
        a = np.sqrt(v.area)
        for k in np.nonzero((g > 0) & (np.sqrt(r2) < 3 * a) & v.indirect)[0]:   # the near field, over the patch
            w = min(1.0, 3.0 - np.sqrt(r2[k]) / a[k])
            g[k] = w * naive.patch_irradiance(p, pn, v.position[k], v.normal[k], v.area[k]) + (1 - w) * g[k]
            near += 1
        for node in range(len(t)):
            if t.right[node] < 0:
                continue
            b = node_bound(tree, node, tuple(p), tuple(pn))
            leaves = leaves_of(t, node)
            assert b >= (lum[leaves] * g[leaves]).sum() * (1 - 1e-9), node
            d2 = (np.maximum(0, np.maximum(t.lo[node] - p, p - t.hi[node])) ** 2).sum()
            loose = t.lum[node] / (np.pi * d2) if d2 > 9 * node_patch[node] else np.inf
            assert b <= loose * (1 + 1e-9), node
            pruned += b < 0.5 * loose
    assert pruned > 0


def test_tree_is_the_same_for_any_thread_count_and_matches_a_plain_build():
    """The subtrees under the top levels are built in parallel: the tree is
    the same for any thread count, and the same as one built node by node
    with every extent measured afresh (a plain-Python reference of the
    split rule on a small input)."""
    from baker.lights.lighttree import BINS, _topology
    from tests.threads import same_for_any_thread_count
    rng = np.random.default_rng(4)
    v = random_vpls(rng, 20000, 300)
    same_for_any_thread_count(lambda: tuple(np.asarray(x) for x in build_tree(v, 3).__dict__.values()))
    pts = np.concatenate([rng.random((300, 6)), np.repeat(rng.random((3, 6)), 40, axis=0)])
    order = np.arange(len(pts))
    right, start, count = _topology(pts, order)
    ref_order = list(range(len(pts)))
    ref_right = {}

    def build(node, a, b):  # the rule, written plainly
        if b - a == 1:
            return
        seg = np.array(ref_order[a:b])
        ext = pts[seg].max(axis=0) - pts[seg].min(axis=0)
        ax = int(np.argmax(ext))  # first axis of largest extent
        mid = (a + b) // 2
        if ext[ax] > 0:
            lo = pts[seg, ax].min()
            scale = BINS / ext[ax]
            hist = np.bincount(np.minimum(BINS - 1, ((pts[seg, ax] - lo) * scale).astype(int)), minlength=BINS)
            cut = int(np.argmax(np.cumsum(hist) >= (b - a) // 2))
            edge = lo + (cut + 1) / scale
            i, j = a, b - 1
            while i <= j:
                if pts[ref_order[i], ax] < edge:
                    i += 1
                else:
                    ref_order[i], ref_order[j] = ref_order[j], ref_order[i]
                    j -= 1
            if a < i < b and abs((i - a) - (b - i)) <= (b - a) // 2:
                mid = i
            else:
                seg = np.array(ref_order[a:b])
                ref_order[a:b] = list(seg[np.argsort(pts[seg, ax], kind="mergesort")])
        ref_right[node] = node + 2 * (mid - a)
        build(node + 1, a, mid)
        build(node + 2 * (mid - a), mid, b)

    build(0, 0, len(pts))
    assert list(order) == ref_order
    assert {k: int(right[k]) for k in range(len(right)) if right[k] >= 0} == ref_right


def test_representatives_follow_power():
    """A representative is drawn in proportion to luminance: two lights of
    luminance 1 and 3 over 4000 seeds, the brighter is the root's
    representative 3/4 of the time (within 4 standard deviations: a false
    alarm once in 16,000 runs)."""
    v = VPLs(np.zeros(2, np.int8), np.array([[0.0, 0, 0], [1, 0, 0]]), np.array([[0.0, 1, 0], [0, 1, 0]]),
             np.array([[1.0, 1, 1], [3, 3, 3]]), np.zeros(2), np.zeros(2, bool))
    hits = sum(build_tree(v, s).rep[0] == 1 for s in range(4000))
    assert abs(hits / 4000 - 0.75) < 4 * np.sqrt(0.75 * 0.25 / 4000)


@pytest.fixture(scope="module")
def cornell_lights(cornell):
    bvh, surf = build_scene_bvh(cornell), pack(cornell)
    sol = solve(cornell, solver_config("preview", resolution=24, photons=100_000), bvh=bvh, surfaces=surf)
    lights = build_lights(Prepared(cornell, bvh, surf), sol, lightcuts_config("default", direct_vpls=4096),
                          on_surface=False)
    return cornell, bvh, surf, sol, lights


def camera_points(scene, bvh, surf, size):
    """The shading points a size x size frame of the scene's camera sees."""
    from baker.render import camera_array
    from baker.render.lightcuts_frame import trace_samples
    cam = camera_array(camera_for(scene, None), size, size)
    pts, nrm, base, alb, shade, mat, depth = trace_samples(bvh.arrays, surf.arrays, cam, size, size,
                                                           np.arange(size * size), np.zeros(size * size, np.int64),
                                                           1, 1e-5)
    return pts[shade], nrm[shade]


@pytest.mark.parametrize("epsilon,within,p99,worst", [(0.005, 0.02, 0.99, 0.04), (0.02, 0.05, 0.96, 0.12)])
def test_lightcuts_against_brute_force(cornell_lights, epsilon, within, p99, worst):
    """The same VPLs and visibility, every VPL summed. Epsilon bounds each
    node of the cut (Walter et al.), not the pixel: the pixel's error is a
    sum over the cut. Measured on the Cornell box's visible points (4096
    direct VPLs, cap 4000): node epsilon 0.005 puts 99.2% of the points
    within 0.02 (max 0.029-0.031, 594 rays per point); 0.02 puts 97-99%
    within 0.05 (over light-tree seeds 0-3, with and without photon
    smoothing: 99th percentile 0.050-0.061, median 0.012-0.016, max
    0.073-0.100, 250 rays), the points above are in the blocks' shadows,
    where the visibility-blind bound stays loose. The brute force casts at
    least 6x the rays."""
    scene, bvh, surf, sol, lights = cornell_lights
    pts, nrm = camera_points(scene, bvh, surf, 40)
    h, cuts, rays = irradiance(lights, bvh, surf, pts, nrm, epsilon=epsilon, cap=4000)
    hb, _, raysb = irradiance(lights, bvh, surf, pts, nrm, brute=True)
    rel = np.abs(h - hb) @ LUM / np.maximum(hb @ LUM, 1e-12)
    assert (rel <= within).mean() >= p99 and rel.max() < worst, np.percentile(rel, [50, 99, 100])
    assert rays.sum() * 6 < raysb.sum()


def test_kernel_against_naive_sum(cornell_lights):
    """The brute-force kernel against the slow reference of tests/naive.py
    on a few points and a few hundred VPLs (the same sum: 1e-9)."""
    from baker.lights import concat
    scene, bvh, surf, sol, lights = cornell_lights
    v = lights.vpls
    pick = np.random.default_rng(5).choice(len(v), 300, replace=False)
    sub = VPLs(*(getattr(v, f)[pick] for f in ("kind", "position", "normal", "power", "area", "indirect")))
    from baker.lights import Lights
    small = Lights(sub, build_tree(sub, 0))
    pts, nrm = camera_points(scene, bvh, surf, 12)
    hb, _, _ = irradiance(small, bvh, surf, pts[::7], nrm[::7], offset=1e-4, brute=True)
    corners = scene.triangle_corners()
    for k, (p, n) in enumerate(zip(pts[::7], nrm[::7])):
        assert np.allclose(hb[k], naive.vpl_irradiance(p, n, sub, corners), rtol=1e-9, atol=1e-12)
    del concat


def test_point_light_over_a_plane(make_scene):
    """A point light of intensity I at height h over a floor: H = I h / (h^2
    + r^2)^(3/2) at distance r along the floor (exact: punctual lights are
    summed with a shadow ray each)."""
    from scenes.generate import GltfBuilder, quad
    b = GltfBuilder()
    b.mesh("floor", *quad((-3, 0, -3), (3, 0, -3), (3, 0, 3), (-3, 0, 3), facing=(0, 1, 0)),
           b.material("floor", (0.5,) * 3))
    b.light("bulb", "point", intensity=7.0, position=(0, 1.5, 0))
    scene = make_scene(b, "lights_point")
    bvh, surf = build_scene_bvh(scene), pack(scene)
    sol = solve(scene, solver_config("preview", resolution=16, photons=20_000), bvh=bvh, surfaces=surf)
    lights = build_lights(Prepared(scene, bvh, surf), sol, lightcuts_config("preview"), on_surface=False)
    r = np.linspace(0, 2.5, 11)
    pts = np.stack([r, np.zeros_like(r), np.zeros_like(r)], axis=1)
    nrm = np.tile([0.0, 1.0, 0.0], (len(r), 1))
    direct = np.zeros(len(r))
    from baker.lights import Lights
    h, _, _ = irradiance(Lights(lights.vpls, lights.tree), bvh, surf, pts, nrm)
    # the floor's own bounce cannot reach the floor: all of H is the bulb's
    direct = 7.0 * 1.5 / (1.5 ** 2 + r ** 2) ** 1.5
    assert np.allclose(h[:, 0], direct, rtol=1e-9)


@pytest.mark.parametrize("name", ["furnace_box", "furnace_sphere"])
def test_furnace_through_lightcuts(name):
    """H = E / (1 - rho) everywhere in a furnace: over points on the walls,
    the mean within 2%; the spread per point (5th-95th percentile within
    12%) is the photons' noise in the voxels' bounced light, which the
    indirect VPLs carry (the direct part, from the emitter VPLs, is smooth).
    Measured: box 0.99 (0.93-1.06), sphere 1.00 (0.95-1.05)."""
    from baker import load_scene
    scene = load_scene(name)
    bvh, surf = build_scene_bvh(scene), pack(scene)
    sol = solve(scene, solver_config("preview", resolution=24, photons=300_000), bvh=bvh, surfaces=surf)
    lights = build_lights(Prepared(scene, bvh, surf), sol, lightcuts_config("preview", direct_vpls=8192),
                          on_surface=False)
    m = scene.materials[0]
    exact = float(np.pi * m.emission[0] / (1 - m.albedo[0]))
    v = sol.voxels
    pick = np.arange(0, len(v), max(1, len(v) // 400))
    pts = v.centroid[pick] + 1e-3 * v.normal[pick]
    h, _, _ = irradiance(lights, bvh, surf, pts, v.normal[pick], epsilon=0.02)
    ratio = h[:, 0] / exact
    assert abs(ratio.mean() - 1) < 0.02, ratio.mean()
    lo, hi = np.percentile(ratio, [5, 95])
    assert lo > 0.88 and hi < 1.12, (lo, hi)


def test_leak_scene_dark_room_is_black(make_scene):
    """Two rooms, the light in one: lightcuts sees the other exactly black
    (no VPL lies there, and every shadow ray into it meets the wall)."""
    from scenes.generate import two_rooms
    scene = make_scene(two_rooms(), "lights_two_rooms")
    bvh, surf = build_scene_bvh(scene), pack(scene)
    sol = solve(scene, solver_config("preview", resolution=32, photons=300_000, radius=5), bvh=bvh, surfaces=surf)
    lights = build_lights(Prepared(scene, bvh, surf), sol, lightcuts_config("preview"), on_surface=False)
    v = sol.voxels
    dark = (v.centroid[:, 0] > 1.0 + 1e-6)
    lit = ~dark
    h, _, _ = irradiance(lights, bvh, surf, v.centroid + 1e-4 * v.normal, v.normal)
    assert dark.sum() > 100 and h[lit].max() > 0
    assert h[dark].max() == 0.0


def test_same_result_for_any_thread_count(cornell_lights):
    import numba
    scene, bvh, surf, sol, lights = cornell_lights
    pts, nrm = camera_points(scene, bvh, surf, 24)
    out = []
    for n in (1, numba.config.NUMBA_NUM_THREADS):
        numba.set_num_threads(n)
        out.append(irradiance(lights, bvh, surf, pts, nrm)[0])
    numba.set_num_threads(min(numba.config.NUMBA_NUM_THREADS, __import__("os").cpu_count() or 1))
    assert np.array_equal(out[0], out[1])


def test_cornell_frame_against_the_path_tracer(cornell_lights):
    """A lightcuts frame of the Cornell box at the default preset (its
    voxel solution and lightcuts settings, as `voxbake render --method
    lightcuts` runs it) against the path tracer at 1024 spp, 48 x 48:
    relative RMSE over 4 x 4-pixel blocks (the path tracer's noise averaged
    down) below 3.5% and the mean within 1.5% (measured: 2.33% and 1.003).
    The preview preset's coarser voxels at 32 cells give 3.5% and 1.014
    (a line a cell thick sees the boxes' bright tops enlarged by up to half
    a cell from the ceiling: docs/design.md)."""
    from baker.render import camera_array, render
    from baker.render.lightcuts_frame import render_lightcuts
    scene, bvh, surf, _, _ = cornell_lights
    sol = solve(scene, solver_config("default"), bvh=bvh, surfaces=surf)
    lights = build_lights(Prepared(scene, bvh, surf), sol, lightcuts_config("default"))
    s = 48
    img, stats = render_lightcuts(bvh, surf, lights, camera_array(camera_for(scene, None), s, s), s, s)
    ref = render(scene, 0, s, s, spp=1024, bvh=bvh, surfaces=surf)
    assert np.isfinite(img).all() and img.min() >= 0
    a = (img @ LUM).reshape(s // 4, 4, s // 4, 4).mean(axis=(1, 3))
    b = (ref @ LUM).reshape(s // 4, 4, s // 4, 4).mean(axis=(1, 3))
    lit = b < 0.5 * b.max()  # the lamp's blocks out
    assert np.sqrt(np.mean((a[lit] - b[lit]) ** 2)) / b[lit].mean() < 0.035
    assert abs(a[lit].mean() / b[lit].mean() - 1) < 0.015
    assert stats.edge_pixels > 0 and stats.cut_mean > 1


def test_ordered_list_is_an_unbiased_running_average(cornell_lights):
    """The instant-radiosity list: draws in proportion to power, each with
    power / probability, so the mean over the first m draws estimates the
    sum over all VPLs. The CPU's progressive image converges to the brute
    force over the VPLs: relative RMSE 6% after 16 frames of 16, below 2%
    after 256 (measured 6.2%, 3.1% at 64, 1.2% at 256; the stratified
    order converges faster than 1/sqrt(m)); same list for the same seed."""
    from baker.lights import ordered_vpls
    from baker.render import camera_array
    from baker.render.instant_radiosity import render_instant_radiosity
    from baker.render.lightcuts_frame import render_lightcuts
    scene, bvh, surf, sol, lights = cornell_lights
    order = ordered_vpls(lights.vpls, 4096, 0.5, 0)
    again = ordered_vpls(lights.vpls, 4096, 0.5, 0)
    assert np.array_equal(order.position, again.position) and np.array_equal(order.power, again.power)
    total = lights.vpls.power.sum(axis=0)
    for m in (64, 1024, 4096):  # the list's own estimate of the total power
        assert np.allclose(order.power[:m].mean(axis=0), total, rtol=0.05)
    s = 32
    cam = camera_array(camera_for(scene, None), s, s)
    brute, _ = render_lightcuts(bvh, surf, lights, cam, s, s, brute=True, aa=False)
    errs = []
    for frames in (16, 256):
        img, st = render_instant_radiosity(bvh, surf, order, cam, s, s, 16, frames)
        assert st.frames == frames and st.vpls_used == 16 * frames
        a, b = img @ LUM, brute @ LUM
        lit = b > 0
        errs.append(np.sqrt(np.mean((a[lit] - b[lit]) ** 2)) / b[lit].mean())
    assert errs[1] < 0.02 and errs[1] < 0.5 * errs[0], errs


def test_near_field_at_a_concave_edge(make_scene):
    """A wall of uniform radiosity B = 1 made of voxel-like VPLs (unit
    squares of side h, power B h^2, at their centres) meeting the floor:
    the irradiance at floor points x from the wall against the exact
    integral over the wall (midpoint rule, 1000 x 2000). With the near
    field the exact form factor of each VPL's patch (lightcuts.patch_g) it
    is within 3% down to x = h / 4 (measured 0.995 at h / 4, 0.991 at
    0.45 h, 0.984-0.986 at h and 2 h, where VPLs 3-5 patch sides away keep
    the bounded point form's -1.5%); the bounded point form alone reads
    0.55 and 0.81 at h / 4 and 0.45 h (the bias at concave edges the bakes
    showed), and still does with near=False, which the viewer's GPU
    preview keeps."""
    from scenes.generate import GltfBuilder, quad
    h, rows, cols = 0.05, 10, 20
    b = GltfBuilder()
    grey = b.material("grey", (0.5,) * 3)
    b.mesh("floor", *quad((0, 0, -1), (1, 0, -1), (1, 0, 1), (0, 0, 1), facing=(0, 1, 0)), grey)
    b.mesh("wall", *quad((0, 0, -1), (0, 1, -1), (0, 1, 1), (0, 0, 1), facing=(1, 0, 0)), grey)
    scene = make_scene(b, "lights_near_field")
    bvh, surf = build_scene_bvh(scene), pack(scene)
    y, z = np.meshgrid((np.arange(rows) + 0.5) * h, (np.arange(cols) - cols / 2 + 0.5) * h)
    n = y.size
    pos = np.stack([np.zeros(n), y.ravel(), z.ravel()], axis=1)
    wall = VPLs(np.zeros(n, np.int8), pos, np.tile([1.0, 0.0, 0.0], (n, 1)), np.full((n, 3), h * h),
                np.full(n, h * h), np.ones(n, bool))
    from baker.lights import Lights
    lights = Lights(wall, build_tree(wall, 0))
    xs = np.array([0.25, 0.45, 1.0, 2.0]) * h
    pts = np.stack([xs, np.zeros_like(xs), np.zeros_like(xs)], axis=1)
    nrm = np.tile([0.0, 1.0, 0.0], (len(xs), 1))
    near, _, _ = irradiance(lights, bvh, surf, pts, nrm, brute=True)
    far, _, _ = irradiance(lights, bvh, surf, pts, nrm, brute=True, near=False)
    cuts, _, _ = irradiance(lights, bvh, surf, pts, nrm, epsilon=1e-3)
    k = 1000
    yy, zz = np.meshgrid((np.arange(k) + 0.5) / k * rows * h, (np.arange(2 * k) + 0.5) / (2 * k) * cols * h
                         - cols * h / 2)
    for i, x in enumerate(xs):
        r2 = x * x + yy * yy + zz * zz
        exact = (x * yy / (np.pi * r2 * r2)).sum() * (rows * h / k) * (cols * h / (2 * k))
        assert abs(near[i, 0] / exact - 1) < 0.03, (x / h, near[i, 0] / exact)
        assert cuts[i, 0] == pytest.approx(near[i, 0], rel=2e-3)     # lightcuts takes the same near field
        if x <= 0.45 * h:
            assert far[i, 0] / exact < 0.85, (x / h, far[i, 0] / exact)


def test_frame_pixels_a_shadow_edge_crosses_take_their_pattern_mean(make_scene):
    """Pass 2 of a frame's anti-aliasing, exactly: a grey floor under a
    point light, a black blocker above it casting a straight shadow edge
    across the view. Pass 1 sees no edge there (one material, one normal,
    smooth depth). The floor's indirect VPLs lie in its plane and light it
    not at all, so a pixel's value is albedo / pi x H at its points, H =
    I h / (h^2 + r^2)^(3/2) where lit. Every pixel the edge crosses (its
    4 x 4 pattern part lit, part dark) is exactly the mean over its
    pattern, neither lit nor dark; every other pixel is exactly its
    centre's value or its pattern's mean. With aa=False the crossed
    pixels are all or nothing."""
    from scenes.generate import quad
    from baker.scene.gltf_write import GltfBuilder
    from baker.render import camera_array
    from baker.render.lightcuts_frame import AA, render_lightcuts, trace_samples
    xe, h, power, rho = 0.3137, 3.0, 5.0, 0.5
    b = GltfBuilder()
    grey = b.material("grey", (rho,) * 3)
    black = b.material("black", (0.0,) * 3)
    b.mesh("floor", *quad((-2, 0, -2), (2, 0, -2), (2, 0, 2), (-2, 0, 2), facing=(0, 1, 0)), grey)
    b.mesh("blocker", *quad((xe, 1, -2.5), (2.5, 1, -2.5), (2.5, 1, 2.5), (xe, 1, 2.5), facing=(0, -1, 0)), black)
    b.light("bulb", "point", intensity=power, position=(xe, h, 0))
    b.camera("down", (xe - 0.05, 0.8, -0.1), (0.0, -1.0, 0.25), yfov_deg=50)
    scene = make_scene(b, "frame_shadow_edge")
    bvh, surf = build_scene_bvh(scene), pack(scene)
    sol = solve(scene, solver_config("preview", resolution=16, photons=20_000), bvh=bvh, surfaces=surf)
    lights = build_lights(Prepared(scene, bvh, surf), sol, lightcuts_config("default"), on_surface=False)
    s = 32
    cam = camera_array(camera_for(scene, None), s, s)
    n = s * s
    pix = np.repeat(np.arange(n), AA * AA)
    pts = trace_samples(bvh.arrays, surf.arrays, cam, s, s, pix, np.tile(np.arange(AA * AA), n), AA,
                        1e-5 * surf.scale)
    assert pts[4].all()  # every sample on the floor
    x, z = pts[0][:, 0], pts[0][:, 2]
    hy = h - pts[0][:, 1]   # the points lie a hair above the floor, back along their rays
    assert np.all(np.abs(hy - h) < 1e-4 * h)
    lit = (x < xe).reshape(n, AA * AA)
    exact = (rho / np.pi * power * hy / (hy * hy + (x - xe) ** 2 + z * z) ** 1.5).reshape(n, AA * AA) * lit
    mean = exact.mean(axis=1)
    centre_pts = trace_samples(bvh.arrays, surf.arrays, cam, s, s, np.arange(n), np.zeros(n, np.int64), 1,
                               1e-5 * surf.scale)[0]
    hc = h - centre_pts[:, 1]
    centre = rho / np.pi * power * hc / (hc * hc + (centre_pts[:, 0] - xe) ** 2 + centre_pts[:, 2] ** 2) ** 1.5
    centre *= centre_pts[:, 0] < xe
    crossed = lit.any(axis=1) & ~lit.all(axis=1)
    assert 10 <= crossed.sum() <= 3 * s
    img, stats = render_lightcuts(bvh, surf, lights, cam, s, s)
    got = img[..., 1].reshape(n).astype(np.float64)
    assert stats.edge_pixels == 0 and stats.contrast_pixels >= crossed.sum()
    assert np.allclose(got[crossed], mean[crossed], rtol=1e-5, atol=0)
    assert np.all((mean[crossed] > 0.02 * exact.max()) & (mean[crossed] < exact[crossed].max(axis=1)))
    either = np.isclose(got, centre, rtol=1e-5, atol=1e-12) | np.isclose(got, mean, rtol=1e-5, atol=1e-12)
    assert either.all()
    plain, _ = render_lightcuts(bvh, surf, lights, cam, s, s, aa=False)
    flat = plain[..., 1].reshape(n).astype(np.float64)
    assert np.allclose(flat, centre, rtol=1e-5, atol=1e-12)
    assert (flat[crossed] == 0).any() and (flat[crossed] > 0).any()


def test_voxel_vpls_under_a_curved_surface_are_put_on_it(make_scene):
    """A sphere standing in a lit room: the photon-weighted centroid of a
    voxel on the sphere lies inside it, by the sagitta of the voxel's patch,
    so a shadow ray to it would leave through the sphere from behind and
    its light would be lost. With the scene's BVH, build_lights moves each
    such VPL along its normal onto the surface (a hair past): then almost
    only VPLs at the contact have a surface just in front of them. VPLs with
    nothing over them (the room's flat walls) stay exactly where they were, and power,
    normals and areas do not change. At the contact, a floor voxel whose
    ray meets the sphere from the front (or the ball's lowest voxels, the
    floor) is not moved."""
    from scenes.generate import box, icosphere, quad
    from baker.scene.gltf_write import GltfBuilder
    from baker.lights.vpl import SKIN
    b = GltfBuilder()
    white = b.material("white", (0.7, 0.7, 0.7))
    lamp = b.material("lamp", (0.0, 0.0, 0.0), emission=(20.0, 20.0, 20.0))
    b.mesh("room", *box((-1, 0, -1), (1, 2, 1), inward=True), white)
    b.mesh("ball", *icosphere(3, 0.45, (0.1, 0.45, 0.05)), white)
    b.mesh("lamp", *quad((-0.2, 1.99, -0.2), (0.2, 1.99, -0.2), (0.2, 1.99, 0.2), (-0.2, 1.99, 0.2),
                         facing=(0, -1, 0)), lamp)
    scene = make_scene(b, "vpl_ball")
    bvh, surf = build_scene_bvh(scene), pack(scene)
    sol = solve(scene, solver_config("preview", resolution=24, photons=100_000), bvh=bvh, surfaces=surf)
    cfg = lightcuts_config("preview")
    plain = build_lights(Prepared(scene, bvh, surf), sol, cfg, on_surface=False).vpls
    moved = build_lights(Prepared(scene, bvh, surf), sol, cfg).vpls
    for f in ("kind", "normal", "power", "area", "indirect"):
        assert np.array_equal(getattr(plain, f), getattr(moved, f))
    ind = np.nonzero(plain.indirect)[0]
    side = np.sqrt(plain.area[ind])

    def under(vp):
        d = 0.25 * side
        return bvh.occluded(vp.position[ind] + vp.normal[ind] * d[:, None], -vp.normal[ind], tmax=d * (1 - 1e-6))

    before, after = under(plain), under(moved)
    floor = plain.position[ind][:, 1] < 1e-6
    shift = np.linalg.norm(moved.position[ind] - plain.position[ind], axis=1)
    changed = shift > 0
    assert changed.sum() >= 100 and not (changed & ~before).any()  # only buried ones move
    assert (shift[changed] <= SKIN * side[changed]).all()
    on_ball = np.abs(np.linalg.norm(moved.position[ind][changed] - [0.1, 0.45, 0.05], axis=1) - 0.45) < 0.02
    assert on_ball.all()  # onto the sphere (its flat facets lie within 1.5% of the radius)
    # what is still under a surface: the contact, where the floor's voxels meet the ball from the front and
    # the ball's lowest voxels the floor (each a surface of another body facing them)
    contact = plain.position[ind][:, 1] < 0.25 * side
    # (and, measured, 1 of 577 on the ball whose voxel's normal is more than 60 degrees off the facet over it)
    assert after.any() and (after & ~contact).sum() <= 0.01 * before.sum() and not changed[floor].any()


@pytest.mark.parametrize("hemisphere", [True, False])
def test_sky_pass_against_the_analytic_sky(tmp_path, hemisphere):
    """The sky shaded along its directions (lightcuts.sky_light), by view
    factors. Unoccluded it is exact at any number of directions: a point
    on the roof facing up gets pi L, a wall facing sideways pi L / 2 under the
    upper hemisphere and pi L under a whole sphere, a face turned down 0
    under the hemisphere. Under a square roof of side 2a at height h above
    it, a floor point gets pi L (1 - F), F the exact view factor of the
    square (four corner rectangles): within 1% at 1024 and 4096 directions
    (measured 0.2%). build_lights keeps the sky out of the tree."""
    from baker.lights import Lights
    from baker.lights.vpl import sky_vpls
    from baker.scene import Sky, load_scene
    from scenes.generate import GltfBuilder, quad
    L, a, h = 2.0, 0.5, 0.4
    b = GltfBuilder()
    grey = b.material("grey", (0.5,) * 3)
    b.mesh("floor", *quad((-3, 0, -3), (3, 0, -3), (3, 0, 3), (-3, 0, 3), facing=(0, 1, 0)), grey)
    b.mesh("roof", *quad((-a, h, -a), (a, h, -a), (a, h, a), (-a, h, a), facing=(0, -1, 0)), grey)
    b.mesh("wall", *quad((9, -1, -1), (9, 0.3, -1), (9, 0.3, 1), (9, -1, 1), facing=(1, 0, 0)), grey)
    b.save(tmp_path / "roof.glb")
    scene = load_scene(tmp_path / "roof.glb", sky=Sky(np.full(3, L), hemisphere))
    bvh, surf = build_scene_bvh(scene), pack(scene)
    # on the roof (nothing above it), on the wall, under the floor, under the roof
    pts = np.array([[0.0, h, 0.0], [9.0, 0.0, 0.0], [2.5, 0.0, -2.5], [0.0, 0.0, 0.0]])
    nrm = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 1.0, 0.0]])
    A = a / h
    q = A / np.sqrt(1 + A * A)
    F = 4 * (2 * q * np.arctan(q)) / (2 * np.pi)  # four a x a rectangles with a corner over the point
    for k, within in ((1024, 0.01), (4096, 0.01)):
        v = sky_vpls(surf, k, seed=3)
        assert np.all(v.kind == KIND_DIRECTIONAL)
        lights = Lights(v, None, np.ascontiguousarray(v.normal))
        assert lights.points == 0
        H, cuts, rays = irradiance(lights, bvh, surf, pts, nrm)
        H = H[:, 0]
        assert H[0] == pytest.approx(np.pi * L, rel=1e-12)
        assert H[1] == pytest.approx(np.pi * L * (0.5 if hemisphere else 1.0), rel=1e-12)
        if hemisphere:
            assert H[2] == 0.0
        assert abs(H[3] / (np.pi * L * (1 - F)) - 1) < within, (k, H[3] / (np.pi * L * (1 - F)))
        assert np.all(cuts == 0) and rays[0] > 0
    sol = solve(scene, solver_config("preview", resolution=16, photons=50_000))
    full = build_lights(Prepared(scene, bvh, surf), sol, lightcuts_config("preview"), on_surface=False)
    n_sky = int(np.sum(full.vpls.kind == KIND_DIRECTIONAL))
    assert n_sky == lightcuts_config("preview").sky_vpls and full.sky.shape == (n_sky, 3)
    assert full.points == len(full.vpls) - n_sky and len(leaves_of(full.tree, 0)) == full.points


@pytest.mark.parametrize("hemisphere", [True, False])
def test_adaptive_sky_casts_a_ray_per_cell_where_the_sky_agrees(tmp_path, hemisphere):
    """sky_cells: every direction in one cell, its representative among its
    own, neighbours mutual. The adaptive sky (a ray per cell where a cell's
    representative and its neighbours' agree) against a ray along every
    direction, under a square roof and beside a thin pole: the open roof
    exactly pi L with a ray per cell whose representative is above its
    horizon (and one per direction above it of the others); under the
    roof and beside the pole within 0.5% of every direction's answer, never
    more than a ray per cell above its rays, and beside the pole (an open
    sky but for the pole) under 40% of them. A part of the pole that no representative meets
    is missed: less than a cell's share of the sky."""
    from baker.lights import Lights, sky_cells
    from baker.lights.vpl import sky_vpls
    from baker.scene import Sky, load_scene
    from scenes.generate import GltfBuilder, box, quad
    L, a, h = 2.0, 0.5, 0.4
    b = GltfBuilder()
    grey = b.material("grey", (0.5,) * 3)
    b.mesh("floor", *quad((-3, 0, -3), (3, 0, -3), (3, 0, 3), (-3, 0, 3), facing=(0, 1, 0)), grey)
    b.mesh("roof", *quad((-a, h, -a), (a, h, -a), (a, h, a), (-a, h, a), facing=(0, -1, 0)), grey)
    b.mesh("pole", *box((2.0, 0.0, 2.0), (2.04, 0.35, 2.04)), grey)   # below the roof's top
    b.save(tmp_path / "roof.glb")
    scene = load_scene(tmp_path / "roof.glb", sky=Sky(np.full(3, L), hemisphere))
    bvh, surf = build_scene_bvh(scene), pack(scene)
    v = sky_vpls(surf, 1024, seed=3)
    cells = sky_cells(v.normal, surf.arrays.sky_up, hemisphere)
    n_cells = len(cells.start) - 1
    assert 100 <= n_cells <= 160 and cells.start[-1] == 1024
    assert sorted(map(tuple, np.round(cells.dirs, 12))) == sorted(map(tuple, np.round(v.normal, 12)))
    for c in range(n_cells):
        if cells.start[c + 1] > cells.start[c]:
            assert cells.start[c] <= cells.rep[c] < cells.start[c + 1]
        for o in cells.nbr[c][cells.nbr[c] >= 0]:
            assert c in cells.nbr[o]
    lights = Lights(v, None, np.ascontiguousarray(v.normal))
    pts = np.array([[0.0, h, 0.0], [0.0, 0.0, 0.0], [0.3, 0.0, 0.2], [1.9, 0.0, 1.9]])
    nrm = np.tile([0.0, 1.0, 0.0], (len(pts), 1))
    H, _, rays = irradiance(lights, bvh, surf, pts, nrm)
    H_all, _, rays_all = irradiance(lights, bvh, surf, pts, nrm, adaptive_sky=False)
    assert H[0, 0] == pytest.approx(np.pi * L, rel=1e-12)
    above = cells.dirs @ np.array([0.0, 1.0, 0.0]) > 1e-6
    per = [above[cells.start[c]:cells.start[c + 1]] for c in range(n_cells)]
    rep_up = above[cells.rep]
    assert rays[0] == sum(1 if rep_up[c] else int(p.sum()) for c, p in enumerate(per) if p.any())
    assert rays_all[0] == above.sum()
    np.testing.assert_allclose(H[1:, 0], H_all[1:, 0], rtol=5e-3)
    assert np.all(rays <= rays_all + n_cells) and rays[3] <= 0.4 * rays_all[3]
    assert H_all[3, 0] < 0.99 * H_all[0, 0]   # the pole shades the point beside it
    assert abs(H[3, 0] - H_all[3, 0]) <= np.pi * L / n_cells


@pytest.mark.parametrize("hemisphere", [True, False])
def test_adaptive_sky_traces_every_direction_where_the_sky_shows_through_a_window(tmp_path, hemisphere):
    """A closed room lit by the sky through one small window (0.4 x 0.4 m
    in a 4 m room: from most of the floor smaller than a cell of the
    adaptive sky, so it slips between the cells' representatives). Points
    that see the sky through so few cells trace every direction: the
    room's floor and back wall get exactly what a ray along every
    direction gives (the shortcut lost the window's light on the living
    room's floor), and some of them are lit."""
    from baker.lights import Lights, sky_cells
    from baker.lights.vpl import sky_vpls
    from baker.scene import Sky, load_scene
    from scenes.generate import GltfBuilder, box, merge, quad
    b = GltfBuilder()
    grey = b.material("grey", (0.5,) * 3)
    b.mesh("room", *box((0, 0, 0), (4, 3, 4), inward=True, skip=("+x",)), grey)
    y0, y1, z0, z1 = 1.2, 1.6, 1.8, 2.2   # the window's hole in the wall x = 4
    wall = merge(quad((4, 0, 0), (4, y0, 0), (4, y0, 4), (4, 0, 4), facing=(-1, 0, 0)),
                 quad((4, y1, 0), (4, 3, 0), (4, 3, 4), (4, y1, 4), facing=(-1, 0, 0)),
                 quad((4, y0, 0), (4, y1, 0), (4, y1, z0), (4, y0, z0), facing=(-1, 0, 0)),
                 quad((4, y0, z1), (4, y1, z1), (4, y1, 4), (4, y0, 4), facing=(-1, 0, 0)))
    b.mesh("window wall", *wall, grey)
    b.save(tmp_path / "room.glb")
    scene = load_scene(tmp_path / "room.glb", sky=Sky(np.full(3, 2.0), hemisphere))
    bvh, surf = build_scene_bvh(scene), pack(scene)
    v = sky_vpls(surf, 1024, seed=3)
    lights = Lights(v, None, np.ascontiguousarray(v.normal))
    g = np.linspace(0.25, 3.75, 8)
    floor = np.array([[x, 0.0, z] for x in g for z in g])
    back = np.array([[0.0, y, z] for y in np.linspace(0.25, 2.75, 6) for z in g])
    pts = np.concatenate([floor, back])
    nrm = np.concatenate([np.tile([0.0, 1.0, 0.0], (len(floor), 1)), np.tile([1.0, 0.0, 0.0], (len(back), 1))])
    H, _, rays = irradiance(lights, bvh, surf, pts, nrm)
    H_all, _, rays_all = irradiance(lights, bvh, surf, pts, nrm, adaptive_sky=False)
    lit = H_all[:, 0] > 0
    assert lit.sum() >= 10
    np.testing.assert_allclose(H, H_all, rtol=1e-12, atol=0)
    n_cells = len(sky_cells(v.normal, surf.arrays.sky_up, hemisphere).start) - 1
    assert np.all(rays <= rays_all + n_cells)


def fine_emitter_sum(surf, p, n, k=300):
    """The emitters' unoccluded irradiance at p (normal n) by the midpoint
    rule over k^2 congruent pieces of each emitter triangle (cos_p clamped
    at p's horizon; a one-sided emitter lights its front only)."""
    a = surf.arrays
    i, j = np.meshgrid(np.arange(k), np.arange(k), indexing="ij")
    up = (i + j <= k - 1).ravel()
    down = (i + j <= k - 2).ravel()
    bary = np.concatenate([np.stack([i.ravel()[up] + 1 / 3, j.ravel()[up] + 1 / 3], 1),
                           np.stack([i.ravel()[down] + 2 / 3, j.ravel()[down] + 2 / 3], 1)]) / k
    total = np.zeros(3)
    for t in a.emitters:
        c = a.corners[t]
        q = c[0] + bary[:, :1] * (c[1] - c[0]) + bary[:, 1:] * (c[2] - c[0])
        d = p - q
        r2 = np.einsum("ij,ij->i", d, d)
        cos_l = d @ a.tri_normal[t] / np.sqrt(r2)
        cos_l = np.abs(cos_l) if a.double_sided[a.tri_material[t]] else np.maximum(cos_l, 0)
        cos_p = np.maximum(-d @ n / np.sqrt(r2), 0)
        total += a.tri_emission[t] * (cos_l * cos_p / r2).sum() * a.tri_area[t] / k ** 2
    return total


def test_emitters_unoccluded_against_a_fine_sum(make_scene):
    """lightcuts.emitters_unoccluded (Lambert's formula per emitter
    triangle, clipped to the receiver's half-space; the point form beyond
    16 of its longest edges) against the midpoint rule over 90,000 pieces
    of each triangle: a slanted one-sided quad lamp and a two-sided
    triangle, at points near and far, facing every way (lamps cut by the
    receiver's plane among them): within 0.3%. A point behind the
    one-sided lamp, and one in its plane, get nothing from it."""
    from scenes.generate import GltfBuilder, quad
    from baker.lights.lightcuts import emitters_unoccluded
    b = GltfBuilder()
    lamp = b.material("lamp", (0.0,) * 3, emission=(2.0, 1.0, 0.5))
    b.mesh("lamp", *quad((-0.3, 1.0, -0.2), (0.3, 1.2, -0.2), (0.3, 1.2, 0.2), (-0.3, 1.0, 0.2), facing=(0.3, -1, 0)),
           lamp)
    two = b.material("two", (0.0,) * 3, emission=(0.5, 0.5, 1.0), double_sided=True)
    b.mesh("sheet", np.array([[1.0, 0.2, 0.0], [1.0, 0.8, 0.3], [1.0, 0.5, -0.4]]), np.array([[0, 1, 2]]), two)
    scene = make_scene(b, "lights_unoccluded")
    surf = pack(scene)
    rng = np.random.default_rng(4)
    pts = np.concatenate([rng.uniform(-1.5, 2.5, (40, 3)), [[0.0, 0.0, 0.0], [0.1, 0.9, 0.0], [1.2, 0.5, 0.0],
                                                              [0.8, 0.5, -0.1], [0.0, 20.0, 0.0], [30.0, 0.5, 0.0]]])
    nrm = rng.normal(size=(len(pts), 3))
    nrm /= np.linalg.norm(nrm, axis=1)[:, None]
    checked = 0
    for p, n in zip(pts, nrm):
        # the midpoint rule needs the pieces (~0.003 across) small against the distance
        if min(np.min(np.linalg.norm(surf.arrays.corners[t] - p, axis=1)) for t in surf.arrays.emitters) < 0.1:
            continue
        got = np.array(emitters_unoccluded(surf.arrays, *p, *n))
        want = fine_emitter_sum(surf, p, n)
        assert np.allclose(got, want, rtol=3e-3, atol=1e-4 * want.max()), (p, n, got, want)
        checked += want.max() > 0
    assert checked >= 25
    lamp_n = np.cross([0.6, 0.2, 0.0], [0.0, 0.0, 0.4])
    lamp_n /= np.linalg.norm(lamp_n)
    behind = np.array([0.0, 1.1, 0.0]) + 0.2 * lamp_n * np.sign(lamp_n[1])   # the lamp faces down: above it
    only_lamp = surf.arrays._replace(emitters=surf.arrays.emitters[:2])
    assert emitters_unoccluded(only_lamp, *behind, *(-np.sign(lamp_n[1]) * lamp_n)) == (0.0, 0.0, 0.0)
    in_plane = np.array([0.6, 1.3, 0.0])     # on the lamp's plane, beyond its edge
    assert emitters_unoccluded(only_lamp, *in_plane, 0.0, -1.0, 0.0) == (0.0, 0.0, 0.0)


def test_ratio_form_is_exact_where_nothing_blocks(make_scene):
    """Inside a furnace of black emitting walls (E = pi L_e = 1), the
    emitters' light lamp by lamp (irradiance(analytic=True): each lamp's
    exact unoccluded light times its visibility by rays) gives exactly 1
    at every point, a millimetre from an edge or a corner as in the middle
    of a wall (within 1e-6: rounding); the cut over the emitters' VPLs
    reads up to 45% low at the edges (the point form of VPLs nearer than
    their spacing). Behind a blocker the same points get exactly 0."""
    from scenes.generate import furnace_box, GltfBuilder, quad
    from baker.lights import Lights, direct_vpls
    scene = make_scene(furnace_box(albedo=0.0, emission=1.0), "lights_furnace_black")
    bvh, surf = build_scene_bvh(scene), pack(scene)
    v = direct_vpls(surf, 4096, seed=3)
    lights = Lights(v, build_tree(v, 0))
    rng = np.random.default_rng(5)
    u = np.concatenate([rng.uniform(0, 1, (200, 2)), [[0.001, 0.5], [0.001, 0.001], [0.5, 0.999], [0.999, 0.002]]])
    pts = np.stack([u[:, 0], np.zeros(len(u)), u[:, 1]], axis=1)      # the floor, y = 0, facing up
    nrm = np.tile([0.0, 1.0, 0.0], (len(u), 1))
    h, _, _ = irradiance(lights, bvh, surf, pts, nrm, offset=1e-5, epsilon=0.01, cap=400, analytic=True)
    np.testing.assert_allclose(h, 1.0, rtol=1e-6)
    plain, _, _ = irradiance(lights, bvh, surf, pts, nrm, offset=1e-5, epsilon=0.01, cap=400)
    assert plain[-4:, 0].min() < 0.8 and np.abs(plain[:200, 0] - 1).max() > 0.01
    b = GltfBuilder()
    lamp = b.material("lamp", (0.0,) * 3, emission=(1.0,) * 3)
    grey = b.material("grey", (0.5,) * 3)
    b.mesh("lamp", *quad((-0.5, 2, -0.5), (0.5, 2, -0.5), (0.5, 2, 0.5), (-0.5, 2, 0.5), facing=(0, -1, 0)), lamp)
    b.mesh("roof", *quad((-2, 1, -2), (2, 1, -2), (2, 1, 2), (-2, 1, 2), facing=(0, 1, 0)), grey)
    b.mesh("floor", *quad((-3, 0, -3), (3, 0, -3), (3, 0, 3), (-3, 0, 3), facing=(0, 1, 0)), grey)
    scene = make_scene(b, "lights_ratio_blocked")
    bvh, surf = build_scene_bvh(scene), pack(scene)
    v = direct_vpls(surf, 1024, seed=3)
    pts = np.array([[0.0, 0.0, 0.0], [1.5, 0.0, 1.5]])
    h, _, _ = irradiance(Lights(v, build_tree(v, 0)), bvh, surf, pts, np.tile([0.0, 1.0, 0.0], (2, 1)),
                         analytic=True)
    assert h.max() == 0.0


def test_spherical_triangle_samples_are_uniform_over_the_solid_angle():
    """lamps.spherical_sample (Arvo's method) puts a share of its samples
    in each part of a spherical triangle equal to that part's share of
    the solid angle (three parts through a point inside, within 1% of the
    whole on 100,000 stratified samples), every sample inside the
    triangle and of unit length. A sampler biased towards a corner, or the
    uniform-in-area map projected onto the sphere, fails."""
    from numba import njit
    from baker.lights.lamps import solid_angle, spherical_sample

    @njit
    def draw(a, b, c, u):
        om = solid_angle(a[0], a[1], a[2], b[0], b[1], b[2], c[0], c[1], c[2])
        out = np.empty((u.shape[0], 3))
        for i in range(u.shape[0]):
            x, y, z, ok = spherical_sample(a[0], a[1], a[2], b[0], b[1], b[2], c[0], c[1], c[2], om, u[i, 0], u[i, 1])
            out[i] = (x, y, z) if ok else (np.nan, np.nan, np.nan)
        return out

    def omega(a, b, c):
        return 2 * np.arctan2(abs(np.dot(a, np.cross(b, c))), 1 + a @ b + b @ c + c @ a)

    def inside(p, q, r, d):
        s = [np.sign(d @ np.cross(p, q)), np.sign(d @ np.cross(q, r)), np.sign(d @ np.cross(r, p))]
        return (s[0] == s[1]) & (s[1] == s[2])

    rng = np.random.default_rng(7)
    g = (np.arange(100_000) + 0.5) / 100_000
    u = np.stack([g, rng.permutation(g)], axis=1)
    # a wide one (most of a hemisphere), a thin sliver, a small far one
    for corners in ([[1, 0, 0.05], [0, 1, 0.05], [-0.7, -0.7, 0.05]],
                    [[1, 0, 1], [1, 0.05, 1], [0.2, 1, 1]],
                    [[0.01, 0, 1], [0, 0.01, 1], [-0.01, -0.01, 1]]):
        a, b, c = (np.array(v, float) / np.linalg.norm(v) for v in corners)
        d = draw(a, b, c, u)
        assert np.all(np.isfinite(d)) and np.abs(np.linalg.norm(d, axis=1) - 1).max() < 1e-9
        assert inside(a, b, c, d).mean() > 0.9999
        m = a + b + c
        m /= np.linalg.norm(m)
        whole = omega(a, b, c)
        for p, q, r in ((m, b, c), (a, m, c), (a, b, m)):
            assert abs(inside(p, q, r, d).mean() - omega(p, q, r) / whole) < 0.01


def test_lamps_are_connected_emitter_triangles(make_scene):
    """lamp_groups: emitter triangles that share a corner are one lamp (a
    quad of 8 triangles), apart they are two; other triangles are in none."""
    from scenes.generate import GltfBuilder, quad
    from baker.lights.lamps import lamp_groups
    b = GltfBuilder()
    lamp = b.material("lamp", (0.0,) * 3, emission=(1.0,) * 3)
    grey = b.material("grey", (0.5,) * 3)
    b.mesh("one", *quad((0, 2, 0), (1, 2, 0), (1, 2, 1), (0, 2, 1), facing=(0, -1, 0), subdiv=2), lamp)
    b.mesh("two", *quad((3, 2, 0), (4, 2, 0), (4, 2, 1), (3, 2, 1), facing=(0, -1, 0)), lamp)
    b.mesh("floor", *quad((-3, 0, -3), (6, 0, -3), (6, 0, 3), (-3, 0, 3), facing=(0, 1, 0)), grey)
    surf = pack(make_scene(b, "lamps_groups")).arrays
    lamps = lamp_groups(surf)
    assert len(lamps.start) == 3 and sorted(np.diff(lamps.start)) == [2, 8]
    assert sorted(lamps.tris.tolist()) == sorted(surf.emitters.tolist())


def test_a_large_lamp_close_by_partly_hidden_matches_rays_over_the_hemisphere(make_scene):
    """Beside a large lamp (a 4 m x 4 m panel 10 cm above the floor) with a
    3 cm bar between them, the emitters' light at 36 floor points across
    the bar's shadow (irradiance(analytic=True): each lamp's exact light
    times its visibility by rays over its solid angle) against 100,000
    cosine-weighted rays from the same origin: no bias (the signed errors'
    mean within 1% of the unblocked light), within 2.5% on average and 10%
    at every point (the first rays of a lamp at a point must not all miss
    the bar's band: with 16 of them one point read 17% bright); a point
    that nothing blocks gets the lamp's exact light. (The lightcut in
    ratio form that this replaced read 0.15 for 0.70 beside the modern hall's
    light panels.)"""
    from scenes.generate import GltfBuilder, quad
    from baker.kernels.traverse import closest_hit_batch
    from baker.lights import Lights, direct_vpls
    from baker.lights.lamps import LAMP_LIFT
    from baker.lights.lightcuts import emitters_unoccluded
    b = GltfBuilder()
    lamp = b.material("lamp", (0.0,) * 3, emission=(1.0,) * 3)
    grey = b.material("grey", (0.5,) * 3)
    b.mesh("panel", *quad((-2, 0.1, -2), (2, 0.1, -2), (2, 0.1, 2), (-2, 0.1, 2), facing=(0, -1, 0)), lamp)
    b.mesh("bar", *quad((0.0, 0.05, -2), (0.03, 0.05, -2), (0.03, 0.05, 2), (0.0, 0.05, 2), facing=(0, -1, 0)), grey)
    b.mesh("floor", *quad((-3, 0, -3), (3, 0, -3), (3, 0, 3), (-3, 0, 3), facing=(0, 1, 0)), grey)
    scene = make_scene(b, "lamps_close_panel")
    bvh, surf = build_scene_bvh(scene), pack(scene)
    v = direct_vpls(surf, 4096, seed=3)
    pts = np.array([[x, 0.0, 0.3] for x in np.linspace(-0.15, 0.2, 36)] + [[-1.5, 0.0, -1.5]])
    nrm = np.tile([0.0, 1.0, 0.0], (len(pts), 1))
    offset = 0.01
    h, _, _ = irradiance(Lights(v, build_tree(v, 0)), bvh, surf, pts, nrm, offset=offset, epsilon=0.01, cap=200,
                         analytic=True)
    a = np.array([emitters_unoccluded(surf.arrays, *p, *n) for p, n in zip(pts, nrm)])
    rng = np.random.default_rng(3)
    m = 100_000
    u1, u2 = rng.random(m), rng.random(m)
    r, phi = np.sqrt(u1), 2 * np.pi * u2
    d = np.stack([r * np.cos(phi), np.sqrt(1 - u1), r * np.sin(phi)], axis=1)
    truth = []
    for p in pts:
        o = np.repeat((p + [0.0, LAMP_LIFT * offset, 0.0])[None], m, 0)
        _, tri, _, _ = closest_hit_batch(bvh.arrays, o, d, 0.0, np.full(m, np.inf))
        truth.append(np.pi * np.isin(tri, surf.arrays.emitters).mean())
    truth = np.array(truth)
    assert truth[:36].min() < 0.75 * np.pi and (truth[:36] > 0.97 * np.pi).sum() >= 4   # shadow and light both
    err = (h[:36, 0] - truth[:36]) / a[:36, 0]
    assert abs(err.mean()) < 0.01 and np.abs(err).mean() < 0.025 and np.abs(err).max() < 0.10, err
    assert h[36, 0] == a[36, 0]                    # nothing between: the exact light
