"""Albedo textures: decoded by Pillow, sRGB to linear."""
from __future__ import annotations

import numpy as np


def srgb_to_linear(img: np.ndarray) -> np.ndarray:
    return np.where(img <= 0.04045, img / 12.92, ((img + 0.055) / 1.055) ** 2.4).astype(np.float32)


def image_to_albedo(img) -> np.ndarray:
    """PIL image (sRGB) -> (h, w, 3) float32 linear."""
    arr = np.asarray(img.convert("RGB"), np.float32) / 255.0
    return srgb_to_linear(arr)


def read_albedo_texture(path) -> np.ndarray:
    from PIL import Image
    with Image.open(path) as img:
        return image_to_albedo(img)
