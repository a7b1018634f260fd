"""The encoder's training: crops cut once and cached per scenes and sampling, cut again when damaged."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "vision"))
from vision_scenes import write_shapes_scene  # noqa: E402

from openreloc_bench.harness.train_encoder import EncoderTrainingConfig, cached_crops  # noqa: E402
from openreloc_bench.vision.offline import TowerConfig  # noqa: E402
from openreloc_bench.vision.training import TrainConfig  # noqa: E402


def test_crops_are_cached_per_scenes_and_sampling(tmp_path: Path) -> None:
    dirs = [write_shapes_scene(tmp_path / "data" / "train" / f"t{i}", seed=i) for i in range(2)]
    cfg = EncoderTrainingConfig(
        out=tmp_path / "w", data=tmp_path / "data", scenes=2, eval_scenes=1, views=2, width=64, height=48,
        workers=1, crop_segmenter="", init=None, train=TrainConfig(), tower=TowerConfig(),
    )  # fmt: skip
    crops = cached_crops(cfg, "train", dirs, 0, None)
    (cache,) = (tmp_path / "w" / "crops").iterdir()
    assert cache.name.startswith("train-") and len(crops) > 0
    again = cached_crops(cfg, "train", dirs, 0, None)
    assert again.instance_keys == crops.instance_keys and np.array_equal(again.images, crops.images)
    cache.write_bytes(b"damaged")
    assert cached_crops(cfg, "train", dirs, 0, None).instance_keys == crops.instance_keys  # cut again
    cached_crops(cfg, "train", dirs, 1, None)  # another sampling: another cache
    assert len(list((tmp_path / "w" / "crops").iterdir())) == 2
