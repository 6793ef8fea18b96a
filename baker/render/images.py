"""Image output: linear EXR (OpenEXR), tone-mapped sRGB PNG (Pillow).

PNG: exposure (automatic: the log-average luminance maps to 0.18, or a
given EV), the ACES filmic fit of Narkowicz 2015, then the sRGB transfer
curve. EXR keeps linear radiance as float32 (or half).
"""
from __future__ import annotations

import os

import numpy as np

from ..errors import VoxgiError
from ..fileio import atomic_write
from ..kernels.colour import LUMINANCE



def auto_exposure(image: np.ndarray) -> float:
    """Scale mapping the log-average luminance of the lit pixels to 0.18."""
    lum = image.astype(np.float64) @ LUMINANCE
    lit = lum[lum > 0]
    if lit.size == 0:
        return 1.0
    return float(0.18 / np.exp(np.mean(np.log(lit + 1e-12))))


def aces_filmic(x: np.ndarray) -> np.ndarray:
    return np.clip((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14), 0.0, 1.0)


def linear_to_srgb(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def tonemap(image: np.ndarray, exposure_ev=None) -> np.ndarray:
    """Linear radiance (h, w, 3) -> uint8 sRGB."""
    scale = auto_exposure(image) if exposure_ev is None else 2.0 ** float(exposure_ev)
    out = linear_to_srgb(aces_filmic(np.nan_to_num(image.astype(np.float64)) * scale))
    return (out * 255.0 + 0.5).astype(np.uint8)


def write_image(path, image: np.ndarray, exposure_ev=None):
    """Writes .exr (linear float32) or .png (tone-mapped sRGB), atomically."""
    ext = os.path.splitext(path)[1].lower()
    image = np.ascontiguousarray(image, np.float32)
    if exposure_ev is not None and not -64 <= exposure_ev <= 64:
        raise VoxgiError(f"exposure must be a finite number of EV in -64..64 (got {exposure_ev})", path)
    if ext == ".exr":
        import OpenEXR

        def w(tmp):
            OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage},
                         {"RGB": image}).write(tmp)
    elif ext == ".png":
        from PIL import Image
        rgb = tonemap(image, exposure_ev)

        def w(tmp):
            Image.fromarray(rgb, "RGB").save(tmp, format="PNG")
    else:
        raise VoxgiError(f"unsupported image format {ext or '(none)'!r}; use .exr or .png", path)
    atomic_write(path, w)


def read_exr(path) -> np.ndarray:
    import OpenEXR
    with OpenEXR.File(str(path)) as f:
        ch = f.channels()
        if "RGB" in ch:
            return np.asarray(ch["RGB"].pixels, np.float32)
        return np.stack([np.asarray(ch[c].pixels, np.float32) for c in "RGB"], axis=-1)
