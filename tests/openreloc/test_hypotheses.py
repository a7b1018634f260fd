"""Choosing among refined hypotheses, the match union their batch aligns, and the restarts of the choice."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from openreloc_bench import geometry
from openreloc_bench.openreloc import hypotheses
from openreloc_bench.openreloc.association import Match
from openreloc_bench.openreloc.hypotheses import (
    Hypothesis,
    RefinedBatch,
    choose_hypothesis,
    orbit_starts,
    restart,
    union_of_matches,
)
from openreloc_bench.openreloc.refine import RefineConfig, RefineResult

K = geometry.intrinsics_from_fov(160, 120, 70.0)
T_GT = geometry.look_at([1.0, -2.0, 1.5], [0.0, 1.0, 0.5])


def match(q: int, lid: int, how: str = "verified") -> Match:
    return Match(query=q, landmark=lid, visual_sim=0.5, text_sim=None, how=how)


@pytest.mark.parametrize(
    ("losses", "explained", "tie", "expected"),
    [
        ([5.0, 1.0, 3.0], [4.0, 2.0, 3.9], 0.1, 2),  # the low-loss pose explains too little; of the ties, lower loss
        ([5.0, 1.0, 3.0], [4.0, 2.0, 3.9], 0.0, 0),  # no ties: the best explained
        ([5.0, 1.0, 3.0], [4.0, 2.0, 3.9], 1.0, 1),  # everything ties: the lowest loss (the paper's choice)
        ([float("nan"), 2.0], [9.0, 1.0], 0.1, 1),  # a diverged hypothesis never wins
    ],
)
def test_choose_hypothesis(losses: list[float], explained: list[float], tie: float, expected: int) -> None:
    assert choose_hypothesis(losses, explained, tie) == expected


def test_union_of_match_sets_holds_each_pair_once() -> None:
    main = [match(0, 10), match(1, 11)]
    union, sets = union_of_matches([main, main, [match(0, 12), match(1, 11)], [match(2, 10)]])
    assert [(mt.query, mt.landmark) for mt in union] == [(0, 10), (1, 11), (0, 12), (2, 10)]
    assert sets == [[0, 1], [0, 1], [2, 1], [3]]


@pytest.mark.parametrize(
    "hop_losses, hop_outliers, wins",
    [
        ({1: 5.0, 2: 5.0, 3: 8.0}, [], True),
        ({1: 5.0, 2: 5.0, 3: 100.0}, [3], False),  # lower only by leaving a third object out of its own mean
        ({1: 9.5, 2: 9.5, 3: 9.5}, [], False),  # lower by less than the margin: the valley is flat
    ],
)
def test_a_restart_is_judged_on_the_objects_the_pose_counted(
    monkeypatch, hop_losses: dict, hop_outliers: list, wins: bool
) -> None:
    def result(losses: dict, outliers: list) -> RefineResult:
        kept = [v for k, v in losses.items() if k not in outliers]
        return RefineResult(np.eye(4), sum(kept) / len(kept), math.nan, losses, outliers)

    before = result({1: 10.0, 2: 10.0, 3: 10.0}, [])
    hop = result(hop_losses, hop_outliers)
    monkeypatch.setattr(hypotheses, "refine_poses", lambda *args, **kwargs: [hop])
    matches = [match(i, lid, "oracle") for i, lid in enumerate([1, 2, 3])]
    batch = RefinedBatch([Hypothesis("reference:0", np.eye(4), matches)], [before], matches, [[0, 1, 2]], [], None)
    landmarks = SimpleNamespace(
        landmarks={lid: SimpleNamespace(center=np.full(3, float(lid))) for lid in (1, 2, 3)},
        up=np.array([0.0, 0.0, 1.0]),
    )
    diag: dict = {}
    chosen = restart(batch, 0, landmarks, K, RefineConfig(), 0, diag)
    assert (chosen is hop) == wins == diag["restart"]["won"]


@pytest.mark.parametrize(("degrees", "up"), [(3.0, (0.0, 0.0, 1.0)), (6.0, (0.0, 0.0, 1.0)), (6.0, (0.0, -1.0, 0.0))])
def test_orbit_starts_keep_the_pivot_in_place_and_turn_by_the_angle(degrees: float, up: tuple) -> None:
    pivot = np.array([0.2, 0.8, 0.6])
    uv0, _ = geometry.project(K, T_GT, pivot[None])
    starts = orbit_starts(T_GT, pivot, degrees, np.array(up))
    assert len(starts) == 4
    for T in starts:
        assert geometry.is_rigid(T)
        uv, _ = geometry.project(K, T, pivot[None])
        np.testing.assert_allclose(uv, uv0, atol=1e-6)
        assert np.linalg.norm(T[:3, 3] - pivot) == pytest.approx(np.linalg.norm(T_GT[:3, 3] - pivot))
        assert float(geometry.rotation_error(T_GT, T)) == pytest.approx(degrees, abs=1e-6)
    # two about the world's vertical (the camera height stays), two about the camera's x axis (it does not)
    heights = [(T[:3, 3] - T_GT[:3, 3]) @ np.array(up) for T in starts]
    assert heights[0] == pytest.approx(0.0, abs=1e-9) and heights[1] == pytest.approx(0.0, abs=1e-9)
    assert min(abs(heights[2]), abs(heights[3])) > 1e-3 and heights[2] * heights[3] < 0  # up, then down
