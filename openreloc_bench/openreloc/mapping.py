"""Reconstruction and instance lifting (paper section 3.1, "Instance Segmentation").

1. :func:`fuse_tsdf` fuses the posed depth maps into a TSDF (open3d ``ScalableTSDFVolume``) and
   returns the mesh vertices, voxel-downsampled, as the scene point cloud P.
2. :func:`observe` projects P into every usable frame once; a point counts as *seen* by a frame when
   it projects inside the image, in front of the camera, and its depth agrees with the frame's depth
   map (so occluded points are discarded). Each frame keeps the seen point indices and their pixels,
   the dataset instance id under them (when the frame has instance masks) and, with a segmenter,
   which seen points fall in each of its 2D masks. Everything later (voting, clustering,
   visibility, 2D boxes, crops) reads these observations instead of the images.
3. Instances, two ways:
   - :func:`lift_by_voting` (oracle masks): every point takes the instance id it was seen under most
     often, if that id has enough votes and a large enough share of the point's views;
   - :func:`lift_by_clustering` (noisy / predicted masks), after MaskClustering (Yan et al., CVPR
     2024): 2D masks are graph nodes; two nodes are linked when, among the frames that see enough of
     both, a large share ("consensus rate") finds both inside one and the same mask of that frame;
     linked nodes merge, and merging repeats with a decreasing requirement on the number of
     observing frames, so that well-observed pairs are decided first.
   All consensus counts are sparse-matrix products (masks x points incidence), not Python loops.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np
import open3d as o3d
import open3d.core as o3c
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components
from tqdm import tqdm

from openreloc_bench import geometry
from openreloc_bench.data import io
from openreloc_bench.data.types import SceneSequence
from openreloc_bench.errors import DataError
from openreloc_bench.vision.base import Segmenter

log = logging.getLogger(__name__)


@dataclass
class FusionConfig:
    """TSDF fusion of the mapping frames."""

    voxel_size: float = 0.02
    """TSDF voxel edge (m); the scene point cloud is downsampled to the same spacing."""
    sdf_trunc_voxels: float = 4.0
    """TSDF truncation distance, in voxels."""
    depth_max: float = 8.0
    """Depth beyond this (m) is ignored by fusion (far depth is noisy in real sensors)."""
    min_valid_depth: float = 0.05
    """A frame whose share of valid (finite, > 0) depth pixels is below this is skipped and reported."""
    min_weight: float = 2.0
    """Surface voxels need this much accumulated TSDF weight (about: observed by this many frames)."""
    block_resolution: int = 8
    """Voxels per block edge in open3d's hashed voxel-block grid."""
    block_count: int = 20000
    """Initial number of voxel blocks the hash map reserves (it grows when needed)."""


@dataclass
class ObservationConfig:
    """When a scene point counts as seen by a frame."""

    depth_tolerance: float = 0.05
    """Max |projected depth - measured depth| (m) for a point to be seen (else occluded)."""
    depth_tolerance_rel: float = 0.02
    """Extra tolerance proportional to depth (share of the measured depth)."""


@dataclass
class VotingConfig:
    """Oracle-mask lifting: per-point majority vote over the frames that see the point."""

    min_votes: int = 2
    """A point needs at least this many frames seeing it under the winning instance id."""
    min_share: float = 0.5
    """...and the winning id must hold at least this share of the point's views (background included)."""


