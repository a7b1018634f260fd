"""Named colours and procedural, tileable material textures for the asset library.

Textures are made from numpy noise only (no image files), so they are redistributable and
deterministic: the same (material, rgb, seed, size) always gives the same bytes, which keeps a
generated scene byte-identical across runs. Every pattern is periodic in both image axes (spectral
noise from an FFT, stripes with an integer number of periods), because renderers repeat a texture
across a surface and a seam would show up as a false edge for the relocalizer.
"""

from __future__ import annotations

import zlib

import numpy as np

from openreloc_bench.errors import ConfigError

MATERIALS: tuple[str, ...] = (
    "wood",
    "fabric",
    "plaster",
    "metal",
    "ceramic",
    "paper",
    "plastic",
    "glass",
    "leather",
    "stone",
    "rubber",
    "foliage",
    "wax",
)
"""Material keys; :func:`make_texture` has one pattern per key."""

COLOURS: dict[str, tuple[float, float, float]] = {
    "red": (0.78, 0.12, 0.12),
    "dark red": (0.45, 0.06, 0.08),
    "orange": (0.93, 0.48, 0.10),
    "yellow": (0.95, 0.82, 0.20),
    "gold": (0.83, 0.66, 0.22),
    "green": (0.20, 0.55, 0.22),
    "dark green": (0.10, 0.30, 0.14),
    "olive": (0.45, 0.47, 0.20),
    "teal": (0.10, 0.50, 0.50),
    "light blue": (0.55, 0.74, 0.90),
    "blue": (0.15, 0.32, 0.75),
    "navy": (0.08, 0.12, 0.35),
    "purple": (0.45, 0.22, 0.60),
    "pink": (0.93, 0.55, 0.68),
    "white": (0.93, 0.93, 0.91),
    "cream": (0.94, 0.90, 0.78),
    "beige": (0.85, 0.77, 0.62),
    "tan": (0.76, 0.60, 0.42),
    "light brown": (0.68, 0.50, 0.32),
    "brown": (0.48, 0.31, 0.17),
    "dark brown": (0.28, 0.17, 0.09),
    "grey": (0.55, 0.55, 0.55),
    "light grey": (0.78, 0.78, 0.78),
    "dark grey": (0.27, 0.27, 0.28),
    "silver": (0.74, 0.75, 0.77),
    "black": (0.08, 0.08, 0.09),
}
"""Colour name -> sRGB in [0, 1]; the names are the words used in asset descriptions."""


def _spectral_noise(
    rng: np.random.Generator, size: int, beta: float, stretch: tuple[float, float] = (1.0, 1.0)
) -> np.ndarray:
    """Tileable noise with a 1/f**beta spectrum, zero mean and unit std.

    ``stretch`` scales the (row, column) frequencies: a large row factor damps variation along
    rows faster, giving streaks that run down the columns (wood fibre, brushed metal).
    """
    white = rng.standard_normal((size, size))
    fy = np.fft.fftfreq(size)[:, None] * stretch[0]
    fx = np.fft.rfftfreq(size)[None, :] * stretch[1]
    f = np.hypot(fx, fy)
    f[0, 0] = 1.0
    spec = np.fft.rfft2(white) / f**beta
    spec[0, 0] = 0.0
    out = np.fft.irfft2(spec, s=(size, size))
    return (out - out.mean()) / (out.std() + 1e-12)


