from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "vision"))
from vision_scenes import write_shapes_scene  # noqa: E402

from openreloc_bench.cli import main  # noqa: E402
from openreloc_bench.vision import create_encoder  # noqa: E402


def train(data: Path, out: Path) -> int:
    return main(["train-encoder", "--out", str(out), "--data", str(data), "--epochs", "1", "--threads", "1"])


@pytest.fixture(scope="module")
def trained(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """(data folder of tiny train/eval scenes, weights trained on them once)."""
    root = tmp_path_factory.mktemp("train-encoder")
    for i in range(3):
        write_shapes_scene(root / "data" / "train" / f"t{i}", seed=i)
    write_shapes_scene(root / "data" / "eval" / "e0", seed=100)
    assert train(root / "data", root / "w") == 0
    return root / "data", root / "w"


def test_train_encoder_end_to_end_on_tiny_scenes(trained: tuple[Path, Path]) -> None:
    out = trained[1]
    cfg = json.loads((out / "config.json").read_text())
    assert cfg["tower"]["dim"] == 384 and cfg["data"]["train_crops"] > 0
    assert cfg["data"]["categories"] and len(cfg["history"]) == 1
    ev = json.loads((out / "evaluation.json").read_text())
    assert 0.0 <= ev["zero_shot_top1"] <= 1.0 and "instance_recall1_within_scene" in ev
    enc = create_encoder("offline", weights=str(out))
    x = enc.encode_images([np.zeros((20, 20, 3), np.uint8), np.full((9, 30), 200, np.uint8)])
    assert x.shape == (2, 384)
    np.testing.assert_allclose(np.linalg.norm(x, axis=1), 1, atol=1e-5)
    t = enc.encode_texts(["a red box"])
    assert t.shape == (1, 384)


def test_train_encoder_reproduces_its_weights(trained: tuple[Path, Path], tmp_path: Path) -> None:
    """Same data, seed and threads: the same bytes (the shipped weights are retrained this way)."""
    data, first = trained
    assert train(data, tmp_path / "again") == 0
    assert (tmp_path / "again" / "image_tower.pt").read_bytes() == (first / "image_tower.pt").read_bytes()
    assert json.loads((tmp_path / "again" / "evaluation.json").read_text()) == json.loads(
        (first / "evaluation.json").read_text()
    )


def test_train_encoder_bad_arguments(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["train-encoder", "--out", str(tmp_path), "--epochs", "0"]) == 2
    assert "must be >= 1" in capsys.readouterr().err


def test_train_encoder_refuses_a_device_it_cannot_use(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["train-encoder", "--out", str(tmp_path / "w"), "--device", "tpu"]) == 2
    assert "unknown torch device" in capsys.readouterr().err
    assert not (tmp_path / "w").exists()  # refused before generating anything


@pytest.mark.parametrize(
    ("bad", "message"),
    [(["--crop-segmenter", "bogus"], "unknown segmenter 'bogus'"), (["--init", "missing"], "weights not found")],
)
def test_a_wrong_segmenter_or_starting_weights_fail_before_any_scene(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], bad: list[str], message: str
) -> None:
    tiny = ["--scenes", "1", "--eval-scenes", "1", "--width", "16", "--height", "16"]  # quick, were it generated
    assert main(["train-encoder", "--out", str(tmp_path / "w"), *tiny, *bad]) == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "w").exists()


def test_training_scenes_stay_out_of_the_validation_range(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # --seed 9000: the scene seeds would start at TRAINING_SEED_MIN + 9,000,000 = VALIDATION_SEED_MIN
    assert (
        main(["train-encoder", "--out", str(tmp_path / "w"), "--seed", "9000", "--scenes", "1", "--eval-scenes", "1"])
        == 2
    )
    assert "outside the training range" in capsys.readouterr().err
    assert not (tmp_path / "w" / "scenes" / "train").exists()  # refused before generating anything


def test_defaults_are_the_recipe_of_the_shipped_weights() -> None:
    """``train-encoder --out DIR`` must retrain what ships, so its defaults follow the weights' config."""
    import argparse

    from openreloc_bench.commands.train_encoder import add_arguments
    from openreloc_bench.vision.offline import WEIGHTS_DIR

    parser = argparse.ArgumentParser()
    add_arguments(parser)
    args = parser.parse_args(["--out", "unused"])
    shipped = json.loads((WEIGHTS_DIR / "config.json").read_text())
    train, data = shipped["train"], shipped["data"]
    assert (args.seed, args.epochs, args.threads) == (train["seed"], train["epochs"], train["threads"])
    assert (args.pairs_per_batch, args.scenes_per_batch) == (train["pairs_per_batch"], train["scenes_per_batch"])
    assert args.instance_weight == train["instance_weight"]
    assert args.device == train.get("device", "cpu")
    assert (args.scenes, args.eval_scenes) == (len(data["train_scenes"]), len(data["eval_scenes"]))
    assert (args.views, [args.width, args.height]) == (data["views_per_object_and_split"], data["render_size"])
    assert args.input_size == shipped["tower"]["input_size"]


def test_fine_tuning_on_a_segmenters_crops_reports_before_and_after(trained: tuple[Path, Path], tmp_path: Path) -> None:
    data, first = trained
    argv = ["--init", str(first), "--crop-segmenter", "learned"]
    assert (
        main(
            [
                "train-encoder",
                "--out",
                str(tmp_path / "ft"),
                "--data",
                str(data),
                "--epochs",
                "1",
                "--threads",
                "1",
                *argv,
            ]
        )
        == 0
    )
    ev = json.loads((tmp_path / "ft" / "evaluation.json").read_text())
    cfg = json.loads((tmp_path / "ft" / "config.json").read_text())
    assert cfg["data"]["crops_cut_by"] == "learned" and cfg["data"]["init"] == str(first)
    # the same held-out crops scored before and after (which metrics exist depends on the crops the
    # shipped segmenter cuts from these toy scenes, not on the fine-tuning)
    assert "zero_shot_top1" in ev["init"] and set(ev["init"]) == set(ev) - {"init"}


def test_fine_tuning_from_another_tower_shape_is_refused(trained: tuple[Path, Path], tmp_path: Path, capsys) -> None:
    data, first = trained
    argv = [
        "train-encoder",
        "--out",
        str(tmp_path / "ft"),
        "--data",
        str(data),
        "--init",
        str(first),
        "--input-size",
        "24",
    ]
    assert main(argv) == 2
    assert "differs from this run's" in capsys.readouterr().err
