"""The ordered VPL list of instant radiosity (docs/design.md section 7):
the VPLs drawn in proportion to their power, with repetition, each draw
carrying power / probability, so that the mean over the first m draws is
an unbiased estimate of the sum over all VPLs for every m. The CPU's
progressive instant radiosity and the viewer's GPU preview take the same
list in the same order (16 draws a frame by default).

Draw j takes u_j = the radical inverse of j in base 2, rotated by a seeded
offset (Cranley-Patterson): any first m draws cover the power's CDF
evenly. A sky direction's importance is its irradiance times the scene's
cross-section pi R^2 (the power it brings to a scene of radius R), an area
VPL's its power.
"""
from __future__ import annotations

import numpy as np

from ..kernels.colour import LUMINANCE
from ..kernels.rng import rand01
from .vpl import KIND_DIRECTIONAL, VPLs

STREAM_ORDER = 0x1A5  # rand01 index of the list's rotation (kernels/rng.py's table)


def radical_inverse(j):
    """Van der Corput sequence in base 2 for integers j (array)."""
    j = np.asarray(j, np.uint64)
    out = np.zeros(j.shape)
    f = 0.5
    for _ in range(64):
        out += f * (j & np.uint64(1))
        j = j >> np.uint64(1)
        f *= 0.5
        if not j.any():
            break
    return out


def ordered_vpls(vpls: VPLs, count: int, scene_radius: float, seed: int = 0) -> VPLs:
    """`count` draws from `vpls` in proportion to importance; each draw's
    power is power / probability (the mean over any first m draws estimates
    the sum over all VPLs)."""
    if len(vpls) == 0 or count <= 0:
        return VPLs(*(getattr(vpls, f)[:0] for f in ("kind", "position", "normal", "power", "area", "indirect")))
    imp = vpls.power @ LUMINANCE
    imp = np.where(vpls.kind == KIND_DIRECTIONAL, imp * np.pi * scene_radius ** 2, imp)
    imp = np.maximum(imp, 0.0)
    total = imp.sum()
    if total <= 0:
        imp, total = np.ones(len(vpls)), float(len(vpls))
    cdf = np.cumsum(imp) / total
    u = (radical_inverse(np.arange(count)) + rand01(seed, STREAM_ORDER, 0)) % 1.0
    idx = np.minimum(np.searchsorted(cdf, u, side="right"), len(vpls) - 1)
    prob = imp[idx] / total
    return VPLs(vpls.kind[idx], vpls.position[idx], vpls.normal[idx], vpls.power[idx] / prob[:, None],
                vpls.area[idx], vpls.indirect[idx])
