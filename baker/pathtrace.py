"""Reference path tracer: Lambertian surfaces, area emitters with next-event
estimation and multiple importance sampling (power heuristic, Veach 1997),
punctual lights, Russian roulette. The yardstick for every other method.

Radiance along a camera ray: L = L_e + integral of (rho / pi) L_in cos.
One-sided triangles are black absorbers from behind (METHOD.md section 2);
emitters emit from their front side (both sides when double-sided).
Random numbers come from (seed, pixel * spp + sample, dimension), so the
image does not depend on the thread count.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from .kernels.rng import rand01
from .kernels.sampling import cosine_hemisphere
from .kernels.traverse import STACK_SIZE, any_hit, closest_hit, hit_normal
from .render import primary_ray
from .surfaces import albedo_at, punctual_irradiance, sample_emitter

MAX_DEPTH = 1000
RR_DEPTH = 3
_DIMS_PER_BOUNCE = 16


@njit(cache=True)
def trace_path(bvh, surf, stack, eps, seed, index, ox, oy, oz, dx, dy, dz):
    """Radiance (r, g, b) arriving at o from direction -d, and the depth reached."""
    tri_index = bvh[6]
    mat_of, emission, double = surf[0], surf[2], surf[3]
    n_emitters = surf[6].shape[0]
    n_lights = surf[13].shape[0]
    lr, lg, lb = 0.0, 0.0, 0.0
    tr, tg, tb = 1.0, 1.0, 1.0
    pdf_bsdf = 0.0  # 0: the camera ray (emission counts in full)
    for depth in range(MAX_DEPTH):
        t, j, u, v = closest_hit(bvh, stack, ox, oy, oz, dx, dy, dz, 0.0, np.inf)
        if j < 0:
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
                pdf_light = surf[8][tri] / surf[5][tri] * t * t / max(cos_in, 1e-300)
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
        dim = depth * _DIMS_PER_BOUNCE
        # next-event estimation on the area emitters
        if n_emitters > 0:
            ltri, qx, qy, qz, b1, b2, pdf_area = sample_emitter(surf, seed, index, dim)
            wx, wy, wz = qx - px, qy - py, qz - pz
            d2 = wx * wx + wy * wy + wz * wz
            dist = math.sqrt(d2)
            wx, wy, wz = wx / dist, wy / dist, wz / dist
            cos_x = nx * wx + ny * wy + nz * wz
            c = surf[4]
            ax, ay, az = c[ltri, 1, 0] - c[ltri, 0, 0], c[ltri, 1, 1] - c[ltri, 0, 1], c[ltri, 1, 2] - c[ltri, 0, 2]
            bx, by, bz = c[ltri, 2, 0] - c[ltri, 0, 0], c[ltri, 2, 1] - c[ltri, 0, 1], c[ltri, 2, 2] - c[ltri, 0, 2]
            mx, my, mz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
            cos_l = -(mx * wx + my * wy + mz * wz) / math.sqrt(mx * mx + my * my + mz * mz)
            lmat = mat_of[ltri]
            if double[lmat]:
                cos_l = abs(cos_l)
            if cos_x > 0.0 and cos_l > 0.0 and not any_hit(bvh, stack, px, py, pz, wx, wy, wz, 0.0, dist * (1.0 - 1e-7)
                                                              - eps):
                pdf_light = pdf_area * d2 / cos_l
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
        dx, dy, dz, cos = cosine_hemisphere(rand01(seed, index, dim + 3), rand01(seed, index, dim + 4),
                                            nx, ny, nz)
        if cos <= 0.0:
            break
        pdf_bsdf = cos / math.pi
        tr, tg, tb = tr * ar, tg * ag, tb * ab
        ox, oy, oz = px, py, pz
        if depth + 1 >= RR_DEPTH:
            q = min(max(tr, max(tg, tb)), 0.95)
            if rand01(seed, index, dim + 5) >= q:
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
            jx = rand01(seed, index, 1000001)
            jy = rand01(seed, index, 1000002)
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
    from .render import render_bands
    eps = 1e-7 * surfaces.scale
    return render_bands(_render_rows, width, height,
                        (scene_bvh.arrays, surfaces.arrays, camera_arr, eps, np.uint64(seed), int(spp),
                         int(width), int(height)), progress)


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
