"""Reconstruction and instance lifting (paper section 3.1, "Instance Segmentation").

1. :func:`fuse_tsdf` fuses the posed depth maps into a TSDF (open3d ``ScalableTSDFVolume``) and
   returns the mesh vertices, voxel-downsampled, as the scene point cloud P.
2. :func:`observe` projects P into every usable frame once; a point counts as *seen* by a frame when
   it projects inside the image, in front of the camera, and its depth agrees with the frame's depth
   map (so occluded points are discarded). Only points in cubes intersecting the frame's view
   frustum (up to its farthest depth) are projected, which makes multi-room scenes cheap. Each frame
   keeps the seen point indices and their pixels, the dataset instance id under them (when the frame
   has instance masks) and, with a segmenter, which seen points fall in each of its 2D masks.
   Everything later (voting, clustering, visibility, 2D boxes, crops) reads these observations.
3. Instances, two ways:
   - :func:`lift_by_voting` (oracle masks): every point takes the instance id it was seen under most
     often, if that id has enough votes and a large enough share of the point's views;
   - :func:`lift_by_clustering` (noisy / predicted masks), after MaskClustering (Yan et al., CVPR
     2024): 2D masks are graph nodes; a frame *observes* a mask only where one of its masks contains
     it (a frame that missed or split the object neither observes nor supports it); masks split in
     many frames are under-segmented and dropped; two nodes are linked when a large share
     ("consensus rate") of their observers contain both in one mask; merging repeats with a
     decreasing requirement on the number of observers; finally each cluster keeps the points its
     masks detect in most of its frames (drops what dilated masks took from the background).
   All consensus counts are sparse-matrix products (masks x points incidence), not Python loops.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import Literal

import numba
import numpy as np
import open3d as o3d
import open3d.core as o3c
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from openreloc_bench import geometry
from openreloc_bench.bars import tqdm
from openreloc_bench.config import check_ranges
from openreloc_bench.data import io
from openreloc_bench.data.scene import ObjectInfo
from openreloc_bench.data.types import SceneSequence
from openreloc_bench.errors import DataError
from openreloc_bench.openreloc.affinity_grouping import AffinityConfig
from openreloc_bench.openreloc.incidence import incidence, sets_matrix, view_evidence
from openreloc_bench.openreloc.instance_repair import RepairConfig
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
    max_fusion_width: int = 320
    """Depth maps wider than this are subsampled by an integer stride before fusion (intrinsics
    scaled to match): at 320 px a pixel spans ~2 cm at 4 m, the TSDF voxel, so fusing every pixel of
    a 640x480 map costs 4x the time for no extra surface. 0 fuses full resolution."""

    def __post_init__(self) -> None:
        check_ranges(
            self,
            positive=("voxel_size", "sdf_trunc_voxels", "depth_max"),
            at_least_one=("block_resolution", "block_count"),
            non_negative=("min_weight", "max_fusion_width"),
            share=("min_valid_depth",),
        )
        if 0 < self.max_fusion_width < 16:  # a stride that leaves a few depth pixels to fuse
            raise ValueError(f"'max_fusion_width' must be 0 (full resolution) or >= 16, got {self.max_fusion_width}")


@dataclass
class ObservationConfig:
    """When a scene point counts as seen by a frame."""

    depth_tolerance: float = 0.05
    """Max |projected depth - measured depth| (m) for a point to be seen (else occluded)."""
    depth_tolerance_rel: float = 0.02
    """Extra tolerance proportional to depth (share of the measured depth)."""
    cell_size: float = 0.5
    """Frustum culling: the cloud is bucketed into cubes of this edge (m) and a frame projects only the
    points of cubes that intersect its view frustum up to its farthest depth. Same result as projecting
    everything; in a multi-room scene a frame sees a small share of the cubes. 0 disables culling."""

    def __post_init__(self) -> None:
        check_ranges(self, non_negative=("depth_tolerance", "depth_tolerance_rel", "cell_size"))


@dataclass
class VotingConfig:
    """Oracle-mask lifting: per-point majority vote over the frames that see the point."""

    min_votes: int = 2
    """A point needs at least this many frames seeing it under the winning instance id."""
    min_share: float = 0.5
    """...and the winning id must hold at least this share of the point's views (background included)."""

    def __post_init__(self) -> None:
        check_ranges(self, at_least_one=("min_votes",), share=("min_share",))


