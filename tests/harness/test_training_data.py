"""The trainings' scenes: disjoint seed ranges, the user's scenes used as they are, held-out seeds."""

from __future__ import annotations

import itertools
import json
from pathlib import Path

import pytest

from generators.spec import TRAINING_SEED_MIN, VALIDATION_SEED_MIN
from openreloc_bench.errors import ConfigError
from openreloc_bench.harness.training_data import (
    ENCODER_DATA,
    MERGER_DATA,
    SEGMENTER_DATA,
    held_out_seeds,
    scene_dirs,
    training_scene_sets,
)


def test_scene_seeds_of_each_training_seed_follow_the_recipes_offsets() -> None:
    assert ENCODER_DATA.seeds(ENCODER_DATA.train_offset, 2, 3) == [TRAINING_SEED_MIN + 2000 + i for i in range(3)]
    assert SEGMENTER_DATA.seeds(SEGMENTER_DATA.eval_offset, 0, 2) == [
        TRAINING_SEED_MIN + 700_000,
        TRAINING_SEED_MIN + 700_001,
    ]


def test_the_trainings_scenes_never_share_a_seed() -> None:
    """Every training's train and eval parts, for training seeds 0-9 of up to 1000 scenes each."""
    parts = [
        set(recipe.seeds(offset, seed, 1000))
        for recipe in (ENCODER_DATA, SEGMENTER_DATA, MERGER_DATA)
        for offset in (recipe.train_offset, recipe.eval_offset)
        for seed in range(10)
    ]
    assert all(not a & b for a, b in itertools.combinations(parts, 2))
    assert all(TRAINING_SEED_MIN <= min(p) and max(p) < VALIDATION_SEED_MIN for p in parts)


def scene(root: Path, seed: int) -> Path:
    root.mkdir(parents=True)
    (root / "scene.json").write_text(json.dumps({"seed": seed}))
    return root


def test_scenes_already_in_train_and_eval_are_used_as_they_are(tmp_path: Path) -> None:
    train = [scene(tmp_path / "train" / n, s) for n, s in (("b", 2), ("a", 1))]
    held = [scene(tmp_path / "eval" / "e", 9)]
    (tmp_path / "train" / "not-a-scene").mkdir()
    assert scene_dirs(tmp_path / "train") == sorted(train)
    assert training_scene_sets(tmp_path, ENCODER_DATA, 0, 5, 5, 64, 48, 1) == (sorted(train), held, False)
    assert held_out_seeds(sorted(train), held) == ([1, 2], [9])
    with pytest.raises(ConfigError, match="share seeds"):
        held_out_seeds(train, [scene(tmp_path / "eval" / "again", 2)])
