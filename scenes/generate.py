"""Generates the built-in scenes (docs/design.md section 10) as .glb files.

    python scenes/generate.py [--out scenes/]

Every scene is also available as a function returning a `GltfBuilder`, so
tests can build variants (other albedo, emission, resolution) on the fly.
Units are metres; one-sided surfaces face where the light should arrive.
"""
from __future__ import annotations

import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from baker.scene.gltf_write import GltfBuilder  # noqa: E402

# ---------------------------------------------------------------------------
# Geometry helpers: each returns (positions (n,3), triangles (m,3)).


def quad(p0, p1, p2, p3, facing=None, subdiv=1):
    """Planar quad p0-p1-p2-p3 (in order around it), split into subdiv^2
    cells. `facing` (a vector) flips the winding so the normal points along it."""
    p = np.array([p0, p1, p2, p3], float)
    n = np.cross(p[1] - p[0], p[3] - p[0])
    if facing is not None and np.dot(n, facing) < 0:
        p = p[[0, 3, 2, 1]]
    s = np.linspace(0.0, 1.0, subdiv + 1)
    u, v = np.meshgrid(s, s, indexing="ij")
    u, v = u.ravel()[:, None], v.ravel()[:, None]
    pos = (1 - u) * (1 - v) * p[0] + u * (1 - v) * p[1] + u * v * p[2] + (1 - u) * v * p[3]
    tris = []
    k = subdiv + 1
    for i in range(subdiv):
        for j in range(subdiv):
            a, b, c, d = i * k + j, (i + 1) * k + j, (i + 1) * k + j + 1, i * k + j + 1
            tris += [(a, b, c), (a, c, d)]
    return pos, np.array(tris, np.int64)


def merge(*parts):
    pos, tris, off = [], [], 0
    for p, t in parts:
        pos.append(p)
        tris.append(t + off)
        off += len(p)
    return np.concatenate(pos), np.concatenate(tris)


