"""One evaluation from its config to its tables: the tables of a results folder, and what is said."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from openreloc_bench.errors import ConfigError
from openreloc_bench.harness import evaluation
from openreloc_bench.harness.runner import EvalConfig, MethodRun

PLUGIN = ["harness_test_methods"]


def cfg(data: Path, out: Path, *methods: str, **kw) -> EvalConfig:
    runs = [MethodRun(m, m) for m in methods]
    return EvalConfig(data=data, out=out, scenes=["sA", "sB"], runs=runs, plugins=PLUGIN, timeout_s=0.0, **kw)


def test_tabulate_writes_nothing_before_a_job_has_finished(tmp_path: Path) -> None:
    assert evaluation.tabulate(tmp_path / "nowhere") is None
    assert not (tmp_path / "nowhere").exists()


def test_main_writes_the_tables_and_says_them_then_the_summary(data_dir: Path, tmp_path: Path) -> None:
    said: list[str] = []
    report = evaluation.main(cfg(data_dir, tmp_path, "test-oracle", "nearest-frame"), say=said.append)
    assert report.errors == [] and report.jobs_run == 4
    assert "test-oracle predicted query" in " ".join(said[0].split())  # the compact suite table
    assert said[1] == f"tables: {tmp_path / 'tables'}" and said[-1].startswith("maps: 4 built, 0 cached; jobs: 4 run")
    assert {"queries.csv", "scenes.csv", "suite.csv"} <= {p.name for p in (tmp_path / "tables").iterdir()}
    queries, suite, seeds = evaluation.tabulate(tmp_path)
    assert set(suite["method"]) == {"test-oracle", "nearest-frame"} and seeds.empty
    assert set(queries["method"]) == set(suite["method"])


def test_failures_are_named_by_their_commonest_reasons_and_a_method_placing_nothing_is_warned_of() -> None:
    queries = pd.DataFrame(
        {
            "method": ["m"] * 5 + ["ok"] * 2,
            "track": "predicted",
            "success": [False, False, False, True, False, True, True],
            "reason": [
                "3 matches after the ratio test",
                "5 matches after the ratio test",
                "timeout",
                None,
                None,
                None,
                None,
            ],
            "t_err_m": [np.inf, np.inf, np.inf, 2.0, np.inf, 0.1, 0.2],
        }
    )
    lines = evaluation.failure_lines(queries, Path("res/tables/queries.csv"))
    assert lines[0] == (
        "failed: m (predicted): 4 of 5 queries: 2 x 'N matches after the ratio test', 1 x 'no reason given', "
        "1 x 'timeout' (every query: res/tables/queries.csv)"
    )
    assert lines[1].startswith("warning: m (predicted) placed none of its 5 queries within 50 cm")
    assert len(lines) == 2  # 'ok' failed nothing and placed its queries


def test_main_refuses_unknown_methods_before_generating_the_suite(tmp_path: Path) -> None:
    suite = tmp_path / "suite.yaml"
    suite.write_text("name: t\nscenes:\n  - {name: x, seed: 1}\n")
    with pytest.raises(ConfigError, match="unknown method 'nope'"):
        evaluation.main(cfg(tmp_path / "data", tmp_path / "r", "nope"), suite=suite)
    assert not (tmp_path / "data").exists()
