"""Object-anchored keypoints (beyond the paper): local features on the landmarks, for the last centimetres.

The paper's pose comes from aligning landmark points with query masks (:mod:`.refine`), which is only as
precise as the masks: decimetres with a learned segmenter, worse on real frames. Here, as in PRAM
(landmark-wise 2D-3D matching) and hloc, each landmark also keeps SIFT keypoints of the mapping frames
that fall on it, lifted to 3D through depth. At query time the query's SIFT keypoints are matched only
against the keypoints of the landmarks the object stages chose -- associated, verified, or seen by the
ranked reference frames -- so the objects do the retrieval and no global search is made; the pose comes
from pycolmap's LO-RANSAC with refinement. Where keypoints fail (dark, textureless, too few inliers),
the object pose stands.

Mapping (:func:`build_anchors`): SIFT on every mapping frame; a keypoint belongs to the landmark whose
scene points lie within ``support_radius`` of its 3D point (keypoints off every landmark are dropped).
Each ``voxel`` of a landmark keeps the ``per_voxel`` points seen in the most mapping frames, one
descriptor each (:func:`_most_seen`), as an SfM map keeps one point per track rather than every view of
it; the descriptors are then stored in ``descriptor_bytes`` bytes each by product quantisation
(:class:`DescriptorCodec`) fitted on the map's own. Both bound the map (storage and matching time)
while keeping every part of every object.

Query (:func:`match_anchors`): a query keypoint matches its nearest anchor (RootSIFT) when that is
closer than ``ratio`` times the nearest anchor lying elsewhere (farther than ``distinct_m`` in 3D): the
same point seen from several mapping frames gives near-identical anchors, which must not fail the
ratio test for one another.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np
from scipy.spatial import cKDTree

from openreloc_bench import geometry
from openreloc_bench.bars import tqdm
from openreloc_bench.config import check_ranges
from openreloc_bench.data.types import SceneSequence
from openreloc_bench.methods import DRAWN_POINTS, drawn_points
from openreloc_bench.vision.absolute_pose import AbsolutePoseConfig, estimate_absolute_pose
from openreloc_bench.vision.local_features import SiftConfig, extract_sift, lift, root_sift

DESCRIPTOR_SIZE = 128
"""SIFT's descriptor length."""


@dataclass
class AnchorBuildConfig:
    """Which keypoints a landmark keeps (mapping; recorded in the map)."""

    enabled: bool = True
    """Keep keypoints on the landmarks (False: a map without them, as the paper's)."""
    features: SiftConfig = field(default_factory=lambda: SiftConfig(max_keypoints=2000))
    """SIFT of the mapping frames, and of the queries matched against them."""
    max_depth_step: float = 0.05
    """A keypoint gets a 3D point only where the depth of its 3x3 pixels varies by at most this share of
    its own (none from depth edges, where a pixel may take either side's depth)."""
    support_radius: float = 0.03
    """A keypoint belongs to a landmark when one of the landmark's scene points lies this close (m)."""
    voxel: float = 0.05
    """Side (m) of the cells in which a landmark's keypoints are thinned."""
    per_voxel: int = 4
    """Points kept per cell, those seen in the most mapping frames first (one a cell lost a third of a
    real recording's queries)."""
    same_point: float = 0.3
    """RootSIFT distance under which two keypoints of a cell count as views of one point."""
    descriptor_bytes: int = 32
    """Bytes a stored descriptor keeps (product quantisation; a divisor of 128, where 128 keeps each
    dimension at 256 levels)."""

    def __post_init__(self) -> None:
        check_ranges(
            self,
            positive=("max_depth_step", "support_radius", "voxel", "same_point"),
            at_least_one=("per_voxel",),
        )
        if self.descriptor_bytes < 1 or DESCRIPTOR_SIZE % self.descriptor_bytes:
            raise ValueError(f"descriptor_bytes must divide {DESCRIPTOR_SIZE}, got {self.descriptor_bytes}")


