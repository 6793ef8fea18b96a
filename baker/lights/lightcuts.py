"""Lightcuts (Walter et al. 2005; docs/design.md section 7): the irradiance
at a shading point p (normal n) from the VPLs of a light tree, by a cut
through the tree chosen so that every node's error bound is below epsilon
times the estimate.

    estimate(node) = power(node) x g(rep(node)),  g = V cos_l cos_p / (pi r^2 + A)  (area VPLs)
                                                   g = V cos_p                       (sky directions)
    bound(node)    = lum(node) x cos_l_ub x cos_p_ub / (pi r_lb^2)   (area; infinite when p is in the box)
                   = lum(node) x cos_p_ub                              (directions)

Start with the root; repeatedly refine the node with the largest bound (a
max-heap) while it exceeds epsilon x the estimate's luminance and the cut
is below the cap; leaves are exact. One shadow ray per new representative:
the child that keeps its parent's representative keeps its g.
`brute_force` sums every VPL with the same g (the reference, and the
speed-up's denominator).
"""
from __future__ import annotations

import math
from collections import namedtuple

import numpy as np
from numba import njit, prange

from ..kernels.bvh import STACK_SIZE
from ..kernels.colour import LUM_B, LUM_G, LUM_R
from ..kernels.inline import borrowed
from ..kernels.traverse import transmittance
from ..scene.surfaces import SKY_HEMISPHERE, SKY_NONE, punctual_irradiance
from .vpl import KIND_DIRECTIONAL

# The kernels' view of a light tree (lights/__init__.py: tree_arrays packs it, one 128-byte record per node)
# and of its VPLs; patch: the tree's largest VPL patch under each node (node_patches), a VPL's patch area (0:
# none, the point form throughout).
TreeArrays = namedtuple("TreeArrays", ["lo", "hi", "axis", "cos", "power", "lum", "rep", "right", "kind", "patch"])
VPLArrays = namedtuple("VPLArrays", ["kind", "position", "normal", "area", "power", "patch"])
# The sky's directions grouped into cells of neighbouring directions (lights.sky_cells): dirs (K, 3) sorted by
# cell, cell c's directions dirs[start[c]:start[c + 1]], its representative rep[c] (an index into dirs; -1:
# empty cell) and its neighbouring cells nbr[c] (-1: none). One direction per cell and no neighbours: a ray
# along every direction.
SkyCells = namedtuple("SkyCells", ["dirs", "start", "rep", "nbr"])

SHADOW_EPS = 1e-4   # shadow rays stop this fraction short of an area VPL (it lies on a surface)
NEAR, FAR = 2.0, 3.0  # a voxel's VPL nearer than NEAR x sqrt(A) takes its patch's form factor; by FAR, the point form
COS_MIN = 1e-6      # cosines below this are 0: a VPL rounded 1e-17 below the plane of the floor it lies on must not
#                     light the face of a box resting on that floor (1e-34 where the truth is 0)


@njit(cache=True, inline="always")
def _edge_term(ax, ay, az, bx, by, bz, nx, ny, nz):
    """Lambert's term of a polygon's edge a -> b seen from the origin: the
    angle it subtends times the cosine between n and the normal of the
    plane through it."""
    la = math.sqrt(ax * ax + ay * ay + az * az)
    lb = math.sqrt(bx * bx + by * by + bz * bz)
    if la <= 0.0 or lb <= 0.0:
        return 0.0
    cx, cy, cz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
    sn = math.sqrt(cx * cx + cy * cy + cz * cz)
    if sn <= 0.0:
        return 0.0
    return math.atan2(sn, ax * bx + ay * by + az * bz) * (nx * cx + ny * cy + nz * cz) / sn


