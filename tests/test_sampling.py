"""Chi-square tests of the samplers, in the style of Mitsuba's
ChiSquareTest: draw many samples, histogram them over a parametrization of
their domain, integrate the density the sampler claims over each bin, pool
bins expected to hold fewer than 5 samples, and reject when the p-value
of Pearson's statistic falls below a significance level corrected for
the number of tests (Sidak). The samplers: the cosine hemisphere, points
on a triangle, points on the area emitters (chosen by power), and the
photons of a sun (across its disc, cells drawn by the guide table) and of
a sky (directions over its hemisphere, points on a disc across each)."""

import numpy as np
import pytest
from numba import njit
from scipy.stats import chi2

from baker.kernels.sampling import cosine_hemisphere, frame, triangle_point
from baker.scene import Sky, load_scene, pack
from baker.scene.gltf_write import GltfBuilder
from baker.scene.surfaces import LIGHT_DIRECTIONAL, LIGHT_SKY, emitter_point, sample_emitter
from baker.solve.photons import _emit
from scenes.generate import quad

N = 200_000
TESTS = 9                                   # the chi-square tests in this file
ALPHA = 1 - (1 - 0.01) ** (1 / TESTS)       # 1% for the file as a whole


def chi_square_p(observed, expected) -> float:
    """Pearson's p-value of observed counts against expected counts (the
    same total), bins expected below 5 pooled into one; 0 when a bin the
    density says is empty holds a sample."""
    observed = np.asarray(observed, np.float64).ravel()
    expected = np.asarray(expected, np.float64).ravel()
    assert abs(observed.sum() - expected.sum()) < 1e-6 * expected.sum()
    if (observed[expected <= 0] > 0).any():
        return 0.0
    small = (expected < 5) & (expected > 0)
    big = expected >= 5
    obs = np.append(observed[big], observed[small].sum()) if small.any() else observed[big]
    exp = np.append(expected[big], expected[small].sum()) if small.any() else expected[big]
    stat = float(((obs - exp) ** 2 / exp).sum())
    return float(chi2.sf(stat, len(exp) - 1))


def _hemisphere_coords(d, n):
    """(cos theta, phi / 2 pi) of unit directions d about normal n, in
    frame(n)'s tangents."""
    t, b = (np.array(v) for v in frame(*n))
    z = d @ n
    phi = np.arctan2(d @ b, d @ t) / (2 * np.pi) % 1.0
    return z, phi


def _cosine_expected(bins_z, bins_phi, total):
    """Counts a cosine-weighted hemisphere puts in (cos theta, phi) bins:
    the density in (z, phi) is z / pi per unit z per radian."""
    z = np.linspace(0, 1, bins_z + 1)
    share_z = z[1:] ** 2 - z[:-1] ** 2                # integral of 2 z dz
    return total * np.outer(share_z, np.full(bins_phi, 1.0 / bins_phi))


@njit(cache=True)
def _draw_cosine(u, n):
    out = np.empty((len(u), 3))
    for i in range(len(u)):
        dx, dy, dz, _ = cosine_hemisphere(u[i, 0], u[i, 1], n[0], n[1], n[2])
        out[i, 0], out[i, 1], out[i, 2] = dx, dy, dz
    return out


@njit(cache=True)
def _draw_triangle(u):
    out = np.empty((len(u), 2))
    for i in range(len(u)):
        out[i, 0], out[i, 1] = triangle_point(u[i, 0], u[i, 1])
    return out


@pytest.mark.parametrize("normal", [(0.0, 0.0, 1.0), (0.3, -0.5, 0.8), (0.0, -1.0, 0.0)])
def test_cosine_hemisphere_has_the_cosine_density(normal):
    n = np.array(normal) / np.linalg.norm(normal)
    d = _draw_cosine(np.random.default_rng(1).random((N, 2)), n)
    assert np.allclose(np.linalg.norm(d, axis=1), 1.0)
    z, phi = _hemisphere_coords(d, n)
    obs, _, _ = np.histogram2d(z, phi, bins=(16, 16), range=((0, 1), (0, 1)))
    assert chi_square_p(obs, _cosine_expected(16, 16, N)) > ALPHA


