"""Coarse stage: pick the reference frame whose view best matches the query (paper Eq. 6).

First the reference frames that contain the largest number of the query's matched landmarks (a
co-visible subset), then, among those, the one whose 2D boxes of the shared landmarks best agree
with the query's boxes under the DIoU distance ``1 - IoU + |b_q - b_r|^2 / c^2`` (centre distance
over the squared diagonal of the smallest enclosing box), averaged over the shared landmarks.
Lower is better; unlike plain IoU it still ranks frames whose boxes do not overlap at all.

The ``visibility`` ranking (an ablation) picks, within the same co-visible subset, the frame
where the shared landmarks are most visible (mean visibility), ignoring where they appear.

Beyond the paper (:class:`CoarseConfig`, each switchable back to the paper-literal single prior):
queries are deliberately taken from new viewpoints (>= 0.3 m and >= 20 deg from every mapping
frame), so the single best reference frame is often 1-3 m / 30-50 deg away, outside the basin of
the 2D ICP. The coarse stage therefore proposes several hypotheses -- the ``top_frames`` best ranked
reference frames (all frames sharing a landmark, ranked by shared count then DIoU) and a PnP pose
from object correspondences (mask centroids <-> landmark centres, the "rough estimate" of centre
alignment the paper mentions) -- and the refinement keeps the one with the lowest final ICP loss.

:func:`place_landmarks` ranks the reference frames by appearance alone, before any association: the
verification's candidate ranking favours the landmarks of the best ones (``VerifyConfig.place_frames``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import cv2
import numpy as np

from openreloc_bench import geometry
from openreloc_bench.config import check_ranges
from openreloc_bench.openreloc.map import ReferenceFrame

Ranking = Literal["diou", "visibility"]


@dataclass
class CoarseConfig:
    """Pose hypotheses of the coarse stage (see the module docstring)."""

    top_frames: int = 3
    """Beyond the paper: the best this-many reference frames each start a refinement; the lowest final
    loss wins. 1 = the paper's single DIoU-best frame."""
    pnp: bool = True
    """Beyond the paper: add a PnP hypothesis from mask centroids to landmark centres (False = paper)."""
    pnp_min_objects: int = 4
    """Matched objects needed for the PnP hypothesis (3 points give up to 4 ambiguous poses)."""
    pnp_threshold: float = 0.08
    """RANSAC inlier threshold of the PnP, as a share of the image diagonal (centroids of partly
    occluded or large objects are off by tens of pixels)."""
    pnp_iterations: int = 2
    """Re-solves pairing each mask centroid with the centroid of its landmark's in-image points at the
    previous PnP pose (border-truncated objects); 0 = landmark centres only."""

    def __post_init__(self) -> None:
        check_ranges(
            self,
            positive=("pnp_threshold",),
            at_least_one=("top_frames",),
            non_negative=("pnp_min_objects", "pnp_iterations"),
        )


def diou_distance(box_a: np.ndarray, box_b: np.ndarray) -> np.ndarray:
    """DIoU distance between boxes ``[x0, y0, x1, y1]`` (broadcasting over leading dims); in [0, 2)."""
    a = np.asarray(box_a, dtype=np.float64)
    b = np.asarray(box_b, dtype=np.float64)
    iw = np.clip(np.minimum(a[..., 2], b[..., 2]) - np.maximum(a[..., 0], b[..., 0]), 0, None)
    ih = np.clip(np.minimum(a[..., 3], b[..., 3]) - np.maximum(a[..., 1], b[..., 1]), 0, None)
    inter = iw * ih
    area_a = (a[..., 2] - a[..., 0]) * (a[..., 3] - a[..., 1])
    area_b = (b[..., 2] - b[..., 0]) * (b[..., 3] - b[..., 1])
    iou = inter / np.maximum(area_a + area_b - inter, 1e-12)
    ca = (a[..., :2] + a[..., 2:]) / 2
    cb = (b[..., :2] + b[..., 2:]) / 2
    enclosing = np.maximum(a[..., 2:], b[..., 2:]) - np.minimum(a[..., :2], b[..., :2])
    c2 = np.maximum((enclosing**2).sum(-1), 1e-12)
    return 1.0 - iou + ((ca - cb) ** 2).sum(-1) / c2


@dataclass
class CoarsePrior:
    """The coarse prior (the chosen reference frame) and how it was chosen."""

    frame: ReferenceFrame
    shared: list[int]
    """Matched landmark ids the frame contains."""
    score: float
    """Mean DIoU distance (lower is better) or mean visibility (higher is better)."""
    ranking: str
    candidates: list[tuple[int, float]] = field(default_factory=list)
    """(mapping frame index, score) of the co-visible subset, best first."""
    ranked: list[ReferenceFrame] = field(default_factory=list)
    """Every frame sharing a matched landmark: most shared first, then by score (``ranked[0] is frame``)."""


def rank_reference_frames(
    query_boxes: dict[int, np.ndarray], frames: list[ReferenceFrame], ranking: Ranking = "diou"
) -> CoarsePrior | None:
    """Best reference frame for the matched landmarks ``{landmark id: query box}``; None if no frame
    shares a landmark with the query."""
    if ranking not in ("diou", "visibility"):
        raise ValueError(f"unknown ranking {ranking!r} (use 'diou' or 'visibility')")
    matched = set(query_boxes)
    scored: list[tuple[int, float, int, ReferenceFrame, list[int]]] = []
    for k, f in enumerate(frames):
        ids = sorted(matched.intersection(f.boxes))
        if not ids:
            continue
        if ranking == "diou":
            q = np.stack([query_boxes[i] for i in ids])
            r = np.stack([f.boxes[i] for i in ids])
            key = float(diou_distance(q, r).mean())
        else:
            key = -float(np.mean([f.visibility.get(i, 0.0) for i in ids]))
        scored.append((-len(ids), key, k, f, ids))
    if not scored:
        return None
    scored.sort(key=lambda s: s[:3])  # most shared, then score; ties: earlier frame (deterministic)
    sign = 1.0 if ranking == "diou" else -1.0
    _, key, _, frame, ids = scored[0]
    return CoarsePrior(
        frame=frame,
        shared=ids,
        score=sign * key,
        ranking=ranking,
        candidates=[(f.index, sign * sc) for n, sc, _, f, _ in scored if n == scored[0][0]],
        ranked=[f for *_, f, _ in scored],
    )


