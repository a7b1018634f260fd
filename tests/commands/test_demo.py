"""The demo's plan: every method on the predicted track's three conditions, the methods that read masks
once more on the oracle-mask track, one board over both with the floor plan; the demo suite big enough
that one query is not a large share of a recall."""

from __future__ import annotations

from pathlib import Path

import pytest

from generators.spec import load_suite
from openreloc_bench.cli import main
from openreloc_bench.commands import demo
from openreloc_bench.harness import evaluation, leaderboard
from openreloc_bench.harness.runner import EvalReport


@pytest.fixture
def calls(monkeypatch: pytest.MonkeyPatch) -> list[tuple]:
    seen: list[tuple] = []
    monkeypatch.setattr(evaluation, "main", lambda cfg, suite: seen.append(("eval", cfg, suite)) or EvalReport())
    monkeypatch.setattr(leaderboard, "main", lambda results, out, data: seen.append(("board", results, out, data)))
    return seen


def test_demo_runs_both_tracks_then_one_board(tmp_path: Path, calls: list[tuple], capsys) -> None:
    assert main(["demo", "--out", str(tmp_path)]) == 0
    (_, predicted, suite), (_, oracle, _), board = calls
    assert suite == demo.DEMO_SUITE
    assert (predicted.track, [r.method for r in predicted.runs]) == (
        "predicted",
        ["openreloc", "sift-pnp", "nearest-frame"],
    )
    assert predicted.splits == ["query", "query_light3", "query_displaced"]
    assert (oracle.track, [r.method for r in oracle.runs], oracle.splits) == ("oracle-mask", ["openreloc"], ["query"])
    assert board == ("board", [predicted.out, oracle.out], tmp_path / "leaderboard", tmp_path / "data")
    printed = capsys.readouterr().out
    assert printed.count("$ openreloc-bench eval") == 2 and "--track oracle-mask" in printed


def test_demo_of_mask_free_methods_has_no_oracle_step(tmp_path: Path, calls: list[tuple]) -> None:
    assert main(["demo", "--out", str(tmp_path), "--methods", "sift-pnp,nearest-frame"]) == 0
    assert [c[0] for c in calls] == ["eval", "board"]


def test_the_demo_suite_gives_each_query_at_most_3_points() -> None:
    (spec,) = load_suite(demo.DEMO_SUITE).scene_specs()
    assert 100 / spec.n_query <= 3
