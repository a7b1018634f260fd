"""A batch of hypotheses' dual-path 2D ICP problem: the loss of every (hypothesis, object) pair at
local poses and its gradient in (quaternion, translation).

:class:`BatchProblem` pads the objects of all hypotheses into arrays (hypotheses may align different
target sets) over the :class:`TargetTables` of their targets, evaluates the compiled loss
(:func:`.icp_kernel.dual_path`) and turns its per-object gradients into the poses' gradients (the chain
rule through the quaternion written out). :mod:`.refine` drives the optimisation.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass

import numpy as np

from openreloc_bench import geometry
from openreloc_bench.openreloc.icp_kernel import dual_path


def _quaternion_forms() -> np.ndarray:
    """(3, 3, 4, 4) symmetric M with R_ij = q^T M_ij q for a unit quaternion q = (w, x, y, z): the
    homogeneous form of the rotation matrix (e.g. R_00 = w^2 + x^2 - y^2 - z^2, R_01 = 2 (xy - wz))."""
    M = np.zeros((3, 3, 4, 4), np.float32)
    for i, diagonal in enumerate(([1.0, 1.0, -1.0, -1.0], [1.0, -1.0, 1.0, -1.0], [1.0, -1.0, -1.0, 1.0])):
        M[i, i][np.diag_indices(4)] = diagonal
    w, x, y, z = range(4)
    for (i, j), (a, b), (c, d), sign in [
        ((0, 1), (x, y), (w, z), -1.0),
        ((1, 0), (x, y), (w, z), 1.0),
        ((0, 2), (x, z), (w, y), 1.0),
        ((2, 0), (x, z), (w, y), -1.0),
        ((1, 2), (y, z), (w, x), -1.0),
        ((2, 1), (y, z), (w, x), 1.0),
    ]:
        M[i, j, a, b] = M[i, j, b, a] = 1.0
        M[i, j, c, d] = M[i, j, d, c] = sign
    return M


QUAT_FORMS = _quaternion_forms()


def quat_to_rotmat(q: np.ndarray) -> np.ndarray:
    """(B, 4) float32 quaternions (w, x, y, z; normalised here) -> (B, 3, 3) rotation matrices."""
    qn = q / np.linalg.norm(q, axis=-1, keepdims=True)
    return np.einsum("bk,ijkl,bl->bij", qn, QUAT_FORMS, qn)


@dataclass
class GradientTerms:
    """What one loss evaluation keeps for its gradient (B hypotheses, O objects)."""

    R: np.ndarray
    """(B, 3, 3) rotations of the local poses."""
    g_R: np.ndarray
    """(B, O, 3, 3) each object's loss gradient with respect to its hypothesis' rotation matrix."""
    g_sum: np.ndarray
    """(B, O, 3) each object's loss gradient with respect to its points in the current camera, summed."""


@dataclass
class TargetTables:
    """What the refinement needs of its targets, whatever the starting poses: subsampled points and
    backward-path pixels, and each target's per-pixel table, at the working resolution. Made once per
    query (:func:`target_tables`) and passed to every refinement of the same targets."""

    landmark_ids: list[int]
    pts_w: np.ndarray
    """(targets, P, 3) float64 subsampled world points, padded."""
    pts_valid: np.ndarray
    """(targets, P) which points are real."""
    pix: np.ndarray
    """(targets, M, 2) float32 backward-path mask pixels (x, y), padded with -BIG."""
    pix_valid: np.ndarray
    """(targets, M) which pixels are real."""
    pixel_table: np.ndarray
    """(targets * H * W, 4) float32 per pixel of each target's image: nearest mask pixel (x, y), outside
    the mask, counted (not hidden by another segment)."""
    camera: np.ndarray
    """float32 (fx, fy, cx, cy) at the working resolution."""
    height: int
    width: int
    scale: float
    """Working resolution / full resolution."""


