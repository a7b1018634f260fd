"""Object-level RANSAC: it finds the one pose that explains the true candidates, and gives up
(None) when no consistent set exists."""

from __future__ import annotations

import numpy as np
import pytest

from openreloc_bench import geometry
from openreloc_bench.openreloc.association import Match, QueryObject
from openreloc_bench.openreloc.box_fit import extreme_points
from openreloc_bench.openreloc.verify import (
    ObjectEvidence,
    VerifyConfig,
    _CandidateTable,
    draw_triples,
    verification_evidence,
    verify_matches,
)
from tests.openreloc.boxworld import Box, render

HW = (240, 320)
K = geometry.intrinsics_from_fov(HW[1], HW[0], 70.0)
T_WC = geometry.look_at(np.array([0.0, -3.0, 1.5]), np.array([0.0, 0.0, 0.6]))


def _boxes(rng: np.random.Generator, n: int, centre: tuple[float, float], spread: float, first_id: int) -> list[Box]:
    out = []
    for i in range(n):
        c = np.array([centre[0] + rng.uniform(-spread, spread), centre[1] + rng.uniform(-spread, spread), 0.0])
        size = rng.uniform(0.3, 0.7, 3)
        lo = c - size / 2
        lo[2] = rng.uniform(0.0, 0.8)
        out.append(
            Box(first_id + i, "thing", tuple(lo), tuple(lo + size), tuple(int(x) for x in rng.integers(50, 250, 3)))
        )
    return out


def _landmark_arrays(boxes: list[Box]) -> tuple[np.ndarray, np.ndarray]:
    corners = [
        np.array([[x, y, z] for x in (b.lo[0], b.hi[0]) for y in (b.lo[1], b.hi[1]) for z in (b.lo[2], b.hi[2])])
        for b in boxes
    ]
    return np.array([c.mean(0) for c in corners]), np.array([extreme_points(c) for c in corners])


@pytest.fixture(scope="module")
def world() -> dict:
    rng = np.random.default_rng(3)
    visible = _boxes(rng, 7, (0.0, 0.5), 1.6, first_id=1)
    elsewhere = _boxes(rng, 25, (0.0, 8.0), 5.0, first_id=100)  # a room behind a wall: never in view
    _, _, inst = render(visible, K, T_WC, HW)
    landmarks = visible + elsewhere
    centers, extremes = _landmark_arrays(landmarks)
    masks = {b.id: inst == b.id for b in visible if (inst == b.id).sum() > 30}
    return {"landmarks": landmarks, "centers": centers, "extremes": extremes, "masks": masks, "rng": rng}


def _evidence(world: dict, true_rank: list[int], with_truth: bool = True) -> tuple[list[ObjectEvidence], list[int]]:
    """Per visible object: 4 distractor rows with the true row inserted at ``true_rank``."""
    rows_of = {b.id: r for r, b in enumerate(world["landmarks"])}
    distractors = [r for r, b in enumerate(world["landmarks"]) if b.id >= 100]
    rng = np.random.default_rng(0)
    out, truth = [], []
    for k, (lid, mask) in enumerate(world["masks"].items()):
        cands = [int(x) for x in rng.choice(distractors, 4, replace=False)]
        if with_truth:
            cands.insert(true_rank[k % len(true_rank)], rows_of[lid])
        out.append(ObjectEvidence(mask, cands))
        truth.append(rows_of[lid])
    return out, truth


@pytest.mark.parametrize("true_rank", [[0], [0, 1, 2], [1, 3, 0, 2, 4]])
@pytest.mark.parametrize(("box_fit", "max_m", "max_deg"), [(True, 0.2, 4.0), (False, 0.5, 10.0)])
def test_recovers_the_true_matches_and_pose(
    world: dict, true_rank: list[int], box_fit: bool, max_m: float, max_deg: float
) -> None:
    evidence, truth = _evidence(world, true_rank)
    assert len(evidence) >= 5
    res = verify_matches(evidence, world["centers"], world["extremes"], K, VerifyConfig(samples=300, box_fit=box_fit))
    assert res is not None
    assert res.assignment == dict(enumerate(truth))
    # mask centroids are not projections of box centres (occlusion): re-solving PnP on them leaves a coarse
    # prior (measured 25-28 cm); fitting the boxes gets closer (4-16 cm; occlusion shrinks some masks)
    t_err, r_err = geometry.pose_errors(T_WC, res.T_wc)
    assert t_err < max_m and r_err < max_deg


