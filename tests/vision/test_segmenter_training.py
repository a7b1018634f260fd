from __future__ import annotations

import shutil
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

sys.path.insert(0, str(Path(__file__).parent))
from vision_scenes import write_shapes_scene  # noqa: E402

from openreloc_bench.errors import ConfigError  # noqa: E402
from openreloc_bench.vision import segmenter_training as training  # noqa: E402
from openreloc_bench.vision.learned_segment import NetConfig, save_weights  # noqa: E402
from openreloc_bench.vision.segmenter_training import (  # noqa: E402
    SegTrainConfig,
    augment,
    average_precision,
    boundary_map,
    frame_metrics,
    load_frames,
    summarize,
    train_boundary_net,
)

NET = NetConfig(widths=(8, 16, 16), work_width=128)


def test_boundary_map_marks_both_sides_of_every_id_change() -> None:
    ids = np.zeros((5, 6), np.int32)
    ids[1:4, 2:5] = 7
    b = boundary_map(ids)
    assert b[2, 3] == 0 and b[0, 0] == 0  # interiors
    assert b[2, 1] == 1 and b[2, 2] == 1  # left edge, both sides
    assert b[0, 3] == 1 and b[1, 3] == 1 and b[4, 3] == 1 and b[3, 3] == 1


def gt_frame() -> np.ndarray:
    gt = np.ones((40, 40), np.int32)  # 1 = wall
    gt[5:20, 5:20] = 2
    gt[25:35, 22:38] = 3
    return gt


def test_perfect_segments_score_one_and_errors_are_named() -> None:
    gt = gt_frame()
    perfect = frame_metrics(gt, gt, None, 0.01)
    assert perfect["best_iou"] == [1.0, 1.0, 1.0] and not any(perfect["split"] + perfect["swallowed"])
    assert summarize([perfect])["ap50"] == pytest.approx(1.0)
    split = gt.copy()
    split[5:20, 12:20] = 9  # object 2 cut in two halves
    s = frame_metrics(split, gt, None, 0.01)
    assert s["split"][1] and not s["split"][2] and s["best_iou"][1] < 0.6
    merged = gt.copy()
    merged[merged == 3] = 1  # object 3 swallowed by the wall
    m = frame_metrics(merged, gt, None, 0.01)
    assert m["swallowed"][2] and not m["swallowed"][1]
    assert summarize([m])["ap50"] < summarize([perfect])["ap50"]


def test_small_objects_are_neither_counted_nor_penalised() -> None:
    gt = gt_frame()
    gt[0:2, 0:2] = 5  # 4 px, under 1% of the image
    stats = frame_metrics(gt, gt, None, 0.01)
    assert stats["n_gt"] == 3 and sum(stats["ignore"]) == 1
    assert average_precision([stats]) == pytest.approx(1.0)


def test_augment_returns_a_crop_and_its_boundaries() -> None:
    rng = np.random.default_rng(0)
    rgb = rng.integers(0, 255, (48, 64, 3), dtype=np.uint8)
    img, b = augment(rgb, np.kron(np.arange(12).reshape(3, 4), np.ones((16, 16), np.int32)), 32, 1.0, rng)
    assert img.shape == (32, 32, 3) and img.dtype == np.uint8 and b.shape == (32, 32) and set(np.unique(b)) <= {0, 1}
    assert img.mean() < rgb.mean()  # darkened (dark_prob 1)


@pytest.fixture(scope="module")
def frames(tmp_path_factory: pytest.TempPathFactory):
    root = tmp_path_factory.mktemp("shapes")
    dirs = [write_shapes_scene(root / f"s{i}", seed=i, frames=3, hw=(64, 96)) for i in range(2)]
    return load_frames(dirs, NET, per_split=3, rng=np.random.default_rng(0), progress=False)


def test_frames_do_not_depend_on_the_reading_threads(tmp_path: Path) -> None:
    dirs = [write_shapes_scene(tmp_path / f"s{i}", seed=i, frames=3, hw=(64, 96)) for i in range(2)]
    one = load_frames(dirs, NET, per_split=2, rng=np.random.default_rng(3), progress=False, threads=1)
    four = load_frames(dirs, NET, per_split=2, rng=np.random.default_rng(3), progress=False, threads=4)
    assert np.array_equal(one.rgb, four.rgb) and np.array_equal(one.ids, four.ids) and one.scene == four.scene
    assert one.scene == ["s0"] * 6 + ["s1"] * 6  # 3 splits x 2 frames per scene, in scene order