@njit(cache=True, inline="always")
def _clip_edge(qx, qy, qz, rx, ry, rz, nx, ny, nz, acc, count, fx, fy, fz, lx, ly, lz):
    """One edge q -> r of a polygon (relative to p) clipped against p's
    upper half-space n . x >= 0 (Sutherland-Hodgman): the vertices it
    emits join the clipped polygon, whose Lambert sum `acc` grows by each
    new edge; f is the polygon's first vertex, l the last emitted, count
    how many. Returns the new (acc, count, f, l)."""
    hq = nx * qx + ny * qy + nz * qz
    hr = nx * rx + ny * ry + nz * rz
    for e in range(2):
        if e == 0:
            if hq < 0.0:
                continue
            ox, oy, oz = qx, qy, qz
        else:
            if not (hq < 0.0) != (hr < 0.0):
                continue
            f = hq / (hq - hr)
            ox, oy, oz = qx + f * (rx - qx), qy + f * (ry - qy), qz + f * (rz - qz)
        if count == 0:
            fx, fy, fz = ox, oy, oz
        else:
            acc += _edge_term(lx, ly, lz, ox, oy, oz, nx, ny, nz)
        lx, ly, lz = ox, oy, oz
        count += 1
    return acc, count, fx, fy, fz, lx, ly, lz


@njit(cache=True)
def patch_g(vpls, v, p, n):
    """The near field of VPL v at p: the form factor from p to its patch
    over the patch's area, F / A (irradiance = power x F / A = B F). The
    patch is the square of area A centred on v's position in its plane
    (edges along the grid's axes where its normal is one: a voxel's),
    clipped to p's upper half-space; F by Lambert's formula,
    |sum over its edges of angle x cos| / (2 pi): exact for any distance,
    B at a point the patch covers."""
    px, py, pz = p
    nx, ny, nz = n
    mx, my, mz = vpls.normal[v, 0], vpls.normal[v, 1], vpls.normal[v, 2]
    if abs(mx) >= abs(my) and abs(mx) >= abs(mz):
        ex, ey, ez = 0.0, 1.0, 0.0
    elif abs(my) >= abs(mz):
        ex, ey, ez = 0.0, 0.0, 1.0
    else:
        ex, ey, ez = 1.0, 0.0, 0.0
    d = ex * mx + ey * my + ez * mz
    tx, ty, tz = ex - d * mx, ey - d * my, ez - d * mz
    tl = math.sqrt(tx * tx + ty * ty + tz * tz)
    tx, ty, tz = tx / tl, ty / tl, tz / tl
    bx, by, bz = my * tz - mz * ty, mz * tx - mx * tz, mx * ty - my * tx
    half = 0.5 * math.sqrt(vpls.patch[v])
    cx, cy, cz = vpls.position[v, 0] - px, vpls.position[v, 1] - py, vpls.position[v, 2] - pz
    acc = 0.0
    count = 0
    fx = fy = fz = 0.0   # the clipped polygon's first vertex, and the last one emitted
    lx = ly = lz = 0.0
    for k in range(4):   # corners (-,-), (+,-), (+,+), (-,+); clipped against n . q >= 0 (Sutherland-Hodgman)
        su = -1.0 if k == 0 or k == 3 else 1.0
        sv = -1.0 if k < 2 else 1.0
        qx = cx + half * (su * tx + sv * bx)
        qy = cy + half * (su * ty + sv * by)
        qz = cz + half * (su * tz + sv * bz)
        k2 = (k + 1) % 4
        su2 = -1.0 if k2 == 0 or k2 == 3 else 1.0
        sv2 = -1.0 if k2 < 2 else 1.0
        rx = cx + half * (su2 * tx + sv2 * bx)
        ry = cy + half * (su2 * ty + sv2 * by)
        rz = cz + half * (su2 * tz + sv2 * bz)
        acc, count, fx, fy, fz, lx, ly, lz = _clip_edge(qx, qy, qz, rx, ry, rz, nx, ny, nz, acc, count, fx, fy, fz,
                                                        lx, ly, lz)
    if count < 3:
        return 0.0
    acc += _edge_term(lx, ly, lz, fx, fy, fz, nx, ny, nz)
    return abs(acc) / (2.0 * math.pi * vpls.patch[v])


FAR_TRIANGLE = 16.0  # an emitter triangle farther than this x its longest edge: the point form (off < 0.2%)


@njit(cache=True)
def triangle_cosine(surf, tri, px, py, pz, nx, ny, nz):
    """The integral of cos over the solid angle of scene triangle `tri`
    seen from p (normal n), the triangle clipped to p's upper half-space
    (Sutherland-Hodgman) and integrated by Lambert's formula,
    |sum over its edges of angle x cos| / 2: pi times the form factor,
    exact at any distance."""
    return corners_cosine(surf.corners, tri, px, py, pz, nx, ny, nz)