def test_the_chi_square_test_rejects_a_wrong_density():
    """The same test on directions uniform over the hemisphere: it must
    fail, or it would pass anything."""
    u = np.random.default_rng(2).random((N, 2))
    z, phi = u[:, 0], u[:, 1]       # uniform over the hemisphere: z uniform
    obs, _, _ = np.histogram2d(z, phi, bins=(16, 16), range=((0, 1), (0, 1)))
    assert chi_square_p(obs, _cosine_expected(16, 16, N)) < 1e-12


def _triangle_share(x0, x1, y0, y1, pieces=2000):
    """Area of the box [x0, x1] x [y0, y1] below x + y = 1, over the
    triangle's 1/2 (midpoint rule on a piecewise-linear integrand)."""
    x = x0 + (np.arange(pieces) + 0.5) * (x1 - x0) / pieces
    h = np.clip(1.0 - x - y0, 0.0, y1 - y0)
    return h.sum() * (x1 - x0) / pieces / 0.5


def test_triangle_points_are_uniform():
    b = _draw_triangle(np.random.default_rng(3).random((N, 2)))
    assert (b >= 0).all() and (b.sum(axis=1) <= 1 + 1e-12).all()
    k = 16
    obs, _, _ = np.histogram2d(b[:, 0], b[:, 1], bins=(k, k), range=((0, 1), (0, 1)))
    edges = np.linspace(0, 1, k + 1)
    exp = np.array([[N * _triangle_share(edges[i], edges[i + 1], edges[j], edges[j + 1]) for j in range(k)]
                    for i in range(k)])
    assert chi_square_p(obs, exp) > ALPHA


@pytest.fixture(scope="module")
def lit(tmp_path_factory):
    """Two lamps facing down on the plane y = 1, of radiance 1 (x in 0..1)
    and 3 (x in 2..4), over a floor, with a sun and a sky."""
    b = GltfBuilder()
    floor = b.material("floor", (0.5,) * 3)
    dim = b.material("dim", (0.5,) * 3, emission=(1.0, 1.0, 1.0))
    bright = b.material("bright", (0.5,) * 3, emission=(3.0, 3.0, 3.0))
    b.mesh("floor", *quad((-1, 0, -1), (5, 0, -1), (5, 0, 2), (-1, 0, 2), facing=(0, 1, 0)), floor)
    b.mesh("dim", *quad((0, 1, 0), (1, 1, 0), (1, 1, 1), (0, 1, 1), facing=(0, -1, 0), subdiv=2), dim)
    b.mesh("bright", *quad((2, 1, 0), (4, 1, 0), (4, 1, 1), (2, 1, 1), facing=(0, -1, 0), subdiv=3), bright)
    b.light("sun", "directional", intensity=2.0, direction=(0.3, -1.0, 0.2))
    path = tmp_path_factory.mktemp("sampling") / "lit.glb"
    b.save(path)
    scene = load_scene(str(path), sky=Sky(np.array([1.0, 1.0, 1.0]), True))
    return scene, pack(scene)


def _lamp_expected(k):
    """Counts of points on the two lamps in k x k bins over each (power:
    1 x 1 m^2 against 3 x 2 m^2, so 1 : 6), uniform within a lamp."""
    p_dim, p_bright = 1 / 7, 6 / 7
    return np.concatenate([np.full(k * k, N * p_dim / k ** 2), np.full(k * k, N * p_bright / k ** 2)])


def _lamp_counts(pts, k):
    x, z = pts[:, 0], pts[:, 2]
    dim = x < 1.5
    a, _, _ = np.histogram2d(x[dim], z[dim], bins=(k, k), range=((0, 1), (0, 1)))
    b, _, _ = np.histogram2d(x[~dim], z[~dim], bins=(k, k), range=((2, 4), (0, 1)))
    return np.concatenate([a.ravel(), b.ravel()])


