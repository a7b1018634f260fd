"""Per-query scoring of one split, and the difficulty each query row carries."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from harness_test_methods import DIFFICULTY, difficulty_scene, perturb

from openreloc_bench import geometry
from openreloc_bench.data.scene import DATA_VERSION, DIFFICULTY_AXES, Scene
from openreloc_bench.errors import DataError
from openreloc_bench.harness.score import Outcome, reprojection_error, score_split, with_difficulty


def test_score_split_rows(data_dir: Path) -> None:
    seq = Scene(data_dir / "sA").sequence("query")
    n0, n1, n2 = seq.names
    df = score_split(
        seq,
        {n0: Outcome(n0, perturb(seq.poses[0], n0, 0.2, 3.0), 0.5, confidence=7.0), n1: Outcome(n1, None, 0.1, "lost")},
    )
    assert df["query"].tolist() == [n0, n1, n2]
    assert df["success"].tolist() == [True, False, False]
    assert df["reason"].tolist() == ["", "lost", "missing"]
    assert df["t_err_m"][0] == pytest.approx(0.2) and df["r_err_deg"][0] == pytest.approx(3.0)
    assert np.isinf(df["t_err_m"][1:]).all() and np.isinf(df["r_err_deg"][1:]).all()
    assert df["runtime_s"][0] == 0.5 and np.isnan(df["runtime_s"][2])
    np.testing.assert_allclose(df[["gt_x", "gt_y", "gt_z"]].to_numpy(), seq.poses[:, :3, 3])
    assert np.isnan(df["est_x"][1])
    assert df["confidence"][0] == 7.0 and df["confidence"][1:].isna().all()  # none for a failure
    assert 0 < df["reproj_err_px"][0] < np.inf and np.isinf(df["reproj_err_px"][1:]).all()


def test_reprojection_error_is_zero_at_the_truth_and_grows_with_the_error(data_dir: Path) -> None:
    seq = Scene(data_dir / "sA").sequence("query")
    T = seq.poses[0]
    assert reprojection_error(seq, 0, T) == pytest.approx(0.0, abs=1e-6)
    near, far = (perturb(T, "q", m, 1.0) for m in (0.05, 0.5))
    assert 0 < reprojection_error(seq, 0, near) < reprojection_error(seq, 0, far)
    behind = T @ geometry.make_pose(np.diag([-1.0, 1.0, -1.0]), np.zeros(3))  # turned around: the scene is behind it
    assert reprojection_error(seq, 0, behind) == np.inf


def test_unknown_query_names_are_rejected(data_dir: Path) -> None:
    seq = Scene(data_dir / "sA").sequence("query")
    with pytest.raises(ValueError, match="unknown queries"):
        score_split(seq, {"query/777777": Outcome("query/777777", np.eye(4))})


def test_query_rows_carry_their_difficulty_and_data_version(tmp_path: Path) -> None:
    scene = Scene(difficulty_scene(tmp_path, "sD", DIFFICULTY))
    df = with_difficulty(score_split(scene.sequence("query_light1"), {}), scene, "query_light1")
    # joined on (split, frame): query_light1's rows, not query's; frame 000001 has no row
    np.testing.assert_array_equal(df["gap_m"], [0.4, np.nan, 1.5])
    np.testing.assert_array_equal(df["light_level"], [0.7, np.nan, 0.7])
    np.testing.assert_array_equal(df["lookalikes_in_view"], [1, np.nan, 0])
    assert df["data_version"].tolist() == [DATA_VERSION] * 3
    full = with_difficulty(score_split(scene.sequence("query"), {}), scene, "query")
    assert full["visible_objects"].tolist() == [4, 2, 0] and full["object_area"].tolist() == [0.3, 0.1, 0.0]


def test_a_scene_without_difficulty_gets_empty_columns(data_dir: Path) -> None:
    scene = Scene(data_dir / "sA")
    df = with_difficulty(score_split(scene.sequence("query"), {}), scene, "query")
    assert df[list(DIFFICULTY_AXES)].isna().all().all() and df["data_version"].isna().all()
    assert list(df.columns[-8:]) == [*DIFFICULTY_AXES, "data_version"]


def test_a_frame_with_two_difficulty_rows_is_a_clear_error(tmp_path: Path) -> None:
    twice = {k: v + v[-1:] for k, v in DIFFICULTY.items()}
    scene = Scene(difficulty_scene(tmp_path, "sD", twice))
    with pytest.raises(DataError, match="frame 000002 of split 'query_light1' has two rows"):
        with_difficulty(score_split(scene.sequence("query"), {}), scene, "query")  # the table is wrong as a whole