@dataclass
class ClusteringConfig:
    """View-consensus clustering of 2D masks (MaskClustering-style, see :func:`lift_by_clustering`)."""

    min_mask_points: int = 10
    """2D masks covering fewer seen scene points are dropped (too small to lift reliably)."""
    visible_share: float = 0.3
    """A mask is visible in another frame when this share of its points lie inside that frame's masks."""
    containment: float = 0.8
    """...and contained there when one mask of that frame holds this share of them (else it is split)."""
    undersegment_share: float = 0.3
    """Masks split in more than this share of the frames they are visible in span several objects
    (under-segmentation): they are dropped and neither observe nor support other masks."""
    consensus: float = 0.9
    """Link two nodes when at least this share of the frames observing both contain them in one mask."""
    observer_percentiles: tuple[float, ...] = tuple(float(p) for p in range(95, -5, -5))
    """Merging rounds: a pair needs at least this percentile of all pairs' observer counts (decreasing)."""
    min_observers: int = 1
    """Never link two nodes observed together by fewer frames than this."""
    min_masks: int = 2
    """Final clusters made of fewer 2D masks are dropped (single-view noise)."""
    point_support: float = 0.5
    """A cluster keeps a point when the cluster's masks hold it in more than this share of the
    cluster's frames that see it (drops points that dilated masks picked up from the background)."""
    split_distance: float = 0.0
    """Clusters are split into parts connected at this distance (m); 0 (default) keeps them whole: on
    the smoke scene a 0.1 m split cut a table apart (precision 0.85 vs 0.89 whole) and on the box room
    it cut the floor at occlusion gaps (0.47 vs 0.80)."""
    min_part_share: float = 0.1
    """...and parts smaller than this share of the cluster's largest part are dropped as fragments."""
    nested_share: float = 0.8
    """A cluster with more than this share of its points inside a larger cluster is dropped."""

    def __post_init__(self) -> None:
        check_ranges(
            self,
            at_least_one=("min_masks",),
            non_negative=("min_mask_points", "min_observers", "split_distance"),
            share=(
                "visible_share",
                "containment",
                "undersegment_share",
                "consensus",
                "point_support",
                "min_part_share",
                "nested_share",
            ),
        )
        if any(not 0 <= p <= 100 for p in self.observer_percentiles):
            raise ValueError(f"'observer_percentiles' must be percentiles in [0, 100], got {self.observer_percentiles}")


