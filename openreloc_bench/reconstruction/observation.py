"""What every frame sees of the scene point cloud.

:func:`observe` projects the cloud into every usable frame once; a point counts as *seen* by a frame when
it projects inside the image, in front of the camera, and its depth agrees with the frame's depth map
(so occluded points are discarded). Only points in cubes intersecting the frame's view frustum (up to
its farthest depth) are projected, which makes multi-room scenes cheap. Each frame keeps the seen point
indices and their pixels, the dataset instance id under them (when the frame has instance masks) and,
with a segmenter, which seen points fall in each of its 2D masks. Everything later (voting, clustering,
visibility, 2D boxes, crops) reads these observations.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from openreloc_bench import geometry
from openreloc_bench.bars import tqdm
from openreloc_bench.config import check_ranges
from openreloc_bench.data.types import SceneSequence
from openreloc_bench.reconstruction.frames import frame_pose, read_color, read_depth, read_instance
from openreloc_bench.vision.base import Segmenter


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
        T = frame_pose(seq, int(i))
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
