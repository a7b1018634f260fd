"""Per-query scoring of one split."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from harness_test_methods import perturb

from openreloc_bench.data.scene import Scene
from openreloc_bench.harness.score import Outcome, score_split


def test_score_split_rows(data_dir: Path) -> None:
    seq = Scene(data_dir / "sA").sequence("query")
    n0, n1, n2 = seq.names
    df = score_split(
        seq, {n0: Outcome(n0, perturb(seq.poses[0], n0, 0.2, 3.0), 0.5), n1: Outcome(n1, None, 0.1, "lost")}
    )
    assert df["query"].tolist() == [n0, n1, n2]
    assert df["success"].tolist() == [True, False, False]
    assert df["reason"].tolist() == ["", "lost", "missing"]
    assert df["t_err_m"][0] == pytest.approx(0.2) and df["r_err_deg"][0] == pytest.approx(3.0)
    assert np.isinf(df["t_err_m"][1:]).all() and np.isinf(df["r_err_deg"][1:]).all()
    assert df["runtime_s"][0] == 0.5 and np.isnan(df["runtime_s"][2])
    np.testing.assert_allclose(df[["gt_x", "gt_y", "gt_z"]].to_numpy(), seq.poses[:, :3, 3])
    assert np.isnan(df["est_x"][1])


def test_unknown_query_names_are_rejected(data_dir: Path) -> None:
    seq = Scene(data_dir / "sA").sequence("query")
    with pytest.raises(ValueError, match="unknown queries"):
        score_split(seq, {"query/777777": Outcome("query/777777", np.eye(4))})