@njit(cache=True, inline="always")
def corners_cosine(c, tri, px, py, pz, nx, ny, nz):
    """triangle_cosine of triangle `tri` of corners c (n, 3, 3), inlined
    where it runs per texel (the irradiance probes' lamps)."""
    acc = 0.0
    count = 0
    fx = fy = fz = 0.0   # the clipped polygon's first vertex, and the last one emitted
    lx = ly = lz = 0.0
    for k in range(3):
        k2 = (k + 1) % 3
        qx, qy, qz = c[tri, k, 0] - px, c[tri, k, 1] - py, c[tri, k, 2] - pz
        rx, ry, rz = c[tri, k2, 0] - px, c[tri, k2, 1] - py, c[tri, k2, 2] - pz
        acc, count, fx, fy, fz, lx, ly, lz = _clip_edge(qx, qy, qz, rx, ry, rz, nx, ny, nz, acc, count, fx, fy, fz,
                                                        lx, ly, lz)
    if count < 3:
        return 0.0
    acc += _edge_term(lx, ly, lz, fx, fy, fz, nx, ny, nz)
    return 0.5 * abs(acc)


@njit(cache=True, inline="always")
def emitter_cosine(surf, t, px, py, pz, nx, ny, nz):
    """(G, far): emitter triangle t's cosine integral at p (normal n) with
    nothing in the way: clipped to p's upper half-space (triangle_cosine),
    or the point form A cos_l cos_p / r^2 beyond FAR_TRIANGLE x its
    longest edge where it lies wholly above p's horizon (then far is
    True). 0 where p is behind a one-sided emitter (it lights only the
    side its winding's normal faces) or in an emitter's plane, or the
    triangle is below p's horizon."""
    c = surf.corners
    mx, my, mz = surf.tri_normal[t, 0], surf.tri_normal[t, 1], surf.tri_normal[t, 2]
    d = mx * (px - c[t, 0, 0]) + my * (py - c[t, 0, 1]) + mz * (pz - c[t, 0, 2])
    e2 = 0.0
    for k in range(3):
        k2 = (k + 1) % 3
        ex, ey, ez = c[t, k2, 0] - c[t, k, 0], c[t, k2, 1] - c[t, k, 1], c[t, k2, 2] - c[t, k, 2]
        e2 = max(e2, ex * ex + ey * ey + ez * ez)
    tiny = 1e-7 * math.sqrt(e2)
    if surf.double_sided[surf.tri_material[t]]:
        if abs(d) <= tiny:
            return 0.0, False
    elif d <= tiny:
        return 0.0, False
    hmin, hmax = np.inf, -np.inf
    for k in range(3):
        h = nx * (c[t, k, 0] - px) + ny * (c[t, k, 1] - py) + nz * (c[t, k, 2] - pz)
        hmin, hmax = min(hmin, h), max(hmax, h)
    if hmax <= 0.0:
        return 0.0, False
    gx = (c[t, 0, 0] + c[t, 1, 0] + c[t, 2, 0]) / 3.0 - px
    gy = (c[t, 0, 1] + c[t, 1, 1] + c[t, 2, 1]) / 3.0 - py
    gz = (c[t, 0, 2] + c[t, 1, 2] + c[t, 2, 2]) / 3.0 - pz
    r2 = gx * gx + gy * gy + gz * gz
    if hmin > 0.0 and r2 > FAR_TRIANGLE * FAR_TRIANGLE * e2:
        return surf.tri_area[t] * abs(d) * (nx * gx + ny * gy + nz * gz) / (r2 * r2), True
    return triangle_cosine(surf, t, px, py, pz, nx, ny, nz), False


@njit(cache=True)
def emitters_unoccluded(surf, px, py, pz, nx, ny, nz):
    """Irradiance (r, g, b) at p (normal n) from every area emitter with
    nothing in the way: each triangle's mean radiance times its cosine
    integral (emitter_cosine)."""
    a0 = a1 = a2 = 0.0
    for e in range(surf.emitters.shape[0]):
        t = surf.emitters[e]
        w, _ = emitter_cosine(surf, t, px, py, pz, nx, ny, nz)
        a0 += surf.tri_emission[t, 0] * w
        a1 += surf.tri_emission[t, 1] * w
        a2 += surf.tri_emission[t, 2] * w
    return a0, a1, a2


