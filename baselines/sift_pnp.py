"""``sift-pnp``: hloc's structure-based localization with hand-crafted features.

Mapping: OpenCV SIFT on every mapping frame, each keypoint lifted to a world point through the
frame's depth and pose, and a per-scene VLAD over RootSIFT for retrieval. Query: SIFT, the top-k
mapping frames by VLAD, 2D-3D matches by Lowe's ratio test against each retrieved frame, pose by
pycolmap's LO-RANSAC + refinement, accepted with enough inliers, otherwise a ``Failure``.

Masks are ignored (``uses_masks = False``): the oracle-mask and predicted tracks give the same poses.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from baselines.features import FeatureMap, build_feature_map
from baselines.frame_retrieval import Vlad, VladConfig, top_k
from openreloc_bench import config as cfglib
from openreloc_bench.data.types import SceneSequence
from openreloc_bench.methods import DRAWN_POINTS, Failure, MapPoints, PoseEstimate, QueryFrame, drawn_points
from openreloc_bench.vision.absolute_pose import AbsolutePoseConfig, estimate_absolute_pose
from openreloc_bench.vision.local_features import SiftConfig, extract_sift, root_sift

MAP_FORMAT = "sift-pnp-map"
MAP_VERSION = 1


@dataclass
class SiftPnPConfig:
    """Every setting of :class:`SiftPnP`; the defaults are the named default chosen on the validation suite."""

    features: SiftConfig = field(default_factory=SiftConfig)
    """SIFT detector, for mapping and query frames alike."""
    max_depth_step: float = 0.05
    """A mapping keypoint gets a world point only where the depth of its 3x3 pixels varies by at most
    this fraction of its own (no points from depth edges)."""
    vlad: VladConfig = field(default_factory=VladConfig)
    """Per-scene VLAD vocabulary for retrieval."""
    retrieval_k: int = 10
    """Mapping frames retrieved per query; matches are pooled over all of them."""
    ratio: float = 0.8
    """Lowe's ratio test: a mapping keypoint matches its nearest query keypoint when that is closer
    than ``ratio`` times the second nearest (RootSIFT Euclidean distance; hloc's 0.8 for SIFT)."""
    flann_checks: int = 128
    """Leaves the (seeded, randomised) FLANN kd-trees visit per search: speed against exactness."""
    pose: AbsolutePoseConfig = field(default_factory=lambda: AbsolutePoseConfig(max_iterations=2000))
    """LO-RANSAC and refinement; at most 2000 iterations, which bound the latency of queries with
    many matches (chosen with the ratio on the validation suite, docs/experiments.md)."""
    min_inliers: int = 16
    """A pose is returned when at least this many query keypoints are inliers, otherwise a ``Failure``
    (below it, on the validation suite, most returned poses were wrong)."""

    def __post_init__(self) -> None:
        if self.retrieval_k < 1 or self.flann_checks < 1 or self.min_inliers < 4:
            raise ValueError("need retrieval_k >= 1, flann_checks >= 1 and min_inliers >= 4")
        if not 0 < self.ratio <= 1 or not self.max_depth_step > 0:
            raise ValueError("need 0 < ratio <= 1 and max_depth_step > 0")


class SiftPnP:
    """SIFT + VLAD retrieval + ratio-test matching + pycolmap LO-RANSAC (see the module doc)."""

    name = "sift-pnp"
    reference = "Sarlin et al., From Coarse to Fine: Robust Hierarchical Localization at Large Scale, CVPR 2019 (hloc), with SIFT; https://github.com/cvg/Hierarchical-Localization"
    uses_masks = False
    """Query instance masks (oracle-mask track) are never read."""

    def __init__(self, **overrides: Any):
        self.config: SiftPnPConfig = cfglib.from_dict(SiftPnPConfig, overrides, "sift-pnp")
        self.map: FeatureMap | None = None
        self._vlad: Vlad | None = None
        self._global = np.zeros((0, 0), np.float32)
        """(frames, VLAD dimension) global descriptors of the mapping frames."""

    def map_config(self) -> dict[str, Any]:
        """What the map depends on; retrieval, matching and RANSAC settings share maps."""
        c = self.config
        return {
            "features": dataclasses.asdict(c.features),
            "max_depth_step": c.max_depth_step,
            "vlad": dataclasses.asdict(c.vlad),
        }

    def build_map(self, mapping: SceneSequence, map_dir: Path) -> None:
        c = self.config
        fmap = build_feature_map(
            mapping, partial(extract_sift, cfg=c.features), c.max_depth_step, MAP_FORMAT, MAP_VERSION, "sift-pnp map"
        )
        vlad = Vlad.fit(fmap.features.descriptors, c.vlad, root_sift)
        fmap.arrays = {
            **vlad.to_arrays(),
            "vlad": vlad.describe_all(fmap.features.descriptors, fmap.offsets, root_sift).astype(np.float16),
        }
        fmap.meta = {"config": self.map_config(), "stats": {"frames": fmap.n_frames, "keypoints": len(fmap.points)}}
        fmap.save(map_dir)

    def map_points(self, map_dir: Path) -> MapPoints:
        return FeatureMap.load(map_dir, MAP_FORMAT, MAP_VERSION).drawn()

    def load_map(self, map_dir: Path) -> None:
        self.map = FeatureMap.load(map_dir, MAP_FORMAT, MAP_VERSION)
        self._vlad = Vlad.from_arrays(self.map.arrays)
        self._global = self.map.arrays["vlad"].astype(np.float32)

    def localize(self, query: QueryFrame) -> PoseEstimate | Failure:
        if self.map is None or self._vlad is None:
            raise RuntimeError("load_map() must be called before localize()")
        c, fmap = self.config, self.map
        t0 = time.perf_counter()
        feats = extract_sift(query.color, c.features)
        diag: dict[str, Any] = {"keypoints": len(feats)}
        if len(feats) < c.min_inliers:
            return Failure(f"{len(feats)} SIFT keypoints, fewer than min_inliers={c.min_inliers}", diag)
        q = root_sift(feats.descriptors)
        frames = top_k(self._global, self._vlad.describe(q), c.retrieval_k)
        t1 = time.perf_counter()
        qi, rows = self._match(q, frames)
        diag.update(retrieved=frames.tolist(), matches=len(qi))
        t2 = time.perf_counter()
        h, w = query.color.shape[:2]
        pose = estimate_absolute_pose(feats.xy[qi], fmap.points[rows], query.K, w, h, c.pose)
        diag["timing_s"] = {"extract_retrieve": t1 - t0, "match": t2 - t1, "pose": time.perf_counter() - t2}
        # a query keypoint may match the same point in several retrieved frames: count keypoints
        kept = np.zeros(0, int) if pose is None else np.unique(qi[pose.inliers])
        n_inliers = len(kept)
        diag["inliers"] = n_inliers
        matched = np.unique(qi)
        diag[DRAWN_POINTS] = drawn_points(feats.xy[matched], np.isin(matched, kept))
        if pose is None or n_inliers < c.min_inliers:
            return Failure(f"{n_inliers} inliers of {len(qi)} matches, fewer than min_inliers={c.min_inliers}", diag)
        return PoseEstimate(pose.T_wc, diag, confidence=n_inliers)

    def _match(self, q: np.ndarray, frames: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Ratio-test matches ``(query keypoint indices, map rows)`` against each retrieved frame.

        hloc matches the query with each retrieved image separately, so that the ratio test compares
        two features of one image (the same point seen in several retrieved frames would otherwise
        fail it). Here one kd-tree over all retrieved frames returns each query keypoint's
        ``2 x retrieval_k`` nearest map keypoints, and per frame the nearest is tested against that
        frame's second nearest, or, where the frame's second is not among them, against the farthest
        returned: with exact search a bound that can only reject, never accept, a match the pairwise
        test would not (``flann_checks`` sets how close to exact the search is). FLANN's randomised
        trees are seeded, so a query gets the same answer in any order.
        """
        c, fmap = self.config, self.map
        rows = fmap.rows(frames)
        k = min(2 * c.retrieval_k, len(rows))
        if not len(q) or k < 2:
            return np.zeros(0, int), np.zeros(0, int)
        cv2.setRNGSeed(0)
        index = cv2.flann_Index(root_sift(fmap.features.descriptors[rows]), {"algorithm": 1, "trees": 4})  # kd-tree
        nn, dist2 = index.knnSearch(q, k, params={"checks": max(c.flann_checks, k)})
        valid = nn >= 0
        nn = np.where(valid, nn, 0)
        dist2 = np.where(valid, dist2, np.inf)
        frame = np.where(valid, np.repeat(np.arange(len(frames)), np.diff(fmap.offsets)[frames])[nn], -1)
        second = np.broadcast_to(dist2[:, -1:], dist2.shape).copy()  # the bound where a frame's second is absent
        first = valid.copy()
        for j in range(1, k):  # each frame's first and second among the k neighbours (k is small)
            same = (frame[:, :j] == frame[:, j : j + 1]) & valid[:, j : j + 1]
            earlier = same.sum(axis=1)
            first[:, j] &= earlier == 0
            is_second = same & first[:, :j] & (earlier == 1)[:, None]
            second[:, :j] = np.where(is_second, dist2[:, j : j + 1], second[:, :j])
        keep = first & (dist2 < c.ratio**2 * second)  # squared L2 distances
        qi, j = np.nonzero(keep)
        return qi, rows[nn[qi, j]]