@dataclass
class ClusteringConfig:
    """View-consensus clustering of 2D masks (MaskClustering-style)."""

    min_mask_points: int = 10
    """2D masks covering fewer seen scene points are dropped (too small to lift reliably)."""
    observe_share: float = 0.1
    """A frame observes a node when it sees at least this share of the node's points."""
    containment: float = 0.8
    """A node is inside a mask of an observing frame when that mask holds this share of its seen points."""
    consensus: float = 0.9
    """Link two nodes when at least this share of the frames observing both contain them in one mask."""
    observer_quantiles: tuple[float, ...] = (0.95, 0.9, 0.8, 0.7, 0.6, 0.5, 0.4, 0.3, 0.2, 0.1, 0.0)
    """Rounds: nodes pairs need at least this quantile of the pairs' observer counts (decreasing)."""
    min_observers: int = 2
    """Never link two nodes observed together by fewer frames than this."""
    min_masks: int = 2
    """Final clusters made of fewer 2D masks are dropped (single-view noise)."""
    max_rounds: int = 5
    """Merging repeats at one observer threshold until nothing merges, at most this many times."""


@dataclass
class InstanceConfig:
    """Turning labelled scene points into landmarks."""

    min_points: int = 20
    """Instances with fewer scene points are dropped."""
    voting: VotingConfig = field(default_factory=VotingConfig)
    clustering: ClusteringConfig = field(default_factory=ClusteringConfig)


@dataclass
class Reconstruction:
    points: np.ndarray
    """(N, 3) float32 scene point cloud (TSDF mesh vertices, voxel-downsampled)."""
    usable: np.ndarray
    """(F,) bool: frames fused (others skipped)."""
    skipped: dict[str, str]
    """Frame name -> why it was skipped."""


@dataclass
class FrameObservation:
    """What one frame sees of the scene point cloud."""

    index: int
    """Frame index in the mapping sequence."""
    point_idx: np.ndarray
    """(M,) int32 indices of seen scene points."""
    uv: np.ndarray
    """(M, 2) int16 pixel (column, row) of each seen point."""
    gt_ids: np.ndarray | None = None
    """(M,) int32 dataset instance id under each seen point (0 = none), when the frame has masks."""
    masks: list[np.ndarray] = field(default_factory=list)
    """Per segmenter mask: indices into ``point_idx`` of the seen points inside it."""


def _pose(seq: SceneSequence, i: int) -> np.ndarray:
    T = seq.records[i].T_wc
    if not geometry.is_rigid(T):
        raise DataError(f"{seq.split}/{seq.records[i].frame_id}", "pose is not a rigid transform")
    return np.asarray(T, dtype=np.float64)


def read_depth(seq: SceneSequence, i: int) -> np.ndarray | None:
    r = seq.records[i]
    if r.depth_path is None or not r.depth_path.exists():
        return None
    return io.read_depth(r.depth_path, seq.depth_scale, expect_hw=(seq.height, seq.width))


def read_color(seq: SceneSequence, i: int) -> np.ndarray:
    return io.read_rgb(seq.records[i].color_path, expect_hw=(seq.height, seq.width))


def read_instance(seq: SceneSequence, i: int) -> np.ndarray | None:
    r = seq.records[i]
    if r.instance_path is None or not seq.load_instances:
        return None
    return io.read_instance(r.instance_path, expect_hw=(seq.height, seq.width))


