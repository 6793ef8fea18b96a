"""Reference path tracer: Lambertian surfaces, area emitters with next-event
estimation and multiple importance sampling (power heuristic, Veach 1997),
punctual lights, a uniform sky, Russian roulette. The yardstick for every
other method; lights and surfaces come from the formulas of
scene/surfaces.py that the photons use as well.

Radiance along a camera ray: L = L_e + integral of (rho / pi) L_in cos.
One-sided triangles are black absorbers from behind (docs/design.md section 2);
emitters emit from their front side (both sides when double-sided).
Random numbers come from (seed, pixel * spp + sample, dimension), so the
image does not depend on the thread count.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ..kernels.bvh import STACK_SIZE
from ..kernels.rng import (PATH_DIM_BOUNCE, PATH_DIM_LIGHT, PATH_DIM_ROULETTE, PATH_DIMS_PER_BOUNCE,
                           STREAM_PIXEL_JITTER, rand01)
from ..kernels.sampling import cosine_hemisphere
from ..kernels.traverse import any_hit, closest_hit, hit_normal
from ..scene.surfaces import albedo_at, punctual_irradiance, sample_emitter, sky_radiance, triangle_normal
from .camera import primary_ray, render_bands

MAX_DEPTH = 1000
RR_DEPTH = 3


@njit(cache=True)
def trace_path(bvh, surf, stack, eps, seed, index, ox, oy, oz, dx, dy, dz):
    """Radiance (r, g, b) arriving at o from direction -d."""
    tri_index = bvh.tri_index
    mat_of, emission, double = surf.tri_material, surf.emission, surf.double_sided
    n_emitters = surf.emitters.shape[0]
    n_lights = surf.light_kind.shape[0]
    lr, lg, lb = 0.0, 0.0, 0.0
    tr, tg, tb = 1.0, 1.0, 1.0
    pdf_bsdf = 0.0  # 0: the camera ray (emission counts in full)
    for depth in range(MAX_DEPTH):
        t, j, u, v = closest_hit(bvh, stack, ox, oy, oz, dx, dy, dz, 0.0, np.inf)
        if j < 0:
            # escaped: the sky, if any (found by direction sampling only: no MIS weight needed)
            sr, sg, sb = sky_radiance(surf, dx, dy, dz)
            lr += tr * sr
            lg += tg * sg
            lb += tb * sb
            break
        tri = tri_index[j]
        nx, ny, nz = hit_normal(bvh, j)
        cos_in = -(nx * dx + ny * dy + nz * dz)
        mat = mat_of[tri]
        if cos_in < 0.0:
            if not double[mat]:
                break  # the back of a one-sided surface absorbs
            nx, ny, nz, cos_in = -nx, -ny, -nz, -cos_in
        er, eg, eb = emission[mat, 0], emission[mat, 1], emission[mat, 2]
        if er > 0.0 or eg > 0.0 or eb > 0.0:
            w = 1.0
            if pdf_bsdf > 0.0 and n_emitters > 0:
                pdf_light = surf.emitter_prob[tri] / surf.tri_area[tri] * t * t / max(cos_in, 1e-300)
                w = pdf_bsdf * pdf_bsdf / (pdf_bsdf * pdf_bsdf + pdf_light * pdf_light)
            lr += tr * er * w
            lg += tg * eg * w
            lb += tb * eb * w
        ar, ag, ab = albedo_at(surf, tri, u, v)
        if ar <= 0.0 and ag <= 0.0 and ab <= 0.0:
            break
        px = ox + t * dx + eps * nx
        py = oy + t * dy + eps * ny
        pz = oz + t * dz + eps * nz
        dim = depth * PATH_DIMS_PER_BOUNCE
        # next-event estimation on the area emitters
        if n_emitters > 0:
            ltri, qx, qy, qz, p_tri = sample_emitter(surf, rand01(seed, index, dim + PATH_DIM_LIGHT),
                                                     rand01(seed, index, dim + PATH_DIM_LIGHT + 1),
                                                     rand01(seed, index, dim + PATH_DIM_LIGHT + 2))
            wx, wy, wz = qx - px, qy - py, qz - pz
            d2 = wx * wx + wy * wy + wz * wz
            dist = math.sqrt(d2)
            wx, wy, wz = wx / dist, wy / dist, wz / dist
            cos_x = nx * wx + ny * wy + nz * wz
            mx, my, mz = triangle_normal(surf.corners, ltri)
            cos_l = -(mx * wx + my * wy + mz * wz)
            lmat = mat_of[ltri]
            if double[lmat]:
                cos_l = abs(cos_l)
            if cos_x > 0.0 and cos_l > 0.0 and not any_hit(bvh, stack, px, py, pz, wx, wy, wz, 0.0, dist * (1.0 - 1e-7)
                                                              - eps):
                pdf_light = p_tri / surf.tri_area[ltri] * d2 / cos_l
                pb = cos_x / math.pi
                w = pdf_light * pdf_light / (pdf_light * pdf_light + pb * pb)
                f = cos_x / math.pi / pdf_light * w
                lr += tr * ar * emission[lmat, 0] * f
                lg += tg * ag * emission[lmat, 1] * f
                lb += tb * ab * emission[lmat, 2] * f
        # punctual lights: all of them, deterministic
        for i in range(n_lights):
            hr, hg, hb, sx, sy, sz, dist = punctual_irradiance(surf, i, px, py, pz, nx, ny, nz)
            if (hr > 0.0 or hg > 0.0 or hb > 0.0) and not any_hit(bvh, stack, px, py, pz, sx, sy, sz, 0.0, dist):
                lr += tr * ar / math.pi * hr
                lg += tg * ag / math.pi * hg
                lb += tb * ab / math.pi * hb
        # continue the path: cosine sampling, f cos / pdf = albedo
        dx, dy, dz, cos = cosine_hemisphere(rand01(seed, index, dim + PATH_DIM_BOUNCE),
                                            rand01(seed, index, dim + PATH_DIM_BOUNCE + 1), nx, ny, nz)
        if cos <= 0.0:
            break
        pdf_bsdf = cos / math.pi
        tr, tg, tb = tr * ar, tg * ag, tb * ab
        ox, oy, oz = px, py, pz
        if depth + 1 >= RR_DEPTH:
            q = min(max(tr, max(tg, tb)), 0.95)
            if rand01(seed, index, dim + PATH_DIM_ROULETTE) >= q:
                break
            tr, tg, tb = tr / q, tg / q, tb / q
    return lr, lg, lb


@njit(cache=True, parallel=True)
def _render_rows(bvh, surf, cam, eps, seed, spp, width, height, row0, row1, out):
    n = (row1 - row0) * width
    for k in prange(n):
        stack = np.empty(STACK_SIZE, np.int32)
        y = row0 + k // width
        x = k % width
        pixel = y * width + x
        sr, sg, sb = 0.0, 0.0, 0.0
        for s in range(spp):
            index = pixel * spp + s
            jx = rand01(seed, index, STREAM_PIXEL_JITTER)
            jy = rand01(seed, index, STREAM_PIXEL_JITTER + 1)
            ox, oy, oz, dx, dy, dz = primary_ray(cam, x, y, jx, jy, width, height)
            r, g, b = trace_path(bvh, surf, stack, eps, seed, index, ox, oy, oz, dx, dy, dz)
            sr += r
            sg += g
            sb += b
        out[y, x, 0] = sr / spp
        out[y, x, 1] = sg / spp
        out[y, x, 2] = sb / spp


def render_pathtrace(scene_bvh, surfaces, camera_arr, width, height, spp, seed=0, progress=None):
    """Linear radiance image (height, width, 3) float32."""
    eps = 1e-7 * surfaces.scale
    return render_bands(_render_rows, width, height,
                        (scene_bvh.arrays, surfaces.arrays, camera_arr, eps, np.uint64(seed), int(spp),
                         int(width), int(height)), progress, samples_per_pixel=int(spp))


@njit(cache=True, parallel=True)
def radiance_batch(bvh, surf, eps, seed, spp, origins, dirs):
    """Mean radiance over spp paths for each (origin, direction) ray: (n, 3) float64."""
    n = origins.shape[0]
    out = np.zeros((n, 3))
    for i in prange(n):
        stack = np.empty(STACK_SIZE, np.int32)
        for s in range(spp):
            r, g, b = trace_path(bvh, surf, stack, eps, seed, i * spp + s, origins[i, 0], origins[i, 1], origins[i, 2],
                                 dirs[i, 0], dirs[i, 1], dirs[i, 2])
            out[i, 0] += r
            out[i, 1] += g
            out[i, 2] += b
    return out / spp