def test_the_likeliest_triples_poses_fitted_to_their_boxes_compete(world: dict) -> None:
    # without local optimisation the verified pose is the best-scoring sampled one: P3P on mask centroids
    # is off by decimetres (occluded masks), the fit of a right triple's three boxes is not
    evidence, _ = _evidence(world, [0])
    errors = {}
    for fitted in (0, 64):
        res = verify_matches(
            evidence, world["centers"], world["extremes"], K, VerifyConfig(samples=100, refits=0, fitted_triples=fitted)
        )
        assert res is not None
        errors[fitted] = geometry.pose_errors(T_WC, res.T_wc)[0]
    assert errors[64] < 0.05 < 0.15 < errors[0]


def test_gives_up_when_no_candidate_is_right(world: dict) -> None:
    evidence, _ = _evidence(world, [0], with_truth=False)
    # three wrong candidates can always be fitted by some P3P pose (the relocalizer's render-and-compare
    # choice rejects such poses), a fourth one cannot
    assert verify_matches(evidence, world["centers"], world["extremes"], K, VerifyConfig(min_inliers=4)) is None


def test_gives_up_with_fewer_objects_than_min_inliers(world: dict) -> None:
    evidence, _ = _evidence(world, [0])
    cfg = VerifyConfig(min_inliers=len(evidence) + 1)
    assert verify_matches(evidence, world["centers"], world["extremes"], K, cfg) is None
    assert verify_matches(evidence[:2], world["centers"], world["extremes"], K, VerifyConfig()) is None


def test_is_deterministic_per_seed(world: dict) -> None:
    evidence, _ = _evidence(world, [2, 0, 1])
    a = verify_matches(evidence, world["centers"], world["extremes"], K, VerifyConfig(samples=50), seed=7)
    b = verify_matches(evidence, world["centers"], world["extremes"], K, VerifyConfig(samples=50), seed=7)
    assert a is not None and b is not None
    assert a.assignment == b.assignment and np.array_equal(a.T_wc, b.T_wc)


def test_further_modes_leave_the_best_as_it_was_and_are_distinct_consensus_sets(world: dict) -> None:
    evidence, _ = _evidence(world, [0, 1, 2])
    args = (evidence, world["centers"], world["extremes"], K)
    one = verify_matches(*args, VerifyConfig(modes=1))
    many = verify_matches(*args, VerifyConfig(modes=4))
    assert one is not None and many is not None and one.alternatives == []
    assert many.assignment == one.assignment and np.allclose(many.T_wc, one.T_wc)
    assert 1 <= len(many.alternatives) <= 3
    seen = [many.assignment]
    for alt in many.alternatives:
        assert alt.inliers >= VerifyConfig().min_inliers and alt.assignment not in seen
        seen.append(alt.assignment)


@pytest.mark.parametrize("chunk", [1, 7, 64])
def test_overlaps_are_the_boxes_of_the_projected_extreme_points(world: dict, chunk: int) -> None:
    evidence, _ = _evidence(world, [0, 1, 2])
    cfg = VerifyConfig(min_iou=0.0, rank_weight=1.0)
    table = _CandidateTable(
        evidence, list(range(len(evidence))), cfg.candidates, world["centers"], world["extremes"], K, cfg
    )
    rng = np.random.default_rng(1)
    poses = [geometry.invert(T_WC)] + [
        geometry.invert(geometry.look_at(rng.uniform(-3, 3, 3) + [0, -3, 1.5], rng.uniform(-1, 1, 3)))
        for _ in range(20)
    ]
    R, t = np.stack([T[:3, :3] for T in poses]), np.stack([T[:3, 3] for T in poses])
    got = table.overlaps(R, t, chunk)
    for k in range(len(poses)):  # one pose and one candidate at a time, the obvious way
        for m in range(len(table.rows)):
            Xc = table.E[m] @ R[k].T + t[k]
            if (Xc[:, 2] <= 0.05).any():
                assert got[k, m] == 0.0
                continue
            uv = Xc[:, :2] / Xc[:, 2:] * K[[0, 1], [0, 1]] + K[:2, 2]
            x0, y0 = np.clip(uv.min(0), 0, (HW[1], HW[0]))
            x1, y1 = np.clip(uv.max(0), 0, (HW[1], HW[0]))
            b = table.box[m]
            inter = max(0.0, min(x1, b[2]) - max(x0, b[0])) * max(0.0, min(y1, b[3]) - max(y0, b[1]))
            union = (x1 - x0) * (y1 - y0) + (b[2] - b[0]) * (b[3] - b[1]) - inter
            assert got[k, m] == pytest.approx(inter / max(union, 1e-9), abs=1e-9)
    assert got[0].max() > 0.5  # the true pose overlaps its objects' boxes


