"""Quality frames (docs/design.md section 7): primary rays from the camera,
lightcuts at the visible points, adaptive anti-aliasing.

Pass 1 shoots one ray through each pixel's centre and records what it hit
(material, normal, depth). Pixels whose 4-neighbours differ from them (an
edge: another material, a normal more than ~25 degrees off, a depth more
than 5% off, or background) take 16 samples on a fixed 4 x 4 pattern
instead; the others keep their one. All shading points go through
lightcuts in one batch. Pass 2: a pixel whose luminance differs from a
4-neighbour's by more than CONTRAST of the brighter (a shadow's or a light
patch's edge across one surface, which pass 1 cannot see) takes the same
16 samples, in a second batch:

    L = albedo / pi * H + L_e      (the back of a one-sided surface: black;
                                    no hit: the sky's radiance, if any)
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numba import njit, prange

from ..kernels.bvh import STACK_SIZE
from ..kernels.colour import LUMINANCE
from ..kernels.traverse import hit_normal
from ..scene.surfaces import albedo_at, emission_at, hit_past_glass, sky_radiance
from .camera import primary_ray, subpixel

AA = 4                 # the edge pixels' pattern: AA x AA
NORMAL_COS = 0.9
DEPTH_REL = 0.05
CONTRAST = 0.2         # pass 2: luminance contrast to a 4-neighbour (a cut's own error is a few %)
BATCH = 1 << 16        # shading points per lightcuts call (progress and Ctrl-C between calls)


class Samples(NamedTuple):
    """Camera samples as trace_samples returns them (the one pack/unpack
    pair): shading point and normal (n, 3), what a sample adds before
    lighting (emission or sky), albedo (n, 3), shade (n,) bool, material
    (n,) int32 (-1: background, -2: a one-sided back), depth (n,)."""
    point: np.ndarray
    normal: np.ndarray
    base: np.ndarray
    albedo: np.ndarray
    shade: np.ndarray
    mat: np.ndarray
    depth: np.ndarray


def camera_samples(bvh, surfaces, cam, width, height, pix, sub, per_axis, eps) -> Samples:
    """trace_samples as a Samples record."""
    return Samples(*trace_samples(bvh.arrays, surfaces.arrays, cam, width, height, pix, sub, per_axis, eps))


@njit(cache=True, parallel=True)
def trace_samples(bvh, surf, cam, width, height, pix, sub, per_axis, eps):
    """One camera ray per sample (pixel pix[i], sub-sample sub[i] of a
    per_axis^2 pattern; per_axis 1: the centre): the shading point (n, 3),
    its normal towards the camera (n, 3), what it adds before lighting
    (emission or sky, (n, 3)), albedo (n, 3), shade (n,) bool, material
    (n,) int32 (-1: background, -2: a one-sided back), depth (n,). Rays go
    through thin glass the voxels leave out (hit_past_glass): what lies
    behind it is tinted."""
    n = pix.shape[0]
    point = np.zeros((n, 3))
    normal = np.zeros((n, 3))
    base = np.zeros((n, 3))
    albedo = np.zeros((n, 3))
    shade = np.zeros(n, np.bool_)
    mat = np.full(n, -1, np.int32)
    depth = np.full(n, np.inf)
    for i in prange(n):
        stack = np.empty(STACK_SIZE, np.int32)
        x, y = pix[i] % width, pix[i] // width
        fx, fy = subpixel(sub[i], per_axis)
        ox, oy, oz, dx, dy, dz = primary_ray(cam, x, y, fx, fy, width, height)
        t, j, u, v, gr, gg, gb = hit_past_glass(bvh, surf, stack, ox, oy, oz, dx, dy, dz)
        if j < 0:
            sr, sg, sb = sky_radiance(surf, dx, dy, dz)
            base[i, 0], base[i, 1], base[i, 2] = sr * gr, sg * gg, sb * gb
            continue
        tri = bvh.tri_index[j]
        m = surf.tri_material[tri]
        nx, ny, nz = hit_normal(bvh, j)
        depth[i] = t
        if nx * dx + ny * dy + nz * dz > 0.0:
            if not surf.double_sided[m]:
                mat[i] = -2
                continue
            nx, ny, nz = -nx, -ny, -nz
        mat[i] = m
        # a hair back along the ray: a point on a concave edge (a camera on a room's diagonal) is on both walls,
        # and every ray it sends along the other wall starts on it
        tp = max(t - eps, 0.5 * t)
        point[i, 0], point[i, 1], point[i, 2] = ox + tp * dx, oy + tp * dy, oz + tp * dz
        normal[i, 0], normal[i, 1], normal[i, 2] = nx, ny, nz
        er, eg, eb = emission_at(surf, tri, u, v)
        base[i, 0], base[i, 1], base[i, 2] = er * gr, eg * gg, eb * gb
        ar, ag, ab = albedo_at(surf, tri, u, v)
        k = 1.0 - surf.transmission[m]   # glass kept in the voxels shows its diffuse part
        albedo[i, 0], albedo[i, 1], albedo[i, 2] = ar * k * gr, ag * k * gg, ab * k * gb
        shade[i] = True
    return point, normal, base, albedo, shade, mat, depth


@njit(cache=True, inline="always")
def _neighbour(x, y, e, width, height):
    """Pixel index of 4-neighbour e (0-3: right, left, down, up) of (x, y),
    -1 beyond the image."""
    xx = x + (1 if e == 0 else (-1 if e == 1 else 0))
    yy = y + (1 if e == 2 else (-1 if e == 3 else 0))
    if xx < 0 or yy < 0 or xx >= width or yy >= height:
        return -1
    return yy * width + xx


@njit(cache=True)
def edge_pixels(mat, normal, depth, width, height):
    """(h * w,) bool: pixels whose 4-neighbours differ (material, normal,
    depth)."""
    out = np.zeros(width * height, np.bool_)
    for y in range(height):
        for x in range(width):
            k = y * width + x
            for e in range(4):
                q = _neighbour(x, y, e, width, height)
                if q < 0:
                    continue
                if mat[k] != mat[q]:
                    out[k] = True
                elif mat[k] >= 0:
                    c = normal[k, 0] * normal[q, 0] + normal[k, 1] * normal[q, 1] + normal[k, 2] * normal[q, 2]
                    if c < NORMAL_COS or abs(depth[k] - depth[q]) > DEPTH_REL * min(depth[k], depth[q]):
                        out[k] = True
    return out


@njit(cache=True, parallel=True)
def contrast_pixels(lum, done, width, height, contrast):
    """(h * w,) bool: pixels not `done` whose luminance differs from a
    4-neighbour's by more than `contrast` of the brighter one."""
    out = np.zeros(width * height, np.bool_)
    for y in prange(height):
        for x in range(width):
            k = y * width + x
            if done[k]:
                continue
            for e in range(4):
                q = _neighbour(x, y, e, width, height)
                if q < 0:
                    continue
                if abs(lum[k] - lum[q]) > contrast * max(lum[k], lum[q]):
                    out[k] = True
    return out


