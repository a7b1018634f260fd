from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
import torch

from openreloc_bench.errors import DataError
from openreloc_bench.vision import create_segmenter
from openreloc_bench.vision.learned_segment import (
    MODEL_FILE,
    BoundaryNet,
    NetConfig,
    load_weights,
    masks_from_labels,
    save_weights,
    segments_from_boundaries,
    work_size,
)
from openreloc_bench.vision.preprocess import InputError


def two_squares_boundary(h: int = 60, w: int = 80) -> np.ndarray:
    """Boundary probability 1 on the outlines of two squares, 0 elsewhere."""
    prob = np.zeros((h, w), np.float32)
    for y0, x0 in ((10, 10), (30, 45)):
        prob[y0 : y0 + 20, x0 : x0 + 20] = 1.0
        prob[y0 + 1 : y0 + 19, x0 + 1 : x0 + 19] = 0.0
    return prob


def test_regions_are_the_areas_between_boundaries_and_every_pixel_gets_one() -> None:
    prob = two_squares_boundary()
    labels = segments_from_boundaries(prob, 0.5, min_area=5)
    assert labels.min() == 1 and labels.max() == 3
    assert len(np.unique(labels[11:29, 11:29])) == 1 and len(np.unique(labels[31:49, 46:64])) == 1
    assert labels[11, 11] != labels[31, 46] != labels[0, 0]
    assert labels[10, 15] in (labels[11, 15], labels[9, 15])  # a boundary pixel joins a neighbouring region


def test_small_regions_dissolve_into_their_neighbours() -> None:
    prob = two_squares_boundary()
    prob[40:43, 5:8] = 1.0  # a 1-pixel hole inside a tiny ring
    prob[41, 6] = 0.0
    assert segments_from_boundaries(prob, 0.5, min_area=5).max() == 3
    assert segments_from_boundaries(np.ones((8, 8), np.float32), 0.5, min_area=5).tolist() == np.ones((8, 8)).tolist()


def test_masks_are_disjoint_cover_the_image_and_score_by_boundary() -> None:
    prob = two_squares_boundary()
    masks = masks_from_labels(segments_from_boundaries(prob, 0.5, 5), prob)
    cover = np.sum([m.mask for m in masks], axis=0)
    assert cover.min() == 1 and cover.max() == 1
    assert [int(m.mask.sum()) for m in masks] == sorted((int(m.mask.sum()) for m in masks), reverse=True)
    for m in masks:
        ys, xs = np.nonzero(m.mask)
        assert m.box.tolist() == [xs.min(), ys.min(), xs.max() + 1, ys.max() + 1] and 0 <= m.score <= 1


def test_work_size_keeps_aspect_and_stride() -> None:
    assert work_size(640, 480, 320, 16) == (320, 240)
    assert work_size(128, 96, 320, 16) == (128, 96)  # never upscaled
    assert work_size(1296, 968, 320, 16) == (320, 240)


@pytest.fixture(scope="module")
def weights(tmp_path_factory: pytest.TempPathFactory) -> Path:
    torch.manual_seed(0)
    cfg = NetConfig(widths=(4, 8, 8), work_width=64)
    out = tmp_path_factory.mktemp("w")
    save_weights(out, BoundaryNet(cfg), cfg, {"threshold": 0.5, "id": "test"})
    return out


def test_segmenter_loads_weights_and_returns_a_partition(weights: Path) -> None:
    seg = create_segmenter("learned", weights=str(weights), threads=1)
    rgb = np.random.default_rng(0).integers(0, 255, (48, 100, 3), dtype=np.uint8)
    masks = seg.segment(rgb)
    cover = np.sum([m.mask for m in masks], axis=0)
    assert masks and cover.shape == (48, 100) and cover.min() == 1 and cover.max() == 1
    assert seg.config()["card"] == "test" and seg.threshold == 0.5


def test_boundaries_are_the_probabilities_the_segments_were_cut_from(weights: Path) -> None:
    seg = create_segmenter("learned", weights=str(weights), threads=1)
    rgb = np.random.default_rng(1).integers(0, 255, (48, 100, 3), dtype=np.uint8)
    masks, prob = seg.segment_with_boundaries(rgb)
    np.testing.assert_array_equal(prob, seg.boundary_probability(rgb))
    assert [m.mask.tolist() for m in masks] == [m.mask.tolist() for m in seg.segment(rgb)]


@pytest.mark.parametrize(
    ("damage", "message"),
    [
        (lambda d: (d / MODEL_FILE).write_bytes((d / MODEL_FILE).read_bytes()[:100]), "checksum mismatch"),
        (lambda d: (d / "manifest.json").unlink(), "missing: no openreloc-segmenter here"),
    ],
)
def test_damaged_weights_fail_with_one_line_naming_the_file_and_how_to_train(
    weights: Path, tmp_path: Path, damage, message
) -> None:
    copy = tmp_path / "w"
    shutil.copytree(weights, copy)
    damage(copy)
    with pytest.raises(DataError, match=message) as e:
        load_weights(copy.resolve())
    assert "train-segmenter" in str(e.value) and "\n" not in str(e.value)


def test_weights_of_another_network_shape_are_refused(weights: Path, tmp_path: Path) -> None:
    cfg = NetConfig(widths=(4, 8, 16), work_width=64)
    save_weights(tmp_path, BoundaryNet(NetConfig(widths=(4, 8, 8), work_width=64)), cfg, {})
    with pytest.raises(DataError, match="weights do not fit the network"):
        load_weights(tmp_path.resolve())


@pytest.mark.parametrize("options", [{"threshold": 1.5}, {"min_area_frac": -1}, {"threads": 0}])
def test_invalid_options_are_one_line_errors(weights: Path, options: dict) -> None:
    with pytest.raises(InputError):
        create_segmenter("learned", weights=str(weights), **options)


def test_the_weights_fingerprint_follows_the_network_file(weights: Path, tmp_path: Path) -> None:
    from openreloc_bench.vision.base import segmenter_fingerprint

    shutil.copytree(weights, tmp_path / "w")
    before = segmenter_fingerprint("learned", {"weights": str(tmp_path / "w")})
    assert before == segmenter_fingerprint("learned", {"weights": str(weights)}) and len(before) == 12
    torch.manual_seed(1)
    cfg = NetConfig(widths=(4, 8, 8), work_width=64)
    save_weights(tmp_path / "w", BoundaryNet(cfg), cfg, {"threshold": 0.5})
    assert segmenter_fingerprint("learned", {"weights": str(tmp_path / "w")}) != before
    assert segmenter_fingerprint("graph", {}) == ""
