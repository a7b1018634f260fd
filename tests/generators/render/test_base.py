"""What both renderers share: a procedural part's texture mapping, the camera intrinsics they accept."""

from __future__ import annotations

import numpy as np
import pytest

from generators.layout.model import box_mesh, make_part
from generators.materials import DETAIL_M
from generators.render.base import TEXTURE_SCALE, TextureMapping, fovy_from_K, part_surface
from openreloc_bench import geometry


def test_fovy_needs_square_pixels_and_a_centred_principal_point() -> None:
    with pytest.raises(ValueError):
        fovy_from_K(geometry.intrinsics(100, 100, 10, 10), 160, 120)


def test_texture_mapping_covers_a_part_once_with_its_own_placement() -> None:
    wall = make_part([box_mesh((0, 0, 0), (5.0, 0.1, 2.7))], "plaster", "white", seed=11)
    v, _, uv, _, image = part_surface(wall)
    mapping = TextureMapping.of(wall)
    assert mapping == TextureMapping.of(make_part([box_mesh((0, 0, 0), (5.0, 0.1, 2.7))], "plaster", "white", 11))
    assert image.shape[:2] == (mapping.size, mapping.size) and mapping.metres * mapping.scale >= np.hypot(5.0, 2.7)
    assert np.all(uv.max(axis=0) - uv.min(axis=0) <= 1.0 + 1e-9)  # the wall never shows its texture twice
    other = TextureMapping.of(make_part([box_mesh((0, 0, 0), (5.0, 0.1, 2.7))], "plaster", "white", 12))
    assert (other.rotation, other.offset) != (mapping.rotation, mapping.offset)  # surfaces do not line up
    cup = TextureMapping.of(make_part([box_mesh((0, 0, 0), (0.08, 0.08, 0.1))], "ceramic", "white", 3))
    assert cup.metres == DETAIL_M and cup.size == 64
    lo, hi = TEXTURE_SCALE
    assert lo <= mapping.scale <= hi and lo <= cup.scale <= hi