def test_training_lowers_the_loss(frames) -> None:
    cfg = SegTrainConfig(steps=60, batch=4, crop=48, lr=1e-2, warmup_steps=5, threads=1, checkpoint_every=20)
    _, info = train_boundary_net(frames, NET, cfg, log=lambda m: None)
    assert info["history"][-1]["loss"] < info["history"][0]["loss"]


def test_fine_tuning_starts_from_the_given_weights(frames, tmp_path: Path) -> None:
    cfg = SegTrainConfig(steps=60, batch=4, crop=48, lr=1e-2, warmup_steps=5, threads=1, checkpoint_every=20)
    trained, info = train_boundary_net(frames, NET, cfg, log=lambda m: None)
    save_weights(tmp_path / "w", trained, NET, {"id": info["recipe"]})
    short = SegTrainConfig(steps=20, batch=4, crop=48, lr=1e-3, warmup_steps=5, threads=1, checkpoint_every=20)
    _, scratch = train_boundary_net(frames, NET, short, log=lambda m: None)
    _, tuned = train_boundary_net(frames, NET, short, log=lambda m: None, init=tmp_path / "w")
    assert tuned["init"] == info["recipe"] and tuned["recipe"] != scratch["recipe"]
    assert tuned["history"][0]["loss"] < scratch["history"][0]["loss"]
    with pytest.raises(ConfigError, match="is not the one to train"):
        train_boundary_net(frames, NetConfig(widths=(8, 8, 16), work_width=128), short, init=tmp_path / "w")


def test_crop_processes_do_not_change_the_weights(frames) -> None:
    cfg = SegTrainConfig(steps=3, batch=2, crop=32, warmup_steps=1, threads=1, checkpoint_every=2)
    inline, info = train_boundary_net(frames, NET, cfg, log=lambda m: None)
    workers = SegTrainConfig(**{**cfg.__dict__, "loader_workers": 2})
    ahead, info_ahead = train_boundary_net(frames, NET, workers, log=lambda m: None)
    assert info["recipe"] == info_ahead["recipe"]
    for a, b in zip(inline.state_dict().values(), ahead.state_dict().values()):
        assert torch.equal(a, b)


def test_max_seconds_stops_the_run_and_says_where(frames) -> None:
    cfg = SegTrainConfig(steps=50, batch=2, crop=32, threads=1, checkpoint_every=20, max_seconds=1e-9)
    logs: list[str] = []
    _, info = train_boundary_net(frames, NET, cfg, log=logs.append)
    assert info["steps_run"] == 1 and info["history"][-1]["step"] == 1
    assert logs == ["stopped at step 1 of 50: max_seconds 1e-09 reached"]
    with pytest.raises(ValueError, match="'loader_workers' must be >= 0"):
        SegTrainConfig(loader_workers=-1)


def test_a_resumed_run_ends_with_the_weights_of_an_uninterrupted_one(frames, tmp_path: Path, monkeypatch) -> None:
    """Kill after step 4 (the checkpoint then is what a killed run leaves); the rerun resumes there."""
    cfg = SegTrainConfig(steps=6, batch=2, crop=32, warmup_steps=2, threads=1, checkpoint_every=2)
    saved = training._save_checkpoint

    def keep_step_4(path: Path, *args) -> None:
        saved(path, *args)
        if args[2] == 4 and path.name == "ckpt.pt":
            shutil.copy(path, tmp_path / "killed.pt")

    monkeypatch.setattr(training, "_save_checkpoint", keep_step_4)
    whole, _ = train_boundary_net(frames, NET, cfg, tmp_path / "ckpt.pt", log=lambda m: None)
    logs: list[str] = []
    resumed, _ = train_boundary_net(frames, NET, cfg, tmp_path / "killed.pt", log=logs.append)
    assert logs == ["resumed from step 4 of 6"]
    for a, b in zip(whole.state_dict().values(), resumed.state_dict().values()):
        assert torch.equal(a, b)
    other = SegTrainConfig(**{**cfg.__dict__, "lr": 1e-3})
    train_boundary_net(frames, NET, other, tmp_path / "killed.pt", log=logs.append)
    assert logs[-1] == "checkpoint is from another recipe: starting over"
