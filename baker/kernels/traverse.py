"""Ray queries on the BVH of `bvh.py`: closest hit and any hit (shadow rays).

`bvh` is a `BVHArrays` (kernels/bvh.py): the binary SAH tree collapsed to an
8-wide one, whose nodes hold their eight children's boxes in one 256-byte
record (four adjacent cache lines). A visit tests the eight boxes in one
branch-free loop (a bit mask of the children hit) and walks the set bits.
Leaf children are intersected at once; closest hit visits the nearest
inner child next, any hit the first in slot order. The scalar queries
take a caller-owned `stack` (int32, STACK_SIZE: the build keeps the tree
shallower, kernels/bvh.py) so that nothing is allocated per ray. Triangles
are hit from both sides (watertight test, float64 arithmetic); the caller
decides what the back side means.

What rays pass (bvh.tri_pass): a masked triangle's cut-out texels are not
there for any query (cut_out); thin glass is a surface for closest_hit
and any_hit (the caller decides: the path tracer and the photons go
through it) and a filter for `transmittance`, the shadow query of the
light paths, which multiplies the tints of the glass it crosses.
"""
import numpy as np
from numba import njit, prange
from numba.cpython.unsafe.numbers import trailing_zeros

from .bvh import PASS_GLASS, PASS_MASK, STACK_SIZE, WIDE_CHILD, WIDE_COUNT, WIDE_HI, WIDE_LO, WIDTH
from .geometry import unit_cross


@njit(cache=True, inline="always", error_model="numpy")
def _inv(d):
    if abs(d) < 1e-30:
        return 1e30 if d >= 0.0 else -1e30
    return 1.0 / d


@njit(cache=True, inline="always", error_model="numpy")
def _slab(b, k, ox, oy, oz, ix, iy, iz, tmin, tmax):
    """Entry distance into box b[k:k+6] (lo xyz, hi xyz), inf on a miss."""
    t0 = (b[k] - ox) * ix
    t1 = (b[k + 3] - ox) * ix
    tn, tf = min(t0, t1), max(t0, t1)
    t0 = (b[k + 1] - oy) * iy
    t1 = (b[k + 4] - oy) * iy
    tn, tf = max(tn, min(t0, t1)), min(tf, max(t0, t1))
    t0 = (b[k + 2] - oz) * iz
    t1 = (b[k + 5] - oz) * iz
    tn, tf = max(tn, min(t0, t1)), min(tf, max(t0, t1))
    tn = max(tn, tmin)
    tf = min(tf, tmax)
    # widen by 4 ulps (Ize 2013) so rounding never drops a box the ray touches
    return tn if tn <= tf * 1.0000000000000009 else np.inf


@njit(cache=True, inline="always", error_model="numpy")
def ray_shear(dx, dy, dz):
    """Per-ray set-up of the watertight test: axis permutation (kx, ky, kz)
    with kz the dominant axis, and the shear (sx, sy, sz)."""
    ax, ay, az = abs(dx), abs(dy), abs(dz)
    if ax >= ay and ax >= az:
        kz = 0
    elif ay >= az:
        kz = 1
    else:
        kz = 2
    kx = (kz + 1) % 3
    ky = (kx + 1) % 3
    d = (dx, dy, dz)
    if d[kz] < 0.0:
        kx, ky = ky, kx
    return kx, ky, kz, d[kx] / d[kz], d[ky] / d[kz], 1.0 / d[kz]


@njit(cache=True, inline="always", error_model="numpy")
def intersect_triangle(tris, j, o, kx, ky, kz, sx, sy, sz):
    """Watertight ray/triangle test (Woop, Benthin & Wald 2013, JCGT 2(1)):
    rays through a shared edge or vertex hit at least one of the triangles,
    never slip between them. o: the ray origin permuted as (o[kx], o[ky],
    o[kz]) (once per ray, not per triangle). Returns (t, u, v) with u, v
    the weights of v1, v2; t = inf on a miss."""
    ox, oy, oz = o  # the origin, already permuted to (kx, ky, kz)
    ax, ay, az = tris[j, kx] - ox, tris[j, ky] - oy, tris[j, kz] - oz
    bx, by, bz = tris[j, 3 + kx] - ox, tris[j, 3 + ky] - oy, tris[j, 3 + kz] - oz
    cx, cy, cz = tris[j, 6 + kx] - ox, tris[j, 6 + ky] - oy, tris[j, 6 + kz] - oz
    ax, ay = ax - sx * az, ay - sy * az
    bx, by = bx - sx * bz, by - sy * bz
    cx, cy = cx - sx * cz, cy - sy * cz
    eu = cx * by - cy * bx
    ev = ax * cy - ay * cx
    ew = bx * ay - by * ax
    # the signs combined without short-circuits: one branch, not six (they mispredict on rejected triangles)
    if ((eu < 0.0) | (ev < 0.0) | (ew < 0.0)) & ((eu > 0.0) | (ev > 0.0) | (ew > 0.0)):
        return np.inf, 0.0, 0.0
    det = eu + ev + ew
    if det == 0.0:
        return np.inf, 0.0, 0.0
    t = (eu * az + ev * bz + ew * cz) * sz / det
    return t, ev / det, ew / det