def box(lo, hi, inward=False, subdiv=1, skip=()):
    """Axis-aligned box; faces named by axis and sign ('-x', '+y', ...) in
    `skip` are left out."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    parts = []
    for axis in range(3):
        for sign in (-1, 1):
            if f"{'-+'[sign > 0]}{'xyz'[axis]}" in skip:
                continue
            a, b = (axis + 1) % 3, (axis + 2) % 3
            corners = []
            for ua, ub in ((0, 0), (1, 0), (1, 1), (0, 1)):
                q = np.empty(3)
                q[axis] = hi[axis] if sign > 0 else lo[axis]
                q[a] = hi[a] if ua else lo[a]
                q[b] = hi[b] if ub else lo[b]
                corners.append(q)
            facing = np.zeros(3)
            facing[axis] = -sign if inward else sign
            parts.append(quad(*corners, facing=facing, subdiv=subdiv))
    return merge(*parts)


def icosphere(subdiv, radius=1.0, center=(0, 0, 0), inward=False):
    t = (1 + 5 ** 0.5) / 2
    v = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t), (0, -1, -t), (0, 1, -t),
         (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    f = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4), (11, 10, 2),
         (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5), (2, 4, 11),
         (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    verts = [np.array(p, float) / np.linalg.norm(p) for p in v]
    faces = f
    for _ in range(subdiv):
        cache, nf = {}, []

        def mid(a, b):
            key = (min(a, b), max(a, b))
            if key not in cache:
                m = verts[a] + verts[b]
                verts.append(m / np.linalg.norm(m))
                cache[key] = len(verts) - 1
            return cache[key]

        for a, b, c in faces:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            nf += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        faces = nf
    pos = np.array(verts) * radius + np.asarray(center, float)
    tris = np.array(faces, np.int64)
    if inward:
        tris = tris[:, ::-1]
    return pos, tris


def cylinder(center, radius, height, segments=32, rings=1, caps=True):
    """Vertical (y) cylinder standing on center, outward normals."""
    cx, cy, cz = center
    ang = np.linspace(0, 2 * np.pi, segments, endpoint=False)
    ys = np.linspace(cy, cy + height, rings + 1)
    pos = np.array([(cx + radius * np.cos(a), y, cz + radius * np.sin(a)) for y in ys for a in ang])
    tris = []
    for r in range(rings):
        for s in range(segments):
            a, b = r * segments + s, r * segments + (s + 1) % segments
            c, d = a + segments, b + segments
            tris += [(a, c, b), (b, c, d)]
    parts = [(pos, np.array(tris, np.int64))]
    if caps:
        for y, up in ((cy, False), (cy + height, True)):
            ring = np.array([(cx + radius * np.cos(a), y, cz + radius * np.sin(a)) for a in ang])
            p = np.vstack([[cx, y, cz], ring])
            t = np.array([(0, 1 + (s + 1) % segments, 1 + s) if up else (0, 1 + s, 1 + (s + 1) % segments)
                          for s in range(segments)], np.int64)
            parts.append((p, t))
    return merge(*parts)


def transform(part, matrix=None, translate=(0, 0, 0)):
    p, t = part
    if matrix is not None:
        p = p @ np.asarray(matrix, float).T
    return p + np.asarray(translate, float), t


# ---------------------------------------------------------------------------
# Cornell box (Cornell Program of Computer Graphics, published data, mm).

WAVELENGTHS = np.arange(400, 701, 4, dtype=float)
# Measured reflectance spectra, 400-700 nm every 4 nm.
WHITE = np.array([
    0.343, 0.445, 0.551, 0.624, 0.665, 0.687, 0.708, 0.723, 0.715, 0.710, 0.745, 0.758, 0.739, 0.767, 0.777,
    0.765, 0.751, 0.745, 0.748, 0.729, 0.745, 0.757, 0.753, 0.750, 0.746, 0.747, 0.735, 0.732, 0.739, 0.734,
    0.725, 0.721, 0.733, 0.725, 0.732, 0.743, 0.744, 0.748, 0.728, 0.716, 0.733, 0.726, 0.713, 0.740, 0.754,
    0.764, 0.752, 0.736, 0.734, 0.741, 0.740, 0.732, 0.745, 0.755, 0.751, 0.744, 0.731, 0.733, 0.744, 0.731,
    0.712, 0.708, 0.729, 0.730, 0.727, 0.707, 0.703, 0.729, 0.750, 0.760, 0.751, 0.739, 0.724, 0.730, 0.740,
    0.737])
GREEN = np.array([
    0.092, 0.096, 0.098, 0.097, 0.098, 0.095, 0.095, 0.097, 0.095, 0.094, 0.097, 0.098, 0.096, 0.101, 0.103,
    0.104, 0.107, 0.109, 0.112, 0.115, 0.125, 0.140, 0.160, 0.187, 0.229, 0.285, 0.343, 0.390, 0.435, 0.464,
    0.472, 0.476, 0.481, 0.462, 0.447, 0.441, 0.426, 0.406, 0.373, 0.347, 0.337, 0.314, 0.285, 0.277, 0.266,
    0.250, 0.230, 0.207, 0.186, 0.171, 0.160, 0.148, 0.141, 0.136, 0.130, 0.126, 0.123, 0.121, 0.122, 0.119,
    0.114, 0.115, 0.117, 0.117, 0.118, 0.120, 0.122, 0.128, 0.132, 0.139, 0.144, 0.146, 0.150, 0.152, 0.157,
    0.159])
RED = np.array([
    0.040, 0.046, 0.048, 0.053, 0.049, 0.050, 0.053, 0.055, 0.057, 0.056, 0.059, 0.057, 0.061, 0.061, 0.060,
    0.062, 0.062, 0.062, 0.061, 0.062, 0.060, 0.059, 0.057, 0.058, 0.058, 0.058, 0.056, 0.055, 0.056, 0.059,
    0.057, 0.055, 0.059, 0.059, 0.058, 0.059, 0.061, 0.061, 0.063, 0.063, 0.067, 0.068, 0.072, 0.080, 0.090,
    0.099, 0.124, 0.154, 0.192, 0.255, 0.287, 0.349, 0.402, 0.443, 0.487, 0.513, 0.558, 0.584, 0.620, 0.606,
    0.609, 0.651, 0.612, 0.610, 0.650, 0.638, 0.627, 0.620, 0.630, 0.628, 0.642, 0.639, 0.657, 0.639, 0.635,
    0.642])
# Measured emission of the light (relative spectral radiance, linear between samples).
LIGHT_NM = np.array([400.0, 500.0, 600.0, 700.0])
LIGHT = np.array([0.0, 8.0, 15.6, 18.4])


def _cmf(lam):
    """CIE 1931 colour matching functions, the analytic multi-lobe fit of
    Wyman, Sloan & Shirley 2013 (JCGT 2(2)); within ~1% of the tables."""
    def gauss(x, mu, s1, s2):
        s = np.where(x < mu, s1, s2)
        return np.exp(-0.5 * ((x - mu) / s) ** 2)
    x = 1.056 * gauss(lam, 599.8, 37.9, 31.0) + 0.362 * gauss(lam, 442.0, 16.0, 26.7) \
        - 0.065 * gauss(lam, 501.1, 20.4, 26.2)
    y = 0.821 * gauss(lam, 568.8, 46.9, 40.5) + 0.286 * gauss(lam, 530.9, 16.3, 31.1)
    z = 1.217 * gauss(lam, 437.0, 11.8, 36.0) + 0.681 * gauss(lam, 459.0, 26.0, 13.8)
    return np.stack([x, y, z], axis=1)


XYZ_TO_LINEAR_SRGB = np.array([[3.2404542, -1.5371385, -0.4985314],
                               [-0.9692660, 1.8760108, 0.0415560],
                               [0.0556434, -0.2040259, 1.0572252]])


def spectrum_to_rgb(values, nm=WAVELENGTHS):
    """Linear sRGB of a spectrum sampled at `nm` (linear in between), over
    400-700 nm, normalised so that a constant spectrum c gives (c, c, c)
    (a per-channel von Kries white point: equal-energy illuminant)."""
    lam = np.linspace(400.0, 700.0, 3001)
    s = np.interp(lam, nm, values)
    cmf = _cmf(lam)
    rgb = XYZ_TO_LINEAR_SRGB @ (cmf * s[:, None]).sum(axis=0)
    white = XYZ_TO_LINEAR_SRGB @ cmf.sum(axis=0)
    return np.clip(rgb / white, 0.0, None)


def cornell_box(light_drop_mm=1.0):
    b = GltfBuilder()
    mm = 1e-3
    white = b.material("white", spectrum_to_rgb(WHITE))
    red = b.material("red", spectrum_to_rgb(RED))
    green = b.material("green", spectrum_to_rgb(GREEN))
    light = b.material("light", (0.78, 0.78, 0.78), emission=spectrum_to_rgb(LIGHT, LIGHT_NM))
    inside = np.array([278.0, 274.4, 279.6])

    def wall(name, pts, mat, center=inside, away=False):
        p = np.array(pts, float)
        c = p.mean(axis=0)
        facing = (c - center) if away else (center - c)
        pos, tri = quad(*p, facing=facing)
        b.mesh(name, pos * mm, tri, mat)

    wall("floor", [(552.8, 0, 0), (0, 0, 0), (0, 0, 559.2), (549.6, 0, 559.2)], white)
    wall("ceiling", [(556.0, 548.8, 0), (556.0, 548.8, 559.2), (0, 548.8, 559.2), (0, 548.8, 0)], white)
    wall("back_wall", [(549.6, 0, 559.2), (0, 0, 559.2), (0, 548.8, 559.2), (556.0, 548.8, 559.2)], white)
    wall("right_wall", [(0, 0, 559.2), (0, 0, 0), (0, 548.8, 0), (0, 548.8, 559.2)], green)
    wall("left_wall", [(552.8, 0, 0), (549.6, 0, 559.2), (556.0, 548.8, 559.2), (556.0, 548.8, 0)], red)
    y = 548.8 - light_drop_mm
    wall("light", [(343.0, y, 227.0), (343.0, y, 332.0), (213.0, y, 332.0), (213.0, y, 227.0)], light,
         center=np.array([278.0, 0.0, 279.5]))
    short = [[(130.0, 165.0, 65.0), (82.0, 165.0, 225.0), (240.0, 165.0, 272.0), (290.0, 165.0, 114.0)],
             [(290.0, 0.0, 114.0), (290.0, 165.0, 114.0), (240.0, 165.0, 272.0), (240.0, 0.0, 272.0)],
             [(130.0, 0.0, 65.0), (130.0, 165.0, 65.0), (290.0, 165.0, 114.0), (290.0, 0.0, 114.0)],
             [(82.0, 0.0, 225.0), (82.0, 165.0, 225.0), (130.0, 165.0, 65.0), (130.0, 0.0, 65.0)],
             [(240.0, 0.0, 272.0), (240.0, 165.0, 272.0), (82.0, 165.0, 225.0), (82.0, 0.0, 225.0)]]
    tall = [[(423.0, 330.0, 247.0), (265.0, 330.0, 296.0), (314.0, 330.0, 456.0), (472.0, 330.0, 406.0)],
            [(423.0, 0.0, 247.0), (423.0, 330.0, 247.0), (472.0, 330.0, 406.0), (472.0, 0.0, 406.0)],
            [(472.0, 0.0, 406.0), (472.0, 330.0, 406.0), (314.0, 330.0, 456.0), (314.0, 0.0, 456.0)],
            [(314.0, 0.0, 456.0), (314.0, 330.0, 456.0), (265.0, 330.0, 296.0), (265.0, 0.0, 296.0)],
            [(265.0, 0.0, 296.0), (265.0, 330.0, 296.0), (423.0, 330.0, 247.0), (423.0, 0.0, 247.0)]]
    for name, faces, h in (("short_block", short, 165.0), ("tall_block", tall, 330.0)):
        center = np.array([q for f in faces for q in f]).mean(axis=0)
        center[1] = h / 2
        parts = []
        for f in faces:
            p = np.array(f)
            parts.append(quad(*p, facing=p.mean(axis=0) - center))
        pos, tri = merge(*parts)
        b.mesh(name, pos * mm, tri, white)
    # Published camera: (278, 273, -800) mm looking +z, 35 mm lens on 25 mm film.
    b.camera("published", np.array([278.0, 273.0, -800.0]) * mm, (0, 0, 1), (0, 1, 0),
             yfov_deg=float(np.degrees(2 * np.arctan(12.5 / 35.0))), aspect=1.0)
    return b


# ---------------------------------------------------------------------------
# Test scenes (docs/design.md section 10).


def furnace_box(albedo=0.5, emission=1.0, subdiv=2, size=1.0):
    """Closed cube, inward-facing, uniform albedo and emitted radiosity
    E = pi * L_e = emission. Exact: B = E / (1 - rho)."""
    b = GltfBuilder()
    m = b.material("furnace", (albedo,) * 3, emission=(emission / np.pi,) * 3)
    pos, tri = box((0, 0, 0), (size,) * 3, inward=True, subdiv=subdiv)
    b.mesh("box", pos, tri, m)
    b.camera("inside", (0.5 * size, 0.5 * size, 0.1 * size), (0, 0, 1), yfov_deg=60)
    return b


def furnace_sphere(albedo=0.5, emission=1.0, subdiv=3, radius=1.0, emission_bottom=None):
    """Closed sphere, inward-facing. With `emission_bottom` the lower
    hemisphere emits that instead (B = E + rho * Ebar / (1 - rho))."""
    b = GltfBuilder()
    pos, tri = icosphere(subdiv, radius, inward=True)
    top = b.material("top", (albedo,) * 3, emission=(emission / np.pi,) * 3)
    if emission_bottom is None:
        b.mesh("sphere", pos, tri, top)
    else:
        bottom = b.material("bottom", (albedo,) * 3, emission=(emission_bottom / np.pi,) * 3)
        lower = pos[tri].mean(axis=1)[:, 1] < 0
        b.mesh("sphere_top", pos, tri[~lower], top)
        b.mesh("sphere_bottom", pos, tri[lower], bottom)
    b.camera("inside", (0, 0, -0.5 * radius), (0, 0, 1), yfov_deg=70)
    return b


def furnace_obstacles(albedo=0.5, emission=1.0, subdiv=2):
    """Furnace box with a floating closed box and one resting on the floor."""
    b = GltfBuilder()
    m = b.material("furnace", (albedo,) * 3, emission=(emission / np.pi,) * 3)
    b.mesh("box", *box((0, 0, 0), (1, 1, 1), inward=True, subdiv=subdiv), m)
    b.mesh("floating", *box((0.2, 0.45, 0.2), (0.45, 0.7, 0.45)), m)
    b.mesh("resting", *box((0.55, 0.0, 0.5), (0.85, 0.3, 0.8), skip=("-y",)), m)
    b.camera("inside", (0.5, 0.5, 0.05), (0, 0, 1), yfov_deg=70)
    return b


def two_rooms(shared_floor=False, wall_x=1.0, albedo=0.7, light_radiance=10.0):
    """Two rooms [0,2]x[0,1]x[0,1] split at x = wall_x by a one-sided wall
    facing the lit room (x < wall_x); the light hangs below the lit room's
    ceiling. `shared_floor` runs one floor under the wall."""
    b = GltfBuilder()
    w = b.material("wall", (albedo,) * 3)
    light = b.material("light", (0.8,) * 3, emission=(light_radiance,) * 3)
    # Room shells (inward), without the faces at the partition.
    b.mesh("lit_room", *box((0, 0, 0), (wall_x, 1, 1), inward=True, skip=("+x", "-y")), w)
    b.mesh("dark_room", *box((wall_x, 0, 0), (2, 1, 1), inward=True, skip=("-x", "-y")), w)
    if shared_floor:
        b.mesh("floor", *quad((0, 0, 0), (2, 0, 0), (2, 0, 1), (0, 0, 1), facing=(0, 1, 0)), w)
    else:
        b.mesh("lit_floor", *quad((0, 0, 0), (wall_x, 0, 0), (wall_x, 0, 1), (0, 0, 1), facing=(0, 1, 0)), w)
        b.mesh("dark_floor", *quad((wall_x, 0, 0), (2, 0, 0), (2, 0, 1), (wall_x, 0, 1), facing=(0, 1, 0)), w)
    b.mesh("partition", *quad((wall_x, 0, 0), (wall_x, 1, 0), (wall_x, 1, 1), (wall_x, 0, 1),
                              facing=(-1, 0, 0)), w)
    cx = wall_x / 2
    b.mesh("light", *quad((cx - 0.15, 0.97, 0.35), (cx + 0.15, 0.97, 0.35), (cx + 0.15, 0.97, 0.65),
                          (cx - 0.15, 0.97, 0.65), facing=(0, -1, 0)), light)
    b.camera("lit", (0.05, 0.5, 0.5), (1, 0, 0), yfov_deg=70)
    b.camera("dark", (1.95, 0.5, 0.5), (-1, 0, 0), yfov_deg=70)
    return b


def thin_wall(albedo=0.7, light_radiance=10.0, thickness=0.004):
    """Two rooms split by a double-sided wall thinner than a cell."""
    b = GltfBuilder()
    w = b.material("wall", (albedo,) * 3)
    ds = b.material("thin", (albedo,) * 3, double_sided=True)
    light = b.material("light", (0.8,) * 3, emission=(light_radiance,) * 3)
    b.mesh("shell", *box((0, 0, 0), (2, 1, 1), inward=True), w)
    x = 1.0 - thickness / 2
    b.mesh("thin_wall", *quad((x, 0, 0), (x, 1, 0), (x, 1, 1), (x, 0, 1)), ds)
    b.mesh("light", *quad((0.35, 0.97, 0.35), (0.65, 0.97, 0.35), (0.65, 0.97, 0.65), (0.35, 0.97, 0.65),
                          facing=(0, -1, 0)), light)
    b.camera("lit", (0.05, 0.5, 0.5), (1, 0, 0), yfov_deg=70)
    return b


def closed_box(albedo=0.7, light_radiance=10.0, double_sided=False):
    """A room lit from below its ceiling; inside it a closed box (outward,
    one-sided, or every surface double-sided) holding an object: the object
    and the box's inside must stay exactly black."""
    b = GltfBuilder()
    w = b.material("wall", (albedo,) * 3, double_sided=double_sided)
    light = b.material("light", (0.8,) * 3, emission=(light_radiance,) * 3)
    b.mesh("room", *box((0, 0, 0), (2, 2, 2), inward=True), w)
    b.mesh("closed_box", *box((0.6, 0.0, 0.6), (1.4, 0.8, 1.4)), w)
    b.mesh("inner_object", *box((0.9, 0.2, 0.9), (1.1, 0.4, 1.1)), w)
    b.mesh("light", *quad((0.8, 1.95, 0.8), (1.2, 1.95, 0.8), (1.2, 1.95, 1.2), (0.8, 1.95, 1.2),
                          facing=(0, -1, 0)), light)
    b.camera("room", (1.0, 1.2, 0.05), (0, -0.3, 1), yfov_deg=70)
    return b