def fuse_tsdf(seq: SceneSequence, cfg: FusionConfig, progress: bool = True) -> Reconstruction:
    """TSDF-fuse every frame with usable depth; return the mesh vertices as the scene cloud.

    Uses open3d's tensor ``VoxelBlockGrid`` (the legacy ``ScalableTSDFVolume`` of the open3d 0.20
    wheel installed here extracts empty meshes even for a single fronto-parallel plane).
    """
    device = o3c.Device("CPU:0")
    vbg = o3d.t.geometry.VoxelBlockGrid(
        attr_names=("tsdf", "weight"), attr_dtypes=(o3c.float32, o3c.float32), attr_channels=((1), (1)),
        voxel_size=cfg.voxel_size, block_resolution=cfg.block_resolution, block_count=cfg.block_count, device=device,
    )
    K = o3c.Tensor(np.asarray(seq.K, dtype=np.float64))
    usable = np.zeros(len(seq), bool)
    skipped: dict[str, str] = {}
    for i in tqdm(range(len(seq)), desc="TSDF fusion", disable=not progress, leave=False):
        T = _pose(seq, i)
        depth = read_depth(seq, i)
        name = f"{seq.split}/{seq.records[i].frame_id}"
        if depth is None:
            skipped[name] = "no depth"
            continue
        ok = np.isfinite(depth) & (depth > 0) & (depth < cfg.depth_max)
        if ok.mean() < cfg.min_valid_depth:
            skipped[name] = f"only {ok.mean():.1%} valid depth pixels"
            continue
        d = o3d.t.geometry.Image(o3c.Tensor(np.where(ok, depth, 0).astype(np.float32)))
        ext = o3c.Tensor(geometry.invert(T))
        blocks = vbg.compute_unique_block_coordinates(d, K, ext, 1.0, cfg.depth_max, cfg.sdf_trunc_voxels)
        vbg.integrate(blocks, d, K, ext, 1.0, cfg.depth_max, cfg.sdf_trunc_voxels)
        usable[i] = True
    if skipped:
        log.warning("skipped %d of %d mapping frames without usable depth", len(skipped), len(seq))
    if not usable.any():
        raise DataError(seq.records[0].color_path.parent.parent, "no mapping frame has usable depth")
    try:
        vertices = vbg.extract_triangle_mesh(weight_threshold=cfg.min_weight).vertex.positions.numpy()
    except RuntimeError:  # open3d raises instead of returning an empty mesh
        vertices = np.zeros((0, 3))
    if len(vertices) == 0:
        raise DataError(seq.records[0].color_path.parent.parent, "TSDF fusion produced no surface")
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(vertices.astype(np.float64)))
    points = np.asarray(pcd.voxel_down_sample(cfg.voxel_size).points, dtype=np.float32)
    order = np.lexsort(points.T[::-1])  # deterministic order, independent of open3d's hashing
    return Reconstruction(points[order], usable, skipped)


def observe(
    seq: SceneSequence,
    points: np.ndarray,
    usable: np.ndarray,
    cfg: ObservationConfig,
    segmenter: Segmenter | None = None,
    progress: bool = True,
) -> list[FrameObservation]:
    """Project the scene cloud into each usable frame (depth-tested) and record what is seen."""
    obs = []
    for i in tqdm(np.flatnonzero(usable), desc="observe", disable=not progress, leave=False):
        depth = read_depth(seq, int(i))
        assert depth is not None  # usable frames have depth
        uv, z = geometry.project(seq.K, _pose(seq, int(i)), points)
        px = np.round(uv).astype(np.int64)
        inside = (z > 1e-6) & (px[:, 0] >= 0) & (px[:, 0] < seq.width) & (px[:, 1] >= 0) & (px[:, 1] < seq.height)
        idx = np.flatnonzero(inside)
        d = depth[px[idx, 1], px[idx, 0]]
        tol = cfg.depth_tolerance + cfg.depth_tolerance_rel * d
        seen = np.isfinite(d) & (d > 0) & (np.abs(z[idx] - d) < tol)
        idx = idx[seen]
        pix = px[idx]
        inst = read_instance(seq, int(i))
        fo = FrameObservation(
            index=int(i), point_idx=idx.astype(np.int32), uv=pix.astype(np.int16),
            gt_ids=None if inst is None else inst[pix[:, 1], pix[:, 0]].astype(np.int32),
        )
        if segmenter is not None:
            for m in segmenter.segment(read_color(seq, int(i)), inst):
                fo.masks.append(np.flatnonzero(m.mask[pix[:, 1], pix[:, 0]]).astype(np.int32))
        obs.append(fo)
    return obs


def gt_point_labels(n_points: int, obs: list[FrameObservation], cfg: VotingConfig) -> np.ndarray:
    """Dataset instance id per scene point by view voting (the oracle track's lifting)."""
    if any(o.gt_ids is None for o in obs):
        raise DataError(f"{len(obs)} observed frames", "some mapping frames have no instance masks")
    return lift_by_voting(n_points, obs, cfg)