@njit(cache=True, inline="always")
def vpl_gu(bvh, stack, vpls, v, p, n, offset, shadows):
    """The geometric factor (r, g, b) of VPL v at p, times the shadow ray's
    transmittance when `shadows` (0 where blocked, the tint of the thin
    glass it crosses), and the factor without it: irradiance = power(v) x
    g. A VPL with a patch (vpls.patch[v] > 0: a voxel's area) nearer than
    FAR x sqrt(A) takes its patch's exact form factor (patch_g), blended
    into the bounded point form from NEAR to FAR x sqrt(A): at a concave
    edge the point form of the next wall's voxels reads 20-45% low a
    quarter to half a voxel from it, the patches 0.5-1%
    (tests/test_lights.py)."""
    px, py, pz = p
    nx, ny, nz = n
    tr, tg, tb = 1.0, 1.0, 1.0
    if vpls.kind[v] == KIND_DIRECTIONAL:
        dx, dy, dz = vpls.normal[v, 0], vpls.normal[v, 1], vpls.normal[v, 2]
        cp = nx * dx + ny * dy + nz * dz
        if cp <= COS_MIN:
            return 0.0, 0.0, 0.0, 0.0
        if shadows:
            tr, tg, tb = transmittance(bvh, stack, px + offset * nx, py + offset * ny, pz + offset * nz, dx, dy, dz,
                                       0.0, np.inf)
        return cp * tr, cp * tg, cp * tb, cp
    dx, dy, dz = vpls.position[v, 0] - px, vpls.position[v, 1] - py, vpls.position[v, 2] - pz
    r2 = dx * dx + dy * dy + dz * dz
    if r2 <= 0.0:
        return 0.0, 0.0, 0.0, 0.0
    r = math.sqrt(r2)
    dx, dy, dz = dx / r, dy / r, dz / r
    cp = nx * dx + ny * dy + nz * dz
    cl = -(vpls.normal[v, 0] * dx + vpls.normal[v, 1] * dy + vpls.normal[v, 2] * dz)
    if cp <= COS_MIN or cl <= COS_MIN:
        return 0.0, 0.0, 0.0, 0.0
    g = cl * cp / (math.pi * r2 + vpls.area[v])
    if r2 < FAR * FAR * vpls.patch[v]:   # the near field: over the VPL's patch, blended into the point form
        w = min(1.0, (FAR - r / math.sqrt(vpls.patch[v])) / (FAR - NEAR))
        g = w * patch_g(vpls, v, p, n) + (1.0 - w) * g
    if shadows:
        ox, oy, oz = px + offset * nx, py + offset * ny, pz + offset * nz
        ex, ey, ez = vpls.position[v, 0] - ox, vpls.position[v, 1] - oy, vpls.position[v, 2] - oz
        d = math.sqrt(ex * ex + ey * ey + ez * ez)
        tr, tg, tb = transmittance(bvh, stack, ox, oy, oz, ex / d, ey / d, ez / d, 0.0, d * (1.0 - SHADOW_EPS))
    return g * tr, g * tg, g * tb, g


@njit(cache=True, inline="always")
def vpl_g(bvh, stack, vpls, v, p, n, offset, shadows):
    """vpl_gu's factor (r, g, b), with the shadow ray when `shadows`."""
    g0, g1, g2, _ = vpl_gu(bvh, stack, vpls, v, p, n, offset, shadows)
    return g0, g1, g2