class Bounced(NamedTuple):
    """A frame's bounced light by a final gather (LightcutsConfig.gather):
    the Solution it reads, rays per gathered point, the records' spacing
    in voxel cells (0: every point gathered), and `smooth`, the Lights
    whose cuts add the sky's light (split_lights; None: no sky). The
    frame's own lights are then the emitters' alone."""
    solution: object
    rays: int
    spacing: float
    smooth: object


LIFT = 0.25   # cells: the gather's rays start this far off the surface (as a bake's texels': lightmap/values.py)


def _bounced(bounce, bvh, surfaces, point, normal, shade, eps, epsilon, cap):
    """The bounced light H (m, 3) at the points gathered, the sky's by its
    cuts (m, 3), the shaded points' indices, the SmoothCache over them
    (None: each gathered) and the sky's rays."""
    from ..lightmap.smooth_cache import SmoothCache
    from ..lights import irradiance
    from ..scene.prepared import Prepared
    from ..solve.gather import gather_bounced
    h = np.zeros((len(point), 3))
    idx = np.nonzero(shade)[0]
    lift = LIFT * float(bounce.solution.voxels.cell_size)
    prepared = Prepared(None, bvh, surfaces)

    def gather(p, nrm):
        return gather_bounced(prepared, bounce.solution, p, nrm, lift, bounce.rays)
    cache = None
    if len(idx) and bounce.spacing > 0:
        cache = SmoothCache(bvh.arrays, gather, point[idx], normal[idx],
                            bounce.spacing * float(bounce.solution.voxels.cell_size), lift)
        h[idx] = cache.values
    elif len(idx):
        h[idx] = gather(point[idx], normal[idx])
    sky = np.zeros((len(point), 3))
    sky_rays = 0
    if bounce.smooth is not None:
        sky, _, r = irradiance(bounce.smooth, bvh, surfaces, point, normal, shade, eps, epsilon, cap, exact=False)
        sky_rays = int(r.sum())
    return h, sky, idx, cache, sky_rays