@dataclass
class InstanceConfig:
    """Turning labelled scene points into landmarks."""

    min_points: int = 20
    """Instances with fewer scene points are dropped."""
    gt_box_margin: float = 0.03
    """Ground truth for the instance precision/recall: points within this distance (m) of an object's
    box in ``objects.json`` (see :func:`box_point_labels`); ~1.5 fusion voxels absorbs surface noise."""
    grouping: Literal["affinity", "clustering"] = "affinity"
    """How a segmenter's masks become 3D instances: 'affinity' (neighbouring points held together by
    the views' masks, :mod:`affinity_grouping`; needs the dense views of a walk-through) or
    'clustering' (view consensus of whole masks, :func:`lift_by_clustering`; best with
    ``repair.fill``)."""
    voting: VotingConfig = field(default_factory=VotingConfig)
    clustering: ClusteringConfig = field(default_factory=ClusteringConfig)
    affinity: AffinityConfig = field(default_factory=AffinityConfig)
    repair: RepairConfig = field(default_factory=RepairConfig)
    """Fill and merge of the grouped instances (segmenter masks only)."""

    def __post_init__(self) -> None:
        check_ranges(self, non_negative=("min_points", "gt_box_margin"))

    @property
    def min_mask_points(self) -> int:
        """The smallest 2D mask the chosen grouping trusts (the repair reads the same masks)."""
        return (self.affinity if self.grouping == "affinity" else self.clustering).min_mask_points


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
    boundary: np.ndarray | None = None
    """(M,) float16 segmenter boundary strength at each seen point's pixel (``observe(boundaries=True)``)."""
    rgb: np.ndarray | None = None
    """(M, 3) uint8 colour at each seen point's pixel (``observe(boundaries=True)``)."""


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
        attr_names=("tsdf", "weight"),
        attr_dtypes=(o3c.float32, o3c.float32),
        attr_channels=((1), (1)),
        voxel_size=cfg.voxel_size,
        block_resolution=cfg.block_resolution,
        block_count=cfg.block_count,
        device=device,
    )
    stride = max(1, -(-seq.width // cfg.max_fusion_width)) if cfg.max_fusion_width > 0 else 1
    K_np = np.asarray(seq.K, dtype=np.float64).copy()
    K_np[:2] /= stride  # pixel j of depth[::stride] is pixel stride * j of the full map
    K = o3c.Tensor(K_np)
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
        d = o3d.t.geometry.Image(
            o3c.Tensor(np.ascontiguousarray(np.where(ok, depth, 0)[::stride, ::stride], dtype=np.float32))
        )
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
    boundaries: bool = False,
) -> list[FrameObservation]:
    """Project the scene cloud into each usable frame (depth-tested) and record what is seen; with
    ``boundaries`` also the segmenter's boundary strength and the colour at each seen point (what the
    instance merge reads; about 5 bytes per seen point and frame)."""
    cells = _PointCells(points, cfg.cell_size)
    obs = []
    for i in tqdm(np.flatnonzero(usable), desc="observe", disable=not progress, leave=False):
        depth = read_depth(seq, int(i))
        assert depth is not None  # usable frames have depth
        T = _pose(seq, int(i))
        valid_depth = depth[np.isfinite(depth) & (depth > 0)]
        far = (
            float(valid_depth.max()) * (1 + cfg.depth_tolerance_rel) + cfg.depth_tolerance if len(valid_depth) else 0.0
        )
        cand = cells.in_frustum(seq.K, T, seq.width, seq.height, far)
        uv, z = geometry.project(seq.K, T, points[cand])
        px = np.round(uv).astype(np.int64)
        inside = (z > 1e-6) & (px[:, 0] >= 0) & (px[:, 0] < seq.width) & (px[:, 1] >= 0) & (px[:, 1] < seq.height)
        sub = np.flatnonzero(inside)
        d = depth[px[sub, 1], px[sub, 0]]
        tol = cfg.depth_tolerance + cfg.depth_tolerance_rel * d
        sub = sub[np.isfinite(d) & (d > 0) & (np.abs(z[sub] - d) < tol)]
        idx, pix = cand[sub], px[sub]
        inst = read_instance(seq, int(i))
        fo = FrameObservation(
            index=int(i),
            point_idx=idx.astype(np.int32),
            uv=pix.astype(np.int16),
            gt_ids=None if inst is None else inst[pix[:, 1], pix[:, 0]].astype(np.int32),
        )
        if segmenter is not None:
            rgb = read_color(seq, int(i))
            if boundaries:
                masks, boundary = segmenter.segment_with_boundaries(rgb, inst)
                fo.boundary = boundary[pix[:, 1], pix[:, 0]].astype(np.float16)
                fo.rgb = rgb[pix[:, 1], pix[:, 0]]
            else:
                masks = segmenter.segment(rgb, inst)
            for m in masks:
                fo.masks.append(np.flatnonzero(m.mask[pix[:, 1], pix[:, 0]]).astype(np.int32))
        obs.append(fo)
    return obs


class _PointCells:
    """The scene cloud bucketed into cubes, for conservative view-frustum culling (sphere vs planes)."""

    def __init__(self, points: np.ndarray, cell: float):
        self.n = len(points)
        self.cell = cell
        if cell <= 0 or self.n == 0:
            return
        keys, inv = np.unique(np.floor(points / cell).astype(np.int64), axis=0, return_inverse=True)
        inv = inv.ravel()
        self.order = np.argsort(inv, kind="stable")  # point indices grouped by cube, ascending within
        self.count = np.bincount(inv, minlength=len(keys))
        self.center = (keys + 0.5) * cell
        self.radius = 0.5 * np.sqrt(3.0) * cell

    def in_frustum(self, K: np.ndarray, T_wc: np.ndarray, width: int, height: int, far: float) -> np.ndarray:
        """Sorted indices of the points in cubes that may be seen by a camera (depth up to ``far``)."""
        if self.cell <= 0 or self.n == 0:
            return np.arange(self.n)
        x, y, z = geometry.transform_points(geometry.invert(T_wc), self.center).T
        r = self.radius
        ok = (z > -r) & (z < far + r)
        K = np.asarray(K, dtype=np.float64)
        for coord, f, c, size in ((x, K[0, 0], K[0, 2], width), (y, K[1, 1], K[1, 2], height)):
            lo, hi = (-0.5 - c) / f, (size - 0.5 - c) / f  # image edges as slopes coord/z
            ok &= (coord - lo * z) / np.hypot(1.0, lo) >= -r
            ok &= (hi * z - coord) / np.hypot(1.0, hi) >= -r
        # the points of the chosen cubes, marked in point order: sorted without a sort
        chosen = np.zeros(self.n, bool)
        chosen[self.order[np.repeat(ok, self.count)]] = True
        return np.flatnonzero(chosen)


def lift_by_voting(n_points: int, obs: list[FrameObservation], cfg: VotingConfig) -> np.ndarray:
    """(N,) int64 label per scene point (0 = unassigned) by majority over the frames that see it: the
    instance id seen most often (the smallest among equally frequent ones; background never wins), kept
    with at least ``min_votes`` and ``min_share`` of the point's views (background included)."""
    if not obs:
        return np.zeros(n_points, np.int64)
    pts = np.concatenate([o.point_idx for o in obs]).astype(np.int64)
    ids = np.concatenate([o.gt_ids for o in obs]).astype(np.int64)  # type: ignore[misc]
    return _vote(pts, ids, n_points, cfg.min_votes, cfg.min_share)


@numba.njit(cache=True, nogil=True)
def _vote(pts: np.ndarray, ids: np.ndarray, n_points: int, min_votes: int, min_share: float) -> np.ndarray:
    """:func:`lift_by_voting` over the (point, id) observations: grouped by point with a counting sort,
    then each point's few dozen ids counted in order. Compiled: a sparse (point x id) vote matrix over
    tens of millions of observations spent seconds in ``np.unique`` and its row-wise argmax."""
    views = np.zeros(n_points, np.int64)
    for p in pts:
        views[p] += 1
    start = np.zeros(n_points + 1, np.int64)
    start[1:] = np.cumsum(views)
    fill = start[:-1].copy()
    grouped = np.empty(len(ids), np.int64)
    for k in range(len(pts)):
        grouped[fill[pts[k]]] = ids[k]
        fill[pts[k]] += 1
    out = np.zeros(n_points, np.int64)
    for p in range(n_points):
        seen = np.sort(grouped[start[p] : start[p + 1]])
        best_id, best_n, i = 0, 0, 0
        while i < len(seen):
            j = i
            while j < len(seen) and seen[j] == seen[i]:
                j += 1
            if seen[i] != 0 and j - i > best_n:  # ascending ids: the smallest wins a tie
                best_id, best_n = seen[i], j - i
            i = j
        if best_n >= min_votes and best_n >= min_share * max(views[p], 1):
            out[p] = best_id
    return out


def lift_by_clustering(points: np.ndarray, obs: list[FrameObservation], cfg: ClusteringConfig) -> np.ndarray:
    """(N,) int64 cluster label per scene point (0 = unassigned), by view-consensus mask clustering.

    Steps (after MaskClustering, Yan et al. CVPR 2024): per-mask statistics over every frame
    (:func:`_mask_frame_stats`: where each mask is visible and which mask of that frame contains it;
    masks split in too many frames are under-segmented and removed), iterative merging with a
    decreasing observer threshold (:func:`_merge_nodes`), then per cluster: keep points detected in
    enough of the cluster's frames, split spatially disconnected parts, drop clusters nested in others.
    """
    n_points = len(points)
    views = view_evidence(n_points, obs, cfg.min_mask_points)
    n_masks = len(views.mask_frame)
    if not n_masks:
        return np.zeros(n_points, np.int64)
    visible, contained, keep = _mask_frame_stats(views.masks, views.mask_frame, len(obs), cfg)
    groups, visible = _merge_nodes(visible[keep], contained[keep], cfg)
    groups = groups @ incidence(np.arange(keep.sum()), np.flatnonzero(keep), (int(keep.sum()), n_masks))
    return _cluster_points(points, groups.tocsr(), visible.tocsr(), views.masks, views.seen, cfg)


def _mask_frame_stats(
    M: sp.csr_matrix, mask_frame: np.ndarray, n_frames: int, cfg: ClusteringConfig
) -> tuple[sp.csr_matrix, sp.csr_matrix, np.ndarray]:
    """(visible: masks x frames, contained: masks x masks, keep: masks that are not under-segmented).

    Points inside two masks of one frame are mask boundaries and ignored here. Mask m is visible in
    frame f when ``visible_share`` of its points lie in masks of f; it is contained there when one
    mask of f holds ``containment`` of those. ``visible`` keeps only frames where m is contained
    (a frame that splits m neither observes nor supports it).
    """
    n_masks = M.shape[0]
    frame_ind = incidence(mask_frame, np.arange(n_masks), (n_frames, n_masks))
    per_frame = (frame_ind @ M).tocsc()
    per_frame.data = (per_frame.data > 1).astype(np.float32)  # >1 mask of one frame holds the point
    boundary = np.asarray(per_frame.max(axis=0).todense()).ravel() > 0
    Mv = sp.csr_matrix(M.multiply(~boundary[None, :]))
    size = np.asarray(Mv.sum(axis=1)).ravel()
    C = (Mv @ Mv.T).tocoo()  # shared valid points of every mask pair
    m, k, n = C.row, C.col, C.data
    f = mask_frame[k]
    key = m.astype(np.int64) * n_frames + f
    order = np.lexsort((-n, key))
    key, m, k, n, f = key[order], m[order], k[order], n[order], f[order]
    start = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
    covered = np.add.reduceat(n, start)
    gm, gf, gk, best = m[start], f[start], k[start], n[start]  # first of each group = best mask
    vis = covered >= cfg.visible_share * size[gm]
    con = vis & (best >= cfg.containment * covered)
    n_vis = np.bincount(gm[vis], minlength=n_masks)
    n_split = np.bincount(gm[vis & ~con], minlength=n_masks)
    under = (n_vis == 0) | (n_split > cfg.undersegment_share * n_vis)
    con &= ~under[gk]  # an under-segmented mask neither observes nor supports the masks it holds
    visible = incidence(gm[con], gf[con], (n_masks, n_frames))
    contained = incidence(gm[con], gk[con], (n_masks, n_masks))
    return visible, contained, ~under


def _merge_nodes(
    visible: sp.csr_matrix, contained: sp.csr_matrix, cfg: ClusteringConfig
) -> tuple[sp.csr_matrix, sp.csr_matrix]:
    """Iterative view-consensus merging; returns (nodes x input masks membership, nodes x frames visible).

    Observers of a pair = frames where both are visible (contained); supporters = masks containing
    both. Pairs with consensus >= ``consensus`` merge; the observer-count requirement falls from the
    95th percentile of all pairs' counts to 0, so that well-observed pairs are decided first.
    """
    groups = sp.identity(visible.shape[0], format="csr", dtype=np.float32)
    observers = (visible @ visible.T).tocsr()
    counts = observers.data[observers.data > 0]
    if len(counts) == 0:
        return groups, visible
    thresholds = []
    for q in cfg.observer_percentiles:
        t = float(np.percentile(counts, q))
        if t <= 1:
            if q < 50:
                break
            t = 1.0
        thresholds.append(max(t, float(cfg.min_observers)))
    for thr in thresholds:
        observers = (visible @ visible.T).tocsr()
        S = (contained @ contained.T).tocsr()
        observers.data[observers.data < thr] = 0
        observers.eliminate_zeros()
        # link where supporters >= consensus * observers, on pairs with enough observers
        observers = observers.tocoo()
        sup = np.asarray(S[observers.row, observers.col]).ravel()
        ok = (observers.row != observers.col) & (sup >= cfg.consensus * observers.data)
        if not ok.any():
            continue
        link = sp.coo_matrix((np.ones(int(ok.sum())), (observers.row[ok], observers.col[ok])), shape=observers.shape)
        n_comp, comp = connected_components(link, directed=False)
        merge = incidence(comp, np.arange(len(comp)), (n_comp, len(comp)))
        groups = _binary(merge @ groups)
        visible = _binary(merge @ visible)
        contained = _binary(merge @ contained)
    return groups, visible


def _cluster_points(
    points: np.ndarray,
    groups: sp.csr_matrix,
    visible: sp.csr_matrix,
    M: sp.csr_matrix,
    seen: sp.csr_matrix,
    cfg: ClusteringConfig,
) -> np.ndarray:
    """Point labels from mask clusters: detection-ratio filter, connectivity split, nesting removal."""
    n_masks_per = np.asarray(groups.sum(axis=1)).ravel()
    seen_pf = seen.T.tocsr()  # points x frames
    objects: list[tuple[np.ndarray, np.ndarray]] = []  # (point idx, detection ratio)
    for c in np.flatnonzero(n_masks_per >= cfg.min_masks):
        hits = groups[c] @ M  # 1 x points: how many of the cluster's masks hold each point
        idx = hits.indices
        frames = visible[c].indices
        den = np.asarray(seen_pf[idx][:, frames].sum(axis=1)).ravel()
        ratio = hits.data / np.maximum(den, 1)
        ok = ratio > cfg.point_support
        idx, ratio = idx[ok], ratio[ok]
        parts = _connected_parts(points[idx], cfg.split_distance)
        largest = max((len(p) for p in parts), default=0)
        objects += [(idx[p], ratio[p]) for p in parts if len(p) >= cfg.min_part_share * largest]
    objects = _drop_nested(objects, cfg.nested_share)
    best = np.zeros(len(points))
    labels = np.zeros(len(points), np.int64)
    for lab, (idx, ratio) in enumerate(objects, start=1):
        win = ratio > best[idx]
        labels[idx[win]] = lab
        best[idx[win]] = ratio[win]
    return labels


def _connected_parts(pts: np.ndarray, eps: float) -> list[np.ndarray]:
    """Index sets of the parts of a point set connected at about distance ``eps`` (all when eps <= 0).

    Connectivity is computed on occupied cells of edge eps/2 (linked when their centres are within
    eps), not on the points: a 40k-point floor has a few thousand cells.
    """
    if eps <= 0 or len(pts) < 2:
        return [np.arange(len(pts))]
    cells, inv = np.unique(np.floor(pts / (eps / 2)).astype(np.int64), axis=0, return_inverse=True)
    inv = inv.ravel()
    pairs = cKDTree(cells.astype(np.float64)).query_pairs(2.0 + 1e-6, output_type="ndarray")
    g = sp.coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(len(cells), len(cells)))
    n, comp = connected_components(g, directed=False)
    point_comp = comp[inv]
    order = np.argsort(point_comp, kind="stable")
    return np.split(order, np.flatnonzero(np.diff(point_comp[order])) + 1)