def place_landmarks(scores: np.ndarray, visible: np.ndarray, frames: int, clip: float = 0.2) -> np.ndarray:
    """(N,) bool: the landmarks seen by the ``frames`` reference frames that look most like the query.

    ``scores`` (Q, N) are the query objects' appearance scores against the landmarks (-inf where a
    landmark must not count), ``visible`` (F, N) which landmarks each reference frame sees. A frame
    scores the sum over objects of how far its best-scoring visible landmark falls short of the object's
    best overall (at most ``clip`` each, so that an object seen nowhere, a wall among them, costs every
    frame alike): object-level place recognition, which needs no hard association. Why: a look-alike in
    another room (a second chair, the same lamp upstairs) is the usual wrong candidate, and the right
    room's frames hold most of a query's true landmarks."""
    scores, visible = np.asarray(scores, np.float64), np.asarray(visible, bool)
    if not len(visible) or not len(scores) or frames <= 0:
        return np.zeros(visible.shape[-1], bool)
    best = scores.max(1, keepdims=True)
    within = np.where(visible[None], scores[:, None, :], -np.inf).max(2)  # (Q, F): each frame's best
    shortfall = np.clip(within - best, -clip, 0.0).sum(0)
    top = np.argsort(-shortfall, kind="stable")[:frames]
    return visible[top].any(0)


def solve_pnp(
    p3: np.ndarray, p2: np.ndarray, K: np.ndarray, ransac_threshold: float | None = None
) -> np.ndarray | None:
    """T_cw from >= 4 2D-3D correspondences: SQPnP, then Levenberg-Marquardt; with ``ransac_threshold``
    (pixels) inside RANSAC and refined on its inliers (at least 4). None when OpenCV finds no finite pose."""
    p3 = np.ascontiguousarray(p3, dtype=np.float64).reshape(-1, 1, 3)
    p2 = np.ascontiguousarray(p2, dtype=np.float64).reshape(-1, 1, 2)
    try:
        if ransac_threshold is None:
            ok, rvec, tvec = cv2.solvePnP(p3, p2, K, None, flags=cv2.SOLVEPNP_SQPNP)
        else:
            ok, rvec, tvec, inliers = cv2.solvePnPRansac(
                p3,
                p2,
                K,
                None,
                iterationsCount=200,
                reprojectionError=ransac_threshold,
                confidence=0.999,
                flags=cv2.SOLVEPNP_SQPNP,
            )
            if not ok or inliers is None or len(inliers) < 4:
                return None
            p3, p2 = p3[inliers.ravel()], p2[inliers.ravel()]
        if not ok:
            return None
        rvec, tvec = cv2.solvePnPRefineLM(p3, p2, K, None, rvec, tvec)
    except cv2.error:
        return None
    T_cw = geometry.make_pose(cv2.Rodrigues(rvec)[0], tvec.ravel())
    return T_cw if np.all(np.isfinite(T_cw)) else None


def pnp_prior(
    centroids: np.ndarray,
    truncated: np.ndarray,
    points: list[np.ndarray],
    K: np.ndarray,
    image_size: tuple[int, int],
    cfg: CoarseConfig,
) -> np.ndarray | None:
    """Camera-to-world pose from object correspondences: query mask centroids (``centroids``, (M, 2))
    <-> the matched landmarks' ``points``; None when there are too few or no consensus.

    A mask cut by the image border only shows part of its object, so its centroid is not the
    projection of the landmark centre. The first solve uses the untruncated objects (all when fewer
    than 4); each of ``pnp_iterations`` further solves pairs every mask centroid with the centroid of
    the landmark points that project inside the image at the previous pose.
    """
    K = np.asarray(K, dtype=np.float64)
    centroids = np.asarray(centroids, dtype=np.float64)
    if len(centroids) < max(4, cfg.pnp_min_objects):
        return None
    w, h = image_size
    thr = cfg.pnp_threshold * float(np.hypot(w, h))
    centres = np.stack([np.asarray(p, np.float64).mean(0) for p in points])
    use = (
        ~np.asarray(truncated, bool)
        if int((~np.asarray(truncated, bool)).sum()) >= 4
        else np.ones(len(centroids), bool)
    )
    T_cw = solve_pnp(centres[use], centroids[use], K, thr)
    for _ in range(cfg.pnp_iterations):
        if T_cw is None:
            break
        visible = []
        T_wc_prev = geometry.invert(T_cw)
        for p in points:
            uv, z = geometry.project(K, T_wc_prev, p)
            inside = (z > 1e-3) & (uv[:, 0] >= -0.5) & (uv[:, 0] < w - 0.5) & (uv[:, 1] >= -0.5) & (uv[:, 1] < h - 0.5)
            visible.append(np.asarray(p, np.float64)[inside].mean(0) if inside.any() else None)
        if any(v is None for v in visible):
            break
        T_next = solve_pnp(np.stack(visible), centroids, K, thr)
        T_cw = T_next if T_next is not None else T_cw
    if T_cw is None or np.any(geometry.transform_points(T_cw, centres)[:, 2] <= 0):
        return None
    return geometry.invert(T_cw)
