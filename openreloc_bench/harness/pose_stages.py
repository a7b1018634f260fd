"""Where OpenReLoc's pose is lost, read from its diagnostics and the true pose alone (no instance labels).

A query's diagnostics name every stage's outcome: segments, unique objects, matches and how association
made each, the verification's inliers, the coarse stage's reference frames, the chosen start and the
final pose. With the true pose beside them (a real recording's ground truth), they say whether the
coarse prior was already right, whether refinement moved away from it, and which share of the wrong
poses had a right prior -- on any scene, generated or recorded, since nothing here needs to know which
object a segment shows. :func:`query_stages` reads one query, :func:`summarize_stages` pools them.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from openreloc_bench import geometry
from openreloc_bench.harness.metrics import summarize
from openreloc_bench.openreloc.map import ObjectMap

RIGHT_M = 0.25
"""A pose within this distance of the truth is right (the paper's tighter threshold)."""
MOVED_M = 0.05
"""Refinement made a pose worse (or better) when it moved it this much farther from (closer to) the truth."""
HOWS = ("agree", "graph", "visual", "fallback", "verified")
"""How association (or the verification, 'verified') made a match: :class:`openreloc.association.Match`."""


@dataclass
class QueryStages:
    """One query's stages, each pose as (translation error m, rotation error deg); inf where absent."""

    detected: int = 0
    unique: int = 0
    matches: Counter[str] = field(default_factory=Counter)
    """Accepted matches by how they were made."""
    verification_inliers: int | None = None
    """Objects the verification's consensus pose explains (None: the query never reached it)."""
    anchor_inliers: int | None = None
    """Keypoints that agree with the keypoint pose (None: no keypoint pose was tried or found)."""
    chosen: str | None = None
    """Where the returned pose comes from: 'anchors' (the keypoint pose) or a refined hypothesis."""
    prior: tuple[float, float] = (np.inf, np.inf)
    """The coarse prior: the reference frame ranked first (paper Eq. 6)."""
    best_reference: tuple[float, float] = (np.inf, np.inf)
    """The nearest of the reference frames that started a refinement."""
    start: tuple[float, float] = (np.inf, np.inf)
    """The start of the refinement whose result was returned."""
    final: tuple[float, float] = (np.inf, np.inf)
    reason: str | None = None
    """The failure's reason, when the method returned none."""

    def to_dict(self) -> dict[str, Any]:
        """As JSON holds it: errors rounded, None for a missing pose."""
        out: dict[str, Any] = dict(vars(self), matches=dict(self.matches))
        for key in POSES:
            out[key] = None if not np.isfinite(out[key][0]) else [round(v, 4) for v in out[key]]
        return out

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> QueryStages:
        poses = {k: (np.inf, np.inf) if d[k] is None else tuple(d[k]) for k in POSES}
        return cls(**{**d, **poses, "matches": Counter(d["matches"])})


POSES = ("prior", "best_reference", "start", "final")
"""The poses :class:`QueryStages` holds as (translation, rotation) errors."""


def query_stages(
    diag: dict[str, Any], T_est: np.ndarray | None, T_gt: np.ndarray, m: ObjectMap, reason: str | None = None
) -> QueryStages:
    """A query's stages from its diagnostics, its estimate (None: a failure, for ``reason``) and its true pose."""

    def error(T: Any) -> tuple[float, float]:
        if T is None:
            return (np.inf, np.inf)
        t, r = geometry.pose_errors(T_gt, np.asarray(T, dtype=np.float64))
        return (float(t), float(r))

    frames = {f.index: f.T_wc for f in m.reference_frames}
    prior = diag.get("reference_frame", {}).get("index")
    starts = [
        error(frames.get(int(h["source"].split(":")[1])))
        for h in diag.get("hypotheses", [])
        if h["source"].startswith("reference:")
    ]
    ver = diag.get("verification")
    anchors = diag.get("anchors", {})
    return QueryStages(
        detected=int(diag.get("detected", 0)),
        unique=int(diag.get("unique", 0)),
        matches=Counter(mt["how"] for mt in diag.get("matches", [])),
        verification_inliers=None if ver is None else int(ver.get("inliers", 0)),
        anchor_inliers=anchors.get("inliers"),
        chosen=diag.get("chosen"),
        prior=error(frames.get(prior)) if prior is not None else (np.inf, np.inf),
        best_reference=min(starts, default=(np.inf, np.inf)),
        start=error(diag.get("prior_T_wc")),
        final=error(T_est),
        reason=reason,
    )


def _recall(errors: list[tuple[float, float]]) -> dict[str, float | None]:
    """Recalls and median errors of one pose of every query (None where no query or no finite median)."""
    t, r = (np.array(v, dtype=np.float64) for v in zip(*errors)) if errors else (np.zeros(0), np.zeros(0))
    s = summarize(t, r)
    keys = ("recall_50cm", "recall_25cm", "recall_25cm_5deg", "median_te_m", "median_re_deg")
    return {k: s[k] if np.isfinite(s[k]) else None for k in keys}


def summarize_stages(rows: list[QueryStages]) -> dict[str, Any]:
    """Every stage over a split's queries (see the module doc); shares in percent of the queries (or
    matches) that reached the stage, None where none did."""
    n = len(rows)
    matched = Counter[str]()
    for q in rows:
        matched.update(q.matches)
    n_matches = sum(matched.values())
    verified = [q.verification_inliers for q in rows if q.verification_inliers is not None]
    by_keypoints = [q for q in rows if q.chosen == "anchors"]
    by_objects = [q for q in rows if q.chosen is not None and q.chosen != "anchors"]  # refined hypotheses
    refined = [q for q in by_objects if np.isfinite(q.final[0]) and np.isfinite(q.start[0])]
    wrong = [q for q in rows if not q.final[0] < RIGHT_M]

    def pct(k: int, of: int) -> float | None:
        return 100.0 * k / of if of else None

    return {
        "queries": n,
        "segments_per_query": float(np.median([q.detected for q in rows])) if rows else None,
        "unique_per_query": float(np.median([q.unique for q in rows])) if rows else None,
        "matches_per_query": n_matches / n if n else None,
        "matches_by_how": {h: pct(matched[h], n_matches) for h in HOWS},
        "modalities_agree": pct(matched["agree"], n_matches - matched["verified"]),
        "verification_pass_rate": pct(sum(v > 0 for v in verified), len(verified)),
        "keypoint_pose": _recall([q.final for q in by_keypoints]) | {"share": pct(len(by_keypoints), n)},
        "object_pose": _recall([q.final for q in by_objects]) | {"share": pct(len(by_objects), n)},
        "coarse_prior": _recall([q.prior for q in rows]),
        "best_reference_start": _recall([q.best_reference for q in by_objects]),
        "refinement_start": _recall([q.start for q in rows]),
        "final": _recall([q.final for q in rows]),
        "refinement_median_change_m": (
            float(np.median([q.final[0] - q.start[0] for q in refined])) if refined else None
        ),
        "refinement_worse": pct(sum(q.final[0] > q.start[0] + MOVED_M for q in refined), len(refined)),
        "refinement_better": pct(sum(q.final[0] < q.start[0] - MOVED_M for q in refined), len(refined)),
        "wrong_with_right_prior": pct(sum(q.prior[0] < RIGHT_M for q in wrong), len(wrong)),
        "wrong_with_right_reference": pct(sum(q.best_reference[0] < RIGHT_M for q in wrong), len(wrong)),
        "failures": dict(Counter(_reason_kind(q.reason) for q in rows if q.reason is not None)),
    }


def _reason_kind(reason: str) -> str:
    """A failure's reason without its numbers, so that alike reasons pool."""
    return " ".join(w for w in reason.split() if not any(c.isdigit() for c in w))


def pool_stages(parts: list[list[dict[str, Any]]]) -> dict[str, Any]:
    """The stages of several scenes' queries (:meth:`QueryStages.to_dict`) as one split."""
    return summarize_stages([QueryStages.from_dict(q) for p in parts for q in p])


def map_summary(m: ObjectMap) -> dict[str, Any]:
    """The map's landmarks and their sizes: what the queries can match."""
    points = np.array([len(lm.points) for lm in m.landmarks.values()])
    extent = np.array([float(np.linalg.norm(lm.box_max - lm.box_min)) for lm in m.landmarks.values()])
    return {
        "landmarks": len(m.landmarks),
        "valid_landmarks": len(m.valid_ids()),
        "reference_frames": len(m.reference_frames),
        "points_per_landmark": _spread(points),
        "landmark_extent_m": _spread(extent),
        "cross_view_recall": m.stats.get("cross_view_recall"),
    }


def _spread(values: np.ndarray) -> dict[str, float]:
    """10th percentile, median and 90th percentile."""
    if not len(values):
        return {"p10": float("nan"), "median": float("nan"), "p90": float("nan")}
    p10, median, p90 = np.percentile(values, [10, 50, 90])
    return {"p10": float(p10), "median": float(median), "p90": float(p90)}
