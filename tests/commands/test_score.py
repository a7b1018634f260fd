"""``openreloc-bench score``: outside pose files, both layouts, missing queries and malformed files."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "harness"))
from harness_test_methods import make_scene, perturb  # noqa: E402

from openreloc_bench import geometry  # noqa: E402
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
        ("query/000000 1 0 0", "expected 'name qw qx qy qz tx ty tz [confidence]'"),
    ],
)
@pytest.mark.parametrize("check", [[], ["--check"]])
def test_malformed_pose_files_are_one_line_errors(
    data: Path, tmp_path: Path, capsys, line: str, message: str, check: list[str]
) -> None:
    (tmp_path / "s1.txt").write_text(RESULTS_HEADER + "\n" + line + "\n")
    assert main(["score", str(tmp_path), "--data", str(data), *check]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1


def test_check_validates_and_counts_without_scoring(data: Path, tmp_path: Path, capsys, monkeypatch) -> None:
    sub = tmp_path / "mysub"
    est = estimates(data, "query", 0.3)
    del est["query/000003"]
    write_results(sub / "s1.txt", est)
    monkeypatch.chdir(tmp_path)
    assert main(["score", str(sub), "--data", str(data), "--check"]) == 0
    out = capsys.readouterr().out
    assert "s1 query: 3 of 4 queries have a pose" in out
    assert "valid: 3 poses for 4 queries in 1 scene(s); the other 1 count as failures" in out
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mysub"]  # nothing written


def test_submission_without_any_scene_file(data: Path, tmp_path: Path, capsys) -> None:
    assert main(["score", str(tmp_path), "--data", str(data)]) == 2
    assert "no '<scene>.txt'" in capsys.readouterr().err


def mapfree_lines(est: dict[str, np.ndarray], name=lambda n: n, confidence: bool = True) -> str:
    """Lines of a map-free submission: ``name qw qx qy qz tx ty tz confidence`` (T_cw)."""
    lines = []
    for i, (n, T) in enumerate(sorted(est.items())):
        q, t = geometry.pose_to_qt(geometry.invert(T))
        conf = f" {100.0 * (i + 1)}" if confidence else ""
        lines.append(f"{name(n)} " + " ".join(f"{v:.10g}" for v in (*q, *t)) + conf)
    return "\n".join(lines) + "\n"


def test_scores_a_mapfree_submission_and_keeps_its_confidence(data: Path, tmp_path: Path) -> None:
    sub = tmp_path / "mapfree"
    sub.mkdir()
    est = estimates(data, "query", 0.3)
    del est["query/000002"]
    (sub / "pose_s1.txt").write_text(mapfree_lines(est))
    assert main(["score", str(sub), "--data", str(data), "--out", str(tmp_path / "scores")]) == 0
    queries = pd.read_csv(tmp_path / "scores" / "tables" / "queries.csv").set_index("query")
    assert queries["confidence"].to_dict() == pytest.approx(
        {"query/000000": 100.0, "query/000001": 200.0, "query/000002": np.nan, "query/000003": 300.0}, nan_ok=True
    )
    assert queries.loc["query/000000", "t_err_m"] == pytest.approx(0.3)
    assert set(queries["scene"]) == {"s1"}


def test_scores_hloc_image_names_when_asked(data: Path, tmp_path: Path, capsys) -> None:
    sub = tmp_path / "hloc"
    sub.mkdir()
    est = estimates(data, "query", 0.1)
    (sub / "s1.txt").write_text(mapfree_lines(est, lambda n: n.replace("/", "/color/") + ".png", confidence=False))
    assert main(["score", str(sub), "--data", str(data), "--out", str(tmp_path / "plain")]) == 2
    assert "hloc image names need --names hloc" in capsys.readouterr().err
    assert main(["score", str(sub), "--data", str(data), "--names", "hloc", "--out", str(tmp_path / "s")]) == 0
    suite = pd.read_csv(tmp_path / "s" / "tables" / "suite.csv")
    assert suite.loc[0, "recall_25cm"] == 100.0 and suite.loc[0, "n_queries"] == 4


@pytest.mark.parametrize(
    "files, argv, message",
    [
        ({"s1.txt": "query/000000 1 0 0 0 0 0 0", "pose_s1.txt": ""}, [], "keep one layout"),
        ({"s1.txt": "query/000000 1 0 0 0 0 0 0 0.5\nquery/000001 1 0 0 0 0 0 0"}, [], "confidence on every line"),
        ({"s1.txt": "query/000000 1 0 0 0 0 0 0"}, ["--names", "hloc"], "not an hloc image name"),
        ({"s1.txt": "query/color/000000.png 1 0 0 0 0 0 0\nquery/color/000000.jpg 1 0 0 0 0 0 0"},
         ["--names", "hloc"], "duplicate query name 'query/000000'"),
        ({"s1.txt": "query/000000 1 0 0 0 0 0 0 0.5 1"}, [], "expected 'name qw qx qy qz tx ty tz [confidence]'"),
        ({"pose_s9.txt": "query/000000 1 0 0 0 0 0 0"}, [], "pose_s9.txt: names no scene"),
    ],
)  # fmt: skip
def test_other_formats_still_fail_loudly(data: Path, tmp_path: Path, capsys, files, argv, message) -> None:
    sub = tmp_path / "sub"
    sub.mkdir()
    for fname, text in files.items():
        (sub / fname).write_text(text + "\n")
    assert main(["score", str(sub), "--data", str(data), "--out", str(tmp_path / "o"), *argv]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1


@pytest.mark.parametrize(("track", "uses_masks"), [("oracle-mask", True), ("mask-free", False)])
def test_the_submission_declares_its_track(data: Path, tmp_path: Path, track: str, uses_masks: bool) -> None:
    """mask-free: a method that reads no masks, whose rows stand in both tracks' tables."""
    write_results(tmp_path / "sub" / "s1.txt", estimates(data, "query", 0.1))
    assert (
        main(["score", str(tmp_path / "sub"), "--data", str(data), "--track", track, "--out", str(tmp_path / "t")]) == 0
    )
    q = pd.read_csv(tmp_path / "t" / "tables" / "queries.csv")
    assert set(q["track"]) == {track} and set(q["uses_masks"]) == {uses_masks}
