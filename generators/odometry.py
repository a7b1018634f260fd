"""Mapping poses as a user has them: RGB-D odometry and a pose graph, aligned to the ground truth.

Real benchmarks map from poses a SLAM system estimated (7-Scenes: KinectFusion), not from the truth.
This module estimates the mapping frames' poses the way open3d's reconstruction system does:
consecutive frames registered (SIFT PnP, refined by dense RGB-D odometry), loop closures between
frames whose estimates are close, and a pose graph optimised with Levenberg-Marquardt and line
processes that prune wrong loop closures. :func:`align_to` then puts the estimate in the ground
truth's world frame as trajectory evaluation does (a rigid alignment of camera centres, no scale: RGB-D
is metric), and :func:`drift` measures what remains. Where no registration joins two consecutive frames
(a jump between floors, a blank frame) and no loop closure joins the parts again, the parts share no
frame of reference, like separate recordings: each is aligned on its own.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np
import open3d as o3d
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial.transform import Rotation

from openreloc_bench import geometry
from openreloc_bench.bars import tqdm
from openreloc_bench.vision.absolute_pose import AbsolutePoseConfig, estimate_absolute_pose
from openreloc_bench.vision.local_features import SiftConfig, extract_sift, lift, root_sift

reg = o3d.pipelines.registration

RATIO = 0.8
"""Lowe's ratio test on RootSIFT distances."""
MAX_DEPTH_STEP = 0.1
"""A keypoint is lifted to 3D only where its 3 x 3 depth neighbourhood varies by less than this share."""
REFINE_ITERATIONS = (5,)
"""Dense odometry from a PnP estimate: the finest level only (the coarser ones were seen to pull good PnP
estimates of rendered frames 5-10 cm away at 320 x 240)."""
SEARCH_ITERATIONS = (20, 10, 5)
"""Dense odometry without PnP: open3d's three-level pyramid, coarse to fine."""


@dataclass
class OdometryConfig:
    """RGB-D odometry, loop closure and pose-graph optimisation of :func:`estimate_trajectory`."""

    work_width: int = 320
    """Wider frames are shrunk by an integer factor to about this width for features and dense odometry
    (runtime: open3d's odometry costs ~0.4 s a pair at 640 x 480 on one core)."""
    max_keypoints: int = 1000
    """SIFT keypoints per frame, strongest first."""
    min_inliers: int = 30
    """PnP inliers that make a feature registration (and so a loop closure) trustworthy."""
    loop_radius_m: float = 1.0
    """Loop closures are tried between frames whose estimated camera centres are this close."""
    loop_angle_deg: float = 45.0
    """... and whose viewing directions differ by at most this angle."""
    max_loop_candidates: int = 2
    """Loop closures tried per frame (the closest frame of each earlier visit, closest first): runtime."""
    depth_trunc_m: float = 5.0
    """Depth beyond this is ignored (a Kinect's is unreliable there)."""
    depth_diff_m: float = 0.07
    """Largest depth difference of a dense odometry correspondence (open3d's reconstruction value)."""
    voxel_m: float = 0.05
    """Voxel of the point clouds that weigh the edges (information matrices) and measure their overlap."""
    min_fitness: float = 0.3
    """Share of a frame's points with a partner within 1.4 voxels that a dense-only edge needs."""
    max_refine_m: float = 0.1
    """Dense refinement that moves the PnP camera centre further than this is discarded."""
    max_refine_deg: float = 5.0
    """... or that turns it by more than this."""
    pnp_max_error_px: float = 4.0
    """PnP RANSAC inlier threshold (pixels)."""
    edge_prune_threshold: float = 0.25
    """Loop closures whose line-process weight ends below this are pruned (open3d's value)."""
    preference_loop_closure: float = 0.1
    """Weight of loop closures against odometry edges (open3d's value for RGB-D sequences)."""
    seed: int = 0
    """RANSAC seed: the estimate is reproducible."""

    def __post_init__(self) -> None:
        for name in ("work_width", "max_keypoints", "min_inliers"):
            if getattr(self, name) < 4:
                raise ValueError(f"{name} must be >= 4, got {getattr(self, name)}")
        if self.max_loop_candidates < 0 or self.seed < 0:
            raise ValueError("max_loop_candidates and seed must be >= 0")
        for name in ("loop_radius_m", "depth_trunc_m", "depth_diff_m", "voxel_m", "max_refine_m", "pnp_max_error_px"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)}")
        for name in ("loop_angle_deg", "max_refine_deg"):
            if not 0 < getattr(self, name) <= 180:
                raise ValueError(f"{name} must be in (0, 180], got {getattr(self, name)}")
        for name in ("min_fitness", "edge_prune_threshold"):
            if not 0 <= getattr(self, name) <= 1:
                raise ValueError(f"{name} must be in [0, 1], got {getattr(self, name)}")
        if not self.preference_loop_closure > 0:
            raise ValueError(f"preference_loop_closure must be > 0, got {self.preference_loop_closure}")