@njit(cache=True)
def _draw_emitter(surf, u, stratified):
    out = np.empty((len(u), 3))
    for i in range(len(u)):
        if stratified:
            _, px, py, pz, _, _, _ = emitter_point(surf, u[i, 0], u[i, 1])
        else:
            _, px, py, pz, _, _, _ = sample_emitter(surf, u[i, 0], u[i, 1], u[i, 2])
        out[i, 0], out[i, 1], out[i, 2] = px, py, pz
    return out


@pytest.mark.parametrize("stratified", [False, True])
def test_emitter_points_follow_power_and_are_uniform_on_each_lamp(lit, stratified):
    _, surfaces = lit
    pts = _draw_emitter(surfaces.arrays, np.random.default_rng(4).random((N, 3)), stratified)
    assert np.allclose(pts[:, 1], 1.0)
    k = 8
    assert chi_square_p(_lamp_counts(pts, k), _lamp_expected(k)) > ALPHA


@njit(cache=True)
def _draw_photons(surf, kind, j, power, center, radius, guide, G, n, rot):
    out = np.empty((n, 6))
    for i in range(n):
        ox, oy, oz, dx, dy, dz, _, _, _, _ = _emit(surf, i, rot, kind, j, power, 1e-6, center, radius, guide, G)
        out[i, 0], out[i, 1], out[i, 2], out[i, 3], out[i, 4], out[i, 5] = ox, oy, oz, dx, dy, dz
    return out


def test_sun_photons_follow_the_guide_table_across_the_disc(lit):
    """A sun's photons leave the square across it in cells drawn by the
    guide table's weights, uniform within a cell."""
    scene, surfaces = lit
    G, radius, center = 4, 3.0, np.array([1.5, 0.5, 0.5])
    weights = np.random.default_rng(5).random(G * G) + 0.05
    guide = np.cumsum(weights)
    rot = np.random.default_rng(6).random(16)
    j = 0
    d = surfaces.arrays.light_dir[j]
    ph = _draw_photons(surfaces.arrays, LIGHT_DIRECTIONAL, j, np.ones(3), center, radius, guide, G, N, rot)
    assert np.allclose(ph[:, 3:], d)
    t, b = (np.array(v) for v in frame(*d))
    rel = ph[:, :3] - (center - 2 * radius * d)
    a1, a2 = rel @ t, rel @ b
    k = 2 * G      # two bins per cell along each side
    obs, _, _ = np.histogram2d(a1, a2, bins=(k, k), range=((-radius, radius), (-radius, radius)))
    cell = (np.arange(k)[:, None] // 2) + G * (np.arange(k)[None, :] // 2)   # cell c = x + G y
    exp = N * weights[cell] / weights.sum() / 4
    assert chi_square_p(obs, exp) > ALPHA


def test_sky_photons_cover_the_hemisphere_and_the_disc_uniformly(lit):
    """A hemisphere sky's photons come from directions uniform over the
    upper hemisphere, each from a point uniform on the disc of radius R
    across its direction."""
    scene, surfaces = lit
    radius, center = 3.0, np.array([1.5, 0.5, 0.5])
    rot = np.random.default_rng(7).random(16)
    ph = _draw_photons(surfaces.arrays, LIGHT_SKY, 0, np.ones(3), center, radius, np.ones(1), 1, N, rot)
    w = -ph[:, 3:]
    up = np.asarray(surfaces.arrays.sky_up)
    ct, phi = _hemisphere_coords(w, up)
    assert (ct >= -1e-12).all()
    obs_dir, _, _ = np.histogram2d(ct, phi, bins=(12, 12), range=((0, 1), (0, 1)))
    rel = ph[:, :3] - center - 2 * radius * w
    radial = np.einsum("ij,ij->i", rel, rel) / radius ** 2       # uniform on a disc: r^2 / R^2 uniform
    across = np.abs(np.einsum("ij,ij->i", rel, w))
    assert across.max() < 1e-9 * radius + 1e-12
    obs_r, _ = np.histogram(radial, bins=12, range=(0, 1))
    assert chi_square_p(obs_dir, np.full((12, 12), N / 144)) > ALPHA
    assert chi_square_p(obs_r, np.full(12, N / 12)) > ALPHA
