"""``orb-reloc``: ORB-SLAM2's relocalization (``Tracking::Relocalization``) against a posed RGB-D map.

Map: every mapping frame is a keyframe holding ORB features (ORB-SLAM2's extractor: 1000 x 8
levels, scale 1.2, FAST 20 with fallback 7) whose depth gives their map points; a per-scene DBoW2
vocabulary (:class:`~baselines.frame_retrieval.VocabularyTree`) stands in for ORBvoc; co-visibility
between keyframes counts the points of one that the other sees (projected into it and confirmed
by its depth), since these keyframes come with poses and depth rather than from tracking.

Query, as ``Relocalization`` runs it:

1. ``DetectRelocalizationCandidates``: keyframes sharing more than 0.8 x the most shared words,
   their BoW score accumulated over their 10 best co-visible keyframes, groups above 0.75 x the
   best kept, each by its best-scoring keyframe;
2. ``SearchByBoW`` per candidate: descriptors under the same vocabulary node, Hamming <= 50,
   ratio 0.75, rotation-consistency histogram; candidates with fewer than 15 matches dropped;
3. EPnP RANSAC per candidate, 5 iterations at a time round-robin over the candidates (inlier if
   the squared reprojection error is under 5.991 x the keypoint octave's variance);
4. for a hypothesis: pose optimisation (Huber, 4 rounds of 10 iterations, outliers by chi2 > 5.991);
   with fewer than 50 inliers, search by projection of the keyframe's points (window 10, Hamming
   100) and optimisation again, then once more (window 3, Hamming 64) when 30-50 remain;
   accepted at 50 inliers.

Solvers: EPnP is OpenCV's (``cv2.solvePnP(SOLVEPNP_EPNP)``) inside the RANSAC loop written here,
because neither OpenCV's nor pycolmap's RANSAC takes per-point thresholds or runs a few iterations
at a time; the pose optimisation is scipy's ``least_squares`` with a Huber loss per residual
coordinate (g2o applies it to each point's 2D error). Masks are ignored (``uses_masks = False``).
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
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from baselines.features import FeatureMap, OrbConfig, build_feature_map, extract_orb
from baselines.frame_retrieval import VocabularyConfig, VocabularyTree, hamming_matrix
from openreloc_bench import config as cfglib
from openreloc_bench import geometry
from openreloc_bench.bars import tqdm
from openreloc_bench.data.types import SceneSequence
from openreloc_bench.methods import DRAWN_POINTS, Failure, MapPoints, PoseEstimate, QueryFrame, drawn_points
from openreloc_bench.vision.local_features import Keypoints

MAP_FORMAT = "orb-reloc-map"
MAP_VERSION = 1
CHI2_2D = 5.991
"""95% quantile of chi-square with 2 degrees of freedom: ORB-SLAM2's inlier bound on a squared
reprojection error in units of the keypoint octave's variance."""