@dataclass
class Trajectory:
    """Estimated mapping poses and how the pose graph that gave them was made."""

    poses: np.ndarray
    """(N, 4, 4) estimated T_wc, frame 0 at the given first pose (later segments only loosely placed)."""
    edges: int
    """Pose-graph edges left after optimisation (odometry and loop closures)."""
    loop_closures: int
    """Loop closures accepted and kept by the optimisation."""
    failed_pairs: int
    """Consecutive pairs no registration succeeded on (bridged by the previous motion, barely weighted)."""
    segments: np.ndarray
    """(N,) int: the connected part of the pose graph (without those bridges) each frame is in, numbered
    from 0 in order; align each part on its own (``align_to(..., segments)``)."""


@dataclass
class Drift:
    """Error of an estimated trajectory after rigid alignment to the truth."""

    ate_rmse_m: float
    """Absolute trajectory error: RMS distance of camera centres (metres)."""
    ate_max_m: float
    """Largest camera-centre distance (metres)."""
    rotation_median_deg: float
    """Median rotation error (degrees)."""
    rotation_max_deg: float
    """Largest rotation error (degrees)."""


@dataclass
class _Features:
    """A frame's SIFT keypoints (uint8 descriptors: a 600-frame scene stays small), their camera-frame 3D
    points where ``lifted``, and its downsampled point cloud."""

    xy: np.ndarray
    descriptors: np.ndarray
    points: np.ndarray
    lifted: np.ndarray
    cloud: o3d.geometry.PointCloud