def _drop_nested(objects: list[tuple[np.ndarray, np.ndarray]], share: float) -> list[tuple[np.ndarray, np.ndarray]]:
    """Drop objects whose points lie mostly (> ``share``) inside another, larger object."""
    if len(objects) < 2:
        return objects
    n_points = 1 + max(int(o[0].max(initial=0)) for o in objects)
    A = sets_matrix([o[0] for o in objects], n_points)
    inter = (A @ A.T).tocoo()
    size = np.array([len(o[0]) for o in objects])
    i, j, n = inter.row, inter.col, inter.data
    nested = (i != j) & (n > share * size[i]) & ((size[i] < size[j]) | ((size[i] == size[j]) & (i > j)))
    drop = set(i[nested].tolist())
    return [o for k, o in enumerate(objects) if k not in drop]


def _binary(m: sp.spmatrix) -> sp.csr_matrix:
    m = sp.csr_matrix(m, dtype=np.float32)
    m.data[:] = 1.0
    return m


def instance_sets(labels: np.ndarray, min_points: int) -> dict[int, np.ndarray]:
    """Label -> sorted point indices, for labels with at least ``min_points`` points (one sort, not a scan per label)."""
    fg = np.flatnonzero(labels > 0)
    order = fg[np.argsort(labels[fg], kind="stable")]
    ids, start, count = np.unique(labels[order], return_index=True, return_counts=True)
    return {int(i): order[s : s + c] for i, s, c in zip(ids, start, count) if c >= min_points}