def _luminance(material: str, rng: np.random.Generator, size: int) -> np.ndarray:
    """Per-pixel brightness factor around 1 that carries the material's pattern."""
    y, x = np.mgrid[0:size, 0:size] / size  # in [0, 1), one period = the whole tile
    if material == "wood":
        warp = _spectral_noise(rng, size, 1.6, (0.25, 1.0))
        rings = np.sin(2 * np.pi * (int(rng.integers(3, 7)) * x + 0.35 * warp))
        fibre = _spectral_noise(rng, size, 0.9, (6.0, 1.0))
        return 1 + 0.13 * np.sign(rings) * np.abs(rings) ** 0.5 + 0.06 * fibre
    if material == "fabric":
        n = max(4, size // 4) // 2 * 2  # even thread count keeps the over/under pattern periodic
        i, j = np.floor(x * n), np.floor(y * n)
        fx, fy = x * n % 1, y * n % 1
        shade = np.where((i + j) % 2 == 0, np.sin(np.pi * fy), np.sin(np.pi * fx))
        return 0.86 + 0.2 * shade + 0.05 * _spectral_noise(rng, size, 1.2)
    if material == "plaster":
        return 1 + 0.05 * _spectral_noise(rng, size, 1.3) + 0.03 * _spectral_noise(rng, size, 0.3)
    if material == "metal":
        return 1 + 0.08 * _spectral_noise(rng, size, 0.8, (1.0, 12.0)) + 0.03 * _spectral_noise(rng, size, 1.8)
    if material == "ceramic":
        speckle = (rng.random((size, size)) < 0.004) * -0.15
        return 1 + 0.02 * _spectral_noise(rng, size, 1.6) + speckle
    if material == "paper":
        return 1 + 0.04 * _spectral_noise(rng, size, 0.2) + 0.03 * _spectral_noise(rng, size, 1.5)
    if material == "plastic":
        return 1 + 0.015 * _spectral_noise(rng, size, 1.0)
    if material == "glass":
        band = np.sin(np.pi * (2 * (x + y) + 0.1 * _spectral_noise(rng, size, 2.0))) ** 8
        return 1.02 + 0.10 * band
    if material == "leather":
        grain = _spectral_noise(rng, size, 0.7)
        return 1 - 0.12 * np.exp(-4 * np.abs(grain)) + 0.05 * _spectral_noise(rng, size, 1.6)
    if material == "stone":
        veins = np.abs(np.sin(2 * np.pi * (2 * x + 0.4 * _spectral_noise(rng, size, 1.8))))
        return 1 + 0.07 * _spectral_noise(rng, size, 1.4) - 0.25 * np.exp(-12 * veins)
    if material == "rubber":
        return 1 + 0.03 * _spectral_noise(rng, size, 0.4)
    if material == "foliage":
        veins = np.abs(np.sin(2 * np.pi * 4 * (x + 0.5 * y) + 0.5 * _spectral_noise(rng, size, 1.5)))
        return 0.95 + 0.18 * _spectral_noise(rng, size, 1.1) - 0.12 * np.exp(-10 * veins)
    if material == "wax":
        return 1.04 + 0.03 * _spectral_noise(rng, size, 1.8)
    raise ConfigError(f"unknown material '{material}' (known: {', '.join(MATERIALS)})")


def make_texture(material: str, rgb: tuple[float, float, float], seed: int, size: int = 64) -> np.ndarray:
    """uint8 (size, size, 3) tileable procedural texture of ``material`` tinted by sRGB ``rgb``.

    Deterministic in (material, rgb, seed, size). The pattern modulates brightness around the tint;
    a small additive term keeps the pattern visible on near-black colours.
    """
    if material not in MATERIALS:
        raise ConfigError(f"unknown material '{material}' (known: {', '.join(MATERIALS)})")
    tint = np.asarray(rgb, dtype=np.float64)
    if tint.shape != (3,) or not np.all(np.isfinite(tint)) or tint.min() < 0 or tint.max() > 1:
        raise ConfigError(f"texture colour must be 3 floats in [0, 1], got {rgb!r}")
    if not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ConfigError(f"texture seed must be a non-negative integer, got {seed!r}")
    if not isinstance(size, (int, np.integer)) or size < 8:
        raise ConfigError(f"texture size must be an integer >= 8, got {size!r}")
    rng = np.random.default_rng([int(seed), zlib.crc32(material.encode())])
    lum = _luminance(material, rng, int(size))
    img = tint[None, None, :] * lum[..., None] + 0.15 * (lum[..., None] - 1)
    return np.round(np.clip(img, 0.0, 1.0) * 255).astype(np.uint8)
