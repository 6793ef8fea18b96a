import numpy as np
import pytest

from baker.config import SolverConfig
from baker.solve.directions import canonical, cube_directions, direction_set, quadrature_cosine


@pytest.mark.parametrize("r", [1, 2, 3, 4, 8, 16])
def test_cube_set_size_and_exact_solid_angles(r):
    vec, omega = cube_directions(r)
    assert len(vec) == 24 * r * r + 2
    assert np.abs(vec).max(axis=1).min() == r and np.abs(vec).max() == r
    assert omega.sum() == pytest.approx(4 * np.pi, abs=1e-12)  # exact, to rounding
    assert (omega > 0).all()
    assert len({tuple(v) for v in vec.tolist()}) == len(vec)


def test_solid_angle_matches_monte_carlo_cell_areas():
    """Each direction owns the cube-face square around it: a direction's
    solid angle equals the fraction of uniform random directions whose
    nearest cube-face lattice point is it (statistical, 5 sigma)."""
    r = 2
    vec, omega = cube_directions(r)
    rng = np.random.default_rng(0)
    d = rng.normal(size=(400_000, 3))
    p = d / np.abs(d).max(axis=1, keepdims=True) * r  # project on the cube of half-size r
    nearest = np.clip(np.round(p), -r, r).astype(int)
    index = {tuple(v): i for i, v in enumerate(vec.tolist())}
    counts = np.bincount([index[tuple(v)] for v in nearest.tolist()], minlength=len(vec))
    frac = counts / len(d)
    expected = omega / (4 * np.pi)
    sigma = np.sqrt(expected * (1 - expected) / len(d))
    assert np.all(np.abs(frac - expected) < 5 * sigma + 1e-12)


def test_families_pair_opposites_with_equal_weight():
    d = direction_set(4)
    assert d.n_directions == 386 and d.n_families == 193
    for v, axis in zip(d.vectors, d.axis):
        assert v[axis] > 0 and abs(v[axis]) == np.abs(v).max()
        assert canonical(-v) == tuple(v) == canonical(v)
    assert 2 * d.solid_angle.sum() == pytest.approx(4 * np.pi, abs=1e-12)


@pytest.mark.parametrize("r", [2, 4, 8])
def test_quadrature_cosine_integral_near_one(r):
    rng = np.random.default_rng(r)
    n = rng.normal(size=(200, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    s = quadrature_cosine(n, direction_set(r))
    # the cube quadrature of the cosine lobe: error falls like 1/r^2
    # the cube quadrature of the cosine lobe: max error measured 0.12 / r^2 over
    # 20000 normals (r = 2..16); 0.15 / r^2 leaves room, and fails if it stops falling
    assert np.abs(s - 1).max() < 0.15 / r ** 2
    axis = quadrature_cosine(np.eye(3), direction_set(r))
    np.testing.assert_allclose(axis, axis[0], rtol=1e-12)  # symmetric for the three axes


def test_schedules():
    halving = SolverConfig(radius=8, r_min=2, max_bounces=8).radii()
    assert halving[0] == 8 and halving[-1] == 2
    sizes = [24 * r * r + 2 for r in halving]
    for a, b in zip(sizes, sizes[1:]):
        assert b <= a and (b >= a / 3 or b == 24 * 4 + 2)  # about half each bounce, floor r_min
    assert SolverConfig(radius=5, schedule="constant", max_bounces=6).radii() == [5] * 5
    with pytest.raises(ValueError):
        SolverConfig(schedule="sometimes")