@njit(cache=True, inline="always")
def node_bound(tree, node, p, n):
    """Upper bound of the luminance the node's VPLs give p (no visibility).
    tree.patch: the largest patch area (vpl_g's near field) under each
    node; within FAR x sqrt of it of the box a patch may lie nearer to p,
    and higher above p's plane, than its VPL's position: there the bound
    is lum cos_p / (pi (d - R)^2), R the patch's half diagonal, cos_p from
    the box's height above p's plane plus R x the sine of the largest
    angle between p's normal and the node's normals."""
    px, py, pz = p
    nx, ny, nz = n
    lum = tree.lum[node]
    if lum <= 0.0:
        return 0.0
    if tree.kind[node] == KIND_DIRECTIONAL:
        # cos_p over the cone of directions: cos(max(0, angle(n, axis) - half angle))
        d = min(1.0, max(-1.0, nx * tree.axis[node, 0] + ny * tree.axis[node, 1] + nz * tree.axis[node, 2]))
        c = tree.cos[node]
        if c <= -1.0:
            return lum
        a = math.acos(d) - math.acos(min(1.0, max(-1.0, c)))
        return lum if a <= 0.0 else (lum * math.cos(a) if a < 0.5 * math.pi else 0.0)
    # distance from p to the box
    d2 = 0.0
    for c in range(3):
        q = (px, py, pz)[c]
        lo, hi = tree.lo[node, c], tree.hi[node, c]
        e = lo - q if q < lo else (q - hi if q > hi else 0.0)
        d2 += e * e
    if d2 <= 0.0:
        return np.inf
    # cos_p: the largest height of the box above p's plane (per axis, from the face the normal points to) over
    # the distance to the box
    zmax = 0.0
    for c in range(3):
        q = (px, py, pz)[c]
        nc = (nx, ny, nz)[c]
        zmax += nc * ((tree.hi[node, c] if nc > 0.0 else tree.lo[node, c]) - q)
    na = tree.patch[node]
    if na > 0.0 and d2 < FAR * FAR * na:
        rr = math.sqrt(0.5 * na)
        d = math.sqrt(d2) - rr
        if d <= 0.0:
            return np.inf
        sn = 1.0
        cc = tree.cos[node]
        if cc > -1.0:   # sin(angle(n, axis) + half angle) below a right angle, else 1
            ca = min(1.0, max(-1.0, nx * tree.axis[node, 0] + ny * tree.axis[node, 1] + nz * tree.axis[node, 2]))
            cc = min(1.0, cc)
            sa, sc = math.sqrt(1.0 - ca * ca), math.sqrt(1.0 - cc * cc)
            s_sum = sa * cc + ca * sc
            # the sum lies in [0, 2 pi]: below a right angle when its cosine and its sine are both positive (a
            # cone wider than a hemisphere, far from n, has a sum past 3 pi / 2: cosine positive, sine negative)
            if ca * cc - sa * sc > 0.0 and s_sum >= 0.0:
                sn = min(1.0, s_sum)
        z = zmax + rr * sn
        if z <= 0.0:
            return 0.0
        return lum * min(1.0, z / d) / (math.pi * d * d)
    if zmax <= 0.0:
        return 0.0
    cos_p = min(1.0, zmax / math.sqrt(d2)) if zmax * zmax < d2 else 1.0
    # cos_l: the light cone against the directions from the box to p, cos(max(0, w - r - c)): w the angle between
    # the cone's axis and the direction from the box's centre to p, r the half angle the box's bounding sphere
    # subtends, c the cone's half angle; by the angle sum rules (no inverse trigonometry)
    cos_l = 1.0
    cc = tree.cos[node]
    if cc > -1.0:
        mx = 0.5 * (tree.lo[node, 0] + tree.hi[node, 0])
        my = 0.5 * (tree.lo[node, 1] + tree.hi[node, 1])
        mz = 0.5 * (tree.lo[node, 2] + tree.hi[node, 2])
        wx, wy, wz = px - mx, py - my, pz - mz
        dist2 = wx * wx + wy * wy + wz * wz
        hx = 0.5 * (tree.hi[node, 0] - tree.lo[node, 0])
        hy = 0.5 * (tree.hi[node, 1] - tree.lo[node, 1])
        hz = 0.5 * (tree.hi[node, 2] - tree.lo[node, 2])
        rad2 = hx * hx + hy * hy + hz * hz
        if dist2 > rad2:
            dist = math.sqrt(dist2)
            cw = min(1.0, max(-1.0, (wx * tree.axis[node, 0] + wy * tree.axis[node, 1] + wz * tree.axis[node, 2])
                              / dist))
            sw = math.sqrt(max(0.0, 1.0 - cw * cw))
            sr = math.sqrt(rad2 / dist2)
            cr = math.sqrt(max(0.0, 1.0 - sr * sr))
            cc = min(1.0, cc)
            sc = math.sqrt(max(0.0, 1.0 - cc * cc))
            cb = cr * cc - sr * sc          # cos and sin of b = r + c, which lies in [0, 3 pi / 2]
            sb = sr * cc + cr * sc
            if sb >= 0.0 and cw < cb:       # b <= pi and w > b: w - b in (0, pi]
                cos_l = cw * cb + sw * sb   # cos(w - b); <= 0 from a right angle on: the cone faces away
                if cos_l <= 0.0:
                    return 0.0
    return lum * cos_l * cos_p / (math.pi * d2)


