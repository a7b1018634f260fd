"""The pose stages read from a query's diagnostics and its true pose."""

from __future__ import annotations

import json

import networkx as nx
import numpy as np
import pytest

from openreloc_bench import geometry
from openreloc_bench.harness.pose_stages import QueryStages, pool_stages, query_stages, summarize_stages
from openreloc_bench.openreloc.map import ObjectMap, ReferenceFrame


def tiny_map() -> ObjectMap:
    frames = [ReferenceFrame(k, geometry.make_pose(np.eye(3), [x, 0.0, 0.0]), {}) for k, x in ((0, 0.0), (4, 2.0))]
    return ObjectMap({}, frames, nx.Graph(), np.eye(3), 64, 48, {}, {}, {})


def test_a_query_right_at_its_prior_and_wrong_after_refinement() -> None:
    truth = geometry.make_pose(np.eye(3), [0.1, 0.0, 0.0])
    diag = {
        "detected": 9,
        "unique": 5,
        "matches": [{"how": "agree"}, {"how": "graph"}, {"how": "verified"}],
        "verification": {"inliers": 3},
        "reference_frame": {"index": 0},
        "hypotheses": [{"source": "reference:4"}, {"source": "reference:0"}, {"source": "pnp"}],
        "prior_T_wc": geometry.make_pose(np.eye(3), [0.2, 0.0, 0.0]).tolist(),
        "anchors": {"keypoints": 300, "inliers": 12},
        "chosen": "reference:0",
    }
    q = query_stages(diag, geometry.make_pose(np.eye(3), [1.1, 0.0, 0.0]), truth, tiny_map())
    assert q.prior[0] == pytest.approx(0.1) and q.best_reference[0] == pytest.approx(0.1)
    assert q.start[0] == pytest.approx(0.1) and q.final[0] == pytest.approx(1.0)
    failed = query_stages({"detected": 1}, None, truth, tiny_map(), reason="1 object(s) detected, need at least 3")
    s = summarize_stages([q, failed])
    assert s["final"]["recall_50cm"] == 0.0 and s["coarse_prior"]["recall_25cm"] == 50.0
    assert s["refinement_worse"] == 100.0 and s["wrong_with_right_prior"] == 50.0
    assert s["modalities_agree"] == 50.0 and s["verification_pass_rate"] == 100.0
    assert s["failures"] == {"object(s) detected, need at least": 1}
    assert q.anchor_inliers == 12 and s["object_pose"]["share"] == 50.0 and s["keypoint_pose"]["share"] == 0.0
    # the per-query record survives JSON (no NaN, no Infinity) and pools the same
    text = json.dumps([q.to_dict(), failed.to_dict()], allow_nan=False)
    assert pool_stages([json.loads(text)]) == s
    assert QueryStages.from_dict(failed.to_dict()).final == (np.inf, np.inf)


def test_no_query_gives_no_shares() -> None:
    s = summarize_stages([])
    assert s["queries"] == 0 and s["verification_pass_rate"] is None and s["final"]["median_te_m"] is None