def emission_test(split=1, radiance=5.0, height=1.0, size=0.5):
    """A floor under a square light of side `size` at `height`, or the same
    light split into split x split tiles of the same radiance."""
    b = GltfBuilder()
    floor = b.material("floor", (0.5,) * 3)
    b.mesh("floor", *quad((-2, 0, -2), (2, 0, -2), (2, 0, 2), (-2, 0, 2), facing=(0, 1, 0), subdiv=4), floor)
    edges = np.linspace(-size / 2, size / 2, split + 1)
    mat = b.material("light", (0.0,) * 3, emission=(radiance,) * 3)
    parts = [quad((edges[i], height, edges[j]), (edges[i + 1], height, edges[j]),
                  (edges[i + 1], height, edges[j + 1]), (edges[i], height, edges[j + 1]), facing=(0, -1, 0))
             for i in range(split) for j in range(split)]
    for k, part in enumerate(parts):
        b.mesh(f"light_{k}", *part, mat)
    b.camera("above", (0, 2.5, -2.5), (0, -1, 1), yfov_deg=50)
    return b


def shadow_test(radiance=8.0):
    """Thin beams over a floor under an area light."""
    b = GltfBuilder()
    white = b.material("white", (0.7,) * 3)
    light = b.material("light", (0.8,) * 3, emission=(radiance,) * 3)
    b.mesh("floor", *quad((-1, 0, -1), (1, 0, -1), (1, 0, 1), (-1, 0, 1), facing=(0, 1, 0), subdiv=4), white)
    beams = [box((-0.8, 0.4, z - 0.01), (0.8, 0.42, z + 0.01)) for z in np.linspace(-0.6, 0.6, 7)]
    b.mesh("beams", *merge(*beams), white)
    b.mesh("light", *quad((-0.3, 1.5, -0.3), (0.3, 1.5, -0.3), (0.3, 1.5, 0.3), (-0.3, 1.5, 0.3),
                          facing=(0, -1, 0)), light)
    b.camera("oblique", (0, 1.2, -2.2), (0, -0.55, 1), yfov_deg=50)
    return b


