from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "vision"))
from vision_scenes import write_shapes_scene  # noqa: E402

from openreloc_bench.cli import main  # noqa: E402
from openreloc_bench.vision import create_segmenter  # noqa: E402


def train(data: Path, out: Path, *extra: str) -> int:
    argv = ["train-segmenter", "--out", str(out), "--data", str(data), "--steps", "4", "--batch", "2"]
    return main([*argv, "--crop", "48", "--threads", "1", "--per-split", "2", *extra])


@pytest.fixture(scope="module")
def trained(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """(data folder of tiny train/eval scenes, weights trained on them once)."""
    root = tmp_path_factory.mktemp("train-segmenter")
    for i in range(2):
        write_shapes_scene(root / "data" / "train" / f"t{i}", seed=i)
    write_shapes_scene(root / "data" / "eval" / "e0", seed=100)
    assert train(root / "data", root / "w") == 0
    return root / "data", root / "w"


def test_train_segmenter_writes_weights_with_a_card(trained: tuple[Path, Path]) -> None:
    card = json.loads((trained[1] / "card.json").read_text())
    assert card["train"]["steps"] == 4 and card["threshold"] in [float(t) for t in card["thresholds"]]
    assert {"mean_best_iou", "ap50", "over_segmentation", "under_segmentation"} <= set(card["held_out"])
    assert card["data"]["train_seeds"] == [0, 1] and card["data"]["eval_seeds"] == [100]
    seg = create_segmenter("learned", weights=str(trained[1]), threads=1)
    masks = seg.segment(np.zeros((96, 128, 3), np.uint8))
    assert np.sum([m.mask for m in masks], axis=0).min() == 1


def test_train_segmenter_reproduces_its_weights(trained: tuple[Path, Path], tmp_path: Path) -> None:
    data, first = trained
    assert train(data, tmp_path / "again") == 0
    assert (tmp_path / "again" / "model.pt").read_bytes() == (first / "model.pt").read_bytes()


def test_train_segmenter_fine_tunes_and_takes_a_network_shape(trained: tuple[Path, Path], tmp_path: Path) -> None:
    data, first = trained
    assert train(data, tmp_path / "tuned", "--init", str(first)) == 0
    card = json.loads((tmp_path / "tuned" / "card.json").read_text())
    assert card["init"] == json.loads((first / "card.json").read_text())["id"]
    assert train(data, tmp_path / "wide", "--widths", "8,16,24", "--work-width", "64") == 0
    assert json.loads((tmp_path / "wide" / "card.json").read_text())["net"] == {"widths": [8, 16, 24], "work_width": 64}


def test_train_segmenter_crop_processes_give_the_same_weights(trained: tuple[Path, Path], tmp_path: Path) -> None:
    data, first = trained
    assert train(data, tmp_path / "ahead", "--loader-workers", "2") == 0
    assert (tmp_path / "ahead" / "model.pt").read_bytes() == (first / "model.pt").read_bytes()


@pytest.mark.parametrize(
    ("extra", "message"),
    [(["--steps", "0"], "'steps' must be >= 1"), (["--crop", "50"], "multiple of the network's stride"),
     (["--device", "cuda:7"], "cuda"), (["--per-split", "0"], "--per-split must be >= 1"),
     (["--widths", "8,x"], "--widths '8,x'"), (["--widths", "8"], "needs >= 2 positive channel counts"),
     (["--work-width", "16"], "'work_width' must be >= 32"), (["--loader-workers", "-1"], "'loader_workers' must be >= 0"),
     (["--max-minutes", "-1"], "'max_seconds' must be >= 0")],
)  # fmt: skip
def test_train_segmenter_bad_arguments(trained: tuple[Path, Path], tmp_path: Path, capsys, extra, message) -> None:
    assert train(trained[0], tmp_path / "w", *extra) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err
    assert not (tmp_path / "w").exists()  # refused before any work
