"""Crop windows, top-k view choice and multi-view mean descriptors."""

from __future__ import annotations

import numpy as np
import pytest

from openreloc_bench.openreloc.descriptors import DescriptorConfig, compute_descriptors, pad_box, top_views
from openreloc_bench.openreloc.reference_frames import Sightings
from tests.openreloc.boxworld import MeanColorEncoder, boxworld_sequence


def test_pad_box_grows_and_clips() -> None:
    assert pad_box(np.array([10, 10, 20, 30]), 0.1, 100, 100) == (9, 8, 21, 32)
    assert pad_box(np.array([0, 0, 64, 48]), 0.5, 64, 48) == (0, 0, 64, 48)


def test_top_views_prefers_visible_and_large() -> None:
    box = np.float32([[0, 0, 20, 20], [0, 0, 20, 20], [0, 0, 2, 2], [0, 0, 20, 20]])
    s = Sightings(np.array([0, 1, 2, 3]), np.array([5, 5, 5, 6]), np.array([0.2, 0.9, 1.0, 1.0]), np.full(4, 50), box)
    assert list(top_views(s, 5, DescriptorConfig(top_k=2))) == [1, 0]  # the tiny box is skipped


def test_descriptors_are_unit_means_of_crops(tmp_path) -> None:
    seq = boxworld_sequence(tmp_path, n_frames=4)
    h, w = seq.height, seq.width
    # landmark 1 seen in frames 0 and 1 on the left half, landmark 2 in frame 2
    s = Sightings(
        np.array([0, 1, 2]),
        np.array([1, 1, 2]),
        np.array([0.5, 0.6, 0.7]),
        np.full(3, 50),
        np.float32([[0, 0, w // 2, h], [0, 0, w // 2, h], [w // 2, 0, w, h]]),
    )
    enc = MeanColorEncoder()
    desc, used = compute_descriptors(seq, s, [1, 2], enc, DescriptorConfig(padding=0.0), progress=False)
    assert used == {1: 2, 2: 1}
    crops = [seq[f].color[:, : w // 2] for f in (0, 1)]
    expected = enc.encode_images(crops).mean(0)
    np.testing.assert_allclose(desc[1], expected / np.linalg.norm(expected), atol=1e-6)
    assert np.linalg.norm(desc[2]) == pytest.approx(1.0, abs=1e-6)
