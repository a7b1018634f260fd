from __future__ import annotations

import json
from pathlib import Path

import pytest

from openreloc_bench.cli import main
from openreloc_bench.reconstruction.instance_repair import FEATURES, MergeClassifier
from tests.openreloc.boxworld import ROOM, write_boxworld
from tests.reconstruction.test_instance_repair import PARTS


@pytest.fixture(scope="module")
def data(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Training scenes with an object in parts (train/) and a held-out one (eval/)."""
    root = tmp_path_factory.mktemp("merger-data")
    for split in ("train", "eval"):
        write_boxworld(root / split / "s0", n_frames=16, hw=(96, 128), boxes=PARTS, objects=ROOM)
    return root


# clustering and fill keep the 16-view room whole but for the shelf's parts (affinity grouping needs more views)
CLUSTERED = ["--set", "mapping.instances.grouping=clustering", "--set", "mapping.instances.repair.fill=true"]


def test_train_merger_writes_a_classifier_with_its_card(data: Path, tmp_path: Path, capsys) -> None:
    assert (
        main(["train-merger", "--out", str(tmp_path / "m"), "--data", str(data), "--segmenter", "gt", *CLUSTERED]) == 0
    )
    clf = MergeClassifier.load(tmp_path / "m")
    assert set(clf.card["weights"]) == set(FEATURES)
    assert clf.card["train_one_object"] == 2 and clf.card["held_out"]["pairs"] > 5
    assert "training pairs" in capsys.readouterr().out
    assert json.loads((tmp_path / "m" / "merger.json").read_text())["features"] == list(FEATURES)


@pytest.mark.parametrize(
    ("extra", "message"),
    [(["--scenes", "0"], "--scenes must be >= 1"), (["--segmenter", "bogus"], "unknown segmenter 'bogus'")],
)
def test_train_merger_bad_arguments(data: Path, tmp_path: Path, capsys, extra: list[str], message: str) -> None:
    assert main(["train-merger", "--out", str(tmp_path / "m"), "--data", str(data), *extra]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err


def test_train_merger_reads_the_method_config(data: Path, tmp_path: Path) -> None:
    args = ["--data", str(data), "--set", "segmenter=gt", "--set", "mapping.instances.grouping=affinity"]
    assert main(["train-merger", "--out", str(tmp_path / "m"), *args]) == 0
    assert MergeClassifier.load(tmp_path / "m").card["grouping"] == "affinity"
    assert main(["train-merger", "--out", str(tmp_path / "m2"), *args, "--set", "mapping.instances.grouping=x"]) == 2