class _Registrar:
    """Registers pairs of frames: ``T_t<-s`` (maps frame s's camera points into frame t's) with its
    information matrix, or None."""

    def __init__(self, rgbs: Sequence[np.ndarray], depths: Sequence[np.ndarray], K: np.ndarray, cfg: OdometryConfig):
        self.rgbs, self.depths, self.cfg = rgbs, depths, cfg
        self.f = max(1, round(depths[0].shape[1] / cfg.work_width))
        self.h, self.w = depths[0].shape[0] // self.f, depths[0].shape[1] // self.f
        self.K = np.diag([1 / self.f, 1 / self.f, 1.0]) @ K  # pixel centres: x' = (x - (f - 1) / 2) / f
        self.K[:2, 2] -= (self.f - 1) / (2 * self.f)
        self.intrinsic = o3d.camera.PinholeCameraIntrinsic(self.w, self.h, *self.K[[0, 1, 0, 1], [0, 1, 2, 2]])
        self.refine, self.search = (
            o3d.pipelines.odometry.OdometryOption(o3d.utility.IntVector(its), cfg.depth_diff_m, 0.0, cfg.depth_trunc_m)
            for its in (REFINE_ITERATIONS, SEARCH_ITERATIONS)
        )
        self.sift = SiftConfig(max_keypoints=cfg.max_keypoints)
        self.pnp = AbsolutePoseConfig(max_error_px=cfg.pnp_max_error_px, seed=cfg.seed)
        self.features: list[_Features] = []
        self.rgbd = lru_cache(maxsize=4)(self._rgbd)

    def add_frame(self, i: int) -> None:
        """Extracts frame i's features (frames are added in order)."""
        rgb, depth = self.small(i)
        kp = extract_sift(rgb, self.sift)
        points, lifted = lift(
            kp.xy, np.where(depth <= self.cfg.depth_trunc_m, depth, 0), self.K, np.eye(4), MAX_DEPTH_STEP
        )
        cloud = o3d.geometry.PointCloud.create_from_depth_image(self.rgbd(i).depth, self.intrinsic, depth_scale=1.0)
        self.features.append(
            _Features(kp.xy, kp.descriptors, points, lifted, cloud.voxel_down_sample(self.cfg.voxel_m))
        )

    def small(self, i: int) -> tuple[np.ndarray, np.ndarray]:
        """Frame i at the working resolution: colour averaged, depth sampled (never mixed across edges)."""
        rgb, depth = np.asarray(self.rgbs[i], np.uint8), np.asarray(self.depths[i], np.float32)
        if self.f == 1:
            return np.ascontiguousarray(rgb), np.ascontiguousarray(depth)
        size = (self.w, self.h)
        return cv2.resize(rgb, size, interpolation=cv2.INTER_AREA), cv2.resize(
            depth, size, interpolation=cv2.INTER_NEAREST
        )

    def _rgbd(self, i: int) -> o3d.geometry.RGBDImage:
        rgb, depth = self.small(i)
        return o3d.geometry.RGBDImage.create_from_color_and_depth(
            o3d.geometry.Image(rgb),
            o3d.geometry.Image(depth),
            depth_scale=1.0,
            depth_trunc=self.cfg.depth_trunc_m,
            convert_rgb_to_intensity=True,
        )

    def pnp_motion(self, s: int, t: int) -> np.ndarray | None:
        """``T_t<-s`` from frame s's lifted keypoints matched to frame t's, or None under min_inliers."""
        a, b = self.features[s], self.features[t]
        if len(a.xy) < 2 or len(b.xy) < 2:
            return None
        cv2.setRNGSeed(self.cfg.seed)  # FLANN's randomised kd-trees
        index = cv2.flann_Index(root_sift(b.descriptors), {"algorithm": 1, "trees": 4})
        nn, dist2 = index.knnSearch(root_sift(a.descriptors), 2, params={"checks": 64})
        keep = a.lifted & (nn[:, 1] >= 0) & (dist2[:, 0] < RATIO**2 * dist2[:, 1])
        ms = np.stack([np.flatnonzero(keep), nn[keep, 0]], axis=1)
        if len(ms) < self.cfg.min_inliers:
            return None
        pose = estimate_absolute_pose(b.xy[ms[:, 1]], a.points[ms[:, 0]], self.K, self.w, self.h, self.pnp)
        return None if pose is None or pose.n_inliers < self.cfg.min_inliers else geometry.invert(pose.T_wc)

    def dense(
        self, s: int, t: int, init: np.ndarray, option: o3d.pipelines.odometry.OdometryOption
    ) -> np.ndarray | None:
        """open3d's hybrid (photometric and geometric) RGB-D odometry from ``init``, or None."""
        ok, motion, _ = o3d.pipelines.odometry.compute_rgbd_odometry(
            self.rgbd(s),
            self.rgbd(t),
            self.intrinsic,
            init,
            o3d.pipelines.odometry.RGBDOdometryJacobianFromHybridTerm(),
            option,
        )
        return motion if ok else None

    def information(self, s: int, t: int, motion: np.ndarray) -> tuple[np.ndarray, float]:
        """The edge's information matrix from point-cloud correspondences, and their share of frame s's points."""
        a, b = self.features[s].cloud, self.features[t].cloud
        if not len(a.points) or not len(b.points):
            return np.zeros((6, 6)), 0.0
        info = reg.get_information_matrix_from_point_clouds(a, b, 1.4 * self.cfg.voxel_m, motion)
        return info, float(info[5, 5] / len(a.points))

    def register(self, s: int, t: int, guesses: Sequence[np.ndarray]) -> tuple[np.ndarray, np.ndarray] | None:
        """``(T_t<-s, information)``: PnP refined by dense odometry when the two agree; without PnP, dense
        odometry from each of ``guesses`` (none: the pair fails) if it overlaps by ``min_fitness``."""
        pnp = self.pnp_motion(s, t)
        if pnp is not None:
            refined = self.dense(s, t, pnp, self.refine)
            if refined is not None:
                shift, turn = geometry.pose_errors(geometry.invert(pnp), geometry.invert(refined))
                info, fitness = self.information(s, t, refined)
                if (
                    shift <= self.cfg.max_refine_m
                    and turn <= self.cfg.max_refine_deg
                    and fitness >= self.cfg.min_fitness
                ):
                    return refined, info
            return pnp, self.information(s, t, pnp)[0]
        best = None
        for guess in guesses:
            motion = self.dense(s, t, guess, self.search)
            if motion is not None:
                info, fitness = self.information(s, t, motion)
                if fitness >= self.cfg.min_fitness and (best is None or fitness > best[2]):
                    best = motion, info, fitness
        return None if best is None else best[:2]


