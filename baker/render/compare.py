"""An image against a reference (the path tracer's), as the accuracy tests
and benchmarks measure it: luminance; the lamp's pixels, and the rings of
pixels its edge covers in part, left out (a lamp a hundred times brighter
than the walls would weigh on the mean more than any wall); the mean
ratio, the ratio per block, and lit pixels that come out black."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])


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


def lit_pixels(ref, lamp_rings: int = 2) -> np.ndarray:
    """(h, w) bool: the pixels of a luminance image that are lit and not the
    lamp (over half the brightest) or the rings of pixels its edge covers."""
    return ~grow(ref > 0.5 * ref.max(), lamp_rings) & (ref > 0)


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


def compare(image, reference, block: int = 8, lamp_rings: int = 2) -> Comparison:
    """image, reference: (h, w, 3) linear radiance of the same view."""
    img = np.asarray(image, np.float64) @ LUMINANCE
    ref = np.asarray(reference, np.float64) @ LUMINANCE
    lit = lit_pixels(ref, lamp_rings)
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
