"""Metrics: hand-computed values and a cross-check of the errors against evo's APE."""

from __future__ import annotations

import math

import numpy as np
import pytest

from openreloc_bench import geometry
from openreloc_bench.harness.metrics import (
    METRIC_COLUMNS,
    RECALLS,
    coverage_auc,
    cumulative_curve,
    hits,
    paired_difference,
    recall_intervals,
    summarize,
)

INF = math.inf


def test_summarize_hand_computed() -> None:
    # errors: 0.1 m/1 deg, 0.3 m/6 deg, 0.6 m/2 deg, one failure
    m = summarize(np.array([0.1, 0.3, 0.6, INF]), np.array([1.0, 6.0, 2.0, INF]))
    assert set(m) == set(METRIC_COLUMNS)
    assert (m["n_queries"], m["n_failed"]) == (4, 1)
    assert m["recall_100cm"] == 75.0 and m["recall_50cm"] == 50.0 and m["recall_25cm"] == 25.0
    assert m["recall_25cm_5deg"] == 25.0
    assert m["mte_50cm_m"] == pytest.approx(0.2) and m["mre_50cm_deg"] == pytest.approx(3.5)
    assert m["mte_25cm_m"] == pytest.approx(0.1) and m["mre_25cm_deg"] == pytest.approx(1.0)
    assert m["median_te_m"] == pytest.approx(0.45) and m["median_re_deg"] == pytest.approx(4.0)


def test_combined_recall_needs_both_thresholds_and_thresholds_are_strict() -> None:
    m = summarize(np.array([0.1, 0.2, 0.25, 0.5]), np.array([6.0, 4.9, 1.0, 1.0]))
    assert m["recall_25cm_5deg"] == 25.0  # only the second: first has 6 deg, third is not < 25 cm
    assert m["recall_25cm"] == 50.0 and m["recall_50cm"] == 75.0


@pytest.mark.parametrize("t, r", [([INF, INF], [INF, INF]), ([math.nan, 0.1], [1.0, math.nan])])
def test_failures_count_in_denominators_and_accuracy_is_nan_without_successes(t: list, r: list) -> None:
    m = summarize(np.array(t), np.array(r))
    assert m["n_failed"] == 2 and m["recall_100cm"] == 0.0
    assert math.isnan(m["mte_50cm_m"]) and math.isnan(m["mre_25cm_deg"])
    assert m["median_te_m"] == INF


def test_the_fields_thresholds_rotation_aware_and_reprojection() -> None:
    t, r = np.array([0.04, 0.04, 0.08, 0.2, INF]), np.array([4.0, 6.0, 9.0, 4.0, INF])
    m = summarize(t, r, reproj_px=np.array([10.0, 95.0, 50.0, math.nan, INF]))
    assert m["recall_5cm_5deg"] == 20.0 and m["recall_10cm_10deg"] == 60.0 and m["recall_25cm_5deg"] == 40.0
    assert m["recall_vcre"] == 40.0 and m["median_reproj_px"] == 95.0  # NaN reprojection: not inside
    assert math.isnan(summarize(t, r)["recall_vcre"]) and math.isnan(summarize(t, r)["auc_25cm_5deg"])


def test_coverage_auc_is_map_frees_area_under_precision_vs_coverage() -> None:
    failed = np.array([False, False, False, True])
    # ranked by confidence: right, wrong, right; one failure never covered
    assert coverage_auc(np.array([3.0, 2.0, 1.0, math.nan]), np.array([1, 0, 1, 0], bool), failed) == pytest.approx(
        100 * (0.25 * 1 + 0.25 * 0.5 + 0.25 * 2 / 3)
    )
    # a confidence that ranks the wrong pose last scores higher
    assert coverage_auc(np.array([3.0, 1.0, 2.0, math.nan]), np.array([1, 0, 1, 0], bool), failed) == pytest.approx(
        100 * (0.25 + 0.25 + 0.25 * 2 / 3)
    )
    # tied confidences are one step: no order among them is rewarded
    assert coverage_auc(np.ones(2), np.array([1, 0], bool), np.zeros(2, bool)) == pytest.approx(50.0)
    assert math.isnan(coverage_auc(np.array([1.0, math.nan]), np.ones(2, bool), np.zeros(2, bool)))
    m = summarize(np.array([0.1, 0.6]), np.array([1.0, 1.0]), confidence=np.array([5.0, 1.0]))
    assert m["auc_25cm_5deg"] == pytest.approx(100 * (0.5 * 1 + 0.5 * 0.5))