def scan_shell(subdiv=5, radius=0.4, seed=7, lumps=0.18, noise_mm=1.5):
    """A scan-like shell: an icosphere (subdiv 5: 20480 triangles, a few
    per voxel cell at the default preset) bent by a few seeded
    low-frequency lumps and roughened by per-vertex noise, like a
    reconstructed scan (adjacent triangles 1-40 degrees apart). Standing on
    y = 0 with its bottom cut open (a scan's hole where it stood), centred
    at x = z = 0."""
    pos, tri = icosphere(subdiv, 1.0)
    rng = np.random.default_rng(seed)
    r = np.ones(len(pos))
    for _ in range(6):  # lumps: smooth bumps around random directions
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        r += lumps * rng.uniform(0.3, 1.0) * np.exp(-((pos @ d - 1.0) ** 2) / 0.15)
    r = r * radius + rng.normal(scale=noise_mm * 1e-3, size=len(pos))
    pos = pos * r[:, None]
    pos[:, 1] += 0.9 * radius  # sunk a little into the floor ...
    keep = pos[tri].mean(axis=1)[:, 1] > 0.0  # ... and cut open there
    tri = tri[keep]
    used = np.unique(tri)
    remap = np.full(len(pos), -1)
    remap[used] = np.arange(len(used))
    return pos[used], remap[tri]


