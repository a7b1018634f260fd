"""Coarse stage: pick the reference frame whose view best matches the query (paper Eq. 6).

First the reference frames that contain the largest number of the query's matched landmarks (a
co-visible subset), then, among those, the one whose 2D boxes of the shared landmarks best agree
with the query's boxes under the DIoU distance ``1 - IoU + |b_q - b_r|^2 / c^2`` (centre distance
over the squared diagonal of the smallest enclosing box), averaged over the shared landmarks.
Lower is better; unlike plain IoU it still ranks frames whose boxes do not overlap at all.

The ``visibility`` ranking (an ablation) picks, within the same co-visible subset, the frame
where the shared landmarks are most visible (mean visibility), ignoring where they appear.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from openreloc_bench.openreloc.map import ReferenceFrame

Ranking = Literal["diou", "visibility"]


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
class Retrieval:
    """The chosen reference frame and how it was chosen."""

    frame: ReferenceFrame
    shared: list[int]
    """Matched landmark ids the frame contains."""
    score: float
    """Mean DIoU distance (lower is better) or mean visibility (higher is better)."""
    ranking: str
    candidates: list[tuple[int, float]] = field(default_factory=list)
    """(mapping frame index, score) of the co-visible subset, best first."""


def retrieve_reference(
    query_boxes: dict[int, np.ndarray], frames: list[ReferenceFrame], ranking: Ranking = "diou"
) -> Retrieval | None:
    """Best reference frame for the matched landmarks ``{landmark id: query box}``; None if no frame
    shares a landmark with the query."""
    if ranking not in ("diou", "visibility"):
        raise ValueError(f"unknown ranking {ranking!r} (use 'diou' or 'visibility')")
    matched = set(query_boxes)
    shared_counts = [len(matched.intersection(f.boxes)) for f in frames]
    best_count = max(shared_counts, default=0)
    if best_count == 0:
        return None
    scored: list[tuple[float, int, ReferenceFrame, list[int]]] = []
    for k, (f, n) in enumerate(zip(frames, shared_counts)):
        if n != best_count:
            continue
        ids = sorted(matched.intersection(f.boxes))
        if ranking == "diou":
            q = np.stack([query_boxes[i] for i in ids])
            r = np.stack([f.boxes[i] for i in ids])
            score = float(diou_distance(q, r).mean())
            key = score
        else:
            score = float(np.mean([f.visibility.get(i, 0.0) for i in ids]))
            key = -score
        scored.append((key, k, f, ids))
    scored.sort(key=lambda s: (s[0], s[1]))  # ties: earlier frame, so results are deterministic
    key, _, frame, ids = scored[0]
    return Retrieval(
        frame=frame,
        shared=ids,
        score=key if ranking == "diou" else -key,
        ranking=ranking,
        candidates=[(f.index, s if ranking == "diou" else -s) for s, _, f, _ in scored],
    )
