"""Slow, obviously-correct references for the fast kernels."""
import numpy as np


def dot(a, b):
    """a . b of two 3-vectors summed left to right, as the kernels do: numpy's
    `@` goes through BLAS, whose rounding depends on the CPU it dispatches
    to (an exact tie in a kernel is not one in BLAS on every machine)."""
    return float(a[0]) * float(b[0]) + float(a[1]) * float(b[1]) + float(a[2]) * float(b[2])


def ray_triangles(origin, direction, corners, tmin=0.0, tmax=np.inf):
    """Brute force: one ray against every triangle (nt, 3, 3) with the
    watertight test of Woop et al. 2013 written out in numpy; returns
    (t, triangle) of the closest hit, (inf, -1) on a miss."""
    d = np.asarray(direction, float)
    kz = int(np.argmax(np.abs(d)))
    kx, ky = (kz + 1) % 3, (kz + 2) % 3
    if d[kz] < 0:
        kx, ky = ky, kx
    sx, sy, sz = d[kx] / d[kz], d[ky] / d[kz], 1.0 / d[kz]
    rel = corners - np.asarray(origin, float)
    x = rel[:, :, kx] - sx * rel[:, :, kz]
    y = rel[:, :, ky] - sy * rel[:, :, kz]
    z = sz * rel[:, :, kz]
    (ax, bx, cx), (ay, by, cy) = x.T, y.T
    eu, ev, ew = cx * by - cy * bx, ax * cy - ay * cx, bx * ay - by * ax
    inside = ~(((eu < 0) | (ev < 0) | (ew < 0)) & ((eu > 0) | (ev > 0) | (ew > 0)))
    det = eu + ev + ew
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (eu * z[:, 0] + ev * z[:, 1] + ew * z[:, 2]) / det
    ok = inside & (det != 0) & (t > tmin) & (t < tmax)
    if not ok.any():
        return np.inf, -1
    i = np.nonzero(ok)[0]
    k = i[np.argmin(t[i])]
    return float(t[k]), int(k)


def rectangle_form_factor(a, b, h):
    """Point-to-rectangle form factor: differential area at height h below
    the corner of an a x b rectangle, parallel to it (closed form)."""
    A, B = a / np.hypot(a, h), b / np.hypot(b, h)
    return (A * np.arctan(b / np.hypot(a, h)) + B * np.arctan(a / np.hypot(b, h))) / (2 * np.pi)


def irradiance_under_rectangle(L, x0, x1, z0, z1, h, px=0.0, pz=0.0):
    """Irradiance at (px, 0, pz) from a Lambertian rectangle [x0,x1]x[z0,z1]
    at height h of radiance L (facing down): L * pi * F, F by corner sums."""
    def corner(a, b):
        sa, sb = np.sign(a), np.sign(b)
        return sa * sb * rectangle_form_factor(abs(a), abs(b), h)
    f = corner(x1 - px, z1 - pz) - corner(x0 - px, z1 - pz) - corner(x1 - px, z0 - pz) + corner(x0 - px, z0 - pz)
    return L * np.pi * f