def lift_by_voting(n_points: int, obs: list[FrameObservation], cfg: VotingConfig) -> np.ndarray:
    """(N,) int64 label per scene point (0 = unassigned) by majority over the frames that see it."""
    if not obs:
        return np.zeros(n_points, np.int64)
    pts = np.concatenate([o.point_idx for o in obs])
    ids = np.concatenate([o.gt_ids for o in obs]).astype(np.int64)  # type: ignore[misc]
    views = np.bincount(pts, minlength=n_points)
    uniq, inv = np.unique(ids, return_inverse=True)
    votes = sp.coo_matrix((np.ones(len(pts)), (pts, inv)), shape=(n_points, len(uniq))).tocsr()
    votes.sum_duplicates()
    fg = uniq != 0  # background votes count in the views, never as a winner
    votes_fg = votes[:, np.flatnonzero(fg)]
    best = np.asarray(votes_fg.argmax(axis=1)).ravel()
    n_best = np.asarray(votes_fg.max(axis=1).todense()).ravel()
    ok = (n_best >= cfg.min_votes) & (n_best >= cfg.min_share * np.maximum(views, 1))
    return np.where(ok, uniq[fg][best], 0)


def lift_by_clustering(n_points: int, obs: list[FrameObservation], cfg: ClusteringConfig) -> np.ndarray:
    """(N,) int64 cluster label per scene point (0 = unassigned), by view-consensus mask clustering."""
    # M: 2D masks x scene points; V: frames x scene points (seen); frame_of[m] = frame row of mask m.
    rows, cols, frame_of = [], [], []
    v_rows, v_cols = [], []
    for f, o in enumerate(obs):
        v_rows.append(np.full(len(o.point_idx), f))
        v_cols.append(o.point_idx)
        for m in o.masks:
            if len(m) >= cfg.min_mask_points:
                rows.append(np.full(len(m), len(frame_of)))
                cols.append(o.point_idx[m])
                frame_of.append(f)
    if not frame_of:
        return np.zeros(n_points, np.int64)
    n_masks, n_frames = len(frame_of), len(obs)
    M = _incidence(np.concatenate(rows), np.concatenate(cols), (n_masks, n_points))
    V = _incidence(np.concatenate(v_rows), np.concatenate(v_cols), (n_frames, n_points))
    mask_frame = np.array(frame_of)

    clusters = sp.identity(n_masks, format="csr", dtype=np.float32)  # clusters x masks
    thresholds = None
    for q in cfg.observer_quantiles:
        for _ in range(cfg.max_rounds):
            S, Ob = _consensus_counts(clusters, M, V, mask_frame, cfg)
            if thresholds is None:  # fixed once, from the first (all single-mask) round
                nz = Ob.data[Ob.data > 0]
                thresholds = [max(cfg.min_observers, float(np.quantile(nz, qq))) if len(nz) else np.inf
                              for qq in cfg.observer_quantiles]
            thr = thresholds[cfg.observer_quantiles.index(q)]
            Ob = Ob.multiply(Ob >= thr).tocsr()
            Sm = S.multiply(Ob > 0).tocsr()
            rate = Sm.multiply(Ob.power(-1.0)) if Ob.nnz else Ob
            link = (rate >= cfg.consensus).astype(np.int8)
            link.setdiag(0)
            link.eliminate_zeros()
            if link.nnz == 0:
                break
            n_comp, comp = connected_components(link, directed=False)
            merge = _incidence(comp, np.arange(len(comp)), (n_comp, len(comp)))
            clusters = (merge @ clusters).astype(bool).astype(np.float32).tocsr()
    n_masks_per = np.asarray(clusters.sum(axis=1)).ravel()
    keep = np.flatnonzero(n_masks_per >= cfg.min_masks)
    if len(keep) == 0:
        return np.zeros(n_points, np.int64)
    support = (clusters[keep] @ M).tocsc()  # clusters x points: how many of its masks hold the point
    best = np.asarray(support.argmax(axis=0)).ravel()
    has = np.asarray(support.max(axis=0).todense()).ravel() > 0
    return np.where(has, best + 1, 0).astype(np.int64)