@njit(cache=True, inline="always", error_model="numpy")
def _slab_slot(w, node, s, ox, oy, oz, ix, iy, iz, tmin, tmax):
    """Entry distance into slot s's box of wide node `node`, inf on a miss
    (boxes widened by 4 ulps as _slab)."""
    t0 = (w[node, WIDE_LO + s] - ox) * ix
    t1 = (w[node, WIDE_HI + s] - ox) * ix
    tn, tf = min(t0, t1), max(t0, t1)
    t0 = (w[node, WIDE_LO + WIDTH + s] - oy) * iy
    t1 = (w[node, WIDE_HI + WIDTH + s] - oy) * iy
    tn, tf = max(tn, min(t0, t1)), min(tf, max(t0, t1))
    t0 = (w[node, WIDE_LO + 2 * WIDTH + s] - oz) * iz
    t1 = (w[node, WIDE_HI + 2 * WIDTH + s] - oz) * iz
    tn, tf = max(tn, min(t0, t1)), min(tf, max(t0, t1))
    tn = max(tn, tmin)
    tf = min(tf, tmax)
    return tn if tn <= tf * 1.0000000000000009 else np.inf


@njit(cache=True, inline="always", error_model="numpy")
def _hit_mask(w, wi, node, ox, oy, oz, ix, iy, iz, tmin, tmax):
    """Bit s set where slot s of wide node `node` holds a child whose box
    the ray meets within (tmin, tmax): the WIDTH slab tests in one loop
    with no branch (faster than a branching loop: bench/rays.py). The slab
    test is written out again here, not shared with _slab_slot: a shared
    helper returning the (entry, exit) pair slowed coherent shadow rays."""
    m = 0
    for s in range(WIDTH):
        t0 = (w[node, WIDE_LO + s] - ox) * ix
        t1 = (w[node, WIDE_HI + s] - ox) * ix
        tn, tf = min(t0, t1), max(t0, t1)
        t0 = (w[node, WIDE_LO + WIDTH + s] - oy) * iy
        t1 = (w[node, WIDE_HI + WIDTH + s] - oy) * iy
        tn, tf = max(tn, min(t0, t1)), min(tf, max(t0, t1))
        t0 = (w[node, WIDE_LO + 2 * WIDTH + s] - oz) * iz
        t1 = (w[node, WIDE_HI + 2 * WIDTH + s] - oz) * iz
        tn, tf = max(tn, min(t0, t1)), min(tf, max(t0, t1))
        tn = max(tn, tmin)
        tf = min(tf, tmax)
        m |= ((tn <= tf * 1.0000000000000009) & (wi[node, WIDE_COUNT + s] >= 0)) << s
    return m


@njit(cache=True, inline="always", error_model="numpy")
def cut_out(bvh, j, u, v):
    """Is the hit (u, v) on masked BVH-order triangle j in a cut-out texel:
    alpha factor x texture alpha (nearest texel, wrapped, as albedo_at)
    below the material's cutoff?"""
    m = bvh.tri_mat[j]
    a = bvh.mask_alpha[m]
    off = bvh.mask_offset[m]
    if off >= 0:
        uv = bvh.tri_uv
        w0 = 1.0 - u - v
        s = w0 * uv[j, 0] + u * uv[j, 2] + v * uv[j, 4]
        t = w0 * uv[j, 1] + u * uv[j, 3] + v * uv[j, 5]
        w, h = bvh.mask_size[m, 0], bvh.mask_size[m, 1]
        x = int(np.floor((s - np.floor(s)) * w)) % w
        y = int(np.floor((t - np.floor(t)) * h)) % h
        a *= bvh.mask_data[off + y * w + x]
    return a < bvh.mask_cutoff[m]


