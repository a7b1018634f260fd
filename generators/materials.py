"""Named colours and procedural, tileable material textures for the asset library.

Textures are made from numpy noise only (no image files), so they are redistributable and
deterministic: the same (material, rgb, seed, size, metres) always gives the same bytes, which keeps a
generated scene byte-identical across runs. Patterns are defined in metres, so a texture covering a
whole wall has the same grain as one covering a cup, and never repeats across the wall: an exactly
periodic surface would let a relocalizer explain its matches with a pose shifted by whole periods,
which no real room allows. Every texture still tiles without a seam in both image axes (spectral noise
from an FFT, stripes with a whole number of periods), as a seam would show up as a false edge.

A part may instead carry a photograph of its material (``surface="photo"``: robosuite's MIT-licensed
texture images, kept as luminance in ``asset_library/photos.npz`` and tinted like the patterns), and a
wall may be bare paint (``surface="bare"``: its material's fine grain without the metre-scale stains).
"""

from __future__ import annotations

import zlib
from functools import lru_cache
from pathlib import Path

import cv2
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


DETAIL_M = 0.5
"""World size (m) of the smallest texture. A part no larger than this gets one texture of this size; a
larger part gets one texture covering it whole (see :func:`texture_size`), so no surface repeats."""

PX_PER_M = 128
"""Texture resolution on surfaces up to :data:`MAX_TEXTURE_PX` pixels across."""

MAX_TEXTURE_PX = 1024
"""Largest texture side; a surface wider than ``MAX_TEXTURE_PX / PX_PER_M`` m gets fewer pixels per metre."""


def texture_size(metres: float) -> int:
    """Pixels across a texture covering ``metres`` (64 for one :data:`DETAIL_M` tile): a multiple of 8, as
    OpenGL reads RGB rows 4-byte aligned (a 701-pixel row would be read with a skew)."""
    return int(min(MAX_TEXTURE_PX, 8 * np.ceil(max(metres, DETAIL_M) * PX_PER_M / 8 - 1e-9)))


SURFACES = ("pattern", "photo", "bare")
"""How a procedural texture is made: the material's noise pattern, a photograph of the material, or the
pattern without its metre-scale wear (bare paint)."""

PHOTO_M = 1.5
"""Width of surface (m) one photograph covers; a part wider than this keeps its pattern (a photograph
stretched further would show its pixels, and repeated it would show the same planks twice)."""


@lru_cache(maxsize=1)
def _photos() -> tuple[np.ndarray, np.ndarray]:
    """(N, 256, 256) uint8 luminance photographs and the material of each."""
    with np.load(Path(__file__).parent / "asset_library" / "photos.npz") as data:
        return data["images"], data["materials"]


@lru_cache(maxsize=1)
def photo_materials() -> frozenset[str]:
    """The materials there are photographs of."""
    return frozenset(str(m) for m in _photos()[1])