def test_intervals_contain_the_recall_shrink_with_queries_and_widen_across_scenes() -> None:
    rng = np.random.default_rng(0)
    t = np.where(rng.random(400) < 0.7, 0.1, 0.7)
    inside = hits(t, np.ones_like(t))
    j = RECALLS.index("recall_50cm")
    lo, hi = recall_intervals(inside)[j]
    assert lo < 100 * inside[:, j].mean() < hi and 5 < hi - lo < 12  # about +-4.5 points at 400 queries
    assert np.array_equal(recall_intervals(inside), recall_intervals(inside))  # seeded
    small_lo, small_hi = recall_intervals(inside[:100])[j]
    assert small_hi - small_lo > hi - lo
    scenes = np.repeat(np.arange(4), 100)  # scenes that differ: 40, 60, 80 and 100 % right
    uneven = hits(np.where(rng.random(400) < np.repeat([0.4, 0.6, 0.8, 1.0], 100), 0.1, 0.7), np.ones(400))
    pooled, by_scene = recall_intervals(uneven)[j], recall_intervals(uneven, scenes)[j]
    assert by_scene[1] - by_scene[0] > 2 * (pooled[1] - pooled[0])
    assert np.isnan(recall_intervals(np.zeros((0, len(RECALLS)), bool))).all()


def test_a_paired_difference_sees_a_lead_that_overlapping_intervals_hide() -> None:
    """Scenes from 30 to 90 % right, and one method right on 10 points more of each scene's queries: the
    two recalls' intervals overlap, the difference's lies above zero."""
    rng = np.random.default_rng(1)
    scenes = np.repeat(np.arange(6), 50)
    u = rng.random(300)
    base = np.repeat([0.3, 0.4, 0.5, 0.7, 0.8, 0.9], 50)
    worse, better = (u < base).astype(float), (u < base + 0.1).astype(float)
    a, b = recall_intervals(better[:, None], scenes)[0], recall_intervals(worse[:, None], scenes)[0]
    assert a[0] < b[1]  # the intervals overlap
    diff, lo, hi = paired_difference(better, worse, scenes)
    assert diff == pytest.approx(100 * (better - worse).mean()) and 0 < lo < diff < hi
    assert paired_difference(worse, better, scenes)[2] < 0
    assert np.isnan(paired_difference(np.zeros(0), np.zeros(0), np.zeros(0))).all()


def test_empty_and_mismatched() -> None:
    assert math.isnan(summarize(np.array([]), np.array([]))["recall_50cm"])
    with pytest.raises(ValueError):
        summarize(np.zeros(2), np.zeros(3))


def test_cumulative_curve() -> None:
    curve = cumulative_curve(np.array([0.1, 0.3, INF, 0.3]), np.array([0.0, 0.1, 0.3, 10.0]))
    assert curve.tolist() == [0.0, 25.0, 75.0, 75.0]


def test_errors_match_evo_ape_from_tum_exports(tmp_path) -> None:
    """Our translation/rotation errors equal evo's APE (no alignment) on the exported TUM files."""
    pytest.importorskip("evo")
    from evo.core import metrics as evo_metrics
    from evo.tools import file_interface

    from openreloc_bench.data.results import write_tum

    rng = np.random.default_rng(3)
    names = [f"query/{i:06d}" for i in range(20)]
    gt, est = {}, {}
    for n in names:
        R = geometry.quat_to_rotmat(geometry.quat_canonical(rng.normal(size=4)))
        gt[n] = geometry.make_pose(R, rng.uniform(-5, 5, 3))
        dR = geometry.quat_to_rotmat(geometry.quat_canonical(np.r_[1.0, rng.normal(scale=0.3, size=3)]))
        est[n] = geometry.make_pose(R @ dR, gt[n][:3, 3] + rng.normal(scale=0.4, size=3))
    stamps = {n: float(i) for i, n in enumerate(names)}
    write_tum(tmp_path / "gt.tum", gt, stamps)
    write_tum(tmp_path / "est.tum", est, stamps)
    ref = file_interface.read_tum_trajectory_file(str(tmp_path / "gt.tum"))
    traj = file_interface.read_tum_trajectory_file(str(tmp_path / "est.tum"))
    ours_t, ours_r = geometry.pose_errors(np.stack([gt[n] for n in names]), np.stack([est[n] for n in names]))
    for relation, ours in [
        (evo_metrics.PoseRelation.translation_part, ours_t),
        (evo_metrics.PoseRelation.rotation_angle_deg, ours_r),
    ]:
        ape = evo_metrics.APE(relation)
        ape.process_data((ref, traj))
        np.testing.assert_allclose(ape.error, ours, atol=1e-6)
    assert summarize(ours_t, ours_r)["median_te_m"] == pytest.approx(np.median(ours_t))