@pytest.mark.parametrize("twin_first", [True, False])
def test_of_two_equally_consistent_sets_the_higher_ranked_candidates_win(world: dict, twin_first: bool) -> None:
    # every visible box has a twin 6 m to the side: a camera 6 m to the side sees the twins exactly as the
    # true camera sees the boxes, so only the candidates' ranks can tell the two consensus sets apart
    offset = np.array([6.0, 0.0, 0.0])
    visible = [b for b in world["landmarks"] if b.id in world["masks"]]
    twins = [Box(b.id + 1000, b.category, tuple(b.lo + offset), tuple(b.hi + offset), b.color) for b in visible]
    centers, extremes = _landmark_arrays(visible + twins)
    n = len(visible)
    evidence = [
        ObjectEvidence(world["masks"][b.id], [i + n, i] if twin_first else [i, i + n]) for i, b in enumerate(visible)
    ]
    res = verify_matches(evidence, centers, extremes, K, VerifyConfig(samples=300))
    assert res is not None
    assert res.assignment == {i: i + n if twin_first else i for i in range(n)}
    expected = T_WC.copy()
    expected[:3, 3] += offset if twin_first else 0.0
    assert geometry.pose_errors(expected, res.T_wc)[0] < 0.2


def _right_share(world: dict, weight: float, covisible: np.ndarray | None) -> float:
    """Share of 4,000 drawn triples whose three candidates are all true, the truth ranked third everywhere."""
    evidence, truth = _evidence(world, [2])
    cfg = VerifyConfig(covisible_weight=weight)
    table = _CandidateTable(
        evidence, list(range(len(evidence))), cfg.candidates, world["centers"], world["extremes"], K, cfg
    )
    objs, flat = draw_triples(table, 4000, np.random.default_rng(0), covisible)
    return float((table.rows[flat] == np.asarray(truth)[objs]).all(1).mean())


def test_covisibility_guides_the_draws_to_triples_seen_together(world: dict) -> None:
    # the visible boxes are seen together, the room behind the wall's boxes together, never the two mixed
    seen = np.array([b.id < 100 for b in world["landmarks"]])
    covisible = seen[:, None] == seen[None, :]
    unguided = _right_share(world, 1.0, covisible)
    assert unguided == _right_share(world, 1.0, None)  # weight 1: the co-visibility is not even looked at
    assert 0 < unguided < 0.01  # 0.13 ** 3 expected: the third of five is drawn with chance 0.25 / 1.94
    assert _right_share(world, 0.05, covisible) > 10 * unguided


def test_verification_evidence_leaves_out_objects_the_association_dropped() -> None:
    """Object 1 was dropped by the association (its best landmark, 30, is a filtered wall: it is one);
    the verification gives it no candidates rather than its best valid look-alike."""
    mask = np.ones((4, 4), bool)
    objects = [QueryObject(mask=mask, box=np.array([0, 0, 4, 4.0]), visual=np.zeros(2, np.float32)) for _ in range(2)]
    ids = [10, 20, 30]
    sims = np.array([[0.2, 0.9, 0.5], [0.4, 0.1, 0.95]])
    matched = {0: Match(query=0, landmark=10, visual_sim=0.2, text_sim=None, how="graph", candidates=[10])}
    evidence = verification_evidence(objects, matched, sims, ids, frozenset({30}), n_candidates=5)
    assert [e.candidates for e in evidence] == [[0, 1], []]  # rows: its match first, then by similarity
    ranked = verification_evidence(objects, matched, sims, ids, frozenset({30}), n_candidates=5, lead=0)
    assert [e.candidates for e in ranked] == [[1, 0], []]  # by the scores alone (the place prior's ranking)