TIE = 1.0 + 1e-12   # hits this near the best are at one point: a ray through a box's convex edge or corner


@njit(cache=True, inline="always", error_model="numpy")
def _facing(bvh, j, dx, dy, dz):
    nx, ny, nz = hit_normal(bvh, j)
    return nx * dx + ny * dy + nz * dz < 0.0


@njit(cache=True, error_model="numpy")
def closest_hit(bvh, stack, ox, oy, oz, dx, dy, dz, tmin, tmax, cull_back=False):
    """First hit with t in (tmin, tmax): (t, bvh-order triangle j, u, v);
    j = -1 and t = inf on a miss. Triangles met at one point (within TIE:
    a ray through a convex edge or corner enters one face as it leaves
    the other) give the one it meets from the front, whichever the
    traversal found first: else a camera ray through a box's corner sees
    the inside of the box. cull_back: triangles seen from behind
    (winding normal . d > 0) are passed through, as a rasterizer culls them.

    Wide traversal: a node's boxes are tested together (_hit_mask); leaf
    children are intersected at once, the nearest inner child is visited
    next and the others wait on the stack."""
    w, wi, root, tris = bvh.wide, bvh.wide_i, bvh.root_box, bvh.tris
    ix, iy, iz = _inv(dx), _inv(dy), _inv(dz)
    kx, ky, kz, sx, sy, sz = ray_shear(dx, dy, dz)
    unpermuted = (ox, oy, oz)
    o = (unpermuted[kx], unpermuted[ky], unpermuted[kz])
    best_t, best_j, best_u, best_v = tmax, -1, 0.0, 0.0
    if _slab(root, 0, ox, oy, oz, ix, iy, iz, tmin, tmax) == np.inf:
        return np.inf, -1, 0.0, 0.0
    sp = 0
    node = 0
    while True:
        m = _hit_mask(w, wi, node, ox, oy, oz, ix, iy, iz, tmin, best_t)
        near, near_t = -1, np.inf
        while m:
            s = trailing_zeros(m)
            m &= m - 1
            n = wi[node, WIDE_COUNT + s]
            c = wi[node, WIDE_CHILD + s]
            if n > 0:
                for j in range(c, c + n):
                    th, u, v = intersect_triangle(tris, j, o, kx, ky, kz, sx, sy, sz)
                    if tmin < th < best_t or (tmin < th <= best_t * TIE and best_j >= 0
                                              and _facing(bvh, j, dx, dy, dz) and not _facing(bvh, best_j, dx, dy, dz)):
                        if cull_back:
                            nx, ny, nz = hit_normal(bvh, j)
                            if nx * dx + ny * dy + nz * dz > 0.0:
                                continue
                        if bvh.tri_pass[j] == PASS_MASK and cut_out(bvh, j, u, v):
                            continue
                        best_t, best_j, best_u, best_v = th, j, u, v
                continue
            t = _slab_slot(w, node, s, ox, oy, oz, ix, iy, iz, tmin, best_t)
            if t == np.inf:
                continue
            if t < near_t:
                if near >= 0:
                    stack[sp] = near
                    sp += 1
                near, near_t = c, t
            else:
                stack[sp] = c
                sp += 1
        if near >= 0:
            node = near
        elif sp == 0:
            break
        else:
            sp -= 1
            node = stack[sp]
    if best_j < 0:
        return np.inf, -1, 0.0, 0.0
    return best_t, best_j, best_u, best_v


