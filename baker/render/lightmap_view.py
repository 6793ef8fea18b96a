"""The bake seen by a camera, on the CPU: what a viewer shows, computed
from the bake alone (docs/design.md section 9):

    L(p) = albedo(p) / pi * H(p) + L_e(p),

H bilinearly interpolated from the lightmap page at the point's
TEXCOORD_1, 4 x 4 box-filtered samples per pixel (as the voxel view and
the path tracer). Triangles seen from behind are culled, as viewers do
(a two-sided surface is two baked triangles, one per face). Albedo
textures are sampled bilinearly, repeated, as glTF's default sampler.
Where a ray meets no surface (or a back face) it shows the sky the bake
was lit by, if any, as the path tracer does. The reference the viewer's
snapshots and the three.js screenshot are checked against.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ..kernels.bvh import STACK_SIZE
from ..scene.surfaces import hit_past_glass, sky_radiance
from .camera import camera_array, primary_ray, render_bands, subpixel
from .voxelview import SUBPIXELS


@njit(cache=True, inline="always")
def bilinear_flat(data, base, w, h, x, y, wrap):
    """Bilinear lookup at (x, y) in texel units (texel i's centre at
    i + 0.5) of the w x h RGB image stored row-major in data[base:]
    ((texels, 3)); edges repeated (wrap) or clamped."""
    x -= 0.5
    y -= 0.5
    x0 = int(math.floor(x))
    y0 = int(math.floor(y))
    fx, fy = x - x0, y - y0
    r0 = r1 = r2 = 0.0
    for dy in range(2):
        for dx in range(2):
            wt = (fx if dx else 1.0 - fx) * (fy if dy else 1.0 - fy)
            if wrap:
                xi, yi = (x0 + dx) % w, (y0 + dy) % h
            else:
                xi, yi = min(max(x0 + dx, 0), w - 1), min(max(y0 + dy, 0), h - 1)
            k = base + yi * w + xi
            r0 += wt * data[k, 0]
            r1 += wt * data[k, 1]
            r2 += wt * data[k, 2]
    return r0, r1, r2


@njit(cache=True, inline="always")
def bilinear(pages_flat, size, p, u, v):
    """Page p (size x size, pages_flat = pages.reshape(-1, 3)) at (u, v),
    clamped to the edge as the file's sampler."""
    return bilinear_flat(pages_flat, p * size * size, size, size, u * size, v * size, False)


@njit(cache=True)
def _textured_bilinear(surf, factor, off, w, h, tri, b1, b2):
    """factor (r, g, b) times the texture at tex_data[off:] (w x h; off < 0:
    none) sampled bilinearly, repeated, at barycentrics (b1, b2) of `tri`
    (what a viewer's sampler does)."""
    r, g, b = factor[0], factor[1], factor[2]
    if off < 0:
        return r, g, b
    uv = surf.uvs
    b0 = 1.0 - b1 - b2
    x = (b0 * uv[tri, 0, 0] + b1 * uv[tri, 1, 0] + b2 * uv[tri, 2, 0]) * w
    y = (b0 * uv[tri, 0, 1] + b1 * uv[tri, 1, 1] + b2 * uv[tri, 2, 1]) * h
    t0, t1, t2 = bilinear_flat(surf.tex_data, off, w, h, x, y, True)
    return r * t0, g * t1, b * t2


@njit(cache=True, inline="always")
def albedo_bilinear(surf, tri, b1, b2):
    """Albedo at barycentrics (b1, b2) of triangle `tri`: the factor times
    the texture sampled bilinearly, repeated (what a viewer's sampler does)."""
    mat = surf.tri_material[tri]
    return _textured_bilinear(surf, surf.albedo[mat], surf.tex_offset[mat], surf.tex_size[mat, 0],
                              surf.tex_size[mat, 1], tri, b1, b2)


@njit(cache=True, inline="always")
def emission_bilinear(surf, tri, b1, b2):
    """L_e at barycentrics (b1, b2) of triangle `tri`: the emissive factor
    times the emissive texture sampled bilinearly, repeated."""
    mat = surf.tri_material[tri]
    return _textured_bilinear(surf, surf.emission[mat], surf.emit_offset[mat], surf.emit_size[mat, 0],
                              surf.emit_size[mat, 1], tri, b1, b2)


@njit(cache=True, parallel=True)
def _rows(bvh, surf, uv1, page, pages_flat, size, cam, width, height, row0, row1, out):
    n = (row1 - row0) * width
    w = 1.0 / (SUBPIXELS * SUBPIXELS)
    inv_pi = 1.0 / math.pi
    for k in prange(n):
        stack = np.empty(STACK_SIZE, np.int32)
        y = row0 + k // width
        x = k % width
        r0 = r1 = r2 = 0.0
        for sub in range(SUBPIXELS * SUBPIXELS):
            fx, fy = subpixel(sub, SUBPIXELS)
            ox, oy, oz, dx, dy, dz = primary_ray(cam, x, y, fx, fy, width, height)
            t, j, u, v, gr, gg, gb = hit_past_glass(bvh, surf, stack, ox, oy, oz, dx, dy, dz, True)
            if j < 0:   # the sky the bake was lit by, if any, through the panes passed
                s0, s1, s2 = sky_radiance(surf, dx, dy, dz)
                r0 += s0 * gr
                r1 += s1 * gg
                r2 += s2 * gb
                continue
            tri = bvh.tri_index[j]
            b0 = 1.0 - u - v
            lu = b0 * uv1[tri, 0, 0] + u * uv1[tri, 1, 0] + v * uv1[tri, 2, 0]
            lv = b0 * uv1[tri, 0, 1] + u * uv1[tri, 1, 1] + v * uv1[tri, 2, 1]
            h0, h1, h2 = bilinear(pages_flat, size, page[tri], lu, lv)
            a0, a1, a2 = albedo_bilinear(surf, tri, u, v)
            m = surf.tri_material[tri]
            k = 1.0 - surf.transmission[m]   # glass kept in the voxels shows its diffuse part
            e0, e1, e2 = emission_bilinear(surf, tri, u, v)
            r0 += (k * a0 * inv_pi * h0 + e0) * gr
            r1 += (k * a1 * inv_pi * h1 + e1) * gg
            r2 += (k * a2 * inv_pi * h2 + e2) * gb
        out[y, x, 0] = r0 * w
        out[y, x, 1] = r1 * w
        out[y, x, 2] = r2 * w


def render_bake(bake, camera=None, width=256, height=256, progress=None, bvh=None):
    """Linear radiance image (height, width, 3) float32 of the bake seen by
    `camera` (a Camera, a name, an index or None: the bake's first)."""
    from ..scene import build_scene_bvh, pack
    from ..scene import camera_for
    from ..scene.model import Camera
    bvh = bvh or build_scene_bvh(bake.scene)
    surf = pack(bake.scene)
    cam = camera if isinstance(camera, Camera) else camera_for(bake.scene, camera, bvh)
    return render_bands(_rows, width, height,
                        (bvh.arrays, surf.arrays, np.ascontiguousarray(bake.uv1, np.float64), bake.page,
                         np.ascontiguousarray(bake.pages, np.float32).reshape(-1, 3), int(bake.pages.shape[1]),
                         camera_array(cam, width, height),
                         int(width), int(height)), progress)