class BatchProblem:
    """Padded, batched arrays of all objects and hypotheses; evaluates per-object losses at local poses.

    Each hypothesis aligns its own set of targets: its objects ("slots", padded to the longest set)
    index the targets, and padding (``real`` false) has no points and no pixels, so it adds nothing.

    Everything runs at the working resolution (``RefineConfig.max_side``); ``delta`` and the reported
    losses are converted so that the outside world only sees full-resolution pixels. Points closer than
    ``min_depth`` (metres, camera z) are ignored.
    """

    def __init__(self, T_inits: list[np.ndarray], tables: TargetTables, target_sets: list[list[int]], min_depth: float):
        n_hyp, H, W = len(T_inits), tables.height, tables.width
        self.H, self.W, self.min_depth, self.scale = H, W, min_depth, tables.scale
        self.unit = tables.scale**2  # full-resolution squared pixels -> working squared pixels
        # each hypothesis' objects ("slots", padded to the longest set): which target, and whether real
        n_obj = max(len(ts) for ts in target_sets)
        slots = np.zeros((n_hyp, n_obj), np.int64)
        real = np.zeros((n_hyp, n_obj), bool)
        for b, ts in enumerate(target_sets):
            slots[b, : len(ts)], real[b, : len(ts)] = ts, True
        # its objects' points in its initial camera frame: (B, n_obj, n_pts, 3)
        n_pts = tables.pts_w.shape[1]
        pts_c = np.stack(
            [
                geometry.transform_points(geometry.invert(T), tables.pts_w[row].reshape(-1, 3)).reshape(n_obj, n_pts, 3)
                for T, row in zip(T_inits, slots)
            ]
        )
        self.slots, self.real = slots, real
        self.pts = np.ascontiguousarray(pts_c, dtype=np.float32)
        self.pts_valid = tables.pts_valid[slots] & real[..., None]
        self.pix = np.ascontiguousarray(tables.pix[slots])
        self.pix_valid = tables.pix_valid[slots] & real[..., None]
        self.pixel_table = tables.pixel_table
        self.offset = slots * (H * W)
        self.camera = tables.camera
        self.n_hyp, self.n_obj = n_hyp, n_obj
        self.nn_idx = np.zeros(self.pix_valid.shape, np.int64)

    def subset(self, rows: list[int]) -> BatchProblem:
        """The problem of hypotheses ``rows`` only (the per-pixel table is shared, not copied), with
        their current backward correspondences: stopped hypotheses leave the batch instead of costing
        every later step."""
        sub = copy.copy(self)
        sub.slots, sub.real = self.slots[rows], self.real[rows]
        sub.pts, sub.pts_valid = self.pts[rows], self.pts_valid[rows]
        sub.pix, sub.pix_valid, sub.offset = self.pix[rows], self.pix_valid[rows], self.offset[rows]
        sub.nn_idx = self.nn_idx[rows]
        sub.n_hyp = len(rows)
        return sub

    def losses(self, q: np.ndarray, t: np.ndarray, delta: float, refresh: bool = True) -> np.ndarray:
        """(B, n_obj) dual-path loss of each object at the local poses (q (B, 4), t (B, 3)), in
        working-resolution squared pixels; ``delta`` in full-resolution pixels. ``refresh=False``
        keeps the backward path's previous nearest-point correspondences."""
        return self.evaluate(q, t, delta, refresh)[0]

    def evaluate(
        self, q: np.ndarray, t: np.ndarray, delta: float, refresh: bool = True
    ) -> tuple[np.ndarray, GradientTerms]:
        """:meth:`losses`, plus each object's gradient, which :meth:`gradient` weights and sums
        (:func:`.icp_kernel.dual_path`)."""
        R = quat_to_rotmat(q)  # (B, 3, 3)
        losses, g_R, g_sum = dual_path(
            R,
            t,
            self.pts,
            self.pts_valid,
            self.pixel_table,
            self.offset,
            self.pix,
            self.pix_valid,
            self.nn_idx,
            self.camera,
            self.H,
            self.W,
            self.min_depth,
            delta * self.scale,
            refresh,
        )
        return losses, GradientTerms(R, g_R.astype(np.float32), g_sum.astype(np.float32))

    def gradient(
        self, q: np.ndarray, t: np.ndarray, terms: GradientTerms, coef: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """d/d(q, t) of sum_(b, o) coef[b, o] * loss[b, o], from the objects' gradients of :meth:`evaluate`:
        pc = (p - t) R gives dL/dt = -R sum(dL/dpc); the rotation's through :func:`_quat_gradient`.
        ``tests/openreloc/test_icp_batch.py`` checks it against autograd through a torch form of the loss."""
        g_R = np.einsum("bo,boij->bij", coef, terms.g_R)
        g_t = -(terms.R @ np.einsum("bo,boj->bj", coef, terms.g_sum)[..., None])[..., 0]
        return _quat_gradient(q, g_R), g_t


def _quat_gradient(q: np.ndarray, g_R: np.ndarray) -> np.ndarray:
    """(B, 4) gradient w.r.t. the unnormalised quaternion ``q`` given (B, 3, 3) d loss / d R of
    :func:`quat_to_rotmat`: d R_ij / d q_unit = 2 M_ij q_unit, then the normalisation's projection."""
    norm = np.linalg.norm(q, axis=-1, keepdims=True)
    qn = q / norm
    g = 2.0 * np.einsum("bij,ijkl,bl->bk", g_R, QUAT_FORMS, qn)
    return (g - qn * (qn * g).sum(-1, keepdims=True)) / norm