@dataclass
class OrbRelocConfig:
    """Every setting of :class:`OrbReloc`; defaults are ORB-SLAM2's values (those chosen on the
    validation suite say so)."""

    features: OrbConfig = field(default_factory=OrbConfig)
    """ORB extractor, for keyframes and queries alike."""
    max_depth_step: float = 0.05
    """A keyframe keypoint gets a map point only where the depth of its 3x3 pixels varies by at most
    this fraction of its own (no points from depth edges)."""
    vocabulary: VocabularyConfig = field(default_factory=VocabularyConfig)
    """Per-scene vocabulary tree."""
    direct_index_level: int = 2
    """Vocabulary level whose nodes restrict BoW matching (ORB-SLAM2: 4 levels above ORBvoc's leaves,
    i.e. level 2 of 6)."""
    covisibility_points: int = 200
    """Points of each keyframe projected into the others to count co-visibility (scaled to all of
    its points): a sample keeps mapping time linear in the points."""
    covisibility_min: int = 15
    """Shared points for a co-visibility edge (ORB-SLAM2's threshold)."""
    covisible_neighbours: int = 10
    """Best co-visible keyframes whose scores add to a candidate's group."""
    min_words_ratio: float = 0.8
    """Candidates share more than this fraction of the most shared words."""
    min_group_ratio: float = 0.75
    """Groups scoring more than this fraction of the best group are kept."""
    bow_hamming: int = 50
    """Largest Hamming distance of a BoW match (ORB-SLAM2's TH_LOW)."""
    bow_ratio: float = 0.75
    """Nearest-neighbour ratio of a BoW match."""
    min_bow_matches: int = 15
    """Candidates with fewer BoW matches are dropped."""
    rotation_bins: int = 30
    """Bins of the rotation-consistency histogram (matches outside the 3 fullest bins are dropped)."""
    ransac_probability: float = 0.99
    """RANSAC confidence that sets its iteration count."""
    ransac_min_inliers: int = 10
    """Least inliers of a RANSAC hypothesis (also at least ``ransac_epsilon`` of the matches)."""
    ransac_epsilon: float = 0.5
    """Expected inlier share: the iteration count and the least inlier share."""
    ransac_iterations: int = 300
    """Most RANSAC iterations per candidate."""
    iterations_per_round: int = 5
    """RANSAC iterations per candidate per round-robin turn."""
    projection_windows: tuple[int, int] = (10, 3)
    """Search radii (pixels at level 0, scaled by the predicted octave) of the two searches by projection."""
    projection_hamming: tuple[int, int] = (100, 64)
    """Largest Hamming distances of the two searches by projection."""
    min_inliers: int = 50
    """Inliers after optimisation to accept a pose (ORB-SLAM2: 50)."""
    seed: int = 0
    """RANSAC sampling seed."""

    def __post_init__(self) -> None:
        if not 0 < self.min_words_ratio <= 1 or not 0 < self.min_group_ratio <= 1 or not 0 < self.bow_ratio <= 1:
            raise ValueError("min_words_ratio, min_group_ratio and bow_ratio must be in (0, 1]")
        if not 0 < self.ransac_probability < 1 or not 0 < self.ransac_epsilon <= 1:
            raise ValueError("need 0 < ransac_probability < 1 and 0 < ransac_epsilon <= 1")
        if min(self.ransac_iterations, self.iterations_per_round, self.rotation_bins, self.covisibility_points) < 1:
            raise ValueError("ransac_iterations, iterations_per_round, rotation_bins, covisibility_points must be >= 1")
        if self.min_inliers < 4 or self.ransac_min_inliers < 4:
            raise ValueError("min_inliers and ransac_min_inliers must be >= 4 (EPnP needs 4 points)")
        if not 0 <= self.direct_index_level <= self.vocabulary.depth:
            raise ValueError(f"direct_index_level must be in [0, vocabulary.depth={self.vocabulary.depth}]")


# --------------------------------------------------------------------------------------------
# The method
# --------------------------------------------------------------------------------------------


