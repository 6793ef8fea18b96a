"""Cameras and image loops shared by every rendering method.

A pinhole camera becomes a (4, 3) float64 array: position, forward, right
scaled by tan(fov_x / 2), up scaled by tan(fov_y / 2). Pixel (x, y) at
sub-pixel offset (sx, sy) looks along
forward + (2 (x + sx) / W - 1) right + (1 - 2 (y + sy) / H) up.
Images are rendered in bands of rows so a progress bar can follow and
Ctrl-C stops between bands.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..scene.model import Camera


def camera_array(camera: Camera, width: int, height: int) -> np.ndarray:
    aspect = width / height
    ty = math.tan(camera.yfov / 2)
    right = np.cross(camera.forward, camera.up)
    right /= np.linalg.norm(right)
    return np.array([camera.position, camera.forward, right * ty * aspect, camera.up * ty], np.float64)


@njit(cache=True, inline="always")
def primary_ray(cam, x, y, sx, sy, width, height):
    a = 2.0 * (x + sx) / width - 1.0
    b = 1.0 - 2.0 * (y + sy) / height
    dx = cam[1, 0] + a * cam[2, 0] + b * cam[3, 0]
    dy = cam[1, 1] + a * cam[2, 1] + b * cam[3, 1]
    dz = cam[1, 2] + a * cam[2, 2] + b * cam[3, 2]
    ln = math.sqrt(dx * dx + dy * dy + dz * dz)
    return cam[0, 0], cam[0, 1], cam[0, 2], dx / ln, dy / ln, dz / ln


@njit(cache=True, inline="always")
def subpixel(sub, per_axis):
    """Offset (fx, fy) in the pixel of sample `sub` of a per_axis x
    per_axis stratified pattern (cell centres)."""
    return (sub % per_axis + 0.5) / per_axis, (sub // per_axis + 0.5) / per_axis


BAND_SAMPLES = 1 << 18  # camera samples per band: a fraction of a second, so Ctrl-C and the bar respond


def render_bands(kernel, width, height, args, progress=None, samples_per_pixel=1):
    """Calls kernel(*args, row0, row1, out) over bands of rows into one
    (height, width, 3) float32 image, about BAND_SAMPLES camera samples per
    band; `progress(n_rows)` after each band."""
    image = np.zeros((height, width, 3), np.float32)
    band = max(1, min(height, BAND_SAMPLES // max(width * samples_per_pixel, 1)))
    for r0 in range(0, height, band):
        r1 = min(height, r0 + band)
        kernel(*args, r0, r1, image)
        if progress is not None:
            progress(r1 - r0)
    return image