def propagate_lines(cell, origin, centroid, normal, radiosity, vectors, axes, units, weights, offsets, h, tau=0.1,
                    kappa=1.0, trace=None, cut=None, sheet=None, flat=None, edge=None, foot=None):
    """Plain-Python linear propagation with the visibility rule of docs/design.md
    section 4: builds every digital line of every family explicitly (dict of
    line id -> voxels), orders each line's voxels by (X, position along s,
    +1 before -1) and runs the waiting-list rule along s and -s.
    cut (n, 5): the plane and side of a surface that cut a voxel (cells;
    the kernel's CUT_REACH = 3 cells). sheet (n,) bool: a face of a
    two-sided sheet (ties -1 first; never sees its sheet's back). flat (n,)
    bool: a voxel on a flat stretch of surface (a grazing ray's gather on it
    is deferred, over up to 8 cells, to the voxel of its plane the line
    meets nearest where the ray meets it). edge (n, 4): where a voxel's
    surface ends in its cell, the half-plane e . g >= t of its plane (zeros:
    it does not); a ray meeting its plane beyond that, within 2 cells,
    passes it. foot (n,): a small piece's footprint radius in cells (0:
    none); a ray passing further from its centroid passes it, and it
    separates nothing the segment between two voxels crosses its plane
    further from.
    Returns (gathered (n, 3), S (n,));
    with trace=x, also the list of (family, sign, source voxel) voxel x
    gathered from."""
    n = len(cell)
    if sheet is None:
        sheet = np.zeros(n, bool)
    if flat is None:
        flat = np.zeros(n, bool)
    if edge is None:
        edge = np.zeros((n, 4))
    if foot is None:
        foot = np.zeros(n)

    def misses(x, y, u):  # x's ray passes small piece y further from its centroid than its footprint radius
        r = centroid[y] - centroid[x]
        return foot[y] > 0 and np.linalg.norm(r - dot(r, u) * u) > foot[y] * h

    def over(x, y):  # x lies over y's surface (inside its edge's half-plane)
        return edge[y, :3].any() and dot(edge[y, :3], centroid[x]) >= edge[y, 3]

    def off_edge(x, y, d, o, u):  # x's ray meets y's plane beyond the edge of y's surface
        if not edge[y, :3].any():
            return False
        p = centroid[x] + (-d / o) * u
        return np.linalg.norm(p - centroid[y]) <= 2.0 * h and dot(edge[y, :3], p) < edge[y, 3]
    gathered = np.zeros((n, 3))
    quad = np.zeros(n)
    sources = []
    for f in range(len(vectors)):
        k = int(axes[f])
        k1, k2 = (k + 1) % 3, (k + 2) % 3
        A, B, C = int(vectors[f][k]), int(vectors[f][k1]), int(vectors[f][k2])
        mu, mu2 = int(offsets[f][0]), int(offsets[f][1])
        lines = {}
        for v in range(n):
            X, Y, Z = int(cell[v][k]), int(cell[v][k1]), int(cell[v][k2])
            lines.setdefault(((C * X - A * Z - mu) // A, (B * X - A * Y - mu2) // A), []).append(v)
        for sign in (1, -1):
            u = units[f] * sign
            for members in lines.values():
                def order_key(v):
                    o = dot(normal[v], u)
                    # ties: +1 first (a box on a floor), but a sheet's faces -1 first (back to back)
                    return (sign * int(cell[v][k]), dot(centroid[v], u), 1 if (o > 0) == bool(sheet[v]) else 0)
                def cut_between(a, b, a_waits):
                    """0: clear; 1: the cutting surface hides b from a (the waiting
                    voxel's ray heads for it); 2: it stands between, the ray moves away"""
                    sign = cut[a][4]
                    if sign == 0:
                        return 0
                    n_, d_ = cut[a][:3], cut[a][3]
                    sa, sb = dot(centroid[a], n_) - d_, dot(centroid[b], n_) - d_
                    if abs(sb) <= tau * h:  # b on that surface: the side it faces
                        if a_waits and abs(sa) > tau * h and dot(n_, u) * sign >= 0:
                            return 2  # a's ray runs along or away from that surface: it passes b
                        return (1 if a_waits else 2) if dot(normal[b], n_) * sign < -0.5 else 0
                    if sb * sign >= -tau * h or sa == sb:
                        return 0
                    way = 2
                    if dot(n_, u) * (sign if a_waits else -sign) < 0:  # heads for the plane: met before level?
                        sw, ahead = (sa, dot(centroid[b] - centroid[a], u)) if a_waits else \
                            (sb, dot(centroid[a] - centroid[b], u))
                        way = 1 if -sw / dot(n_, u) <= ahead + tau * h else 2
                    if cut[b][4] != 0:
                        cn = dot(n_, cut[b][:3])
                        if abs(cn) > 0.999 and abs(d_ - cn * cut[b][3]) < tau * h:
                            return way
                    p = centroid[a] + (centroid[b] - centroid[a]) * (sa / (sa - sb))
                    return way if bool(np.all(p >= cell[a] - 3.0) and np.all(p <= cell[a] + 4.0)) else 0

                def hidden_by(q, x, y):
                    sx = dot(centroid[x] - centroid[q], normal[q])
                    sy = dot(centroid[y] - centroid[q], normal[q])
                    if not ((sx > tau * h and sy < -tau * h) or (sx < -tau * h and sy > tau * h)):
                        return False
                    p = centroid[x] + (centroid[y] - centroid[x]) * (sx / (sx - sy))
                    if foot[q] > 0 and np.linalg.norm(p - centroid[q]) > foot[q] * h:
                        return 0  # q a small piece the segment passes by
                    lo = origin + cell[y] * h
                    inside = bool(np.all(p >= lo - 0.5 * h) and np.all(p <= lo + h + 0.5 * h))
                    if not (inside and dot(p - centroid[y], normal[y]) * dot(centroid[q] - centroid[y], normal[y]) > 0):
                        return 0
                    nu = dot(normal[q], u)  # x's ray heads for q's plane, meeting it before level with y
                    return 1 if nu * sx < 0 and -sx / nu <= dot(centroid[y] - centroid[x], u) + tau * h else 2
                waiting, last = [], None
                passed = {}  # waiting voxel -> the last voxel parallel to the line it passed, beyond tau of its plane
                met = {}       # voxel -> the voxel its ray met (a deferred gather while it waits)
                deferred = {}  # waiting voxel -> the flat voxel it deferred its gather on

                def below(x, y):  # y beyond tau behind the plane x deferred its gather on
                    p = deferred.get(x)
                    return p is not None and dot(centroid[y] - centroid[p], normal[p]) < -tau * h - 1e-5 * h

                def plane_t(x, p):  # how far along x's ray it meets p's plane
                    op = dot(normal[p], u)
                    return np.inf if op >= 0 else dot(centroid[x] - centroid[p], normal[p]) / -op

                def defer(x, y, d, o):  # what x records on deferring its gather on flat y
                    if x in deferred and plane_t(x, deferred[x]) < d / -o - tau * h:
                        return deferred[x]
                    deferred[x] = y
                    return y

                for y in sorted(members, key=order_key):
                    o = dot(normal[y], u)
                    if o == 0.0:
                        for x in waiting:
                            if abs(dot(centroid[x] - centroid[y], normal[y])) > tau * h and not misses(x, y, u):
                                passed[x] = y
                        continue
                    if o < 0:
                        def sheet_edge(w):  # w and the other face of y's sheet form a convex edge
                            dw = dot(centroid[w] - centroid[y], normal[y])
                            return bool(sheet[y]) and 0 < dw <= kappa * h and dot(centroid[y] - centroid[w], normal[w]) < 0
                        edge_last = last is not None and sheet_edge(last)
                        keep = []
                        for x in waiting:
                            if below(x, y):  # the line passed below the plane x deferred on: x keeps it
                                continue
                            d = dot(centroid[x] - centroid[y], normal[y])
                            ex = dot(centroid[y] - centroid[x], normal[x])
                            backs = sheet[x] and sheet[y] and dot(normal[x], normal[y]) <= -0.5 and \
                                d <= kappa * h and ex <= kappa * h
                            backs = backs or edge_last or sheet_edge(x)
                            if d >= (0.0 if sheet[y] else -tau * h) and not backs:
                                ways = [hidden_by(q, x, y) for q in members
                                        if q not in (x, y) and tuple(cell[q]) == tuple(cell[y])]
                                if cut is not None:
                                    ways += [cut_between(y, x, False), cut_between(x, y, True)]
                                    d_xy = dot(centroid[x] - centroid[y], normal[y])
                                    if d_xy < 0 and cut[x][4] != 0:  # x's cell is cut by y's own plane
                                        cn = dot(cut[x][:3], normal[y])
                                        same = abs(cn) > 0.999 and \
                                            abs(cut[x][3] - cn * dot(centroid[y], normal[y])) < tau * h
                                        ways.append(1 if same else 0)
                                between = 1 in ways
                                if not between and 2 in ways:  # a surface stands between, x's ray moves away
                                    keep.append(x)
                                    continue
                                if x in passed:  # across the plane of a surface the line ran along
                                    w = passed[x]
                                    sx = dot(centroid[x] - centroid[w], normal[w])
                                    sy = dot(centroid[y] - centroid[w], normal[w])
                                    between = between or (sx > tau * h and sy < -tau * h) or \
                                        (sx < -tau * h and sy > tau * h)
                                if d > 0 and misses(x, y, u):
                                    # its ray passes small piece y by: hidden, y does not matter; seen, x gathers y
                                    # unless it meets a front further on
                                    keep.append(x)
                                    if not between and x not in deferred:
                                        met[x] = y
                                    continue
                                if between:
                                    if x in deferred:
                                        met.pop(x, None)
                                    continue
                                if d > 0 and not over(x, y) and off_edge(x, y, d, o, u):
                                    keep.append(x)  # beside y's surface, its ray passes its edge
                                    continue
                                ty = dot(centroid[y] - centroid[x], u)
                                above = d + ty * o
                                val = y
                                if flat[y] and above > tau * h + 1e-5 * h and above > -o * 0.5 * h + 1e-5 * h and \
                                        above < -o * 8.0 * h - 1e-5 * h:
                                    keep.append(x)  # deferred: the ray meets y's plane further on
                                    val = defer(x, y, d, o)
                                elif x in deferred and ty > plane_t(x, deferred[x]) + 1.0 * h:
                                    val = deferred[x]  # the ray met that plane before it reached y
                                met[x] = val
                            else:
                                keep.append(x)
                        waiting = keep
                    else:
                        def convex(z):
                            dz = dot(centroid[z] - centroid[y], normal[y])
                            ez = dot(centroid[y] - centroid[z], normal[z])
                            return dz < 0 and ez < tau * h and dz >= -kappa * h
                        edge_last = last is not None and convex(last)
                        stay = []
                        for x in waiting:
                            if dot(centroid[x] - centroid[y], normal[y]) >= -tau * h or edge_last or convex(x):
                                stay.append(x)
                            elif not flat[y] and dot(centroid[x] - centroid[y], normal[y]) + \
                                    dot(centroid[y] - centroid[x], u) * o > tau * h:
                                stay.append(x)  # level with curved y, its ray is in front of y's plane: past it
                            elif misses(x, y, u) or (not over(x, y) and off_edge(
                                    x, y, dot(centroid[x] - centroid[y], normal[y]), o, u)):
                                stay.append(x)  # it passes small piece y by, or (beside y's surface) crosses y's
                                #                 plane beyond its edge
                            elif cut is not None and (lambda w: 1 not in w and 2 in w)(
                                    [cut_between(y, x, False), cut_between(x, y, True)]):
                                stay.append(x)  # y's back lies beyond a cutting surface x's ray moves away from
                            elif x in deferred and dot(centroid[y] - centroid[deferred[x]],
                                                       normal[deferred[x]]) > tau * h + 1e-5 * h:
                                met.pop(x, None)  # its ray hits y's back before the plane it deferred on
                        waiting = stay
                        quad[y] += o * weights[f]
                        passed.pop(y, None)
                        waiting.append(y)
                        last = y
                for x, y in met.items():
                    gathered[x] += radiosity[y] * dot(normal[x], u) * weights[f]
                    if x == trace:
                        sources.append((f, sign, y))
    if trace is not None:
        return gathered, quad, sources
    return gathered, quad


def vpl_irradiance(point, normal, vpls, corners, offset=1e-4):
    """Brute force over the VPLs, one at a time in Python, visibility by
    ray_triangles: sum of power x V cos_l cos_p / (pi r^2 + A) (area kind)
    or power x V cos_p (directions)."""
    p = np.asarray(point, float)
    n = np.asarray(normal, float)
    o = p + offset * n
    total = np.zeros(3)
    for k in range(len(vpls.kind)):
        if vpls.kind[k] == 1:
            w = vpls.normal[k]
            cp = dot(n, w)
            if cp <= 1e-6 or ray_triangles(o, w, corners)[1] >= 0:
                continue
            total += vpls.power[k] * cp
            continue
        d = vpls.position[k] - p
        r2 = dot(d, d)
        r = np.sqrt(r2)
        w = d / r
        cp, cl = dot(n, w), -dot(vpls.normal[k], w)
        if cp <= 1e-6 or cl <= 1e-6:  # grazing: 0, as lightcuts.COS_MIN
            continue
        e = vpls.position[k] - o
        de = np.sqrt(dot(e, e))
        if ray_triangles(o, e / de, corners, 0.0, de * (1 - 1e-4))[1] >= 0:
            continue
        g = cl * cp / (np.pi * r2 + vpls.area[k])
        a = np.sqrt(vpls.area[k])
        if vpls.indirect[k] and r < 3.0 * a:    # the near field of a voxel's patch: lightcuts.patch_g, blended into the point form from 2 to 3 sqrt(A)
            g = (min(1.0, 3.0 - r / a) * patch_irradiance(p, n, vpls.position[k], vpls.normal[k], vpls.area[k])
                 + max(0.0, r / a - 2.0) * g)
        total += vpls.power[k] * g
    return total


def patch_irradiance(p, n, centre, normal, area):
    """F / A: the form factor from p (normal n) to the square of area A
    centred on `centre` in the plane of `normal` (one pair of its edges
    along the grid axis after the normal's largest component: x -> y,
    y -> z, z -> x), the part above p's plane, by Lambert's formula
    (|sum of edge angle x cos| / 2 pi)."""
    e = np.roll(np.eye(3), -1, axis=0)[int(np.argmax(np.abs(normal)))]
    t = e - dot(e, normal) * normal
    t /= np.sqrt(dot(t, t))
    b = np.cross(normal, t)
    half = 0.5 * np.sqrt(area)
    quad = [centre + half * (su * t + sv * b) - p for su, sv in ((-1, -1), (1, -1), (1, 1), (-1, 1))]
    poly = []
    for q, r in zip(quad, quad[1:] + quad[:1]):       # clip to n . x >= 0
        hq, hr = dot(n, q), dot(n, r)
        if hq >= 0:
            poly.append(q)
        if (hq < 0) != (hr < 0):
            poly.append(q + hq / (hq - hr) * (r - q))
    if len(poly) < 3:
        return 0.0
    total = 0.0
    for a, c in zip(poly, poly[1:] + poly[:1]):
        ua, uc = a / np.sqrt(dot(a, a)), c / np.sqrt(dot(c, c))
        w = np.cross(ua, uc)
        sn = np.sqrt(dot(w, w))
        if sn > 0:
            total += np.arctan2(sn, dot(ua, uc)) * dot(n, w) / sn
    return abs(total) / (2 * np.pi * area)


def line_inputs(voxels):
    """What propagate_lines reads, derived from a Voxels on its own (not from
    the sweeper it checks): centroids in grid coordinates and normals as
    the kernel stores them (float32), the cutting planes in absolute grid
    coordinates with each voxel's side, the two-sided sheets, the flat
    voxels (the voxels stage's flat_voxels) and the edges of surfaces that
    end inside their cell (voxels/edges.py)."""
    from baker.voxels.edges import edge_planes, footprints
    from baker.voxels.lookup import flat_voxels
    from baker.voxels.tolerances import FLAT_COS, FLAT_PLANE, SMOOTH_COS
    v = voxels
    centroid = ((v.centroid - v.origin) / v.cell_size).astype(np.float32).astype(np.float64)
    normal = np.asarray(v.normal, np.float32).astype(np.float64)
    cut = np.zeros((len(v), 5))
    rows = np.nonzero(v.cut_sign != 0)[0]
    plane = v.cut_plane[rows].astype(np.float64)
    cut[rows, :3] = plane[:, :3]
    cut[rows, 3] = plane[:, 3] + (plane[:, :3] * v.cell[rows]).sum(axis=1)
    cut[:, 4] = np.sign(v.cut_sign)
    flat = flat_voxels(v.key, v.cell, v.centroid, v.normal, v.planar, v.dims, v.cell_size, SMOOTH_COS, FLAT_COS,
                       FLAT_PLANE)
    edge = np.zeros((len(v), 4))
    edge_planes(v.cell, centroid.astype(np.float32).astype(np.float64), v.normal.astype(np.float64),
                np.asarray(v.area, np.float64) / v.cell_size ** 2, (v.cut_sign == 0) & np.asarray(v.planar, bool),
                edge)
    foot = footprints(v.cell, centroid, v.normal, np.asarray(v.area, np.float64) / v.cell_size ** 2,
                      ~np.any(edge[:, :3] != 0, axis=1) & np.asarray(v.planar, bool))
    return dict(centroid=centroid, normal=normal, cut=cut, sheet=np.asarray(v.two_sided, bool),
                flat=np.asarray(flat, bool), edge=edge, foot=foot)