def _seamless(image: np.ndarray) -> np.ndarray:
    """``image`` made to tile: along each axis, blended with itself shifted by half a period, with the
    shifted copy's weight rising linearly to 1 at the borders (where it is continuous across the wrap) and
    falling to 0 where its own seam lies; the blend keeps the contrast (weights normalised in norm 2)."""
    n = image.shape[0]
    w = 1 - np.abs(np.arange(n) + 0.5 - n / 2) / (n / 2)
    mean = image.mean()
    out = image - mean
    for axis, weight in ((1, w[None, :]), (0, w[:, None])):
        shifted = np.roll(out, n // 2, axis=axis)
        out = (weight * out + (1 - weight) * shifted) / np.sqrt(weight**2 + (1 - weight) ** 2)
    return out + mean


def _photo_luminance(material: str, rng: np.random.Generator, size: int, metres: float) -> np.ndarray:
    """Brightness factor around 1 from a photograph of ``material``: a random window of one of its
    photographs, as wide as ``metres`` of surface (:data:`PHOTO_M` per photograph), made to tile."""
    images, materials = _photos()
    image = images[int(rng.choice(np.flatnonzero(materials == material)))]
    side = max(8, round(image.shape[0] * metres / PHOTO_M))
    top, left = (int(v) for v in rng.integers(0, image.shape[0] - side + 1, size=2))
    crop = image[top : top + side, left : left + side].astype(np.float64)
    resized = cv2.resize(crop, (size, size), interpolation=cv2.INTER_AREA if size < side else cv2.INTER_LINEAR)
    return np.clip(_seamless(resized) / max(resized.mean(), 1.0), 0.25, 2.0)


def _spectral_noise(
    rng: np.random.Generator,
    size: int,
    beta: float,
    stretch: tuple[float, float] = (1.0, 1.0),
    metres: float = DETAIL_M,
    flat_below_m: float = DETAIL_M,
) -> np.ndarray:
    """Tileable noise with a 1/f**beta spectrum (f in cycles per metre), zero mean and unit std.

    ``stretch`` scales the (row, column) frequencies: a large row factor damps variation along
    rows faster, giving streaks that run down the columns (wood fibre, brushed metal). The spectrum is
    flat for wavelengths above ``flat_below_m``: a texture wider than that gets more of the same
    pattern, not a pattern dominated by its own size.
    """
    white = rng.standard_normal((size, size))
    fy = np.fft.fftfreq(size)[:, None] * (size / metres) * stretch[0]
    fx = np.fft.rfftfreq(size)[None, :] * (size / metres) * stretch[1]
    f = np.maximum(np.hypot(fx, fy), min(stretch) / flat_below_m)
    spec = np.fft.rfft2(white) / f**beta
    spec[0, 0] = 0.0
    out = np.fft.irfft2(spec, s=(size, size))
    return (out - out.mean()) / (out.std() + 1e-12)


def _cycles(per_tile: float, metres: float) -> int:
    """Whole periods across a texture of ``metres`` for a pattern with ``per_tile`` periods per
    :data:`DETAIL_M`: whole, so the texture still tiles without a seam."""
    return max(1, int(round(per_tile * metres / DETAIL_M)))


def _luminance(material: str, rng: np.random.Generator, size: int, metres: float) -> np.ndarray:
    """Per-pixel brightness factor around 1 that carries the material's pattern."""
    y, x = np.mgrid[0:size, 0:size] / size  # in [0, 1), one period = the whole texture

    def noise(beta: float, stretch: tuple[float, float] = (1.0, 1.0)) -> np.ndarray:
        return _spectral_noise(rng, size, beta, stretch, metres)

    if material == "wood":
        warp = noise(1.6, (0.25, 1.0))
        rings = np.sin(2 * np.pi * (_cycles(int(rng.integers(3, 7)), metres) * x + 0.35 * warp))
        fibre = noise(0.9, (6.0, 1.0))
        return 1 + 0.13 * np.sign(rings) * np.abs(rings) ** 0.5 + 0.06 * fibre
    if material == "fabric":
        n = max(4, size // 4) // 2 * 2  # even thread count keeps the over/under pattern periodic
        i, j = np.floor(x * n), np.floor(y * n)
        fx, fy = x * n % 1, y * n % 1
        shade = np.where((i + j) % 2 == 0, np.sin(np.pi * fy), np.sin(np.pi * fx))
        return 0.86 + 0.2 * shade + 0.05 * noise(1.2)
    if material == "plaster":
        return 1 + 0.05 * noise(1.3) + 0.03 * noise(0.3)
    if material == "metal":
        return 1 + 0.08 * noise(0.8, (1.0, 12.0)) + 0.03 * noise(1.8)
    if material == "ceramic":
        speckle = (rng.random((size, size)) < 0.004) * -0.15
        return 1 + 0.02 * noise(1.6) + speckle
    if material == "paper":
        return 1 + 0.04 * noise(0.2) + 0.03 * noise(1.5)
    if material == "plastic":
        return 1 + 0.015 * noise(1.0)
    if material == "glass":
        band = np.sin(np.pi * (_cycles(2, metres) * (x + y) + 0.1 * noise(2.0))) ** 8
        return 1.02 + 0.10 * band
    if material == "leather":
        grain = noise(0.7)
        return 1 - 0.12 * np.exp(-4 * np.abs(grain)) + 0.05 * noise(1.6)
    if material == "stone":
        veins = np.abs(np.sin(2 * np.pi * (_cycles(2, metres) * x + 0.4 * noise(1.8))))
        return 1 + 0.07 * noise(1.4) - 0.25 * np.exp(-12 * veins)
    if material == "rubber":
        return 1 + 0.03 * noise(0.4)
    if material == "foliage":
        c = 2 * _cycles(2, metres)  # even, so the half-rate term along y is whole too
        veins = np.abs(np.sin(2 * np.pi * c * (x + 0.5 * y) + 0.5 * noise(1.5)))
        return 0.95 + 0.18 * noise(1.1) - 0.12 * np.exp(-10 * veins)
    if material == "wax":
        return 1.04 + 0.03 * noise(1.8)
    raise ConfigError(f"unknown material '{material}' (known: {', '.join(MATERIALS)})")


def _wear(rng: np.random.Generator, size: int, metres: float) -> np.ndarray:
    """Brightness factor around 1 that varies over metres (uneven paint, stains, wear): what makes two
    places on one large surface look different, as they do in real rooms."""
    broad = _spectral_noise(rng, size, 2.0, metres=metres, flat_below_m=2.0)
    stains = _spectral_noise(rng, size, 2.5, metres=metres, flat_below_m=1.0)
    return 1 + 0.06 * broad - 0.12 * np.clip(stains - 1.0, 0.0, 1.0)


def make_texture(
    material: str,
    rgb: tuple[float, float, float],
    seed: int,
    size: int = 64,
    metres: float = DETAIL_M,
    surface: str = "pattern",
) -> np.ndarray:
    """uint8 (size, size, 3) tileable procedural texture of ``material`` tinted by sRGB ``rgb``, covering
    ``metres`` of surface.

    Deterministic in (material, rgb, seed, size, metres, surface). The pattern modulates brightness around
    the tint; a small additive term keeps the pattern visible on near-black colours. A texture wider than
    :data:`DETAIL_M` also varies at metre scale (:func:`_wear`), except bare paint. ``surface="photo"``
    takes the brightness from a photograph of the material instead, where there is one and the surface is
    no wider than :data:`PHOTO_M` (else the pattern).
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
    if not (isinstance(metres, (int, float)) and np.isfinite(metres) and metres > 0):
        raise ConfigError(f"texture width must be a positive number of metres, got {metres!r}")
    if surface not in SURFACES:
        raise ConfigError(f"unknown texture surface '{surface}' (known: {', '.join(SURFACES)})")
    rng = np.random.default_rng([int(seed), zlib.crc32(material.encode())])
    if surface == "photo" and material in photo_materials() and metres <= PHOTO_M:
        lum = _photo_luminance(material, rng, int(size), float(metres))
    else:
        lum = _luminance(material, rng, int(size), float(metres))
        if metres > DETAIL_M and surface != "bare":
            lum = lum * _wear(rng, int(size), float(metres))
    img = tint[None, None, :] * lum[..., None] + 0.15 * (lum[..., None] - 1)
    return np.round(np.clip(img, 0.0, 1.0) * 255).astype(np.uint8)