def scan_room(albedo=0.7, light_radiance=20.0):
    """A scan-like two-sided shell (`scan_shell`) standing in a closed white
    room under a small ceiling light: the case of a scanned model read from
    a PLY file (two-sided, noisy curved surface, resting on the floor)."""
    b = GltfBuilder()
    wall = b.material("wall", (albedo,) * 3)
    obj = b.material("scan", (albedo,) * 3, double_sided=True)
    light = b.material("light", (0.8,) * 3, emission=(light_radiance,) * 3)
    b.mesh("room", *box((-1, 0, -1), (1, 2, 1), inward=True), wall)
    pos, tri = scan_shell()
    b.mesh("scan", pos + [0.0, 0.0, 0.1], tri, obj)
    b.mesh("light", *quad((-0.15, 1.99, -0.15), (0.15, 1.99, -0.15), (0.15, 1.99, 0.15), (-0.15, 1.99, 0.15),
                          facing=(0, -1, 0)), light)
    b.camera("room", (0.0, 1.0, -0.98), (0, -0.35, 1), yfov_deg=60)
    return b


def _case_room(b, light_radiance=15.0, flush=False, look_up=False):
    """The room of the reproduction cases: closed, 2 x 2 x 2 m, white, a
    0.4 m square ceiling lamp (1 cm under the ceiling, or flush with it),
    a camera at the front wall looking in and down (or up at the lamp)."""
    w = b.material("wall", (0.7,) * 3)
    lamp = b.material("lamp", (0.8,) * 3, emission=(light_radiance,) * 3)
    b.mesh("room", *box((-1, 0, -1), (1, 2, 1), inward=True), w)
    y = 2.0 if flush else 1.99
    b.mesh("lamp", *quad((-0.2, y, -0.2), (0.2, y, -0.2), (0.2, y, 0.2), (-0.2, y, 0.2), facing=(0, -1, 0)), lamp)
    if look_up:
        b.camera("lamp", (0.0, 0.8, -0.98), (0, 1.2, 1.08), yfov_deg=65)
    else:
        b.camera("room", (0.0, 1.2, -0.98), (0, -0.45, 1), yfov_deg=65)
    return w


