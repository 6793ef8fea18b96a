"""The path tracer's irradiance at a point: the reference the probes are
measured against (tests/test_probes.py, bench/probes.py)."""
from __future__ import annotations

import numpy as np


def path_traced_irradiance(prepared, point, normals, directions=8192, spp=2, seed=5) -> np.ndarray:
    """(n, 3) E at `point` for each unit normal (n, 3): pi times the mean
    path-traced radiance over `directions` cosine-distributed directions
    about it (a fixed spiral: a small lamp needs many distinct
    directions, not many paths per direction), `spp` paths each; plus
    the punctual lights and the sun at the point itself behind a shadow
    ray (deltas no sampled direction meets)."""
    from ..kernels.sampling import spiral_hemisphere
    from .pathtrace import radiance_batch
    local = spiral_hemisphere(directions)
    o, d = [], []
    for n in np.asarray(normals, np.float64):
        a = np.array([1.0, 0, 0]) if abs(n[0]) < 0.9 else np.array([0, 1.0, 0])
        t = np.cross(a, n)
        t /= np.linalg.norm(t)
        b = np.cross(n, t)
        d.append(local[:, :1] * t + local[:, 1:2] * b + local[:, 2:3] * n)
        o.append(np.repeat(np.asarray(point, float)[None], len(local), 0))
    s = prepared.surfaces
    radiance = radiance_batch(prepared.bvh.arrays, s.arrays, 1e-7 * s.scale, np.uint64(seed), spp,
                              np.concatenate(o), np.concatenate(d))
    e = np.pi * radiance.reshape(len(normals), -1, 3).mean(axis=1)
    return e + _punctual(prepared, np.asarray(point, np.float64), np.asarray(normals, np.float64), 1e-7 * s.scale)


def _punctual(prepared, p, normals, eps):
    from ..kernels.traverse import transmittance_batch
    from ..scene.surfaces import punctual_irradiance
    surf = prepared.surfaces.arrays
    out = np.zeros((len(normals), 3))
    for k in range(surf.light_kind.shape[0]):
        for j, n in enumerate(normals):
            r, g, b, dx, dy, dz, dist = punctual_irradiance(surf, k, p[0], p[1], p[2], n[0], n[1], n[2])
            if r + g + b > 0.0:
                t = transmittance_batch(prepared.bvh.arrays, p[None], np.array([[dx, dy, dz]]), eps,
                                        np.array([dist]))[0]
                out[j] += np.array([r, g, b]) * t
    return out
