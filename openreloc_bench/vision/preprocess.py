"""Input checking and image preparation shared by every encoder, describer and segmenter.

Callers hand us whatever their readers produce (grey PNGs, RGBA, float renders in [0, 1]); one
coercion function turns all of them into RGB uint8 so each backend sees one format, and rejects what
cannot be an image with a one-line :class:`InputError`.
"""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np

from openreloc_bench.errors import OpenRelocError


class InputError(OpenRelocError, ValueError):
    """An image, crop or mask passed to a vision backend is unusable (empty, wrong shape or type)."""


def as_rgb_uint8(image: np.ndarray, what: str = "image") -> np.ndarray:
    """RGB uint8 (H, W, 3) from grey (H, W) / (H, W, 1), RGBA, or float images (0-1 or 0-255 range)."""
    a = np.asarray(image)
    if a.ndim == 3 and a.shape[2] == 1:
        a = a[..., 0]
    if a.ndim == 2:
        a = np.repeat(a[..., None], 3, axis=2)
    elif a.ndim == 3 and a.shape[2] == 4:
        a = a[..., :3]
    if a.ndim != 3 or a.shape[2] != 3:
        raise InputError(f"{what}: expected an RGB image (H, W, 3), grey (H, W) or RGBA, got shape {a.shape}")
    if a.shape[0] == 0 or a.shape[1] == 0:
        raise InputError(f"{what}: empty image (shape {a.shape})")
    if a.dtype == np.uint8:
        return np.ascontiguousarray(a)
    if a.dtype == bool or not np.issubdtype(a.dtype, np.number):
        raise InputError(f"{what}: unsupported pixel type {a.dtype}")
    f = a.astype(np.float64)
    if not np.all(np.isfinite(f)):
        raise InputError(f"{what}: contains NaN or infinite values")
    if np.issubdtype(a.dtype, np.floating) and f.max(initial=0.0) <= 1.0:
        f = f * 255.0
    elif a.dtype == np.uint16:
        f = f / 257.0
    return np.ascontiguousarray(np.clip(np.rint(f), 0, 255).astype(np.uint8))


def check_mask(mask: np.ndarray, hw: tuple[int, int], what: str = "mask") -> np.ndarray:
    """A bool (H, W) mask matching the image, with at least one pixel set."""
    m = np.asarray(mask)
    if m.shape != hw:
        raise InputError(f"{what}: shape {m.shape} does not match the image {hw}")
    m = m.astype(bool)
    if not m.any():
        raise InputError(f"{what}: zero-area mask (no pixel set)")
    return m


def mask_box(mask: np.ndarray) -> np.ndarray:
    """[x0, y0, x1, y1] (exclusive ends) of a non-empty bool mask."""
    ys = np.flatnonzero(mask.any(axis=1))
    xs = np.flatnonzero(mask.any(axis=0))
    return np.array([xs[0], ys[0], xs[-1] + 1, ys[-1] + 1], dtype=np.int64)


def touches_border(mask: np.ndarray) -> bool:
    """Whether a bool mask reaches the image border: the object is cut there, so the mask's centroid
    and box are not the whole object's."""
    return bool(mask[[0, -1]].any() or mask[:, [0, -1]].any())


def square_crop(rgb: np.ndarray, box: Sequence[float], scale: float = 1.2, fill: int = 0) -> np.ndarray:
    """The square around ``box`` enlarged by ``scale`` (1.2 = 10% padding each side); outside pixels = ``fill``.

    Square and zero-filled rather than clipped, so an object at the border keeps its aspect ratio and
    position in the crop, as the encoder saw in training.
    """
    x0, y0, x1, y1 = (float(v) for v in box)
    cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
    side = max(x1 - x0, y1 - y0, 1.0) * scale
    half = side / 2
    ix0, iy0 = int(np.floor(cx - half)), int(np.floor(cy - half))
    n = max(int(np.ceil(side)), 1)
    out = np.full((n, n, 3), fill, dtype=np.uint8)
    h, w = rgb.shape[:2]
    sx0, sy0 = max(ix0, 0), max(iy0, 0)
    sx1, sy1 = min(ix0 + n, w), min(iy0 + n, h)
    if sx1 > sx0 and sy1 > sy0:
        out[sy0 - iy0 : sy1 - iy0, sx0 - ix0 : sx1 - ix0] = rgb[sy0:sy1, sx0:sx1]
    return out


def object_crop(rgb: np.ndarray, mask: np.ndarray, scale: float = 1.2) -> np.ndarray:
    """Square crop of one masked object with padding (the view the encoders are trained on)."""
    rgb = as_rgb_uint8(rgb)
    m = check_mask(mask, rgb.shape[:2])
    return square_crop(rgb, mask_box(m), scale)


def resize_square(crop: np.ndarray, size: int) -> np.ndarray:
    """Resize a crop to size x size; INTER_AREA when shrinking (no aliasing), cubic when enlarging."""
    h, w = crop.shape[:2]
    interp = cv2.INTER_AREA if max(h, w) > size else cv2.INTER_CUBIC
    return cv2.resize(crop, (size, size), interpolation=interp)


def check_crops(crops: Sequence[np.ndarray]) -> list[np.ndarray]:
    """Coerce each crop to RGB uint8; name the offending index in the error."""
    if isinstance(crops, np.ndarray) and crops.ndim in (2, 3) and crops.dtype != object:
        raise InputError("expected a sequence of crops, got a single image array (wrap it in a list)")
    return [as_rgb_uint8(c, f"crop {i}") for i, c in enumerate(crops)]


def check_texts(texts: Sequence[str]) -> list[str]:
    if isinstance(texts, str):
        raise InputError("expected a sequence of texts, got a single string (wrap it in a list)")
    out = list(texts)
    for i, t in enumerate(out):
        if not isinstance(t, str):
            raise InputError(f"text {i}: expected a string, got {type(t).__name__}")
    return out