def _incidence(rows: np.ndarray, cols: np.ndarray, shape: tuple[int, int]) -> sp.csr_matrix:
    m = sp.csr_matrix((np.ones(len(rows), np.float32), (rows, cols)), shape=shape)
    m.data[:] = 1.0  # duplicates collapse to 1
    return m


def _consensus_counts(
    clusters: sp.csr_matrix, M: sp.csr_matrix, V: sp.csr_matrix, mask_frame: np.ndarray, cfg: ClusteringConfig
) -> tuple[sp.csr_matrix, sp.csr_matrix]:
    """(supporters, observers) for every pair of clusters.

    A frame observes a cluster when it sees ``observe_share`` of the cluster's points; a cluster is
    contained in mask k of an observing frame when k holds ``containment`` of the points seen there.
    Observers of a pair = frames observing both; supporters = frames where both sit in the same mask.
    """
    P = (clusters @ M).astype(bool).astype(np.float32).tocsr()  # cluster point sets (union of masks)
    size = np.asarray(P.sum(axis=1)).ravel()
    seen = (P @ V.T).toarray()  # clusters x frames: points seen
    observed = seen >= cfg.observe_share * size[:, None]
    shared = (P @ M.T).tocoo()  # clusters x masks: points of the cluster inside the mask
    c, k = shared.row, shared.col
    f = mask_frame[k]
    ok = observed[c, f] & (shared.data >= cfg.containment * seen[c, f])
    C = _incidence(c[ok], k[ok], shared.shape)
    O = sp.csr_matrix(observed.astype(np.float32))
    return (C @ C.T).tocsr(), (O @ O.T).tocsr()


def instance_sets(labels: np.ndarray, min_points: int) -> dict[int, np.ndarray]:
    """Label -> point indices, for labels with at least ``min_points`` points."""
    out = {}
    for lab, count in zip(*np.unique(labels[labels > 0], return_counts=True)):
        if count >= min_points:
            out[int(lab)] = np.flatnonzero(labels == lab)
    return out


def instance_quality(
    pred: dict[int, np.ndarray], gt: dict[int, np.ndarray], iou_threshold: float = 0.5
) -> dict[str, float]:
    """3D instance precision/recall: a prediction is correct when it has IoU >= threshold with a GT
    instance (IoU > 0.5 makes the matching one-to-one, as in ScanNet instance evaluation)."""
    n_pred, n_gt = len(pred), len(gt)
    if not n_pred or not n_gt:
        return {"precision": 0.0, "recall": 0.0, "n_pred": n_pred, "n_gt": n_gt, "iou_threshold": iou_threshold}
    n_points = 1 + max(int(v.max(initial=0)) for v in (*pred.values(), *gt.values()))
    P = _sets_matrix(list(pred.values()), n_points)
    G = _sets_matrix(list(gt.values()), n_points)
    inter = (P @ G.T).toarray()
    union = np.asarray(P.sum(1)) + np.asarray(G.sum(1)).T - inter
    hit = inter / np.maximum(union, 1) >= iou_threshold
    return {
        "precision": float(hit.any(axis=1).mean()),
        "recall": float(hit.any(axis=0).mean()),
        "n_pred": n_pred,
        "n_gt": n_gt,
        "iou_threshold": iou_threshold,
    }


def _sets_matrix(sets: list[np.ndarray], n_points: int) -> sp.csr_matrix:
    rows = np.concatenate([np.full(len(s), i) for i, s in enumerate(sets)])
    return _incidence(rows, np.concatenate(sets), (len(sets), n_points))