def _shade(samples, owner, weight, n, lights, bvh, surfaces, eps, epsilon, cap, brute, progress, totals,
           bounce=None):
    """Radiance (n, 3) summed per owner pixel from the samples (the tuple
    trace_samples returns) by lightcuts; adds to the totals (points,
    cut sizes, shadow rays). bounce: a Bounced, the bounced light by a
    final gather (lights: the emitters' alone), whose luminance bounds
    the cuts' error too; where the gather's records around a point
    disagree by more than CONTRAST of its light (a contact, the bounced
    light's shadow) the point is gathered itself."""
    from ..lights import irradiance
    from ..startup import checkpoint
    point, normal, base, albedo, shade = samples.point, samples.normal, samples.base, samples.albedo, samples.shade
    h = np.zeros((len(point), 3))
    cuts = np.zeros(len(point), np.int64)
    rays = np.zeros(len(point), np.int64)
    ind, sky, idx, cache = None, None, None, None
    floor = np.zeros(len(point))
    if bounce is not None:
        ind, sky, idx, cache, sky_rays = _bounced(bounce, bvh, surfaces, point, normal, shade, eps, epsilon, cap)
        totals["rays"] += sky_rays   # the sky's visibility rays count as the frame's shadow rays
        floor = (ind + sky) @ LUMINANCE
        checkpoint()
    for a in range(0, len(point), BATCH):
        s = slice(a, a + BATCH)
        h[s], cuts[s], rays[s] = irradiance(lights, bvh, surfaces, point[s], normal[s], shade[s], eps, epsilon, cap,
                                            brute, floor=floor[s], analytic=bounce is not None)
        checkpoint()
        if progress is not None:
            progress(min(BATCH, len(point) - a))
    if cache is not None:   # the records' spread against the point's whole light: contacts gathered there
        cache.refine((h[idx] + sky[idx]) @ LUMINANCE, CONTRAST)
        ind[idx] = cache.values
    if ind is not None:
        h += ind + sky
    radiance = base + albedo / math.pi * h
    image = np.zeros((n, 3))
    np.add.at(image, owner, radiance * weight[:, None])
    totals["points"] += len(point)
    totals["shaded"] += int(shade.sum())
    totals["cuts"] += int(cuts[shade].sum())
    totals["cut_max"] = max(totals["cut_max"], int(cuts.max(initial=0)))
    totals["rays"] += int(rays.sum())
    return image


def _supersample(bvh, surfaces, cam, width, height, pixels, eps):
    """Samples on the AA x AA pattern over each of `pixels`, their owners
    and weights."""
    epix = np.repeat(pixels, AA * AA)
    esub = np.tile(np.arange(AA * AA), len(pixels))
    samples = camera_samples(bvh, surfaces, cam, width, height, epix, esub, AA, eps)
    return samples, epix, np.full(len(epix), 1.0 / (AA * AA))


@dataclass(frozen=True)
class FrameStats:
    """What a lightcuts frame cost: shading points (pixels plus the
    anti-aliased pixels' extra samples), the pixels anti-aliased at
    geometric edges and at sharp changes of light, the cut sizes and the
    shadow rays."""
    shading_points: int
    edge_pixels: int
    contrast_pixels: int
    cut_mean: float
    cut_max: int
    shadow_rays: int
    shadow_rays_per_pixel: float


def render_lightcuts(bvh, surfaces, lights, cam, width, height, epsilon=0.02, cap=1000, progress=None,
                     brute=False, aa=True, grow=None, bounce=None):
    """Linear radiance image (height, width, 3) float32 and its
    FrameStats. bounce: a Bounced (the bounced light by a final gather;
    `lights` then the emitters' alone). progress(k): k more
    shading points done; grow(k): k more points than width x height (the
    anti-aliased pixels' samples), for a progress bar's total."""
    n = width * height
    eps = 1e-5 * surfaces.scale
    pix = np.arange(n, dtype=np.int64)
    first = camera_samples(bvh, surfaces, cam, width, height, pix, np.zeros(n, np.int64), 1, eps)
    edges = edge_pixels(first.mat, first.normal, first.depth, width, height) if aa else np.zeros(n, bool)
    e = np.nonzero(edges)[0]
    if len(e):
        second, epix, eweight = _supersample(bvh, surfaces, cam, width, height, e, eps)
        keep = ~edges
        samples = Samples(*(np.concatenate([a[keep], b]) for a, b in zip(first, second)))
        owner = np.concatenate([pix[keep], epix])
        weight = np.concatenate([np.ones(int(keep.sum())), eweight])
    else:
        samples, owner, weight = first, pix, np.ones(n)
    if grow is not None:
        grow(len(samples.point) - n)
    totals = {"points": 0, "shaded": 0, "cuts": 0, "cut_max": 0, "rays": 0}
    image = _shade(samples, owner, weight, n, lights, bvh, surfaces, eps, epsilon, cap, brute, progress, totals,
                   bounce)
    c = np.zeros(0, np.int64)
    if aa:
        c = np.nonzero(contrast_pixels(image @ LUMINANCE, edges, width, height, CONTRAST))[0]
    if len(c):
        samples, owner, weight = _supersample(bvh, surfaces, cam, width, height, c, eps)
        if grow is not None:
            grow(len(samples.point))
        image[c] = 0.0
        image += _shade(samples, owner, weight, n, lights, bvh, surfaces, eps, epsilon, cap, brute, progress,
                        totals, bounce)
    stats = FrameStats(totals["points"], int(len(e)), int(len(c)),
                       totals["cuts"] / totals["shaded"] if totals["shaded"] else 0.0, totals["cut_max"],
                       totals["rays"], totals["rays"] / n)
    return image.reshape(height, width, 3).astype(np.float32), stats


def shading_points_estimate(width, height):
    return width * height