def loop_candidates(poses: np.ndarray, i: int, cfg: OdometryConfig) -> list[int]:
    """Earlier frames (more than 2 back) that frame i's estimate sees from nearby: the closest of each
    visit (a run of consecutive candidates), closest visits first, at most ``max_loop_candidates``."""
    earlier = poses[: max(i - 2, 0)]
    dist = np.linalg.norm(earlier[:, :3, 3] - poses[i, :3, 3], axis=1)
    cos = earlier[:, :3, 2] @ poses[i, :3, 2]
    near = np.flatnonzero((dist <= cfg.loop_radius_m) & (cos >= np.cos(np.radians(cfg.loop_angle_deg))))
    visits = np.split(near, np.flatnonzero(np.diff(near) > 1) + 1) if len(near) else []
    best = sorted((int(v[np.argmin(dist[v])]) for v in visits), key=lambda j: dist[j])
    return best[: cfg.max_loop_candidates]


def estimate_trajectory(
    rgbs: Sequence[np.ndarray],
    depths: Sequence[np.ndarray],
    K: np.ndarray,
    first_pose: np.ndarray,
    cfg: OdometryConfig | None = None,
    progress: bool = False,
) -> Trajectory:
    """Camera-to-world poses of an RGB-D sequence (uint8 (H, W, 3) colours, float32 metric depths with 0
    where missing, pinhole ``K``) by odometry, loop closure and pose-graph optimisation; frame 0 is put
    at ``first_pose``. Deterministic: open3d runs on one thread meanwhile."""
    cfg = cfg or OdometryConfig()
    if len(rgbs) != len(depths) or not len(rgbs):
        raise ValueError(f"need as many colour as depth images, at least one: got {len(rgbs)} and {len(depths)}")
    if any(d.shape != depths[0].shape or c.shape != (*d.shape, 3) for c, d in zip(rgbs, depths)):
        raise ValueError("colour images must be (H, W, 3) and depths (H, W), all of one size")
    first_pose = geometry.check_pose(first_pose, "first_pose")
    threads = o3d.utility.get_max_threads()
    o3d.utility.set_max_threads(1)
    try:
        with o3d.utility.VerbosityContextManager(o3d.utility.VerbosityLevel.Error):
            graph, bridges = _pose_graph(
                _Registrar(rgbs, depths, np.asarray(K, np.float64), cfg), len(rgbs), cfg, progress
            )
            option = reg.GlobalOptimizationOption(
                max_correspondence_distance=1.4 * cfg.voxel_m,
                edge_prune_threshold=cfg.edge_prune_threshold,
                preference_loop_closure=cfg.preference_loop_closure,
                reference_node=0,
            )
            reg.global_optimization(
                graph, reg.GlobalOptimizationLevenbergMarquardt(), reg.GlobalOptimizationConvergenceCriteria(), option
            )
    finally:
        o3d.utility.set_max_threads(threads)
    poses = np.array([node.pose for node in graph.nodes])
    poses = first_pose @ geometry.invert(poses[0]) @ poses
    loops = sum(e.uncertain for e in graph.edges)
    joined = [
        (e.source_node_id, e.target_node_id) for e in graph.edges if e.uncertain or e.target_node_id not in bridges
    ]
    s, t = np.array(joined, int).reshape(-1, 2).T
    _, segments = connected_components(coo_matrix((np.ones(len(s)), (s, t)), shape=(len(poses),) * 2), directed=False)
    return Trajectory(poses, len(graph.edges), loops, len(bridges), segments.astype(int))


