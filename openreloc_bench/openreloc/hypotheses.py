"""Pose hypotheses: where the refinement starts, which starts it refines, and which refined pose wins.

The paper refines one prior, the best reference frame's pose. Beyond it, each switchable:

- the coarse stage proposes the ``coarse.top_frames`` best-ranked reference frames and a PnP pose
  (:func:`coarse_hypotheses`, from :mod:`.coarse_prior`), and the verification its pose;
- the keypoints of the landmarks they chose give a pose (:func:`anchor_pose`), a start like the others
  when too few keypoints agree with it to return it;
- the verification's further modes, each with its own matches, are screened by render-and-compare
  before any is refined (:func:`screen_modes`: drawing a pose costs far less than refining it);
- every hypothesis is refined in one batch over the union of their matches (:func:`refine_hypotheses`);
- render-and-compare and the ICP loss choose among the refined poses (:func:`choose_hypothesis`);
- the chosen pose is refined again from starts orbiting its landmarks (:func:`restart`, basin hopping).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from openreloc_bench import geometry
from openreloc_bench.openreloc.anchors import AnchorConfig, AnchorIndex, AnchorPose
from openreloc_bench.openreloc.association import Match, QueryObject
from openreloc_bench.openreloc.coarse_prior import CoarseConfig, Ranking, pnp_prior, rank_reference_frames
from openreloc_bench.openreloc.consistency import Compare
from openreloc_bench.openreloc.icp_batch import TargetTables
from openreloc_bench.openreloc.map import ObjectMap
from openreloc_bench.openreloc.refine import RefineConfig, RefineResult, RefineTarget, refine_poses, target_tables
from openreloc_bench.vision.preprocess import touches_border


@dataclass
class Hypothesis:
    """A starting pose of the refinement and the matches it aligns."""

    source: str
    """Where it comes from: ``reference:<frame index>``, ``pnp``, ``verified``, ``verified:<mode>`` or
    ``uninformed`` (the no-coarse ablation's start)."""
    T_wc: np.ndarray
    matches: list[Match]
    """The query's matches, or a further verification mode's own."""
    frame: int | None = None
    """The reference frame (mapping frame index) it starts from, if it does."""


@dataclass
class RefinedBatch:
    """Every hypothesis refined in one batch, and what a restart of one of them needs to compare with it."""

    hypotheses: list[Hypothesis]
    results: list[RefineResult]
    """One per hypothesis, in their order."""
    union: list[Match]
    """The distinct matches of all hypotheses (:func:`union_of_matches`); ``targets`` align them."""
    target_sets: list[list[int]]
    """Per hypothesis, its matches as indices into ``union``."""
    targets: list[RefineTarget]
    tables: TargetTables


def coarse_hypotheses(
    matches: list[Match],
    objects: list[QueryObject],
    m: ObjectMap,
    K: np.ndarray,
    cfg: CoarseConfig,
    ranking: Ranking,
    no_coarse: bool,
    diag: dict[str, Any],
) -> list[Hypothesis]:
    """The coarse stage's starts: the ranked reference frames and the PnP pose, or only the uninformed
    start of the no-coarse ablation; none when no reference frame shares a matched landmark."""
    boxes = {mt.landmark: objects[mt.query].box.astype(np.float64) for mt in matches}
    prior = rank_reference_frames(boxes, m.reference_frames, ranking)
    if prior is None:
        return []
    diag["reference_frame"] = {
        "index": prior.frame.index,
        "shared": prior.shared,
        "score": round(prior.score, 4),
        "ranking": prior.ranking,
    }
    if no_coarse:
        return [Hypothesis("uninformed", uninformed_start(m, [mt.landmark for mt in matches]), matches)]
    ranked = prior.ranked[: max(1, cfg.top_frames)]
    out = [Hypothesis(f"reference:{f.index}", f.T_wc, matches, f.index) for f in ranked]
    if cfg.pnp:
        qmasks = [objects[mt.query].mask for mt in matches]
        centroids = np.array([np.argwhere(mk)[:, ::-1].mean(0) for mk in qmasks])
        truncated = np.array([touches_border(mk) for mk in qmasks])
        points = [m.landmarks[mt.landmark].points for mt in matches]
        T = pnp_prior(centroids, truncated, points, K, (m.width, m.height), cfg)
        if T is not None:
            out.append(Hypothesis("pnp", T, matches))
    return out


def uninformed_start(m: ObjectMap, matched: list[int]) -> np.ndarray:
    """The no-coarse ablation's start: at the centroid of all landmarks, at the mean height of the
    reference cameras, looking at the matched landmarks' centroid."""
    centres = np.stack([lm.center for lm in m.landmarks.values()])
    eye = centres.mean(axis=0)
    if m.reference_frames:
        eye[2] = float(np.mean([f.T_wc[2, 3] for f in m.reference_frames]))
    target = np.stack([m.landmarks[i].center for i in matched]).mean(axis=0)
    if np.linalg.norm(target - eye) < 1e-3:
        target = eye + np.array([1.0, 0.0, 0.0])
    return geometry.look_at(eye, target)


def anchor_pose(
    index: AnchorIndex,
    rgb: np.ndarray,
    K: np.ndarray,
    hypotheses: list[Hypothesis],
    frame_landmarks: dict[int, set[int]],
    cfg: AnchorConfig,
    seed: int,
    diag: dict[str, Any],
) -> AnchorPose | None:
    """The keypoint pose (:mod:`.anchors`) from the landmarks the object stages chose: every hypothesis'
    matched landmarks and those its reference frame sees (``frame_landmarks``: frame index -> landmarks)."""
    landmarks = {mt.landmark for h in hypotheses for mt in h.matches}
    for h in hypotheses:
        if h.frame is not None:
            landmarks |= frame_landmarks[h.frame]
    diag["anchors"] = {}
    views = [h.T_wc for h in hypotheses]
    return index.localize(rgb, K, landmarks, views, cfg, seed, diag["anchors"])


def screen_modes(modes: list[Hypothesis], room: int, compare: Compare | None, diag: dict[str, Any]) -> list[Hypothesis]:
    """The further verification modes worth refining, at most ``room``: those whose unrefined pose
    explains the query best by render-and-compare (``compare``), or, without it, the RANSAC's next best."""
    if len(modes) <= room:
        return modes
    if compare is None:
        return modes[:room]
    drawn = compare([h.T_wc for h in modes])
    diag["verification"]["screened"] = {h.source: round(e, 4) for h, e in zip(modes, drawn)}
    keep = sorted(np.argsort(-np.asarray(drawn), kind="stable")[:room].tolist())
    return [modes[j] for j in keep]


def union_of_matches(match_sets: list[list[Match]]) -> tuple[list[Match], list[list[int]]]:
    """The distinct (query object, landmark) matches of all match sets, in order of first use, and each
    set as indices into them: one refinement batch serves hypotheses with different matches."""
    first: dict[tuple[int, int], Match] = {}
    for mt in (mt for ms in match_sets for mt in ms):
        first.setdefault((mt.query, mt.landmark), mt)
    position = {key: i for i, key in enumerate(first)}
    return list(first.values()), [[position[mt.query, mt.landmark] for mt in ms] for ms in match_sets]


def refine_hypotheses(
    hypotheses: list[Hypothesis],
    objects: list[QueryObject],
    m: ObjectMap,
    K: np.ndarray,
    cfg: RefineConfig,
    seed: int,
    occluders: np.ndarray,
) -> RefinedBatch:
    """Refine every hypothesis in one batch: each matched object's mask against its landmark's points."""
    union, target_sets = union_of_matches([h.matches for h in hypotheses])
    targets = [RefineTarget(mt.landmark, m.landmarks[mt.landmark].points, objects[mt.query].mask) for mt in union]
    tables = target_tables(targets, K, cfg, seed, occluders)  # shared with the restarts
    results = refine_poses(
        [h.T_wc for h in hypotheses],
        K,
        targets,
        cfg,
        seed=seed,
        occluders=occluders,
        target_sets=target_sets,
        tables=tables,
    )
    return RefinedBatch(hypotheses, results, union, target_sets, targets, tables)


def choose_hypothesis(losses: list[float], explained: list[float], tie_share: float) -> int:
    """Index of the refined hypothesis to keep: among those explaining at least ``1 - tie_share`` of the
    best render-and-compare score, the lowest ICP loss (the coarse label grid separates wrong solutions
    but cannot rank poses a few decimetres apart; the loss can). Non-finite losses never win."""
    finite = [i for i, v in enumerate(losses) if np.isfinite(v)]
    if not finite:
        return 0
    top = max(explained[i] for i in finite)
    return min((i for i in finite if explained[i] >= (1.0 - tie_share) * top), key=lambda i: (losses[i], i))


def orbit_starts(T_wc: np.ndarray, pivot: np.ndarray, degrees: float, up: np.ndarray) -> list[np.ndarray]:
    """Four camera-to-world poses: ``T_wc`` orbited about ``pivot`` (world point) by -``degrees`` and
    +``degrees`` around the world's vertical axis ``up``, then around the camera's x axis. The pivot
    stays where it was in the image, so each start keeps the matched objects in view."""
    out = []
    for axis in (np.asarray(up, dtype=np.float64), T_wc[:3, 0]):
        for sign in (-1.0, 1.0):
            R = Rotation.from_rotvec(np.radians(sign * degrees) * axis).as_matrix()
            out.append(geometry.make_pose(R @ T_wc[:3, :3], pivot + R @ (T_wc[:3, 3] - pivot)))
    return out


def restart(
    batch: RefinedBatch, best: int, m: ObjectMap, K: np.ndarray, cfg: RefineConfig, seed: int, diag: dict[str, Any]
) -> RefineResult:
    """Basin hopping (``refinement.restart_degrees``): hypothesis ``best`` of ``batch`` refined again from
    starts orbiting its landmarks' centre; the lowest loss wins. The batch's targets and tables, so that
    the same points are subsampled and the losses compare."""
    res, target_set = batch.results[best], batch.target_sets[best]
    pivot = np.mean([m.landmarks[batch.union[i].landmark].center for i in target_set], axis=0)
    starts = orbit_starts(res.T_wc, pivot, cfg.restart_degrees, m.up)
    short = dataclasses.replace(cfg, max_iterations=min(cfg.max_iterations, cfg.restart_iterations))
    hops = refine_poses(
        starts, K, batch.targets, short, seed=seed, target_sets=[target_set] * len(starts), tables=batch.tables
    )
    # over the objects that count in res.loss: a restart that pushes one more object past the outlier
    # factor would otherwise win by dropping it from its own mean
    counted = [i for i in res.object_losses if i not in res.outliers]

    def loss(r: RefineResult) -> float:
        return float(np.mean([r.object_losses[i] for i in counted])) if np.isfinite(r.loss) else math.inf

    hop = min(hops, key=loss)
    won = loss(hop) < (1.0 - cfg.restart_margin) * loss(res)
    diag["restart"] = {"loss": rounded(loss(hop)), "before": rounded(loss(res)), "won": won}
    return hop if won else res


def batch_diag(batch: RefinedBatch, explained: list[float]) -> list[dict[str, Any]]:
    """Each refined hypothesis as the query's diagnostics report it."""
    return [
        {
            "source": h.source,
            "initial_loss": rounded(r.initial_loss),
            "loss": rounded(r.loss),
            "explained": round(e, 4),
            "iterations": r.iterations,
            "T_wc": np.round(r.T_wc, 6).tolist(),
        }
        for h, r, e in zip(batch.hypotheses, batch.results, explained)
    ]


def rounded(v: float) -> float | None:
    """A loss or a similarity as the diagnostics report it: 4 decimals, None when not finite."""
    return round(float(v), 4) if np.isfinite(v) else None
