from __future__ import annotations

from typing import Any

import numpy as np
import pytest
import torch

from openreloc_bench.errors import ConfigError
from openreloc_bench.vision import vocabulary as voc
from openreloc_bench.vision.crops import CropSet
from openreloc_bench.vision.offline import TowerConfig
from openreloc_bench.vision.training import (
    TrainConfig,
    _average_precision,
    _instance_recall,
    caption_table,
    epoch_batches,
    repeat_factors,
    train_tower,
    training_device,
)


def _crops(categories: list[str], colours: list[str], descriptions: list[str] | None = None) -> CropSet:
    n = len(categories)
    return CropSet(
        np.zeros((n, 8, 8, 3), np.uint8),
        scene=["s"] * n,
        split=["mapping"] * n,
        frame=["0"] * n,
        object_id=list(range(1, n + 1)),
        category=categories,
        colour=colours,
        material=["wood"] * n,
        description=descriptions or [""] * n,
    )


def test_captions_vary_and_never_use_held_out_synonyms() -> None:
    c = _crops(["sofa", "dining_table"], ["red", "orange"], ["a big red couch", "a large orange dining table"])
    captions, per_crop = caption_table(c)
    sofa = {captions[i] for i in per_crop[0]}
    table = {captions[i] for i in per_crop[1]}
    assert "a photo of a sofa" in sofa and "a red wooden sofa" in sofa and "a sofa made of wood" in sofa
    assert "a big red couch" not in sofa  # the generator's description had a held-out synonym
    assert "a large orange dining table" in table and "an orange dining table" in table
    assert not any(voc.contains_held_out(t) for t in captions)
    assert len(sofa) >= 8


def test_vocabulary_is_open_and_consistent() -> None:
    assert len(voc.OBJECT_NOUNS) >= 300 and len(set(voc.OBJECT_NOUNS)) == len(voc.OBJECT_NOUNS)
    assert voc.noun("coffee_table") == "coffee table"
    assert voc.with_article("a orange mug") == "an orange mug"
    assert voc.contains_held_out("A Couch!") and not voc.contains_held_out("a light blue chair")
    for t in voc.CAPTION_TEMPLATES:  # templates themselves never contain a held-out word
        assert not voc.contains_held_out(t)


def test_average_precision() -> None:
    assert _average_precision(np.array([3.0, 2.0, 1.0]), np.array([True, False, True])) == pytest.approx(
        (1 + 2 / 3) / 2
    )
    assert _average_precision(np.array([3.0, 2.0]), np.array([False, True])) == pytest.approx(0.5)


def test_instance_recall_within_scene_and_pooled() -> None:
    keys = [1, 2, 1, 2]
    c = CropSet(
        np.zeros((4, 8, 8, 3), np.uint8),
        scene=["a", "a", "a", "a"],
        split=["mapping", "mapping", "query", "query"],
        frame=["0"] * 4,
        object_id=keys,
        category=["x"] * 4,
        colour=[""] * 4,
        material=[""] * 4,
        description=[""] * 4,
    )
    E = np.array([[1, 0], [0, 1], [1, 0], [0, 1]], np.float32)
    r = _instance_recall(E, c)
    assert r["instance_recall1_within_scene"] == 1.0 and r["instance_queries"] == 2
    swapped = _instance_recall(E[[0, 1, 3, 2]], c)
    assert swapped["instance_recall1_pooled"] == 0.0


def test_describer_vocabulary_covers_generator_categories() -> None:
    from generators.assets import CATEGORIES

    missing = sorted(c for c in CATEGORIES if voc.noun(c) not in voc.OBJECT_NOUNS)
    assert not missing, missing


@pytest.mark.parametrize("scenes_per_batch", [0, 1, 4])
def test_epoch_batches_use_each_crop_once_and_group_scenes(scenes_per_batch: int) -> None:
    rng = np.random.default_rng(0)
    scene_of = np.repeat(np.arange(10), 100)  # 10 scenes of 100 crops
    batches = epoch_batches(scene_of, 32, scenes_per_batch, rng)
    used = np.concatenate(batches)
    assert all(len(b) == 32 for b in batches) and len(batches) == len(scene_of) // 32
    assert len(np.unique(used)) == len(used)
    if scenes_per_batch:
        # k runs of one scene each; a run may straddle a scene boundary, adding one scene at most
        assert max(len(np.unique(scene_of[b])) for b in batches) <= 2 * scenes_per_batch
        assert np.mean([len(np.unique(scene_of[b])) for b in batches]) < 1.5 * scenes_per_batch
    else:
        assert np.mean([len(np.unique(scene_of[b])) for b in batches]) > 8


