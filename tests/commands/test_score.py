"""``openreloc-bench score``: outside pose files, both layouts, missing queries and malformed files."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "harness"))
from harness_test_methods import make_scene, perturb  # noqa: E402

from openreloc_bench.cli import main  # noqa: E402
from openreloc_bench.data.results import RESULTS_HEADER, write_results  # noqa: E402
from openreloc_bench.data.scene import Scene  # noqa: E402


@pytest.fixture(scope="module")
def data(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("data")
    make_scene(root, "s1", n_query=4, splits=("query", "query_light1"), seed=5)
    return root


def estimates(data: Path, split: str, noise_m: float) -> dict[str, np.ndarray]:
    seq = Scene(data / "s1").sequence(split)
    return {n: perturb(T, n, noise_m, 1.0) for n, T in zip(seq.names, seq.poses)}


@pytest.mark.parametrize("layout", ["per-scene", "per-split"])
def test_scores_both_layouts_and_counts_missing_queries_as_failures(
    data: Path, tmp_path: Path, layout: str, capsys, monkeypatch
) -> None:
    sub = tmp_path / "mysub"
    est = {**estimates(data, "query", 0.3), **estimates(data, "query_light1", 0.1)}
    del est["query/000003"]
    if layout == "per-scene":
        write_results(sub / "s1.txt", est)
    else:
        for split in ("query", "query_light1"):
            write_results(sub / "s1" / f"{split}.txt", {n: T for n, T in est.items() if n.startswith(split + "/")})
    monkeypatch.chdir(tmp_path)  # the tables go to ./mysub-scores, beside the submission, not into it
    assert main(["score", str(sub), "--data", str(data), "--splits", "query,query_light1"]) == 0
    assert "1 of 8 queries have no estimate" in capsys.readouterr().out
    suite = pd.read_csv(tmp_path / "mysub-scores" / "tables" / "suite.csv").set_index("split")
    assert suite.loc["query", "recall_50cm"] == 75.0 and suite.loc["query", "recall_25cm"] == 0.0
    assert suite.loc["query", "mte_50cm_m"] == pytest.approx(0.3)
    assert suite.loc["query_light1", "recall_25cm"] == 100.0
    assert set(suite["method"]) == {"mysub"} and set(suite["track"]) == {"predicted"}


@pytest.mark.parametrize(
    "line, message",
    [
        ("query/000000 1 0 0 0 0 0 0\nquery/000000 1 0 0 0 0 0 0", "duplicate query name"),
        ("query/000000 1 0 0 0 nan 0 0", "NaN"),
        ("query/000000 0.5 0 0 0 0 0 0", "not unit"),
        ("query/999999 1 0 0 0 0 0 0", "not queries of scene 's1'"),
        ("query/000000 1 0 0", "expected 'name qw qx qy qz tx ty tz'"),
    ],
)
def test_malformed_pose_files_are_one_line_errors(data: Path, tmp_path: Path, capsys, line: str, message: str) -> None:
    (tmp_path / "s1.txt").write_text(RESULTS_HEADER + "\n" + line + "\n")
    assert main(["score", str(tmp_path), "--data", str(data)]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1


def test_submission_without_any_scene_file(data: Path, tmp_path: Path, capsys) -> None:
    assert main(["score", str(tmp_path), "--data", str(data)]) == 2
    assert "no '<scene>.txt'" in capsys.readouterr().err
