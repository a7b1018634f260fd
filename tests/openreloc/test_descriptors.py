"""Crop windows, top-k view choice and multi-view mean descriptors."""

from __future__ import annotations

import numpy as np
import pytest

from openreloc_bench.openreloc.descriptors import (
    DescriptorConfig,
    compute_descriptors,
    cross_view_recall,
    pad_box,
    top_views,
)
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
    described = compute_descriptors(seq, s, [1, 2], enc, DescriptorConfig(padding=0.0), progress=False)
    desc = described.descriptors
    assert described.crops == {1: 2, 2: 1}
    assert described.cross_view_recall in (0.0, 0.5, 1.0)  # landmark 1's two crops, each left out once
    crops = [seq[f].color[:, : w // 2] for f in (0, 1)]
    expected = enc.encode_images(crops).mean(0)
    np.testing.assert_allclose(desc[1], expected / np.linalg.norm(expected), atol=1e-6)
    assert np.linalg.norm(desc[2]) == pytest.approx(1.0, abs=1e-6)


def test_cross_view_recall_leaves_each_crop_out() -> None:
    e = np.eye(3, dtype=np.float32)
    # landmark 1: two crops along x; landmark 2: one crop along y; landmark 3: crops along z and x
    emb = np.stack([e[0], e[0], e[1], e[2], e[0]])
    owners = np.array([1, 1, 2, 3, 3])
    desc = {lid: emb[owners == lid].mean(0) / np.linalg.norm(emb[owners == lid].mean(0)) for lid in (1, 2, 3)}
    # landmark 1's crops each find the other; landmark 3's two views share nothing: left out, each is
    # nearer another landmark (or no nearer its own) than its own other view; landmark 2 has one crop
    assert cross_view_recall(emb, owners, [1, 2, 3], desc) == pytest.approx(2 / 4)
    assert cross_view_recall(emb[:1], owners[:1], [1], {1: desc[1]}) is None