@njit(cache=True, error_model="numpy")
def any_hit(bvh, stack, ox, oy, oz, dx, dy, dz, tmin, tmax):
    """True if anything is hit with t in (tmin, tmax) (wide traversal,
    children in slot order, leaves at once)."""
    w, wi, root, tris = bvh.wide, bvh.wide_i, bvh.root_box, bvh.tris
    ix, iy, iz = _inv(dx), _inv(dy), _inv(dz)
    kx, ky, kz, sx, sy, sz = ray_shear(dx, dy, dz)
    unpermuted = (ox, oy, oz)
    o = (unpermuted[kx], unpermuted[ky], unpermuted[kz])
    if _slab(root, 0, ox, oy, oz, ix, iy, iz, tmin, tmax) == np.inf:
        return False
    sp = 0
    node = 0
    while True:
        m = _hit_mask(w, wi, node, ox, oy, oz, ix, iy, iz, tmin, tmax)
        nxt = -1
        while m:
            s = trailing_zeros(m)
            m &= m - 1
            n = wi[node, WIDE_COUNT + s]
            c = wi[node, WIDE_CHILD + s]
            if n > 0:
                for j in range(c, c + n):
                    th, u, v = intersect_triangle(tris, j, o, kx, ky, kz, sx, sy, sz)
                    if tmin < th < tmax:
                        if bvh.tri_pass[j] == PASS_MASK and cut_out(bvh, j, u, v):
                            continue
                        return True
            elif nxt < 0:
                nxt = c
            else:
                stack[sp] = c
                sp += 1
        if nxt >= 0:
            node = nxt
        elif sp == 0:
            return False
        else:
            sp -= 1
            node = stack[sp]


@njit(cache=True, error_model="numpy")
def transmittance(bvh, stack, ox, oy, oz, dx, dy, dz, tmin, tmax):
    """(r, g, b) of the light that crosses (tmin, tmax): 0 where an opaque
    surface lies on it, else the product of the glass tints it crosses (1
    through nothing); cut-out texels pass. The traversal of any_hit, which
    stops at the first opaque hit; through glass it visits every node the
    ray meets."""
    w, wi, root, tris = bvh.wide, bvh.wide_i, bvh.root_box, bvh.tris
    ix, iy, iz = _inv(dx), _inv(dy), _inv(dz)
    kx, ky, kz, sx, sy, sz = ray_shear(dx, dy, dz)
    unpermuted = (ox, oy, oz)
    o = (unpermuted[kx], unpermuted[ky], unpermuted[kz])
    tr, tg, tb = 1.0, 1.0, 1.0
    seen0 = seen1 = seen2 = -np.inf   # the last glass crossings counted
    if _slab(root, 0, ox, oy, oz, ix, iy, iz, tmin, tmax) == np.inf:
        return tr, tg, tb
    sp = 0
    node = 0
    while True:
        m = _hit_mask(w, wi, node, ox, oy, oz, ix, iy, iz, tmin, tmax)
        nxt = -1
        while m:
            s = trailing_zeros(m)
            m &= m - 1
            n = wi[node, WIDE_COUNT + s]
            c = wi[node, WIDE_CHILD + s]
            if n > 0:
                for j in range(c, c + n):
                    th, u, v = intersect_triangle(tris, j, o, kx, ky, kz, sx, sy, sz)
                    if tmin < th < tmax:
                        kind = bvh.tri_pass[j]
                        if kind == PASS_MASK and cut_out(bvh, j, u, v):
                            continue
                        if kind != PASS_GLASS:
                            return 0.0, 0.0, 0.0
                        # a ray through an edge the pane's triangles share hits each of them (watertight):
                        # a crossing at the distance of one already counted is that same crossing
                        tol = 1e-9 * max(th, 1e-9)
                        if abs(th - seen0) <= tol or abs(th - seen1) <= tol or abs(th - seen2) <= tol:
                            continue
                        seen0, seen1, seen2 = th, seen0, seen1
                        g = bvh.glass_tint[bvh.tri_mat[j]]
                        tr, tg, tb = tr * g[0], tg * g[1], tb * g[2]
                        if tr <= 0.0 and tg <= 0.0 and tb <= 0.0:
                            return 0.0, 0.0, 0.0
            elif nxt < 0:
                nxt = c
            else:
                stack[sp] = c
                sp += 1
        if nxt >= 0:
            node = nxt
        elif sp == 0:
            return tr, tg, tb
        else:
            sp -= 1
            node = stack[sp]


@njit(cache=True, inline="always", error_model="numpy")
def hit_normal(bvh, j):
    """Unit geometric normal (winding order) of BVH-order triangle j."""
    tr = bvh.tris
    return unit_cross(tr[j, 3] - tr[j, 0], tr[j, 4] - tr[j, 1], tr[j, 5] - tr[j, 2],
                      tr[j, 6] - tr[j, 0], tr[j, 7] - tr[j, 1], tr[j, 8] - tr[j, 2])