def test_repeat_factors_lift_rare_categories_only() -> None:
    cats = ["cabinet"] * 90 + ["bed"] * 9 + ["toaster"]
    r = repeat_factors(cats, 0.04)
    assert set(r[:90]) == {1.0} and set(r[90:99]) == {1.0}  # shares 0.90 and 0.09 are above 0.04
    assert r[99] == pytest.approx(np.sqrt(0.04 / 0.01))
    np.testing.assert_array_equal(repeat_factors(cats, 0.0), np.ones(100))


@pytest.mark.parametrize("scenes_per_batch", [0, 4])
def test_epoch_batches_repeat_crops_by_their_factor(scenes_per_batch: int) -> None:
    rng = np.random.default_rng(0)
    scene_of = np.repeat(np.arange(10), 100)
    repeats = np.ones(1000)
    repeats[:50] = 3.0  # exactly three times
    repeats[50:100] = 1.5  # once or twice, 1.5 on average
    batches = epoch_batches(scene_of, 32, scenes_per_batch, rng, repeats)
    used = np.concatenate(batches)
    counts = np.bincount(used, minlength=1000)
    assert all(len(b) == 32 for b in batches)
    assert len(used) >= 1000 + 100 + 25 - 32 - 20  # ~1125 anchors; runs that do not fill a batch are cut
    assert counts[:50].mean() > 2.5 and set(counts[50:100]) <= {0, 1, 2} and counts[50:100].mean() > 1.2
    assert counts[100:].max() <= 1


def test_epoch_batches_never_return_nothing() -> None:
    batches = epoch_batches(np.zeros(5, int), 32, 4, np.random.default_rng(0))
    assert len(batches) == 1 and sorted(batches[0]) == list(range(5))


class _FixedTexts:
    """A text tower of fixed random unit vectors per caption (MiniLM is not needed to test the loop)."""

    def __init__(self) -> None:
        self.table: dict[str, np.ndarray] = {}

    def encode(self, texts: list[str]) -> np.ndarray:
        for t in texts:
            if t not in self.table:
                v = np.random.default_rng(len(self.table)).normal(size=384).astype(np.float32)
                self.table[t] = v / np.linalg.norm(v)
        return np.stack([self.table[t] for t in texts])


def _two_view_crops() -> CropSet:
    """Six objects of three colours and shapes, four views each, at 16 px."""
    rng = np.random.default_rng(0)
    images, labels = [], []
    for obj, (cat, col, rgb) in enumerate(
        [("bed", "red", (200, 30, 30)), ("sofa", "blue", (30, 30, 200)), ("lamp", "green", (30, 200, 30))] * 2
    ):
        for view in range(4):
            im = rng.integers(0, 40, (16, 16, 3)).astype(np.uint8)
            im[3 + view : 12 + view // 2, 2 + obj : 13] = rgb
            images.append(im)
            labels.append((f"s{obj % 2}", ["mapping", "query"][view % 2], cat, col, obj))
    return CropSet(
        np.stack(images),
        scene=[x[0] for x in labels],
        split=[x[1] for x in labels],
        frame=[str(i) for i in range(len(labels))],
        object_id=[x[4] for x in labels],
        category=[x[2] for x in labels],
        colour=[x[3] for x in labels],
        material=["wood"] * len(labels),
        description=[""] * len(labels),
    )


def _train(device: str) -> tuple[Any, dict[str, Any]]:
    cfg = TrainConfig(epochs=3, pairs_per_batch=8, scenes_per_batch=0, device=device, threads=1)
    return train_tower(
        _two_view_crops(), _FixedTexts(), cfg, TowerConfig(input_size=16, widths=[8, 8, 16, 16]), log=lambda _: None
    )


@pytest.mark.parametrize(
    "device",
    ["cpu", pytest.param("cuda", marks=pytest.mark.skipif(not torch.cuda.is_available(), reason="no CUDA GPU here"))],
)
def test_train_tower_runs_on_its_device_and_returns_a_cpu_tower(device: str) -> None:
    tower, info = _train(device)
    assert all(p.device.type == "cpu" for p in tower.parameters()) and not tower.training
    losses = [h["loss"] for h in info["history"]]
    assert len(losses) == 3 and np.isfinite(losses).all() and losses[-1] < losses[0]
    if device == "cuda":  # the same initial weights and batches: the same losses up to TF32 convolutions
        np.testing.assert_allclose(losses, [h["loss"] for h in _train("cpu")[1]["history"]], rtol=1e-2)


@pytest.mark.parametrize(
    "name, message",
    [("tpu", "unknown torch device"), ("meta", "runs on cpu or cuda")]
    + ([] if torch.cuda.is_available() else [("cuda", "no CUDA GPU")]),
)
def test_training_device_refuses_what_cannot_train_here(name: str, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        training_device(name)