@njit(cache=True, inline="always")
def _swap(heap_b, heap_n, heap_g, i, j):
    heap_b[i], heap_b[j] = heap_b[j], heap_b[i]
    heap_n[i], heap_n[j] = heap_n[j], heap_n[i]
    for c in range(4):
        heap_g[i, c], heap_g[j, c] = heap_g[j, c], heap_g[i, c]


@njit(cache=True)
def _push(heap_b, heap_n, heap_g, size, b, node, g):
    i = size
    heap_b[i], heap_n[i] = b, node
    heap_g[i, 0], heap_g[i, 1], heap_g[i, 2], heap_g[i, 3] = g
    while i > 0:
        p = (i - 1) // 2
        if heap_b[p] >= heap_b[i]:
            break
        _swap(heap_b, heap_n, heap_g, p, i)
        i = p
    return size + 1


@njit(cache=True)
def _pop(heap_b, heap_n, heap_g, size):
    node, g = heap_n[0], (heap_g[0, 0], heap_g[0, 1], heap_g[0, 2], heap_g[0, 3])
    size -= 1
    _swap(heap_b, heap_n, heap_g, 0, size)
    i = 0
    while True:
        l, r, m = 2 * i + 1, 2 * i + 2, i
        if l < size and heap_b[l] > heap_b[m]:
            m = l
        if r < size and heap_b[r] > heap_b[m]:
            m = r
        if m == i:
            break
        _swap(heap_b, heap_n, heap_g, m, i)
        i = m
    return node, g, size


def scratch(cap):
    """Per-thread scratch of a lightcut: a heap of at most cap + 2 nodes."""
    return np.empty(cap + 2), np.empty(cap + 2, np.int64), np.empty((cap + 2, 4))