def reproduction_case(name):
    """The small scenes that reproduce each way real meshes went wrong
    (docs/design.md section 2, "Which geometry is handled how"), each in
    the same closed room under a ceiling lamp:
    'hole_shell'  a two-sided icosphere shell with a hole cut in its side;
    'noisy_shell' a scan-like noisy two-sided shell (scan_shell, smaller);
    'duplicates'  a box whose every face is repeated (same corners), and a
                  slab overlapping the floor in its plane;
    'lamp_edges'  the lamp 1 cm under the ceiling, seen from below;
    'flush_lamp'  the lamp in the ceiling's plane (coplanar, overlapping),
                  seen from below;
    'box_floor'   a box resting on the floor;
    'sphere_floor' a one-sided sphere touching the floor at one point."""
    b = GltfBuilder()
    w = _case_room(b, flush=name == "flush_lamp", look_up=name in ("flush_lamp", "lamp_edges"))
    if name == "hole_shell":
        pos, tri = icosphere(3, 0.35, center=(0, 0.6, 0.2))
        c = pos[tri].mean(axis=1)
        tri = tri[~((c[:, 2] < 0.2 - 0.2) & (np.abs(c[:, 0]) < 0.15) & (np.abs(c[:, 1] - 0.6) < 0.15))]
        b.mesh("shell", pos, tri, b.material("shell", (0.7,) * 3, double_sided=True))
    elif name == "noisy_shell":
        pos, tri = scan_shell(subdiv=4, radius=0.3)
        b.mesh("shell", pos + [0.0, 0.0, 0.2], tri, b.material("shell", (0.7,) * 3, double_sided=True))
    elif name == "duplicates":
        pos, tri = box((-0.3, 0.0, 0.0), (0.2, 0.5, 0.5))
        b.mesh("box", pos, np.concatenate([tri, tri]), w)
        b.mesh("slab", *quad((-0.9, 0, 0.4), (-0.4, 0, 0.4), (-0.4, 0, 0.9), (-0.9, 0, 0.9), facing=(0, 1, 0)), w)
    elif name == "box_floor":
        b.mesh("box", *box((-0.3, 0.0, 0.0), (0.2, 0.5, 0.5)), w)
    elif name == "sphere_floor":
        b.mesh("sphere", *icosphere(4, 0.3, center=(0, 0.3, 0.2)), w)
    elif name not in ("flush_lamp", "lamp_edges"):
        raise ValueError(f"unknown case {name!r}")
    return b


