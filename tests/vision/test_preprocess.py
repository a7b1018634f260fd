from __future__ import annotations

import numpy as np
import pytest

from openreloc_bench.vision.preprocess import (
    InputError,
    as_rgb_uint8,
    check_crops,
    check_mask,
    mask_box,
    object_crop,
    square_crop,
    touches_border,
)


@pytest.mark.parametrize(
    "img",
    [
        np.full((5, 7), 128, np.uint8),
        np.full((5, 7, 1), 128, np.uint8),
        np.full((5, 7, 4), 128, np.uint8),
        np.full((5, 7, 3), 128 / 255, np.float32),
        np.full((5, 7, 3), 128.0, np.float64),
        np.full((5, 7, 3), 128 * 257, np.uint16),
    ],
)
def test_as_rgb_uint8_coerces(img: np.ndarray) -> None:
    out = as_rgb_uint8(img)
    assert out.shape == (5, 7, 3) and out.dtype == np.uint8
    assert np.all(out == 128)


@pytest.mark.parametrize(
    "img, msg",
    [
        (np.zeros((0, 4, 3), np.uint8), "empty"),
        (np.zeros((4, 4, 5), np.uint8), "expected an RGB"),
        (np.zeros((2, 4, 4, 3), np.uint8), "expected an RGB"),
        (np.full((4, 4, 3), np.nan), "NaN"),
        (np.zeros((4, 4, 3), bool), "pixel type"),
    ],
)
def test_as_rgb_uint8_rejects(img: np.ndarray, msg: str) -> None:
    with pytest.raises(InputError, match=msg):
        as_rgb_uint8(img)


def test_check_mask_zero_area_and_shape() -> None:
    with pytest.raises(InputError, match="zero-area"):
        check_mask(np.zeros((4, 4), bool), (4, 4))
    with pytest.raises(InputError, match="does not match"):
        check_mask(np.ones((3, 4), bool), (4, 4))


def test_check_crops_names_index_and_rejects_single_image() -> None:
    with pytest.raises(InputError, match="crop 1"):
        check_crops([np.zeros((3, 3, 3), np.uint8), np.zeros((3, 0, 3), np.uint8)])
    with pytest.raises(InputError, match="single image"):
        check_crops(np.zeros((3, 3, 3), np.uint8))


def test_square_crop_keeps_position_at_border() -> None:
    img = np.zeros((20, 20, 3), np.uint8)
    img[0:4, 0:4] = 255
    m = img[..., 0] > 0
    assert mask_box(m).tolist() == [0, 0, 4, 4]
    crop = square_crop(img, mask_box(m), scale=2.0)
    assert crop.shape == (8, 8, 3)
    # the crop is centred on the object; the out-of-image pixels are zero-filled
    assert crop[2:6, 2:6].min() == 255 and crop[:2].max() == 0 and crop[6:].max() == 0
    crop2 = object_crop(img, m)
    assert crop2.shape[0] == crop2.shape[1] >= 4


@pytest.mark.parametrize(
    ("rows", "cols", "cut"),
    [
        (slice(2, 5), slice(3, 6), False),
        (slice(0, 3), slice(3, 6), True),
        (slice(2, 5), slice(7, 10), True),
        (slice(7, 10), slice(3, 6), True),
        (slice(2, 5), slice(0, 1), True),
    ],
)
def test_touches_border_iff_the_mask_reaches_an_image_edge(rows: slice, cols: slice, cut: bool) -> None:
    mask = np.zeros((10, 10), bool)
    mask[rows, cols] = True
    assert touches_border(mask) is cut
