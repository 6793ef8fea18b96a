"""Direction sets (docs/design.md section 3).

The cube set D_r: all integer vectors s = (a, b, c) with max(|a|,|b|,|c|) = r,
|D_r| = 24 r^2 + 2. Each s owns the unit square around it on the cube face
at distance r (clipped at the face edges; vectors on an edge or corner own
one piece on each face they touch), so the solid angles are exact and sum to
4 pi. A *family* is the pair {s, -s}: one partition of space into parallel
digital lines; it is stored once, as the member whose dominant axis
component is positive (ties: the first axis of the tie, for s and -s alike).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError


def _rect_solid_angle(x1, x2, y1, y2, r):
    """Solid angle of [x1,x2]x[y1,y2] on the plane at distance r from the origin:
    F(x2,y2) - F(x1,y2) - F(x2,y1) + F(x1,y1), F = atan(x y / (r sqrt(r^2+x^2+y^2)))."""
    def f(x, y):
        return np.arctan(x * y / (r * np.sqrt(r * r + x * x + y * y)))
    return f(x2, y2) - f(x1, y2) - f(x2, y1) + f(x1, y1)


def cube_directions(r: int):
    """All s in D_r (n, 3) int32 and their exact solid angles (n,) float64."""
    if r < 1:
        raise ConfigError(f"direction radius must be >= 1 (got {r})")
    owned = {}
    g = np.arange(-r, r + 1)
    u, v = np.meshgrid(g, g, indexing="ij")
    u, v = u.ravel(), v.ravel()
    w = _rect_solid_angle(np.maximum(u - 0.5, -r), np.minimum(u + 0.5, r), np.maximum(v - 0.5, -r),
                          np.minimum(v + 0.5, r), float(r))
    for axis in range(3):
        a1, a2 = (axis + 1) % 3, (axis + 2) % 3
        for sign in (-1, 1):
            vec = np.zeros((len(u), 3), np.int64)
            vec[:, axis] = sign * r
            vec[:, a1] = u
            vec[:, a2] = v
            for s, omega in zip(map(tuple, vec), w):
                owned[s] = owned.get(s, 0.0) + omega
    keys = sorted(owned)
    return np.array(keys, np.int32), np.array([owned[k] for k in keys], np.float64)


def canonical(s) -> tuple:
    """The family representative of s: dominant-axis component positive
    (ties broken by the first axis, identically for s and -s)."""
    s = np.asarray(s)
    k = int(np.argmax(np.abs(s)))
    return tuple(int(v) for v in (s if s[k] > 0 else -s))


@dataclass(frozen=True)
class DirectionSet:
    """Families of D_r: vectors (nf, 3) int32 (the canonical member), their
    dominant axis (nf,) int32, unit vectors (nf, 3) float64 and the solid
    angle each member owns (nf,) float64 (s and -s own equal angles)."""
    radius: int
    vectors: np.ndarray
    axis: np.ndarray
    unit: np.ndarray
    solid_angle: np.ndarray

    @property
    def n_directions(self) -> int:
        return 2 * len(self.vectors)

    @property
    def n_families(self) -> int:
        return len(self.vectors)


def direction_set(r: int) -> DirectionSet:
    vec, omega = cube_directions(r)
    fam, w = [], []
    for v, om in zip(vec.tolist(), omega):
        c = canonical(v)
        if tuple(v) == c:
            fam.append(c)
            w.append(om)  # -s owns the mirror image of s's square: the same solid angle (tests/test_directions.py)
    fam = np.array(fam, np.int32)
    axis = np.argmax(np.abs(fam), axis=1).astype(np.int32)
    unit = fam / np.linalg.norm(fam, axis=1, keepdims=True)
    return DirectionSet(r, fam, axis, unit, np.array(w))


def quadrature_cosine(normal, dirs: DirectionSet) -> np.ndarray:
    """S(n) = (1/pi) sum over s in D with n.s > 0 of (n.s) dW(s): the
    quadrature's own value of the cosine integral (1 in the continuum).
    normal (m, 3) -> (m,). Reference implementation; the propagation
    accumulates the same sum per voxel as it sweeps."""
    n = np.asarray(normal, np.float64).reshape(-1, 3)
    cos = n @ dirs.unit.T
    return (np.clip(cos, 0, None) * dirs.solid_angle + np.clip(-cos, 0, None) * dirs.solid_angle).sum(axis=1) / np.pi