class OrbReloc:
    """ORB-SLAM2's relocalization (see the module doc)."""

    name = "orb-reloc"
    reference = "Mur-Artal and Tardos, ORB-SLAM2, T-RO 2017 (its relocalization); https://github.com/raulmur/ORB_SLAM2"
    uses_masks = False
    """Query instance masks (oracle-mask track) are never read."""

    def __init__(self, **overrides: Any):
        self.config: OrbRelocConfig = cfglib.from_dict(OrbRelocConfig, overrides, "orb-reloc")
        self.map: FeatureMap | None = None

    def map_config(self) -> dict[str, Any]:
        """What the map depends on; the query-time settings share maps."""
        c = self.config
        return {
            "features": dataclasses.asdict(c.features),
            "max_depth_step": c.max_depth_step,
            "vocabulary": dataclasses.asdict(c.vocabulary),
            "direct_index_level": c.direct_index_level,
            "covisibility_points": c.covisibility_points,
            "covisibility_min": c.covisibility_min,
            "covisible_neighbours": c.covisible_neighbours,
        }

    def build_map(self, mapping: SceneSequence, map_dir: Path) -> None:
        c = self.config
        fmap = build_feature_map(
            mapping, partial(extract_orb, cfg=c.features), c.max_depth_step, MAP_FORMAT, MAP_VERSION, "orb-reloc map"
        )
        voc = VocabularyTree.fit(fmap.features.descriptors, fmap.offsets, c.vocabulary)
        words, nodes = voc.transform(fmap.features.descriptors, c.direct_index_level)
        fmap.arrays = {
            **voc.to_arrays(),
            "words": words.astype(np.uint32),
            "nodes": nodes.astype(np.uint32),
            "covisible": covisibility(fmap, mapping, c),
        }
        fmap.meta = {"config": self.map_config(), "stats": {"keyframes": fmap.n_frames, "points": len(fmap.points)}}
        fmap.save(map_dir)

    def map_points(self, map_dir: Path) -> MapPoints:
        return FeatureMap.load(map_dir, MAP_FORMAT, MAP_VERSION).drawn()

    def load_map(self, map_dir: Path) -> None:
        fmap = FeatureMap.load(map_dir, MAP_FORMAT, MAP_VERSION)
        self.voc = VocabularyTree.from_arrays(fmap.arrays)
        self.words = fmap.arrays["words"].astype(np.int64)
        self.nodes = fmap.arrays["nodes"].astype(np.int64)
        self.covisible = fmap.arrays["covisible"]
        self.bow = self.voc.bow_matrix(self.words, fmap.offsets)
        centres = fmap.poses[fmap.frame_of(), :3, 3]
        self.obs_distance = np.linalg.norm(fmap.points - centres, axis=1)  # for the scale prediction
        self.map = fmap

    # ------------------------------------------------------------------------------------ query

    def localize(self, query: QueryFrame) -> PoseEstimate | Failure:
        if self.map is None:
            raise RuntimeError("load_map() must be called before localize()")
        c = self.config
        t0 = time.perf_counter()
        feats = extract_orb(query.color, c.features)
        diag: dict[str, Any] = {"keypoints": len(feats)}
        if len(feats) < c.min_inliers:
            return Failure(f"{len(feats)} ORB keypoints, fewer than min_inliers={c.min_inliers}", diag)
        words, nodes = self.voc.transform(feats.descriptors, c.direct_index_level)
        candidates = self.candidates(words)
        diag["candidates"] = candidates.tolist()
        if not len(candidates):
            return Failure("no keyframe shares words with the query", diag)
        sigma2 = c.features.scale_factor ** (2 * feats.octaves.astype(np.float64))
        rng = np.random.default_rng(c.seed)
        solvers = []
        for kf in candidates:
            rows = self.map.rows([kf])
            dist = hamming_matrix(self.map.features.descriptors[rows], feats.descriptors)
            qi, ri = self.search_by_bow(rows, dist, nodes, feats)
            if len(qi) >= c.min_bow_matches:
                solver = PnPRansac(feats.xy[qi], self.map.points[rows[ri]], sigma2[qi], query.K, c, rng)
                solvers.append((kf, rows, dist, qi, ri, solver))
        diag["bow_candidates"] = len(solvers)
        t1 = time.perf_counter()
        best_good = 0
        while solvers:
            for entry in list(solvers):
                kf, rows, dist, qi, ri, solver = entry
                T_cw, inliers, no_more = solver.iterate(c.iterations_per_round)
                if no_more:
                    solvers.remove(entry)
                if T_cw is None:
                    continue
                T_cw, good = self.verify(T_cw, qi[inliers], ri[inliers], rows, dist, feats, sigma2, query)
                best_good = max(best_good, len(good))
                if len(good) >= c.min_inliers:
                    diag.update(
                        keyframe=int(kf),
                        inliers=len(good),
                        timing_s={"retrieve": t1 - t0, "pnp": time.perf_counter() - t1},
                    )
                    diag[DRAWN_POINTS] = drawn_points(feats.xy[good], np.ones(len(good), bool))
                    return PoseEstimate(geometry.invert(T_cw), diag, confidence=len(good))
        diag["inliers"] = best_good
        if not diag["bow_candidates"]:
            return Failure(f"no candidate keyframe with {c.min_bow_matches} BoW matches", diag)
        return Failure(f"best hypothesis keeps {best_good} inliers, fewer than min_inliers={c.min_inliers}", diag)

    def candidates(self, words: np.ndarray) -> np.ndarray:
        """``KeyFrameDatabase::DetectRelocalizationCandidates``: keyframe indices, best group first.

        The scores of co-visible neighbours are their current scores against this query (ORB-SLAM2
        reads a neighbour's last computed score, stale for neighbours under the word threshold).
        """
        c = self.config
        score, shared = self.voc.score(self.bow, self.voc.bow(words))
        if shared.max(initial=0) == 0:
            return np.zeros(0, int)
        considered = np.flatnonzero(shared > c.min_words_ratio * shared.max())
        sharing = shared > 0
        groups = []
        for kf in considered:
            members = [kf, *(n for n in self.covisible[kf, : c.covisible_neighbours] if n >= 0 and sharing[n])]
            members = np.array(members)
            groups.append((score[members].sum(), int(members[np.argmax(score[members])])))
        best = max(g[0] for g in groups)
        kept = sorted((g for g in groups if g[0] > c.min_group_ratio * best), key=lambda g: -g[0])
        return np.array(list(dict.fromkeys(kf for _, kf in kept)), dtype=int)

    def search_by_bow(
        self, rows: np.ndarray, dist: np.ndarray, query_nodes: np.ndarray, feats: Keypoints
    ) -> tuple[np.ndarray, np.ndarray]:
        """``ORBmatcher::SearchByBoW``: (query indices, keyframe-local indices) of the matches.

        Each keyframe point takes its nearest query descriptor under the same direct-index node
        (Hamming <= ``bow_hamming``, ratio ``bow_ratio`` to the second nearest); a query keypoint
        claimed twice keeps its nearer point; then rotation consistency.
        """
        c = self.config
        d = np.where(self.nodes[rows][:, None] == query_nodes[None, :], dist, 256)
        if d.shape[1] < 2:
            return np.zeros(0, int), np.zeros(0, int)
        two = np.partition(d, 1, axis=1)[:, :2]
        best = np.argmin(d, axis=1)
        ok = (two[:, 0] <= c.bow_hamming) & (two[:, 0] < c.bow_ratio * two[:, 1])
        ri = np.flatnonzero(ok)
        qi = best[ri]
        ri, qi = _one_per_query(ri, qi, two[ri, 0])
        keep = self.rotation_consistent(self.map.features.angles[rows[ri]] - feats.angles[qi])
        return qi[keep], ri[keep]

    def rotation_consistent(self, rotation_deg: np.ndarray) -> np.ndarray:
        """``ORBmatcher`` rotation check: matches in the three fullest bins of the histogram of
        keypoint angle differences (the 2nd and 3rd only with at least 10% of the 1st). Bins span
        360 / ``rotation_bins`` degrees (ORB-SLAM3's fix of ORB-SLAM2's bin width)."""
        n = self.config.rotation_bins
        bins = np.floor((rotation_deg % 360.0) * n / 360.0).astype(int) % n
        counts = np.bincount(bins, minlength=n)
        top = np.argsort(-counts, kind="stable")[:3]
        top = [b for k, b in enumerate(top) if k == 0 or counts[b] >= 0.1 * counts[top[0]]]
        return np.isin(bins, top)

    def verify(
        self,
        T_cw: np.ndarray,
        qi: np.ndarray,
        ri: np.ndarray,
        rows: np.ndarray,
        dist: np.ndarray,
        feats: Keypoints,
        sigma2: np.ndarray,
        query: QueryFrame,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Pose optimisation, then searches by projection while under ``min_inliers`` (ORB-SLAM2's
        sequence; a hypothesis left with fewer than ``ransac_min_inliers`` is dropped at once);
        returns the pose and the query indices of its inliers."""
        c, K = self.config, query.K
        pts = self.map.points
        T_cw, good = optimize_pose(T_cw, feats.xy[qi], pts[rows[ri]], sigma2[qi], K)
        qi, ri = qi[good], ri[good]
        if len(qi) < c.ransac_min_inliers or len(qi) >= c.min_inliers:
            return T_cw, qi
        for k, (window, max_hamming) in enumerate(zip(c.projection_windows, c.projection_hamming)):
            if k and not 30 < len(qi) < c.min_inliers:
                break
            nq, nr = self.search_by_projection(T_cw, rows, dist, feats, qi, ri, window, max_hamming, query)
            if len(qi) + len(nq) < c.min_inliers:
                break
            qi, ri = np.concatenate([qi, nq]), np.concatenate([ri, nr])
            T_cw, good = optimize_pose(T_cw, feats.xy[qi], pts[rows[ri]], sigma2[qi], K)
            qi, ri = qi[good], ri[good]
        return T_cw, qi

    def search_by_projection(
        self,
        T_cw: np.ndarray,
        rows: np.ndarray,
        dist: np.ndarray,
        feats: Keypoints,
        found_q: np.ndarray,
        found_r: np.ndarray,
        window: float,
        max_hamming: int,
        query: QueryFrame,
    ) -> tuple[np.ndarray, np.ndarray]:
        """``ORBmatcher::SearchByProjection(Frame, KeyFrame, ...)``: the keyframe's points not yet
        matched, projected with the pose; each takes the nearest unmatched query keypoint within
        ``window`` x 1.2^(predicted octave) pixels and one octave of the predicted one, if within
        ``max_hamming``; then rotation consistency."""
        c, fmap, K = self.config, self.map, query.K
        h, w = query.color.shape[:2]
        s, levels = c.features.scale_factor, c.features.levels
        pts_c = geometry.transform_points(T_cw, fmap.points[rows])
        z = pts_c[:, 2]
        uv = (pts_c[:, :2] / np.where(z > 0, z, 1)[:, None]) @ K[:2, :2].T + K[:2, 2]
        depth = np.linalg.norm(pts_c, axis=1)
        max_d = self.obs_distance[rows] * s ** fmap.features.octaves[rows].astype(float)
        min_d = max_d / s ** (levels - 1)
        level = np.clip(np.ceil(np.log(max_d / np.maximum(depth, 1e-9)) / np.log(s)), 0, levels - 1)
        usable = (z > 0) & (uv[:, 0] >= 0) & (uv[:, 0] < w) & (uv[:, 1] >= 0) & (uv[:, 1] < h)
        usable &= (depth >= 0.8 * min_d) & (depth <= 1.2 * max_d)
        usable[found_r] = False
        radius = window * s**level
        near = np.all(np.abs(uv[:, None, :] - feats.xy[None, :, :]) < radius[:, None, None], axis=2)
        near &= np.abs(feats.octaves[None, :].astype(float) - level[:, None]) <= 1
        near[:, found_q] = False
        near[~usable] = False
        d = np.where(near, dist, 256)
        best = np.argmin(d, axis=1)
        bd = d[np.arange(len(d)), best]
        ri = np.flatnonzero(bd <= max_hamming)
        qi = best[ri]
        ri, qi = _one_per_query(ri, qi, bd[ri])
        keep = self.rotation_consistent(fmap.features.angles[rows[ri]] - feats.angles[qi])
        return qi[keep], ri[keep]


def _one_per_query(ri: np.ndarray, qi: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Of the matches claiming one query keypoint, keep the nearest (ORB-SLAM2 keeps the first)."""
    order = np.lexsort((d, qi))
    _, first = np.unique(qi[order], return_index=True)
    keep = order[first]
    return ri[keep], qi[keep]


# --------------------------------------------------------------------------------------------
# Geometry: co-visibility, EPnP RANSAC, pose optimisation
# --------------------------------------------------------------------------------------------


def covisibility(fmap: FeatureMap, mapping: SceneSequence, c: OrbRelocConfig) -> np.ndarray:
    """(F, covisible_neighbours) int32: each keyframe's best co-visible keyframes, -1 padded.

    Weight of (i, j): the points of i that project into j in front of it and agree with j's depth
    (within ``max_depth_step``, on a 4x subsampled depth image), from a sample of
    ``covisibility_points`` of i's points scaled to all of them, taking the smaller of the two
    directions; edges need ``covisibility_min``, as ORB-SLAM2's.
    """
    stride = 4
    depths = np.stack([f.depth[::stride, ::stride] for f in tqdm(mapping, desc="co-visibility", leave=False)])
    n, (h, w) = fmap.n_frames, depths.shape[1:]
    K = np.asarray(fmap.K, float)
    T_cw = np.stack([geometry.invert(T) for T in fmap.poses])
    rng = np.random.default_rng(c.vocabulary.seed)
    weight = np.zeros((n, n))
    for i in range(n):
        a, b = fmap.offsets[i], fmap.offsets[i + 1]
        if b == a:
            continue
        sample = fmap.points[np.sort(rng.choice(np.arange(a, b), min(b - a, c.covisibility_points), replace=False))]
        p = np.einsum("fij,nj->fni", T_cw[:, :3, :3], sample) + T_cw[:, None, :3, 3]
        z = p[..., 2]
        uv = p[..., :2] / np.where(z > 0, z, 1)[..., None] @ K[:2, :2].T + K[:2, 2]
        u = np.round(uv[..., 0] / stride).astype(int)
        v = np.round(uv[..., 1] / stride).astype(int)
        inside = (z > 0) & (u >= 0) & (u < w) & (v >= 0) & (v < h)
        d = depths[np.arange(n)[:, None], np.clip(v, 0, h - 1), np.clip(u, 0, w - 1)]
        seen = inside & (d > 0) & (np.abs(d - z) <= c.max_depth_step * z)
        weight[i] = seen.sum(axis=1) * (b - a) / len(sample)
    weight = np.minimum(weight, weight.T)
    np.fill_diagonal(weight, 0)
    order = np.argsort(-weight, axis=1, kind="stable")[:, : c.covisible_neighbours]
    best = np.take_along_axis(weight, order, axis=1)
    return np.where(best >= c.covisibility_min, order, -1).astype(np.int32)


class PnPRansac:
    """ORB-SLAM2's ``PnPsolver``: EPnP on 4-point samples, inliers by per-octave thresholds, the
    best hypothesis refined by EPnP on its inliers, run a few iterations at a time."""

    def __init__(
        self,
        xy: np.ndarray,
        X: np.ndarray,
        sigma2: np.ndarray,
        K: np.ndarray,
        c: OrbRelocConfig,
        rng: np.random.Generator,
    ):
        self.xy, self.X, self.K, self.rng = xy.astype(np.float64), X.astype(np.float64), K, rng
        self.max_err2 = CHI2_2D * sigma2
        n = len(xy)
        self.min_inliers = max(c.ransac_min_inliers, int(n * c.ransac_epsilon), 4)
        eps = max(c.ransac_epsilon, self.min_inliers / n)
        its = np.log(1 - c.ransac_probability) / np.log(1 - eps**4) if eps < 1 else 1
        self.max_iterations = int(max(1, min(np.ceil(its), c.ransac_iterations)))
        self.iterations = 0
        self.best: tuple[np.ndarray, np.ndarray] | None = None

    def _inliers(self, T_cw: np.ndarray) -> np.ndarray:
        p = geometry.transform_points(T_cw, self.X)
        z = p[:, 2]
        uv = p[:, :2] / np.where(z > 0, z, 1)[:, None] @ self.K[:2, :2].T + self.K[:2, 2]
        return (z > 0) & (((uv - self.xy) ** 2).sum(axis=1) < self.max_err2)

    def _epnp(self, idx: np.ndarray) -> np.ndarray | None:
        ok, rvec, tvec = cv2.solvePnP(self.X[idx], self.xy[idx], self.K, None, flags=cv2.SOLVEPNP_EPNP)
        if not ok or not np.all(np.isfinite(tvec)):
            return None
        return geometry.make_pose(cv2.Rodrigues(rvec)[0], tvec.ravel())

    def iterate(self, n: int) -> tuple[np.ndarray | None, np.ndarray | None, bool]:
        """Up to ``n`` more iterations: ``(T_cw, inlier mask, exhausted)``; a pose once a hypothesis
        with enough inliers refines to enough inliers, or the best hypothesis when exhausted."""
        if len(self.xy) < self.min_inliers:
            return None, None, True
        for _ in range(n):
            if self.iterations >= self.max_iterations:
                break
            self.iterations += 1
            T = self._epnp(self.rng.choice(len(self.xy), 4, replace=False))
            if T is None:
                continue
            inl = self._inliers(T)
            if inl.sum() < self.min_inliers:
                continue
            if self.best is None or inl.sum() > self.best[1].sum():
                self.best = (T, inl)
            refined = self._epnp(np.flatnonzero(inl))
            if refined is not None:
                ref_inl = self._inliers(refined)
                if ref_inl.sum() > self.min_inliers:
                    return refined, ref_inl, False
        exhausted = self.iterations >= self.max_iterations
        if exhausted and self.best is not None:
            return self.best[0], self.best[1], True
        return None, None, exhausted


def optimize_pose(
    T_cw: np.ndarray, xy: np.ndarray, X: np.ndarray, sigma2: np.ndarray, K: np.ndarray, rounds: int = 4
) -> tuple[np.ndarray, np.ndarray]:
    """``Optimizer::PoseOptimization``: 4 rounds of 10 iterations on the matches not flagged as
    outliers, Huber (delta sqrt(5.991)) in the first two, each round re-flagging every match by
    chi2 > 5.991 in its octave's variance. Returns the pose and the inlier mask."""
    inv_sigma = 1.0 / np.sqrt(sigma2)
    X = X.astype(np.float64)
    outlier = np.zeros(len(xy), bool)

    def residuals(x: np.ndarray, T: np.ndarray, sel: np.ndarray) -> np.ndarray:
        p = geometry.transform_points(_exp(x) @ T, X[sel])
        z = np.where(np.abs(p[:, 2]) < 1e-9, 1e-9, p[:, 2])
        uv = p[:, :2] / z[:, None] @ K[:2, :2].T + K[:2, 2]
        return ((uv - xy[sel]) * inv_sigma[sel, None]).ravel()

    for it in range(rounds):
        sel = ~outlier
        if sel.sum() < 3:
            break
        loss = "huber" if it < 2 else "linear"
        res = least_squares(
            residuals, np.zeros(6), args=(T_cw, sel), loss=loss, f_scale=np.sqrt(CHI2_2D), max_nfev=10, method="trf"
        )
        T_cw = _exp(res.x) @ T_cw
        all_ = np.ones(len(xy), bool)
        chi2 = (residuals(np.zeros(6), T_cw, all_).reshape(-1, 2) ** 2).sum(axis=1)
        z = geometry.transform_points(T_cw, X)[:, 2]
        outlier = (chi2 > CHI2_2D) | (z <= 0)
    return T_cw, ~outlier


def _exp(x: np.ndarray) -> np.ndarray:
    """A left increment of a pose: rotation vector ``x[:3]``, translation ``x[3:]``."""
    return geometry.make_pose(Rotation.from_rotvec(x[:3]).as_matrix(), x[3:])
