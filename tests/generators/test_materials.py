"""Procedural textures: shape, determinism, tiling, tinting, and clear errors."""

from __future__ import annotations

import numpy as np
import pytest

from generators.materials import (
    COLOURS,
    DETAIL_M,
    MATERIALS,
    PHOTO_M,
    PX_PER_M,
    make_texture,
    photo_materials,
    texture_size,
)
from openreloc_bench.errors import ConfigError

REQUIRED_MATERIALS = ("wood", "fabric", "plaster", "metal", "ceramic", "paper", "plastic", "glass", "leather", "stone")
REQUIRED_COLOURS = (
    "red",
    "blue",
    "white",
    "black",
    "grey",
    "brown",
    "beige",
    "green",
    "yellow",
    "orange",
    "pink",
    "purple",
)


def test_required_materials_and_colours_exist():
    assert set(REQUIRED_MATERIALS) <= set(MATERIALS)
    assert set(REQUIRED_COLOURS) <= set(COLOURS)
    for name, rgb in COLOURS.items():
        assert len(rgb) == 3 and all(0.0 <= c <= 1.0 for c in rgb), name


@pytest.mark.parametrize("material", MATERIALS)
def test_texture_shape_dtype_and_determinism(material):
    a = make_texture(material, COLOURS["red"], seed=3, size=32)
    assert a.shape == (32, 32, 3) and a.dtype == np.uint8
    assert np.array_equal(a, make_texture(material, COLOURS["red"], seed=3, size=32))
    assert not np.array_equal(a, make_texture(material, COLOURS["red"], seed=4, size=32))
    blue = make_texture(material, COLOURS["blue"], seed=3, size=32)
    assert blue[..., 2].mean() > a[..., 2].mean() and a[..., 0].mean() > blue[..., 0].mean()
    assert make_texture(material, COLOURS["grey"], seed=0).shape == (64, 64, 3)


@pytest.mark.parametrize("material", MATERIALS)
def test_texture_tiles_without_seam(material):
    """The wrap-around column/row step is no larger than typical neighbour steps (no seam)."""
    t = make_texture(material, COLOURS["beige"], seed=1, size=64).astype(float).mean(axis=2)
    for axis in (0, 1):
        inner = np.abs(np.diff(t, axis=axis)).mean()
        wrap = np.abs(np.take(t, 0, axis=axis) - np.take(t, -1, axis=axis)).mean()
        assert wrap <= 3 * inner + 2.0, (material, axis, wrap, inner)


def _shift_correlation(t: np.ndarray, px: int) -> float:
    a, b = t[:, :-px] - t[:, :-px].mean(), t[:, px:] - t[:, px:].mean()
    return float((a * b).sum() / np.sqrt((a * a).sum() * (b * b).sum()))


@pytest.mark.parametrize("material", MATERIALS)
def test_wide_texture_does_not_repeat_and_still_tiles(material):
    """A texture covering 2 m is not its 0.5 m pattern repeated (which correlates 1.0 with itself shifted
    by 0.5 m), and wraps around without a seam like the small one."""
    t = make_texture(material, COLOURS["beige"], seed=2, size=texture_size(2.0), metres=2.0).astype(float).mean(axis=2)
    assert t.shape == (2 * PX_PER_M * 1, 2 * PX_PER_M * 1) and texture_size(DETAIL_M) == 64
    assert _shift_correlation(t, int(DETAIL_M * PX_PER_M)) < 0.5
    for axis in (0, 1):
        inner = np.abs(np.diff(t, axis=axis)).mean()
        wrap = np.abs(np.take(t, 0, axis=axis) - np.take(t, -1, axis=axis)).mean()
        assert wrap <= 3 * inner + 2.0, (material, axis, wrap, inner)


def test_materials_have_distinct_patterns():
    stds = {m: make_texture(m, COLOURS["grey"], seed=0).astype(float).std() for m in MATERIALS}
    assert stds["plastic"] < stds["wood"] and stds["plastic"] < stds["fabric"] and stds["plastic"] < stds["stone"]
    assert stds["wood"] > 5 and stds["fabric"] > 5


@pytest.mark.parametrize(
    ("kwargs", "word"),
    [
        ({"material": "unobtainium"}, "unobtainium"),
        ({"rgb": (1.5, 0.0, 0.0)}, "colour"),
        ({"rgb": (0.1, 0.2)}, "colour"),
        ({"seed": -1}, "seed"),
        ({"size": 2}, "size"),
        ({"metres": 0.0}, "metres"),
        ({"metres": float("nan")}, "metres"),
    ],
)
def test_bad_texture_arguments_raise_config_error(kwargs, word):
    args = {"material": "wood", "rgb": (0.5, 0.5, 0.5), "seed": 0, "size": 16} | kwargs
    with pytest.raises(ConfigError, match=word):
        make_texture(**args)


@pytest.mark.parametrize("material", sorted(photo_materials()))
def test_photographed_texture_is_tinted_and_tiles(material):
    """A photograph of the material, not its pattern; tinted like the pattern; seamless; deterministic."""
    photo = make_texture(material, COLOURS["blue"], seed=5, size=128, metres=1.0, surface="photo")
    pattern = make_texture(material, COLOURS["blue"], seed=5, size=128, metres=1.0)
    assert not np.array_equal(photo, pattern)
    assert np.array_equal(photo, make_texture(material, COLOURS["blue"], seed=5, size=128, metres=1.0, surface="photo"))
    assert photo[..., 2].mean() > photo[..., 0].mean()  # blue stays blue
    t = photo.astype(float).mean(axis=2)
    for axis in (0, 1):
        inner = np.abs(np.diff(t, axis=axis)).mean()
        wrap = np.abs(np.take(t, 0, axis=axis) - np.take(t, -1, axis=axis)).mean()
        assert wrap <= 3 * inner + 2.0, (material, axis, wrap, inner)


def test_photographs_only_where_there_is_one_and_the_surface_fits():
    """Materials without photographs, and surfaces wider than one photograph, keep their pattern."""
    assert "wood" in photo_materials() and "paper" not in photo_materials()
    args = (COLOURS["red"], 2, texture_size(2 * PHOTO_M), 2 * PHOTO_M)
    assert np.array_equal(make_texture("wood", *args, surface="photo"), make_texture("wood", *args))
    assert np.array_equal(
        make_texture("paper", COLOURS["red"], 2, 64, surface="photo"), make_texture("paper", COLOURS["red"], 2, 64)
    )


def test_bare_paint_drops_only_the_metre_scale_wear():
    wide = (COLOURS["beige"], 4, texture_size(3.0), 3.0)
    bare, worn = make_texture("plaster", *wide, surface="bare"), make_texture("plaster", *wide)
    assert not np.array_equal(bare, worn) and bare.astype(float).std() < worn.astype(float).std()
    small = (COLOURS["beige"], 4, 64, DETAIL_M)
    assert np.array_equal(make_texture("plaster", *small, surface="bare"), make_texture("plaster", *small))
    with pytest.raises(ConfigError, match="unknown texture surface 'glossy'"):
        make_texture("plaster", *small, surface="glossy")
