"""Shading points: the exact parts (the scene's punctual lights, the sky
along its directions), then the area emitters lamp by lamp (lamps.py) or a
lightcut over the VPLs (lightcuts.py)."""
from __future__ import annotations

import numpy as np
from numba import njit, prange

from ..kernels.bvh import STACK_SIZE
from ..kernels.colour import LUM_B, LUM_G, LUM_R
from ..kernels.traverse import transmittance
from ..scene.surfaces import punctual_irradiance
from .lamps import BUDGET, FIRST, LAMP_LIFT, lamps_light
from .lightcuts import SHADOW_EPS, brute_force, lightcut, sky_light


CHUNK = 64  # shading points per parallel work item


@njit(cache=True, parallel=True)
def shade_points(bvh, surf, tree, vpls, cells, points, normals, valid, floors, offset, epsilon, cap, brute,
                 lamps, first=FIRST, budget=BUDGET):
    """Irradiance H (N, 3) float64 at points (N, 3) with normals (N, 3)
    (where valid): lightcuts over the tree (TreeArrays) of the VPLs
    (VPLArrays; brute: every VPL) plus the scene's punctual lights, exact,
    and the sky along its directions (SkyCells, sky_light; none: the
    sky, if any, is among the VPLs); cut size (N,) and shadow rays (N,).
    lamps (LampArrays, lamps.lamp_groups; with no lamp, the VPLs' cut):
    the area emitters' light lamp by lamp instead of the VPLs, each
    lamp's exact unoccluded irradiance times its visibility by shadow
    rays over its solid angle (lamps.lamps_light; first and budget its
    rays), leaving LAMP_LIFT x offset off the surface; exact wherever
    nothing blocks a lamp (a concave edge beside it, where the VPLs'
    point form reads up to 45% low); the cut size is then the rays the
    lamps took."""
    n = points.shape[0]
    out = np.zeros((n, 3))
    cuts = np.zeros(n, np.int64)
    rays = np.zeros(n, np.int64)
    n_lights = surf.light_kind.shape[0]
    n_lamps = lamps.start.shape[0] - 1
    for ch in prange((n + CHUNK - 1) // CHUNK):
        stack = np.empty(STACK_SIZE, np.int32)
        heap = (np.empty(cap + 2), np.empty(cap + 2, np.int64), np.empty((cap + 2, 4)))
        seen = np.empty((cells.start.shape[0], 4))
        g = np.empty(lamps.tris.shape[0])
        far = np.empty(lamps.tris.shape[0], np.bool_)
        cum = np.empty(lamps.tris.shape[0])
        for k in range(ch * CHUNK, min(n, (ch + 1) * CHUNK)):
            if not valid[k]:
                continue
            px, py, pz = points[k, 0], points[k, 1], points[k, 2]
            nx, ny, nz = normals[k, 0], normals[k, 1], normals[k, 2]
            # the exact parts first: their sum is the floor the cut's error is bounded against
            h0, h1, h2, r = sky_light(bvh, stack, surf, cells, seen, px, py, pz, nx, ny, nz, offset)
            rays[k] += r
            for i in range(n_lights):
                lr, lg, lb, dx, dy, dz, dist = punctual_irradiance(surf, i, px, py, pz, nx, ny, nz)
                if lr + lg + lb <= 0.0:
                    continue
                rays[k] += 1
                ox, oy, oz = px + offset * nx, py + offset * ny, pz + offset * nz
                tr, tg, tb = transmittance(bvh, stack, ox, oy, oz, dx, dy, dz, 0.0, dist * (1.0 - SHADOW_EPS))
                h0 += lr * tr
                h1 += lg * tg
                h2 += lb * tb
            if n_lamps > 0:
                floor = LUM_R * h0 + LUM_G * h1 + LUM_B * h2 + floors[k]
                c0, c1, c2, r = lamps_light(bvh, stack, surf, lamps, g, far, cum, px, py, pz, nx, ny, nz,
                                            LAMP_LIFT * offset, floor, first, budget)
                cuts[k] = r
                rays[k] += r
                h0 += c0
                h1 += c1
                h2 += c2
            elif vpls.kind.shape[0] > 0:
                if brute:
                    c0, c1, c2 = brute_force(bvh, stack, vpls, (px, py, pz), (nx, ny, nz), offset)
                    cuts[k] = vpls.kind.shape[0]
                    rays[k] += vpls.kind.shape[0]
                else:
                    floor = LUM_R * h0 + LUM_G * h1 + LUM_B * h2 + floors[k]
                    c0, c1, c2, u0, u1, u2, c, r = lightcut(bvh, stack, tree, vpls, (px, py, pz), (nx, ny, nz),
                                                            offset, epsilon, cap, heap, floor)
                    cuts[k] = c
                    rays[k] += r
                h0 += c0
                h1 += c1
                h2 += c2
            out[k, 0], out[k, 1], out[k, 2] = h0, h1, h2
    return out, cuts, rays