REPRODUCTION_CASES = ("hole_shell", "noisy_shell", "duplicates", "lamp_edges", "flush_lamp", "box_floor",
                      "sphere_floor")


def walkthrough(columns_segments=96, column_rings=64):
    """Procedural building: a row of rooms joined by doors, windows in the
    outer walls (sun outside), columns in the hall, a stair to a mezzanine,
    ceiling lights in every room; >= 100k triangles; named cameras along a
    path through it."""
    b = GltfBuilder()
    plaster = b.material("plaster", (0.75, 0.73, 0.70))
    floor_m = b.material("floor", (0.45, 0.35, 0.25))
    stone = b.material("stone", (0.6, 0.6, 0.58))
    lamp = b.material("lamp", (0.8, 0.8, 0.8), emission=(12.0, 11.0, 9.0))
    H, D = 3.0, 6.0  # storey height, room depth (z)
    rooms = [(0.0, 6.0), (6.0, 14.0), (14.0, 20.0)]  # x extents; the middle one is the hall
    t = 0.2  # wall thickness
    walls = []
    # Floor and ceiling slabs (subdivided so the mesh is fine enough to look real).
    x0, x1 = rooms[0][0], rooms[-1][1]
    b.mesh("floor", *quad((x0, 0, 0), (x1, 0, 0), (x1, 0, D), (x0, 0, D), facing=(0, 1, 0), subdiv=80), floor_m)
    b.mesh("ceiling", *quad((x0, H, 0), (x1, H, 0), (x1, H, D), (x0, H, D), facing=(0, -1, 0), subdiv=80),
           plaster)
    # Outer walls: back (z = D) solid; front (z = 0) with a window per room.
    walls.append(quad((x0, 0, D), (x1, 0, D), (x1, H, D), (x0, H, D), facing=(0, 0, -1), subdiv=20))
    walls.append(quad((x0, 0, 0), (x0, 0, D), (x0, H, D), (x0, H, 0), facing=(1, 0, 0), subdiv=10))
    walls.append(quad((x1, 0, 0), (x1, 0, D), (x1, H, D), (x1, H, 0), facing=(-1, 0, 0), subdiv=10))
    for (a, c) in rooms:
        wx0, wx1 = a + 1.5, c - 1.5
        wy0, wy1 = 1.0, 2.2
        for lo, hi in (((a, 0), (c, wy0)), ((a, wy1), (c, H)), ((a, wy0), (wx0, wy1)), ((wx1, wy0), (c, wy1))):
            walls.append(quad((lo[0], lo[1], 0), (hi[0], lo[1], 0), (hi[0], hi[1], 0), (lo[0], hi[1], 0),
                              facing=(0, 0, 1), subdiv=4))
        # Window reveal (the thickness of the wall around the opening).
        walls.append(box((wx0, wy0, -t), (wx1, wy1, 0.0), inward=True, skip=("-z", "+z")))
    # Partition walls (thick, closed) with door openings 1.0 m wide, 2.1 m high.
    for xw in (rooms[0][1], rooms[1][1]):
        dz0, dz1 = 2.5, 3.5
        for z0, z1 in ((0.0, dz0), (dz1, D)):
            walls.append(box((xw - t / 2, 0, z0), (xw + t / 2, H, z1), skip=("-y", "+y")))
        walls.append(box((xw - t / 2, 2.1, dz0), (xw + t / 2, H, dz1), skip=("+y",)))
    b.mesh("walls", *merge(*walls), plaster)
    # Columns in the hall.
    cols = [cylinder((x, 0, z), 0.18, H, segments=columns_segments, rings=column_rings)
            for x in (8.0, 10.0, 12.0) for z in (1.5, 4.5)]
    b.mesh("columns", *merge(*cols), stone)
    # Stair along the back wall of the hall up to a mezzanine.
    steps = []
    n_steps, rise, run = 12, 1.5 / 12, 0.3
    for i in range(n_steps):
        xs = 6.6 + i * run
        steps.append(box((xs, 0, D - 1.2), (xs + run, (i + 1) * rise, D), skip=("-y", "+z")))
    steps.append(box((6.6 + n_steps * run, 1.4, D - 1.2), (13.8, 1.5, D), skip=("+z",)))
    b.mesh("stair", *merge(*steps), stone)
    # Lights: one panel under the ceiling per room, two in the hall.
    lamps = []
    for (a, c) in rooms:
        centers = [(a + c) / 2] if c - a < 7 else [a + (c - a) / 3, a + 2 * (c - a) / 3]
        for cx in centers:
            lamps.append(quad((cx - 0.4, H - 0.02, 2.6), (cx + 0.4, H - 0.02, 2.6), (cx + 0.4, H - 0.02, 3.4),
                              (cx - 0.4, H - 0.02, 3.4), facing=(0, -1, 0)))
    b.mesh("lamps", *merge(*lamps), lamp)
    b.light("sun", "directional", color=(1.0, 0.95, 0.85), intensity=3.0, direction=(0.3, -0.6, 0.75))
    path = [((1.0, 1.6, 1.0), (1, -0.1, 1)), ((4.5, 1.6, 3.0), (1, 0, 0)), ((7.0, 1.6, 3.0), (1, 0.1, 0.3)),
            ((11.0, 1.6, 2.0), (1, 0, 0.5)), ((13.0, 1.6, 3.0), (1, 0, 0)), ((18.5, 1.6, 5.0), (-1, -0.1, -1))]
    for i, (p, f) in enumerate(path):
        b.camera(f"path_{i:02d}", p, f, yfov_deg=65, aspect=16 / 9)
    return b


SCENES = {
    "cornell_box": cornell_box,
    "furnace_box": furnace_box,
    "furnace_sphere": furnace_sphere,
    "furnace_obstacles": furnace_obstacles,
    "two_rooms": two_rooms,
    "two_rooms_shared_floor": lambda: two_rooms(shared_floor=True),
    "thin_wall": thin_wall,
    "closed_box": closed_box,
    "emission_one": lambda: emission_test(1),
    "emission_split": lambda: emission_test(10),
    "shadow_test": shadow_test,
    "walkthrough": walkthrough,
    "scan_room": scan_room,
}


def main(argv=None):
    ap = argparse.ArgumentParser(description="Write the built-in scenes as .glb files.")
    ap.add_argument("--out", default=os.path.dirname(os.path.abspath(__file__)), help="output folder")
    ap.add_argument("names", nargs="*", help=f"scenes to write (default: all of {', '.join(SCENES)})")
    args = ap.parse_args(argv)
    for name in args.names or SCENES:
        path = os.path.join(args.out, name + ".glb")
        SCENES[name]().save(path)
        print(f"wrote {path}")


if __name__ == "__main__":
    main()