@dataclass
class AnchorConfig:
    """Matching the query against the chosen landmarks' keypoints (query time)."""

    enabled: bool = True
    """Match keypoints where the map has them (False: the object pose only, as the paper)."""
    ratio: float = 0.8
    """Lowe's ratio test against the nearest anchor lying elsewhere (hloc's 0.8 for SIFT)."""
    distinct_m: float = 0.05
    """Anchors closer than this (m) to the nearest one are views of the same point, not rivals."""
    neighbours: int = 8
    """Nearest anchors searched per query keypoint (to find the nearest one lying elsewhere)."""
    min_inliers: int = 10
    """Query keypoints that must agree with the keypoint pose for it to be returned; with fewer, the pose
    only joins the object stage's hypotheses (from ``seed_inliers``), which render-and-compare judges.
    Chosen on the validation suite (lower thresholds place more queries there) and checked on real
    recordings, where poses with 8 inliers were wrong and none with 10 or more."""
    seed_inliers: int = 8
    """Inliers a keypoint pose needs to join the object stage's hypotheses."""
    view_margin: float = 0.5
    """Only anchors that project within the image grown by this share of its size on every side, at
    one of the object stage's hypotheses, are matched: the hypotheses lie near the query, and a large
    landmark's far side costs matching time without matching."""
    max_anchors: int = 40_000
    """At most this many candidate anchors are matched (a seeded random subset of more): the matching
    index is built per query, and its time grows with them."""
    keep_prior: bool = True
    """Reject a refinement that leaves its keypoint evidence: where the refined pose explains fewer
    keypoint matches than its starting prior (and the prior at least ``seed_inliers``), the prior is
    returned instead."""
    pose: AbsolutePoseConfig = field(default_factory=lambda: AbsolutePoseConfig(max_iterations=2000))
    """LO-RANSAC and refinement of the keypoint pose."""

    def __post_init__(self) -> None:
        check_ranges(
            self,
            positive=("distinct_m",),
            non_negative=("view_margin",),
            share=("ratio",),
            at_least_one=("neighbours", "seed_inliers", "max_anchors"),
        )
        if not 4 <= self.seed_inliers <= self.min_inliers:
            raise ValueError(f"need 4 <= seed_inliers <= min_inliers, got {self.seed_inliers} and {self.min_inliers}")