def boxed_objects(objects: dict[int, ObjectInfo]) -> dict[int, ObjectInfo]:
    """The objects with a box (``objects.json`` of generated scenes; converted real data has none)."""
    return {i: o for i, o in objects.items() if np.any(np.asarray(o.aabb[1]) > np.asarray(o.aabb[0]))}


def box_point_labels(points: np.ndarray, objects: dict[int, ObjectInfo], margin: float) -> np.ndarray:
    """(N,) ground-truth instance id per point from the objects' world boxes (0 = in no box).

    Independent of the instance masks, so both the oracle and the predicted tracks can be scored
    against it. A point strictly inside one or more boxes takes the smallest of them (a lamp on a
    table, a painting on a wall); a point only within ``margin`` of boxes (surface noise, thin walls
    and floors) takes the smallest of those. Loose boxes of rotated objects make it slightly coarse.
    """
    ids = np.array(sorted(objects))
    labels = np.zeros(len(points), np.int64)
    if len(ids) == 0 or len(points) == 0:
        return labels
    lo = np.array([objects[i].aabb[0] for i in ids], np.float64)
    hi = np.array([objects[i].aabb[1] for i in ids], np.float64)
    volume = np.prod(hi - lo + 2 * margin, axis=1)
    order = np.argsort(points[:, 0], kind="stable")  # each box tests only its slab of x
    xs = points[order, 0]
    best_strict = np.full(len(points), np.inf)
    best_loose = np.full(len(points), np.inf)
    lab_strict = np.zeros(len(points), np.int64)
    lab_loose = np.zeros(len(points), np.int64)
    for k in np.argsort(-volume):  # small boxes last, so they win ties of containment
        cand = order[np.searchsorted(xs, lo[k, 0] - margin) : np.searchsorted(xs, hi[k, 0] + margin, side="right")]
        p = points[cand]
        for m, best, lab in ((0.0, best_strict, lab_strict), (margin, best_loose, lab_loose)):
            idx = cand[np.all((p >= lo[k] - m) & (p <= hi[k] + m), axis=1)]
            idx = idx[volume[k] <= best[idx]]
            best[idx] = volume[k]
            lab[idx] = ids[k]
    return np.where(lab_strict > 0, lab_strict, lab_loose)
