"""An image against a reference (the path tracer's), as the accuracy tests
and benchmarks measure it: luminance; the lamp's pixels left out (a lamp
a hundred times brighter than the walls would weigh on the mean more than
any wall); the mean ratio, the ratio per block, and lit pixels that come
out black.

The lamp's pixels are found by the camera's own rays (`lamp_pixels`: a
pixel any of whose 4 x 4 sub-pixel rays first meets an emitter or the
sky, which a window shows but a lightmap does not hold), so a
pixel the lamp's edge covers in part is the lamp's. Without that mask the
brightest pixels and two rings of pixels around them stand in for the
lamp, which is wrong where no lamp is in view (the brightest surface
would be left out)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from ..kernels.bvh import STACK_SIZE
from ..kernels.colour import LUMINANCE
from ..scene.surfaces import SKY_NONE, hit_past_glass
from .camera import camera_array, primary_ray, subpixel



@dataclass(frozen=True)
class Comparison:
    mean: float            # mean of the image / mean of the reference over the lit pixels
    blocks: np.ndarray     # the same ratio per block (blocks at least half lit)
    black: int             # lit pixels (over a quarter of the reference's median) black in the image

    @property
    def worst(self) -> float:
        """The worst block's |ratio - 1|."""
        return float(np.abs(self.blocks - 1).max()) if len(self.blocks) else 0.0

    def within(self, tol: float) -> float:
        """The share of blocks within tol of the reference."""
        return float((np.abs(self.blocks - 1) <= tol).mean()) if len(self.blocks) else 1.0


def lit_pixels(ref, lamp_rings: int = 2, lamp=None) -> np.ndarray:
    """(h, w) bool: the pixels of a luminance image that are lit and not the
    lamp: `lamp` (a mask, as lamp_pixels gives) grown by `lamp_rings`
    rings, or without it the pixels over half the brightest and the rings
    of pixels their edge covers."""
    if lamp is None:
        lamp = ref > 0.5 * ref.max()
    return ~grow(lamp, lamp_rings) & (ref > 0)


@njit(cache=True, parallel=True)
def _emitter_cover(bvh, surf, cam, width, height, per_axis, out):
    sky = surf.sky_mode != SKY_NONE
    for k in prange(width * height):
        stack = np.empty(STACK_SIZE, np.int32)
        y = k // width
        x = k % width
        for sub in range(per_axis * per_axis):
            fx, fy = subpixel(sub, per_axis)
            ox, oy, oz, dx, dy, dz = primary_ray(cam, x, y, fx, fy, width, height)
            t, j, u, v, gr, gg, gb = hit_past_glass(bvh, surf, stack, ox, oy, oz, dx, dy, dz)
            if j < 0:
                if sky:
                    out[y, x] = True
                    break
                continue
            m = surf.tri_material[bvh.tri_index[j]]
            if surf.emission[m, 0] + surf.emission[m, 1] + surf.emission[m, 2] > 0.0:
                out[y, x] = True
                break


def lamp_pixels(bvh, surfaces, camera, width: int, height: int, per_axis: int = 4) -> np.ndarray:
    """(height, width) bool: the pixels of `camera`'s view (a Camera) some of
    whose per_axis x per_axis sub-pixel rays first meet a light source: an
    emitter, or the sky (also through thin glass the voxels leave out)."""
    out = np.zeros((height, width), np.bool_)
    _emitter_cover(bvh.arrays, surfaces.arrays, camera_array(camera, width, height), int(width), int(height),
                   int(per_axis), out)
    return out


def grow(mask, rings: int) -> np.ndarray:
    """(h, w) bool mask grown by `rings` rings of 4-connected pixels."""
    mask = np.asarray(mask, bool)
    for _ in range(rings):
        out = mask.copy()
        out[1:] |= mask[:-1]
        out[:-1] |= mask[1:]
        out[:, 1:] |= mask[:, :-1]
        out[:, :-1] |= mask[:, 1:]
        mask = out
    return mask


def compare(image, reference, block: int = 8, lamp_rings: int | None = None, lamp=None) -> Comparison:
    """image, reference: (h, w, 3) linear radiance of the same view; lamp:
    the lamp's pixels (lamp_pixels), left out as they are (lamp_rings 0),
    or None: the pixels over half the brightest, and two rings."""
    img = np.asarray(image, np.float64) @ LUMINANCE
    ref = np.asarray(reference, np.float64) @ LUMINANCE
    rings = lamp_rings if lamp_rings is not None else (0 if lamp is not None else 2)
    lit = lit_pixels(ref, rings, lamp)
    if not lit.any():
        return Comparison(1.0, np.zeros(0), 0)
    ratios = []
    h, w = ref.shape
    for y in range(0, h, block):
        for x in range(0, w, block):
            m = lit[y:y + block, x:x + block]
            if m.sum() >= block * block // 2:
                ratios.append(img[y:y + block, x:x + block][m].mean() / ref[y:y + block, x:x + block][m].mean())
    black = int(((img == 0) & lit & (ref > 0.25 * np.median(ref[lit]))).sum())
    return Comparison(float(img[lit].mean() / ref[lit].mean()), np.array(ratios), black)
