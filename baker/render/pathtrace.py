"""Reference path tracer: Lambertian surfaces, area emitters with next-event
estimation and multiple importance sampling (power heuristic, Veach 1997),
punctual lights, a uniform sky, Russian roulette. The yardstick for every
other method; lights and surfaces come from the formulas of
scene/surfaces.py that the photons use as well.

Radiance along a camera ray: L = L_e + integral of (rho / pi) L_in cos.
One-sided triangles are black absorbers from behind (docs/design.md section 2);
emitters emit from their front side (both sides when double-sided).

Sampling: a path's choices come in groups of four numbers, each group
from its own Owen-scrambled four-dimensional Sobol sequence per pixel
(kernels/sobol.py): the position in the pixel with the first vertex's
emitter point, then each next direction with the emitter point of the
vertex it leads to. A pixel's samples are stratified in each group. The numbers are a pure
function of (seed, pixel, sample, pair): the image does not depend on the
thread count, nor on how the samples are split into passes.

Noise: the even and the odd samples of each pixel are summed apart; half
their difference estimates the error of the full mean, which is what
`--noise` stops on and what the stats report.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from ..kernels.bvh import STACK_SIZE
from ..kernels.colour import LUMINANCE
from ..kernels.inline import borrowed, inlined
from ..kernels.rng import ROULETTE_GLASS_DIM, STREAM_ROULETTE, mix64, rand01
from ..kernels.sampling import cosine_hemisphere
from ..kernels.sobol import sample4
from ..kernels.traverse import closest_hit, transmittance
from ..scene.surfaces import albedo_at, emission_at, emitter_point, punctual_irradiance, sky_radiance
from .camera import primary_ray

MAX_BOUNCES = 999   # reflections a path makes at most (Russian roulette ends it long before)
RR_DEPTH = 5


# The kernels a path vertex calls, inlined into the one loop that calls them
# (kernels/inline.py: a call would pass the BVH's or the surface tables'
# arrays one by one and count references to each)
_closest_hit, _transmittance = inlined(closest_hit), inlined(transmittance)
_albedo_at, _emitter_point, _punctual_irradiance = inlined(albedo_at), inlined(emitter_point), inlined(punctual_irradiance)
_emission_at = inlined(emission_at)
_sky_radiance, _cosine_hemisphere = inlined(sky_radiance), inlined(cosine_hemisphere)


@njit(cache=True, inline="always")
def trace_path(bvh, surf, stack, eps, seed, pixel, index, ox, oy, oz, dx, dy, dz, l1, l2, bounces):
    """Radiance (r, g, b) arriving at o from direction -d, sample `index` of
    `pixel`'s sequences; and whether the ray's first hit is an emitter.
    (l1, l2): the numbers of the first vertex's emitter point (drawn with
    the camera ray's, group 0). The vertex at depth k draws its next
    direction together with the next vertex's emitter point, group k + 1:
    a direction and the light seen from where it leads are stratified
    jointly. Direct light at a vertex is one shadow query per light: the
    emitter point first, then each punctual light (one shadow-query call
    site, so one inlined copy). Thin glass (transmission t): the path goes
    straight through with probability t, tinted by the base colour factor
    (the tint shadow rays take, traverse.transmittance), else the surface
    is diffuse with its albedo. `bounces`: the reflections light makes
    before it is counted, at most (1: direct light only; 0: the emitters
    seen); the last vertex takes no next-event light, its emitter hit its
    MIS share."""
    tri_index = bvh.tri_index
    mat_of, emission, double, normal = surf.tri_material, surf.emission, surf.double_sided, surf.tri_normal
    transmission = surf.transmission
    n_emitters = surf.emitters.shape[0]
    n_lights = surf.light_kind.shape[0]
    lr, lg, lb = 0.0, 0.0, 0.0
    tr, tg, tb = 1.0, 1.0, 1.0
    pdf_bsdf = 0.0  # 0: the camera ray (emission counts in full)
    saw_emitter = False
    seg = 0.0  # the path's length since its last diffuse vertex (through glass): the emitter's MIS weight
    roulette = mix64(np.uint64(seed) ^ mix64(np.uint64(pixel) + np.uint64(STREAM_ROULETTE)))
    for depth in range(bounces + 1):
        t, j, u, v = _closest_hit(bvh, stack, ox, oy, oz, dx, dy, dz, 0.0, np.inf)
        if j < 0:
            # escaped: the sky, if any (found by direction sampling only: no MIS weight needed)
            sr, sg, sb = _sky_radiance(surf, dx, dy, dz)
            lr += tr * sr
            lg += tg * sg
            lb += tb * sb
            break
        tri = tri_index[j]
        mat = mat_of[tri]
        tt = transmission[mat]
        if tt > 0.0 and (tt >= 1.0 or rand01(roulette, index, ROULETTE_GLASS_DIM + depth) < tt):
            tr, tg, tb = tr * surf.albedo[mat, 0], tg * surf.albedo[mat, 1], tb * surf.albedo[mat, 2]
            if tr <= 0.0 and tg <= 0.0 and tb <= 0.0:
                break
            ox, oy, oz = ox + (t + eps) * dx, oy + (t + eps) * dy, oz + (t + eps) * dz
            seg += t + eps
            continue
        nx, ny, nz = normal[tri, 0], normal[tri, 1], normal[tri, 2]
        cos_in = -(nx * dx + ny * dy + nz * dz)
        if cos_in < 0.0:
            if not double[mat]:
                break  # the back of a one-sided surface absorbs
            nx, ny, nz, cos_in = -nx, -ny, -nz, -cos_in
        if emission[mat, 0] > 0.0 or emission[mat, 1] > 0.0 or emission[mat, 2] > 0.0:
            er, eg, eb = _emission_at(surf, tri, u, v)
            saw_emitter = saw_emitter or pdf_bsdf == 0.0
            w = 1.0
            if pdf_bsdf > 0.0 and n_emitters > 0:
                r = seg + t
                pdf_light = surf.emitter_prob[tri] / surf.tri_area[tri] * r * r / max(cos_in, 1e-300)
                w = pdf_bsdf * pdf_bsdf / (pdf_bsdf * pdf_bsdf + pdf_light * pdf_light)
            lr += tr * er * w
            lg += tg * eg * w
            lb += tb * eb * w
        ar, ag, ab = _albedo_at(surf, tri, u, v)
        if ar <= 0.0 and ag <= 0.0 and ab <= 0.0:
            break
        px = ox + t * dx + eps * nx
        py = oy + t * dy + eps * ny
        pz = oz + t * dz + eps * nz
        # direct light: query 0 the area emitters (next-event estimation,
        # MIS-weighted), then every punctual light (deterministic)
        for light in range(n_lights + 1 if depth < bounces else 0):
            if light == 0:
                if n_emitters == 0:
                    continue
                ltri, qx, qy, qz, p_tri, lb1, lb2 = _emitter_point(surf, l1, l2)
                wx, wy, wz = qx - px, qy - py, qz - pz
                d2 = wx * wx + wy * wy + wz * wz
                dist = math.sqrt(d2)
                wx, wy, wz = wx / dist, wy / dist, wz / dist
                cos_x = nx * wx + ny * wy + nz * wz
                mx, my, mz = normal[ltri, 0], normal[ltri, 1], normal[ltri, 2]
                cos_l = -(mx * wx + my * wy + mz * wz)
                lmat = mat_of[ltri]
                if double[lmat]:
                    cos_l = abs(cos_l)
                if cos_x <= 0.0 or cos_l <= 0.0:
                    continue
                pdf_light = p_tri / surf.tri_area[ltri] * d2 / cos_l
                pb = cos_x / math.pi
                w = pdf_light * pdf_light / (pdf_light * pdf_light + pb * pb)
                f = cos_x / math.pi / pdf_light * w
                er, eg, eb = _emission_at(surf, ltri, lb1, lb2)
                cr = tr * ar * er * f
                cg = tg * ag * eg * f
                cb = tb * ab * eb * f
                reach = dist * (1.0 - 1e-7) - eps
            else:
                hr, hg, hb, wx, wy, wz, reach = _punctual_irradiance(surf, light - 1, px, py, pz, nx, ny, nz)
                if hr <= 0.0 and hg <= 0.0 and hb <= 0.0:
                    continue
                cr = tr * ar / math.pi * hr
                cg = tg * ag / math.pi * hg
                cb = tb * ab / math.pi * hb
            sr, sg, sb = _transmittance(bvh, stack, px, py, pz, wx, wy, wz, 0.0, reach)
            lr += cr * sr
            lg += cg * sg
            lb += cb * sb
        # continue the path: cosine sampling, f cos / pdf = albedo
        u1, u2, l1, l2 = sample4(seed, pixel, index, depth + 1)
        dx, dy, dz, cos = _cosine_hemisphere(u1, u2, nx, ny, nz)
        if cos <= 0.0:
            break
        pdf_bsdf = cos / math.pi
        seg = 0.0
        tr, tg, tb = tr * ar, tg * ag, tb * ab
        ox, oy, oz = px, py, pz
        if depth + 1 >= RR_DEPTH:
            q = min(max(tr, max(tg, tb)), 0.95)
            if rand01(roulette, index, depth) >= q:
                break
            tr, tg, tb = tr / q, tg / q, tb / q
    return lr, lg, lb, saw_emitter


@njit(cache=True, error_model="numpy")
def trace_samples(bvh, surf, stack, eps, seed, pixel, s0, s1, cam, x, y, width, height, origins, dirs, bounces):
    """Sums over samples s0..s1-1 of `pixel`'s paths: (r, g, b, n), n the
    samples whose first hit is an emitter. Each sample's camera ray goes
    through pixel (x, y) of `cam`, placed in it by the sample's first pair;
    or, when `origins` is not empty, every sample starts on ray `pixel`
    (origins[pixel], dirs[pixel]). Its arguments are borrowed (no reference
    counts in the loop; kernels/inline.py); the caller holds them."""
    bvh, surf, stack, cam = borrowed(bvh), borrowed(surf), borrowed(stack), borrowed(cam)
    origins, dirs = borrowed(origins), borrowed(dirs)
    sr, sg, sb, lamp = 0.0, 0.0, 0.0, 0
    for s in range(s0, s1):
        jx, jy, l1, l2 = sample4(seed, pixel, s, 0)
        if origins.shape[0] == 0:
            ox, oy, oz, dx, dy, dz = primary_ray(cam, x, y, jx, jy, width, height)
        else:
            ox, oy, oz = origins[pixel, 0], origins[pixel, 1], origins[pixel, 2]
            dx, dy, dz = dirs[pixel, 0], dirs[pixel, 1], dirs[pixel, 2]
        r, g, b, hit = trace_path(bvh, surf, stack, eps, seed, pixel, s, ox, oy, oz, dx, dy, dz, l1, l2, bounces)
        sr += r
        sg += g
        sb += b
        if hit:
            lamp += 1
    return sr, sg, sb, lamp


@njit(cache=True)
def _coprime_stride(n):
    """A stride near 0.618 n with no factor in common with n: i -> i stride
    mod n visits 0..n-1 once each, neighbours far apart."""
    s = max(1, int(0.618 * n))
    while math.gcd(s, n) != 1:
        s += 1
    return s


@njit(cache=True, parallel=True)
def _accumulate_rows(bvh, surf, cam, eps, seed, s0, s1, width, height, row0, row1, acc, lamp, origins, dirs, bounces):
    """Samples s0..s1-1 of every pixel of rows row0..row1-1, summed into
    `acc` (float64); lamp counts the samples whose camera ray meets an
    emitter first. With `origins` and `dirs` not empty, (n, 3) each, pixel
    (x, 0) of a width-n row takes ray x instead of a camera ray
    (radiance_batch). The one caller of trace_samples, so the path loop
    and the kernels it inlines compile once."""
    rows = row1 - row0
    stride = _coprime_stride(rows)
    n = rows * width
    for k in prange(n):
        stack = np.empty(STACK_SIZE, np.int32)
        y = row0 + (k // width) * stride % rows  # rows dealt out of order: each thread's share spans the image
        x = k % width
        pixel = y * width + x
        sr, sg, sb, hits = trace_samples(bvh, surf, stack, eps, seed, pixel, s0, s1, cam, x, y, width, height,
                                         origins, dirs, bounces)
        lamp[y, x] += hits
        acc[y, x, 0] += sr
        acc[y, x, 1] += sg
        acc[y, x, 2] += sb


NO_RAYS = np.empty((0, 3))
BAND_SAMPLES = 1 << 18  # camera samples per band: a fraction of a second, so Ctrl-C and the bar respond


@dataclass(frozen=True)
class PathTrace:
    """A path-traced image and how far it converged."""
    image: np.ndarray   # (h, w, 3) float32 linear radiance
    spp: int            # samples per pixel taken
    noise: float        # estimated relative RMSE of the image (noise_estimate); inf below 2 spp
    seconds: float
    stopped: str        # "spp", "noise" or "time": what ended it
    lamp: np.ndarray    # (h, w) bool: pixels where a camera ray met an emitter first (left out of `noise`)


def noise_estimate(first, second, lamp):
    """Relative RMSE against the converged image of the mean of two equal
    halves of a pixel's samples, from their sums: per pixel the error of
    the full mean is about half the difference of the half means (exact
    in expectation for independent halves; the halves here are the two
    aligned blocks of a scrambled Sobol sequence, stratified apart, so the
    estimate errs on the high side). Luminance, over the pixels that see
    no emitter directly (a lamp a hundred times brighter than the walls
    would weigh on it more than all the walls), relative to their mean."""
    keep = lamp == 0
    if not keep.any():
        return 0.0
    a = first[keep] @ LUMINANCE
    b = second[keep] @ LUMINANCE
    m = float((a + b).mean())
    if m <= 0.0:
        return 0.0
    return float(math.sqrt(np.mean((a - b) ** 2)) / m)


def pathtrace(scene_bvh, surfaces, camera_arr, width, height, spp, seed=0, time_limit=None, noise=None,
              progress=None, bounces=MAX_BOUNCES):
    """Path traces until `spp` samples per pixel, or the estimated relative
    noise falls to `noise`, or `time_limit` seconds pass, whichever comes
    first. Samples go in passes: sample 0, then 1, then 2-3, 4-7, ... (the
    aligned blocks of the Sobol sequences), each in bands of rows; after a
    pass that completes a power of two the noise is estimated from its two
    halves (noise_estimate). A time limit shortens the pass that would
    overrun it; the estimate then scales the last one by the square root
    of the sample counts. progress(n) gets camera samples done. bounces:
    the reflections counted at most (trace_path; 1: direct light only), to
    split an image's error by bounce."""
    t0 = time.perf_counter()
    eps = 1e-7 * surfaces.scale
    total = np.zeros((height, width, 3))
    last = np.zeros((height, width, 3))
    lamp = np.zeros((height, width), np.int32)
    args = (scene_bvh.arrays, surfaces.arrays, camera_arr, eps, np.uint64(seed))
    done, est, est_at, stopped = 0, math.inf, 0, "spp"
    rate = None  # seconds per camera sample, measured
    while done < spp:
        step = min(max(done, 1), spp - done)
        if time_limit is not None and rate is not None:
            fit = int((time_limit - (time.perf_counter() - t0)) / (rate * width * height))
            if fit < 1:
                stopped = "time"
                break
            step = min(step, fit)
        band = max(1, min(height, BAND_SAMPLES // max(width * step, 1)))
        last[:] = 0.0
        ts = time.perf_counter()
        for r0 in range(0, height, band):
            r1 = min(height, r0 + band)
            _accumulate_rows(*args, done, done + step, width, height, r0, r1, last, lamp, NO_RAYS, NO_RAYS,
                             int(bounces))
            if progress is not None:
                progress((r1 - r0) * width * step)
        rate = (time.perf_counter() - ts) / (width * height * step)
        total += last
        done += step
        if step == done // 2 and done >= 2:  # a complete power of two: its halves are [0, n/2), [n/2, n)
            est, est_at = noise_estimate(total - last, last, lamp), done
            if noise is not None and est <= noise:
                stopped = "noise"
                break
    if est_at and est_at < done:
        est *= math.sqrt(est_at / done)
    image = (total / max(done, 1)).astype(np.float32)
    return PathTrace(image, done, est, time.perf_counter() - t0, stopped, lamp > 0)


def render_pathtrace(scene_bvh, surfaces, camera_arr, width, height, spp, seed=0, progress=None):
    """Linear radiance image (height, width, 3) float32, `spp` samples per
    pixel; progress(n) gets rows done."""
    rows = None if progress is None else (lambda n: progress(n / (width * spp)))
    return pathtrace(scene_bvh, surfaces, camera_arr, width, height, spp, seed, progress=rows).image


def radiance_batch(bvh, surf, eps, seed, spp, origins, dirs, bounces=MAX_BOUNCES):
    """Mean radiance over spp paths for each (origin, direction) ray: (n, 3)
    float64. Ray i takes the sequences of pixel i; bounces as pathtrace's
    (0: only the emitters the rays meet)."""
    n = origins.shape[0]
    acc = np.zeros((1, n, 3))
    _accumulate_rows(bvh, surf, np.zeros((4, 3)), eps, seed, 0, spp, n, 1, 0, 1, acc, np.zeros((1, n), np.int32),
                     np.ascontiguousarray(origins, np.float64), np.ascontiguousarray(dirs, np.float64), int(bounces))
    return acc[0] / spp
