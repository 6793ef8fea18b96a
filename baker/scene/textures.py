"""Albedo textures: decoded by Pillow, sRGB to linear, no larger than the
load's limit (refs.LoadLimits.max_texture)."""
from __future__ import annotations

import io
import warnings

import numpy as np

from ..errors import SceneError


def srgb_to_linear(img: np.ndarray) -> np.ndarray:
    return np.where(img <= 0.04045, img / 12.92, ((img + 0.055) / 1.055) ** 2.4).astype(np.float32)


def image_to_albedo(img) -> np.ndarray:
    """PIL image (sRGB) -> (h, w, 3) float32 linear."""
    arr = np.asarray(img.convert("RGB"), np.float32) / 255.0
    return srgb_to_linear(arr)


def decode_texture(data: bytes, what: str, path, limits, alpha=False):
    """(h, w, 3) float32 linear albedo from encoded image bytes, and a note
    (or None) when it was scaled down to `limits.max_texture` on its longer
    side. The size in the image's header is checked against the memory
    budget before a pixel is decoded. alpha: return (albedo, alpha (h, w)
    float32 in [0, 1], stored linearly as glTF says; ones when the image
    has none, note) instead."""
    from PIL import Image
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", Image.DecompressionBombWarning)  # our own limits below decide
        try:
            img = Image.open(io.BytesIO(data))
            w, h = img.size
            # decoded as 8-bit RGBA at most, then float32 RGB at the limited size
            limits.check_bytes(4.0 * w * h, f"{what} ({w}x{h} pixels)", path)
            note = None
            if max(w, h) > limits.max_texture:
                img.thumbnail((limits.max_texture, limits.max_texture), Image.Resampling.BOX)
                note = (f"{path}: {what} is {w}x{h} pixels; scaled down to {img.size[0]}x{img.size[1]} "
                        f"(--max-texture {limits.max_texture})")
            if alpha:
                a = np.asarray(img.convert("RGBA"), np.float32)[..., 3] / 255.0
                return image_to_albedo(img), a, note
            return image_to_albedo(img), note
        except Image.DecompressionBombError:
            raise SceneError(f"{what}: an image of too many pixels to decode", path) from None
        except (OSError, ValueError, SyntaxError, Image.UnidentifiedImageError) as e:
            raise SceneError(f"{what}: not a readable image ({type(e).__name__})", path) from None