@dataclass
class DescriptorCodec:
    """RootSIFT descriptors as product-quantisation codes (Jegou et al. 2011; faiss trains and encodes):
    the descriptor is cut into one part per byte, each stored as the nearest of 256 centroids fitted on
    the map's own. Matching decodes them once (:meth:`decode`) and compares queries' descriptors with
    the decoded ones."""

    centroids: np.ndarray
    """(bytes, 256, 128 / bytes) float32: the centroids of every part."""

    @classmethod
    def fit(cls, root: np.ndarray, n_bytes: int) -> tuple[DescriptorCodec, np.ndarray]:
        """The codec of ``n_bytes`` parts fitted on RootSIFT descriptors ``root`` (N, 128), and their
        (N, n_bytes) uint8 codes. Seeded and on one thread: the same map, byte for byte, every time."""
        import faiss  # only when a map is built

        pq = faiss.ProductQuantizer(DESCRIPTOR_SIZE, n_bytes, 8)
        pq.cp.seed, pq.cp.min_points_per_centroid = 0, 1  # (a small map: fewer points than centroids)
        train = np.ascontiguousarray(np.resize(root, (max(len(root), 256), DESCRIPTOR_SIZE)), np.float32)
        threads = faiss.omp_get_max_threads()
        faiss.omp_set_num_threads(1)
        try:
            pq.train(train)
            codes = pq.compute_codes(np.ascontiguousarray(root, np.float32))
        finally:
            faiss.omp_set_num_threads(threads)
        centroids = faiss.vector_to_array(pq.centroids).reshape(n_bytes, 256, DESCRIPTOR_SIZE // n_bytes)
        return cls(centroids.astype(np.float32)), codes

    @classmethod
    def empty(cls) -> DescriptorCodec:
        return cls(np.zeros((0, 256, 0), np.float32))

    def decode(self, codes: np.ndarray) -> np.ndarray:
        """(N, 128) float32 descriptors the (N, bytes) codes stand for."""
        parts = self.centroids[np.arange(len(self.centroids)), codes.astype(np.intp)]  # (N, bytes, 128 / bytes)
        return np.ascontiguousarray(parts.reshape(len(codes), -1), np.float32)


@dataclass
class Anchors:
    """Every kept keypoint of every landmark."""

    xyz: np.ndarray
    """(N, 3) float32 world points."""
    codes: np.ndarray
    """(N, bytes) uint8 product-quantised RootSIFT descriptors."""
    landmark: np.ndarray
    """(N,) int32 landmark id."""
    codec: DescriptorCodec = field(default_factory=DescriptorCodec.empty)
    """How ``codes`` stand for RootSIFT descriptors."""

    def __len__(self) -> int:
        return len(self.xyz)

    @classmethod
    def empty(cls) -> Anchors:
        return cls(np.zeros((0, 3), np.float32), np.zeros((0, 0), np.uint8), np.zeros(0, np.int32))


def build_anchors(
    seq: SceneSequence, points: np.ndarray, labels: np.ndarray, cfg: AnchorBuildConfig, progress: bool = True
) -> Anchors:
    """The keypoints of the mapping frames on the landmarks: ``points`` (N, 3) is the scene cloud and
    ``labels`` (N,) each point's landmark (0: none)."""
    on = labels > 0
    if not on.any() or not seq.has_depth:
        return Anchors.empty()
    tree, owner = cKDTree(points[on]), labels[on].astype(np.int32)
    xyz, root, landmark = [], [], []
    for frame in tqdm(seq, total=len(seq), desc="anchors", disable=not progress, leave=False):
        feats = extract_sift(frame.color, cfg.features)
        lifted, valid = lift(feats.xy, frame.depth, frame.K, frame.T_wc, cfg.max_depth_step)
        dist, nearest = tree.query(lifted[valid], distance_upper_bound=cfg.support_radius)
        found = np.isfinite(dist)
        rows = np.flatnonzero(valid)[found]
        xyz.append(lifted[rows].astype(np.float32))
        root.append(root_sift(feats.descriptors[rows]))
        landmark.append(owner[nearest[found]])
    every_xyz, every_root, every_landmark = (np.concatenate(a) for a in (xyz, root, landmark))
    if not len(every_xyz):
        return Anchors.empty()
    keep = _most_seen(every_xyz, every_root, every_landmark, cfg)
    codec, codes = DescriptorCodec.fit(every_root[keep], cfg.descriptor_bytes)
    return Anchors(every_xyz[keep], codes, every_landmark[keep], codec)


def _most_seen(xyz: np.ndarray, root: np.ndarray, landmark: np.ndarray, cfg: AnchorBuildConfig) -> np.ndarray:
    """Rows kept, sorted: in each (landmark, voxel) cell, the keypoint with the most others within
    ``same_point`` of its RootSIFT descriptor (its views), then the same among those it does not cover,
    up to ``per_voxel`` (a greedy cover; ties to the earlier keypoint)."""
    cell = np.floor(xyz / cfg.voxel).astype(np.int64)
    _, group = np.unique(np.column_stack([landmark, cell]), axis=0, return_inverse=True)
    order = np.argsort(group.ravel(), kind="stable")
    bounds = np.flatnonzero(np.diff(group.ravel()[order])) + 1
    near = 2.0 - cfg.same_point**2  # unit vectors: |a - b|^2 = 2 - 2 a.b
    kept = []
    for rows in np.split(order, bounds):
        if len(rows) == 1:
            kept.append(rows)
            continue
        views = 2.0 * (root[rows] @ root[rows].T) > near
        uncovered = np.ones(len(rows), bool)
        for _ in range(cfg.per_voxel):
            counts = (views & uncovered).sum(axis=1) * uncovered
            best = int(np.argmax(counts))
            if not uncovered[best]:
                break
            kept.append(rows[best : best + 1])
            uncovered &= ~views[best]
    return np.sort(np.concatenate(kept))


@dataclass
class AnchorPose:
    """The keypoint pose of a query and its evidence."""

    T_wc: np.ndarray
    inliers: int
    """Query keypoints that agree with the pose."""
    matches: int
    """Query keypoints matched (the ratio test's survivors)."""
    landmarks: dict[int, int]
    """Landmark id -> inliers on it."""
    points2d: np.ndarray
    """(matches, 2) the matched query keypoints' pixels."""
    points3d: np.ndarray
    """(matches, 3) their anchors' world points."""

    def support(self, T_wc: np.ndarray, K: np.ndarray, max_error_px: float) -> int:
        """Matches that project within ``max_error_px`` of their keypoint at camera-to-world ``T_wc``:
        the keypoint evidence for any pose, the object stages' too."""
        uv, z = geometry.project(K, T_wc, self.points3d)
        return int(((z > 0) & (np.linalg.norm(uv - self.points2d, axis=1) < max_error_px)).sum())


def refined_or_prior(
    anchored: AnchorPose | None, prior: np.ndarray, refined: np.ndarray, K: np.ndarray, cfg: AnchorConfig
) -> tuple[np.ndarray, float]:
    """The pose an object-stage refinement ends at and its confidence (keypoint support: 0 where the
    keypoint stage found no pose, NaN with anchors switched off): ``refined``, unless
    :attr:`AnchorConfig.keep_prior` finds that it leaves the keypoint evidence its ``prior`` had."""
    if anchored is None:
        return refined, 0.0 if cfg.enabled else float("nan")
    at_prior, at_refined = (anchored.support(T, K, cfg.pose.max_error_px) for T in (prior, refined))
    if cfg.keep_prior and at_prior >= cfg.seed_inliers and at_refined < at_prior:
        return prior, float(at_prior)
    return refined, float(at_refined)


class AnchorIndex:
    """A map's anchors ready for queries: their descriptors decoded once."""

    def __init__(self, anchors: Anchors, features: SiftConfig):
        self.anchors, self.features = anchors, features
        self.space = anchors.codec.decode(anchors.codes)

    def localize(
        self,
        rgb: np.ndarray,
        K: np.ndarray,
        landmarks: set[int],
        views: list[np.ndarray],
        cfg: AnchorConfig,
        seed: int,
        diag: dict[str, Any],
    ) -> AnchorPose | None:
        """The keypoint pose from the anchors of ``landmarks`` seen from one of ``views`` (camera-to-world
        poses near the query: :attr:`AnchorConfig.view_margin`; none: every anchor of ``landmarks``);
        None without one (too few anchors, keypoints or matches, or no model)."""
        rows = np.flatnonzero(np.isin(self.anchors.landmark, sorted(landmarks)))
        h, w = rgb.shape[:2]
        if views:
            rows = rows[in_some_view(self.anchors.xyz[rows], views, K, (w, h), cfg.view_margin)]
        if len(rows) > cfg.max_anchors:
            rows = np.sort(np.random.default_rng(seed).choice(rows, cfg.max_anchors, replace=False))
        feats = extract_sift(rgb, self.features)
        diag.update(landmarks=len(landmarks), anchors=len(rows), keypoints=len(feats))
        if len(rows) < cfg.seed_inliers or len(feats) < cfg.seed_inliers:
            return None
        query, mapped = match_anchors(root_sift(feats.descriptors), self.space[rows], self.anchors.xyz[rows], cfg)
        diag["matches"] = len(query)
        pose = estimate_absolute_pose(
            feats.xy[query], self.anchors.xyz[rows[mapped]], K, w, h, dataclasses.replace(cfg.pose, seed=seed)
        )
        if pose is None:
            return None
        owners = self.anchors.landmark[rows[mapped[pose.inliers]]]
        ids, counts = np.unique(owners, return_counts=True)
        diag["inliers"] = pose.n_inliers
        diag[DRAWN_POINTS] = drawn_points(feats.xy[query], pose.inliers)
        by_landmark = dict(zip(ids.tolist(), counts.tolist()))
        return AnchorPose(
            pose.T_wc, pose.n_inliers, len(query), by_landmark, feats.xy[query], self.anchors.xyz[rows[mapped]]
        )


def in_some_view(
    xyz: np.ndarray, views: list[np.ndarray], K: np.ndarray, size: tuple[int, int], margin: float
) -> np.ndarray:
    """(N,) bool: which world points project in front of one of ``views`` (camera-to-world) within the
    image of ``size`` (width, height) grown by ``margin`` of it on every side."""
    w, h = size
    seen = np.zeros(len(xyz), bool)
    for T_wc in views:
        uv, z = geometry.project(K, T_wc, xyz)
        seen |= (
            (z > 0)
            & (uv[:, 0] >= -margin * w)
            & (uv[:, 0] <= (1 + margin) * w)
            & (uv[:, 1] >= -margin * h)
            & (uv[:, 1] <= (1 + margin) * h)
        )
    return seen


def match_anchors(
    query: np.ndarray, anchors: np.ndarray, xyz: np.ndarray, cfg: AnchorConfig
) -> tuple[np.ndarray, np.ndarray]:
    """Ratio-test matches ``(query rows, anchor rows)`` of RootSIFT descriptors, each query row's rival
    being its nearest anchor farther than ``distinct_m`` from its nearest (see the module doc).
    FLANN's randomised kd-trees are seeded, so a query gets the same answer in any order."""
    k = min(cfg.neighbours, len(anchors))
    if not len(query) or k < 2:
        return np.zeros(0, int), np.zeros(0, int)
    cv2.setRNGSeed(0)
    index = cv2.flann_Index(anchors, {"algorithm": 1, "trees": 4})  # kd-tree
    nn, dist2 = index.knnSearch(query, k, params={"checks": 64})
    valid = nn >= 0
    nn = np.where(valid, nn, 0)
    elsewhere = valid & (np.linalg.norm(xyz[nn] - xyz[nn[:, :1]], axis=-1) > cfg.distinct_m)
    rival = np.where(elsewhere.any(axis=1), dist2[np.arange(len(nn)), np.argmax(elsewhere, axis=1)], np.inf)
    keep = valid[:, 0] & (dist2[:, 0] < cfg.ratio**2 * rival)  # squared L2 distances
    rows = np.flatnonzero(keep)
    return rows, nn[rows, 0]
