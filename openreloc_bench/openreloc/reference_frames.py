"""Object-oriented reference frames (paper section 3.1, "Distribution of Reference Frames").

A *sighting* is one landmark seen by one mapping frame: its visibility (share of the landmark's
scene points that project inside the image, in front of the camera and are not occluded, i.e. pass
the depth test of :func:`~openreloc_bench.reconstruction.observation.observe`) and the 2D box of those
points. The depth test matters: without it a chair behind a wall would count as visible.

Reference frames keep only a pose and {landmark id: 2D box}. Frames are visited in capture order and
one is kept when a landmark appears for the first time, or when a landmark's visibility exceeds
``gain`` (2x in the paper) times its best visibility in the reference frames kept so far.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from openreloc_bench.config import check_ranges
from openreloc_bench.openreloc.map import ReferenceFrame
from openreloc_bench.reconstruction.observation import FrameObservation


@dataclass
class ReferenceFrameConfig:
    """Which mapping frames become reference frames."""

    gain: float = 2.0
    """Keep a frame when a landmark's visibility exceeds this times its best in earlier reference frames."""
    min_visibility: float = 0.05
    """A landmark counts as seen in a frame (for appearing, boxes and n_views) above this visibility."""
    min_points: int = 5
    """...and with at least this many seen points (one stray point is not a sighting)."""

    def __post_init__(self) -> None:
        check_ranges(self, positive=("gain",), non_negative=("min_points",), share=("min_visibility",))


@dataclass
class Sightings:
    """Every (frame, landmark) pair with visible points, as flat arrays."""

    frame: np.ndarray
    """(S,) mapping frame index."""
    landmark: np.ndarray
    """(S,) landmark id."""
    visibility: np.ndarray
    """(S,) share of the landmark's points seen by the frame."""
    n_points: np.ndarray
    """(S,) number of the landmark's points seen."""
    box: np.ndarray
    """(S, 4) float32 [x0, y0, x1, y1] of the seen points' pixels (x1, y1 exclusive)."""

    def select(self, keep: np.ndarray) -> Sightings:
        return Sightings(
            self.frame[keep], self.landmark[keep], self.visibility[keep], self.n_points[keep], self.box[keep]
        )


def landmark_sightings(obs: list[FrameObservation], labels: np.ndarray, cfg: ReferenceFrameConfig) -> Sightings:
    """Visibility and 2D box of every landmark in every observed frame (point labels: 0 = none)."""
    sizes = np.bincount(labels, minlength=1)
    parts = []
    for o in obs:
        lab = labels[o.point_idx]
        fg = lab > 0
        if not fg.any():
            continue
        lab, uv = lab[fg], o.uv[fg].astype(np.float32)
        order = np.argsort(lab, kind="stable")
        lab, uv = lab[order], uv[order]
        ids, start, count = np.unique(lab, return_index=True, return_counts=True)
        lo = np.minimum.reduceat(uv, start, axis=0)
        hi = np.maximum.reduceat(uv, start, axis=0) + 1.0
        parts.append((np.full(len(ids), o.index), ids, count / sizes[ids], count, np.concatenate([lo, hi], axis=1)))
    if not parts:
        return Sightings(
            np.zeros(0, int), np.zeros(0, int), np.zeros(0), np.zeros(0, int), np.zeros((0, 4), np.float32)
        )
    f, i, v, n, b = (np.concatenate(x) for x in zip(*parts))
    s = Sightings(
        f.astype(np.int64), i.astype(np.int64), v.astype(np.float64), n.astype(np.int64), b.astype(np.float32)
    )
    return s.select((s.visibility >= cfg.min_visibility) & (s.n_points >= cfg.min_points))


def select_reference_frames(sightings: Sightings, poses: np.ndarray, cfg: ReferenceFrameConfig) -> list[ReferenceFrame]:
    """Greedy selection in frame order: keep a frame that shows a new landmark or a much better view."""
    best: dict[int, float] = {}
    out = []
    for f in np.unique(sightings.frame):
        s = sightings.select(sightings.frame == f)
        ids = [int(i) for i in s.landmark]
        if not any(i not in best or v > cfg.gain * best[i] for i, v in zip(ids, s.visibility)):
            continue
        for i, v in zip(ids, s.visibility):
            best[i] = max(best.get(i, 0.0), float(v))
        out.append(
            ReferenceFrame(
                index=int(f),
                T_wc=np.asarray(poses[f], dtype=np.float64),
                boxes={i: b.copy() for i, b in zip(ids, s.box)},
                visibility={i: float(v) for i, v in zip(ids, s.visibility)},
            )
        )
    return out