@njit(cache=True, inline="always", error_model="numpy")
def back_hit(bvh, stack, double, mat_of, ox, oy, oz, dx, dy, dz, reach, near):
    """What the ray from o along d first meets, for the inside tests
    (lightmap/texels.inside_geometry, voxels/buried.py): 0 nothing within
    `reach` or a triangle's front, 1 a two-sided triangle from behind
    (against its winding) beyond `near`, 2 a one-sided one from behind,
    3 a two-sided one from behind within `near`."""
    t, j, _, _ = closest_hit(bvh, stack, ox, oy, oz, dx, dy, dz, 0.0, reach)
    if j < 0:
        return 0
    hx, hy, hz = hit_normal(bvh, j)
    if hx * dx + hy * dy + hz * dz <= 0.0:
        return 0
    if not double[mat_of[bvh.tri_index[j]]]:
        return 2
    return 3 if t <= near else 1


@njit(cache=True, error_model="numpy")
def enclosed_in_plane(bvh, stack, ox, oy, oz, tx, ty, tz, bx, by, bz, reach):
    """True where the rays from o along +-t and +-b (two unit tangents of a
    surface under o) each first meet a triangle from behind (against its
    winding) within `reach`: o lies inside a closed object around the
    surface (a wall's point inside a step that runs into it, a floor's
    point inside a board pushed into it), not in a gap under a sheet seen
    from behind (the ceiling's point over a lamp hung 1 cm under it: those
    rays leave the gap and meet the walls from the front)."""
    for e in range(4):
        s = 1.0 if e % 2 == 0 else -1.0
        if e < 2:
            dx, dy, dz = s * tx, s * ty, s * tz
        else:
            dx, dy, dz = s * bx, s * by, s * bz
        _, j, _, _ = closest_hit(bvh, stack, ox, oy, oz, dx, dy, dz, 0.0, reach)
        if j < 0:
            return False
        hx, hy, hz = hit_normal(bvh, j)
        if hx * dx + hy * dy + hz * dz <= 0.0:
            return False
    return True


_CHUNK = 256


@njit(cache=True, parallel=True, error_model="numpy")
def closest_hit_batch(bvh, origins, dirs, tmin, tmax):
    """origins, dirs (n, 3) float64 -> t (n,) float64 (inf: miss),
    triangle (n,) int32 (scene numbering, -1: miss), u, v (n,) float64."""
    n = origins.shape[0]
    t_out = np.empty(n)
    tri = np.empty(n, np.int32)
    u_out = np.empty(n)
    v_out = np.empty(n)
    index = bvh.tri_index
    for c in prange((n + _CHUNK - 1) // _CHUNK):
        stack = np.empty(STACK_SIZE, np.int32)
        for i in range(c * _CHUNK, min(n, (c + 1) * _CHUNK)):
            t, j, u, v = closest_hit(bvh, stack, origins[i, 0], origins[i, 1], origins[i, 2], dirs[i, 0],
                                     dirs[i, 1], dirs[i, 2], tmin, tmax[i])
            t_out[i], u_out[i], v_out[i] = t, u, v
            tri[i] = index[j] if j >= 0 else -1
    return t_out, tri, u_out, v_out


@njit(cache=True, parallel=True, error_model="numpy")
def any_hit_batch(bvh, origins, dirs, tmin, tmax):
    """(n,) bool: occluded within (tmin, tmax[i])."""
    n = origins.shape[0]
    out = np.empty(n, np.bool_)
    for c in prange((n + _CHUNK - 1) // _CHUNK):
        stack = np.empty(STACK_SIZE, np.int32)
        for i in range(c * _CHUNK, min(n, (c + 1) * _CHUNK)):
            out[i] = any_hit(bvh, stack, origins[i, 0], origins[i, 1], origins[i, 2], dirs[i, 0], dirs[i, 1],
                             dirs[i, 2], tmin, tmax[i])
    return out


@njit(cache=True, parallel=True, error_model="numpy")
def transmittance_batch(bvh, origins, dirs, tmin, tmax):
    """(n, 3) float64: the light that crosses (tmin, tmax[i]) (transmittance)."""
    n = origins.shape[0]
    out = np.empty((n, 3))
    for c in prange((n + _CHUNK - 1) // _CHUNK):
        stack = np.empty(STACK_SIZE, np.int32)
        for i in range(c * _CHUNK, min(n, (c + 1) * _CHUNK)):
            out[i, 0], out[i, 1], out[i, 2] = transmittance(bvh, stack, origins[i, 0], origins[i, 1], origins[i, 2],
                                                            dirs[i, 0], dirs[i, 1], dirs[i, 2], tmin, tmax[i])
    return out