@njit(cache=True)
def lightcut(bvh, stack, tree, vpls, p, n, offset, epsilon, cap, heap, floor=0.0):
    """Irradiance (r, g, b) at p by a lightcut, the same cut's estimate
    without shadow rays (r, g, b), the cut's size and the shadow rays
    cast. p, n: the point and its unit normal (3-tuples); heap: scratch
    (bound, node, g) of cap + 2 entries each (the cut's refinable nodes
    with their bound and representative's g: 3 channels with the shadow
    ray, the tint of glass on it, and one without); floor: the luminance
    of the irradiance p gets from elsewhere (the sky, punctual lights):
    the cut's error is bounded relative to the whole."""
    # borrowed: the records' arrays read in the loop take no reference counts (kernels/inline.py)
    bvh, stack, tree, vpls = borrowed(bvh), borrowed(stack), borrowed(tree), borrowed(vpls)
    heap_b, heap_n, heap_g = borrowed(heap)
    root = 0
    g = vpl_gu(bvh, stack, vpls, tree.rep[root], p, n, offset, True)
    rays = 1
    e0 = tree.power[root, 0] * g[0]
    e1 = tree.power[root, 1] * g[1]
    e2 = tree.power[root, 2] * g[2]
    size = 0
    cut = 1
    f0 = f1 = f2 = 0.0  # the cut's nodes that are final (leaves, nodes that cannot light p), summed once
    u0 = u1 = u2 = 0.0  # the same without shadow rays
    b = 0.0
    if tree.right[root] >= 0:
        b = node_bound(tree, root, p, n)
    if b > 0.0:
        size = _push(heap_b, heap_n, heap_g, size, b, root, g)
    else:
        f0, f1, f2 = e0, e1, e2
        u0, u1, u2 = tree.power[root, 0] * g[3], tree.power[root, 1] * g[3], tree.power[root, 2] * g[3]
    while size > 0:
        est = LUM_R * e0 + LUM_G * e1 + LUM_B * e2
        if heap_b[0] <= epsilon * (est + floor) or cut >= cap:
            break
        node, g, size = _pop(heap_b, heap_n, heap_g, size)
        e0 -= tree.power[node, 0] * g[0]
        e1 -= tree.power[node, 1] * g[1]
        e2 -= tree.power[node, 2] * g[2]
        cut -= 1
        for child in (node + 1, tree.right[node]):
            if tree.rep[child] == tree.rep[node]:
                gc = g
            else:
                gc = vpl_gu(bvh, stack, vpls, tree.rep[child], p, n, offset, True)
                rays += 1
            e0 += tree.power[child, 0] * gc[0]
            e1 += tree.power[child, 1] * gc[1]
            e2 += tree.power[child, 2] * gc[2]
            cut += 1
            bc = 0.0
            if tree.right[child] >= 0:
                bc = node_bound(tree, child, p, n)
            if bc > 0.0:
                size = _push(heap_b, heap_n, heap_g, size, bc, child, gc)
            else:
                f0 += tree.power[child, 0] * gc[0]
                f1 += tree.power[child, 1] * gc[1]
                f2 += tree.power[child, 2] * gc[2]
                u0 += tree.power[child, 0] * gc[3]
                u1 += tree.power[child, 1] * gc[3]
                u2 += tree.power[child, 2] * gc[3]
    # the result summed afresh over the cut (the running estimate above subtracts: rounding would leave 1e-31
    # where every term is 0, and a dark room must stay exactly black)
    for i in range(size):
        f0 += tree.power[heap_n[i], 0] * heap_g[i, 0]
        f1 += tree.power[heap_n[i], 1] * heap_g[i, 1]
        f2 += tree.power[heap_n[i], 2] * heap_g[i, 2]
        u0 += tree.power[heap_n[i], 0] * heap_g[i, 3]
        u1 += tree.power[heap_n[i], 1] * heap_g[i, 3]
        u2 += tree.power[heap_n[i], 2] * heap_g[i, 3]
    return f0, f1, f2, u0, u1, u2, cut, rays


@njit(cache=True)
def brute_force(bvh, stack, vpls, p, n, offset):
    """Irradiance (r, g, b) at p: every VPL, with visibility."""
    bvh, stack, vpls = borrowed(bvh), borrowed(stack), borrowed(vpls)
    h0 = h1 = h2 = 0.0
    for v in range(vpls.kind.shape[0]):
        g = vpl_g(bvh, stack, vpls, v, p, n, offset, True)
        h0 += vpls.power[v, 0] * g[0]
        h1 += vpls.power[v, 1] * g[1]
        h2 += vpls.power[v, 2] * g[2]
    return h0, h1, h2