def _pose_graph(registrar: _Registrar, n: int, cfg: OdometryConfig, progress: bool) -> tuple[reg.PoseGraph, set[int]]:
    """The pose graph (nodes at the chained odometry, frame 0 at the identity) and the frames t whose
    pair (t - 1, t) failed."""
    graph = reg.PoseGraph()
    poses = np.tile(np.eye(4), (n, 1, 1))
    motion, bridges = np.eye(4), set()
    graph.nodes.append(reg.PoseGraphNode(poses[0]))
    registrar.add_frame(0)
    for t in tqdm(range(1, n), disable=not progress, desc="odometry", unit="frame"):
        registrar.add_frame(t)
        edge = registrar.register(t - 1, t, [np.eye(4), motion])
        if edge is None:  # keep the graph connected, by an edge too weak to pull
            bridges.add(t)
            edge = motion, np.eye(6)
        motion = edge[0]
        poses[t] = poses[t - 1] @ geometry.invert(motion)
        graph.nodes.append(reg.PoseGraphNode(poses[t]))
        graph.edges.append(reg.PoseGraphEdge(t - 1, t, edge[0], edge[1], uncertain=False))
        for s in loop_candidates(poses, t, cfg):
            edge = registrar.register(s, t, [])
            if edge is not None:
                graph.edges.append(reg.PoseGraphEdge(s, t, edge[0], edge[1], uncertain=True))
    return graph, bridges


def align_to(estimated: np.ndarray, truth: np.ndarray, segments: np.ndarray | None = None) -> np.ndarray:
    """``estimated`` (N, 4, 4) T_wc moved rigidly (rotation and translation, no scale) so that its camera
    centres best fit ``truth``'s in the least-squares sense (Kabsch); with a single distinct centre,
    the first poses are made to coincide. ``segments`` (N,) labels parts moved each on its own."""
    est, gt = np.asarray(estimated, np.float64), np.asarray(truth, np.float64)
    if est.ndim != 3 or est.shape[1:] != (4, 4) or est.shape != gt.shape or not len(est):
        raise ValueError(f"need two (N, 4, 4) pose arrays of one length, got {est.shape} and {gt.shape}")
    if segments is not None:
        segments = np.asarray(segments)
        if segments.shape != (len(est),):
            raise ValueError(f"segments must have shape ({len(est)},), got {segments.shape}")
        aligned = np.empty_like(est)
        for k in np.unique(segments):
            aligned[segments == k] = align_to(est[segments == k], gt[segments == k])
        return aligned
    ce, cg = est[:, :3, 3], gt[:, :3, 3]
    me, mg = ce.mean(axis=0), cg.mean(axis=0)
    if np.ptp(ce, axis=0).max() < 1e-9 or np.ptp(cg, axis=0).max() < 1e-9:
        return gt[0] @ geometry.invert(est[0]) @ est
    with warnings.catch_warnings():  # collinear centres: any rotation about their line fits as well
        warnings.simplefilter("ignore", UserWarning)
        R = Rotation.align_vectors(cg - mg, ce - me)[0].as_matrix()
    return geometry.make_pose(R, mg - R @ me) @ est


def drift(estimated: np.ndarray, truth: np.ndarray, segments: np.ndarray | None = None) -> Drift:
    """Position and rotation errors of ``estimated`` against ``truth`` after :func:`align_to`."""
    t, r = geometry.pose_errors(truth, align_to(estimated, truth, segments))
    return Drift(float(np.sqrt(np.mean(t**2))), float(t.max()), float(np.median(r)), float(r.max()))
