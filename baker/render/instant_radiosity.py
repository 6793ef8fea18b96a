"""Progressive instant radiosity on the CPU (Keller 1997; docs/design.md
section 7): the reference for the viewer's GPU preview. Frame f adds the
next `per_frame` VPLs of the ordered list (lights/ordered.py) at every
pixel's centre (visibility by shadow rays); the image is the running
average, which converges to the sum over all VPLs. Punctual lights are
exact in every frame.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .lightcuts_frame import camera_samples


@dataclass(frozen=True)
class IRStats:
    """frames averaged, VPLs used, and the last frame's relative change."""
    frames: int
    vpls_used: int
    change: float


def render_instant_radiosity(bvh, surfaces, ordered, cam, width, height, per_frame=16, frames=256,
                             tolerance=0.0, progress=None):
    """Linear radiance (height, width, 3) float32 after `frames` frames (or
    fewer: stops when a frame changes the image by less than `tolerance`,
    relative to its mean, 0: never), and its IRStats."""
    from ..lights import Lights, irradiance
    from ..lights.vpl import VPLs
    from ..startup import checkpoint
    n = width * height
    eps = 1e-5 * surfaces.scale
    s = camera_samples(bvh, surfaces, cam, width, height, np.arange(n, dtype=np.int64), np.zeros(n, np.int64), 1, eps)
    point, normal, base, albedo, shade = s.point, s.normal, s.base, s.albedo, s.shade
    from dataclasses import replace
    no_punctual = replace(surfaces, arrays=surfaces.arrays._replace(light_kind=np.zeros(0, np.int32)))
    empty = VPLs(*(getattr(ordered, k)[:0] for k in ("kind", "position", "normal", "power", "area", "indirect")))
    punctual, _, _ = irradiance(Lights(empty, None), bvh, surfaces, point, normal, shade, eps, brute=True)
    accum = np.zeros((n, 3))
    image = base + albedo / math.pi * punctual
    change, f = np.inf, 0
    total = len(ordered)
    for f in range(1, frames + 1):
        a, b = (f - 1) * per_frame, min(f * per_frame, total)
        if a >= b:
            f -= 1
            break
        sub = VPLs(*(getattr(ordered, k)[a:b] for k in ("kind", "position", "normal", "power", "area", "indirect")))
        h, _, _ = irradiance(Lights(sub, None), bvh, no_punctual, point, normal, shade, eps, brute=True, near=False)
        accum += h  # the sum over this frame's draws: the estimate is the mean over all draws so far
        new = base + albedo / math.pi * (punctual + accum / b)
        mean = float(new.mean()) or 1.0
        change = float(np.abs(new - image).mean()) / mean
        image = new
        checkpoint()
        if progress is not None:
            progress(1)
        if tolerance > 0 and f > 1 and change < tolerance:
            break
    return image.reshape(height, width, 3).astype(np.float32), IRStats(f, min(f * per_frame, total), change)