@njit(cache=True)
def sky_light(bvh, stack, surf, cells, seen, px, py, pz, nx, ny, nz, offset):
    """Irradiance (r, g, b) at p (normal n) from the sky, and the rays
    cast: the sky's directions (SkyCells: a fixed set stratified over its
    domain, the same for every point, so no noise from point to point),
    each weighted by its cosine, with the ratio form
    E = L E0(n) sum(cos T) / sum(cos), E0 the unoccluded integral of the
    cosine over the sky's domain (pi, or pi (1 + n.up) / 2 for a
    hemisphere): exact wherever nothing blocks the sky, at any K.
    Adaptive: one visibility ray per cell first (its representative's);
    a cell whose representative lies above the point's horizon and sees
    what the representatives of its neighbours above it see takes that for
    all its directions above the horizon, every other cell casts a ray
    along each of its directions above it. The open sky and a wall's inside cost a ray per cell, an
    occluder's outline a ray per direction near it; an occluder that slips
    between the representatives of a cell and all its neighbours is missed
    (its share of the cosine is below a cell's, 1/C of the sky's). That
    is small against an open sky but not against a room's light through
    its windows: where fewer than SKY_OPEN of the representatives above
    the horizon see any sky, every direction casts its own ray.
    seen (C, 4): scratch, per cell its representative's transmittance and
    its state (0: wholly below the horizon, 1: its representative above
    it, 2: its representative below, some direction above)."""
    mode = surf.sky_mode
    sky = cells.dirs
    if mode == SKY_NONE or sky.shape[0] == 0:
        return 0.0, 0.0, 0.0, 0
    L = surf.sky_radiance
    if L[0] <= 0.0 and L[1] <= 0.0 and L[2] <= 0.0:
        return 0.0, 0.0, 0.0, 0
    e0 = math.pi
    if mode == SKY_HEMISPHERE:
        up = surf.sky_up
        e0 = 0.5 * math.pi * (1.0 + nx * up[0] + ny * up[1] + nz * up[2])
    if e0 <= 0.0:
        return 0.0, 0.0, 0.0, 0
    ox, oy, oz = px + offset * nx, py + offset * ny, pz + offset * nz
    w = a0 = a1 = a2 = 0.0
    rays = 0
    n_cells = cells.start.shape[0] - 1
    for c in range(n_cells):
        above = 0
        for k in range(cells.start[c], cells.start[c + 1]):
            if nx * sky[k, 0] + ny * sky[k, 1] + nz * sky[k, 2] > COS_MIN:
                above += 1
        r = cells.rep[c]
        seen[c, 3] = 0.0
        if above > 0:
            seen[c, 3] = 1.0 if nx * sky[r, 0] + ny * sky[r, 1] + nz * sky[r, 2] > COS_MIN else 2.0
        if seen[c, 3] == 1.0:
            seen[c, 0], seen[c, 1], seen[c, 2] = transmittance(bvh, stack, ox, oy, oz, sky[r, 0], sky[r, 1],
                                                               sky[r, 2], 0.0, np.inf)
            rays += 1
    up_cells = open_cells = 0
    for c in range(n_cells):
        if seen[c, 3] == 1.0:
            up_cells += 1
            if seen[c, 0] > 0.0 or seen[c, 1] > 0.0 or seen[c, 2] > 0.0:
                open_cells += 1
    trust = open_cells >= SKY_OPEN * up_cells
    for c in range(n_cells):
        if seen[c, 3] == 0.0:
            continue
        same = trust and seen[c, 3] == 1.0
        if same:
            for e in range(cells.nbr.shape[1]):
                o = cells.nbr[c, e]
                if o < 0 or seen[o, 3] != 1.0:
                    continue
                if (abs(seen[o, 0] - seen[c, 0]) > 1e-6 or abs(seen[o, 1] - seen[c, 1]) > 1e-6
                        or abs(seen[o, 2] - seen[c, 2]) > 1e-6):
                    same = False
                    break
        for k in range(cells.start[c], cells.start[c + 1]):
            dx, dy, dz = sky[k, 0], sky[k, 1], sky[k, 2]
            cs = nx * dx + ny * dy + nz * dz
            if cs <= COS_MIN:
                continue
            w += cs
            if same or k == cells.rep[c] and seen[c, 3] == 1.0:
                tr, tg, tb = seen[c, 0], seen[c, 1], seen[c, 2]
            else:
                tr, tg, tb = transmittance(bvh, stack, ox, oy, oz, dx, dy, dz, 0.0, np.inf)
                rays += 1
            a0 += cs * tr
            a1 += cs * tg
            a2 += cs * tb
    if w <= 0.0:
        return 0.0, 0.0, 0.0, rays
    s = e0 / w
    return L[0] * s * a0, L[1] * s * a1, L[2] * s * a2, rays


# Below this share of open cells, a point sees the sky only through
# apertures (a room's windows), which can slip between the cells'
# representatives: the living room's floor lost 7% of its sky light to the
# adaptive shortcut; with every direction traced it matches the path tracer.
SKY_OPEN = 0.25


@njit(cache=True)
def node_patches(rep, right, patch):
    """(m,) the largest patch area under each node of a depth-first tree
    (children after their parent)."""
    out = np.zeros(rep.shape[0])
    for node in range(rep.shape[0] - 1, -1, -1):
        out[node] = patch[rep[node]] if right[node] < 0 else max(out[node + 1], out[right[node]])
    return out
