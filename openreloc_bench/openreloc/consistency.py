"""Render-and-compare: how well a camera pose explains the *whole* query segmentation (beyond the paper).

The refinement's loss measures how well the matched landmarks fit their own masks, so a wrong set of
matches can fit a wrong pose about as well as the right set fits the right one. Every landmark of the
map, walls and floors included, can be drawn at a pose, though, and a right pose reproduces the
query's segmentation: each query mask is covered by one drawn landmark that also looks like it. The
score is the optimal one-to-one assignment (``scipy.optimize.linear_sum_assignment``) of query masks to
drawn landmarks by IoU on a coarse grid, a pair's IoU weighted down when the landmark is not among
the object's visual candidates.

The drawing is a z-buffered splat of each landmark's (subsampled) points into cells of ``stride``
pixels, each point a square as wide as the landmark's point spacing at its depth (``splat``): drawn as
single cells, the points of a near landmark leave holes through which farther ones show, so a near
object's mask is under-explained and a wall hides nothing. Hand-written (a compiled z-buffer loop)
because the map keeps points, not meshes (pyrender and open3d's raycasting need triangles), and
because a few hundred cells per pose is all the comparison needs.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numba
import numpy as np
from scipy.optimize import linear_sum_assignment
from scipy.spatial import cKDTree

from openreloc_bench.config import check_ranges

Compare = Callable[[list[np.ndarray]], list[float]]
"""Render-and-compare: how well each camera-to-world pose explains the query's masks (higher is better)."""


@dataclass
class ConsistencyConfig:
    """Choice among refined hypotheses by render-and-compare (see the module docstring)."""

    enabled: bool = True
    """Beyond the paper: only the refined poses that best explain all query masks compete on ICP loss
    (False = the lowest 2D ICP loss of all, as the paper has it for its single hypothesis)."""
    stride: int = 8
    """Pixels per cell of the label grid (8: an 80 x 60 grid at 640 x 480). A finer grid costs four times
    the cells per halving and, with ``splat``, ranks the hypotheses no better."""
    points_per_landmark: int = 400
    """At most this many points of each landmark are drawn (a seeded subsample). More points leave fewer
    holes when drawn as single cells; with ``splat`` the holes are filled and more points add only cost."""
    candidates: int = 5
    """A landmark among an object's visual top-k counts fully; any other is weighted by ``off_candidate_weight``."""
    off_candidate_weight: float = 0.2
    """Weight of a mask-landmark overlap when the landmark does not look like the object."""
    min_depth: float = 0.1
    """Points nearer than this (metres) are not drawn."""
    splat: float = 1.0
    """Each drawn point covers a square of half-width ``splat`` x its landmark's point spacing (the median
    distance to the nearest other drawn point of the landmark), projected at its depth. 0 = one cell per
    point, which leaves most of the grid undrawn even at the true pose (see the module docstring)."""
    max_splat_cells: int = 12
    """A point's square spans at most about this many cells per side (a point at the lens would cover the
    image)."""
    tie_share: float = 0.1
    """Hypotheses scoring at least (1 - tie_share) of the best score tie; the lowest ICP loss among them
    wins. The grid cannot rank poses a few decimetres apart (it may prefer a pose a metre off to the one
    the loss picks a decimetre from the truth); the loss can. 0 = the best-explained pose alone."""

    def __post_init__(self) -> None:
        check_ranges(
            self,
            positive=("min_depth",),
            at_least_one=("stride", "points_per_landmark", "candidates", "max_splat_cells"),
            non_negative=("splat",),
            share=("off_candidate_weight", "tie_share"),
        )


class LabelRenderer:
    """Draws the map's landmarks (rows of the landmark arrays) into a coarse label grid at any pose."""

    def __init__(self, points: list[np.ndarray], width: int, height: int, cfg: ConsistencyConfig, seed: int = 0):
        rng = np.random.default_rng(seed)
        keep = [
            p if len(p) <= cfg.points_per_landmark else p[rng.choice(len(p), cfg.points_per_landmark, replace=False)]
            for p in points
        ]
        self.points = (
            np.concatenate([np.asarray(p, np.float64).reshape(-1, 3) for p in keep]) if keep else np.zeros((0, 3))
        )
        self.rows = np.concatenate([np.full(len(p), r) for r, p in enumerate(keep)]) if keep else np.zeros(0, int)
        self.radius = (
            np.concatenate([np.full(len(p), cfg.splat * _spacing(p)) for p in keep]) if keep else np.zeros(0)
        )  # metres: half-width of each point's square
        self.cfg = cfg
        self.landmarks = len(points)
        s = cfg.stride
        self.grid = (height // s, width // s)

    def render(self, T_wc: np.ndarray, K: np.ndarray) -> np.ndarray:
        """(H/stride, W/stride) int grid: the nearest drawn landmark's row per cell, -1 where none is."""
        T_wc = np.asarray(T_wc, np.float64)
        K = np.asarray(K, np.float64)
        grid = np.full(self.grid, -1, np.int64)
        _splat(
            grid,
            self.points,
            self.rows,
            self.radius,
            np.ascontiguousarray(T_wc[:3, :3]),
            np.ascontiguousarray(T_wc[:3, 3]),
            K[0, 0],
            K[1, 1],
            K[0, 2],
            K[1, 2],
            self.cfg.stride,
            self.cfg.min_depth,
            0.5 * self.cfg.stride * self.cfg.max_splat_cells,
        )
        return grid

    def compare(self, masks: list[np.ndarray], appearance: np.ndarray | None, K: np.ndarray) -> Compare:
        """The render-and-compare score of camera-to-world poses against all query ``masks``, the query's
        label grid and pair weights computed once; without ``appearance`` (the oracle diagnostic) every
        mask-landmark pair weighs 1."""
        labels = query_labels(masks, self.cfg.stride)
        weights = (
            np.ones((len(masks), self.landmarks)) if appearance is None else candidate_weights(appearance, self.cfg)
        )
        return lambda poses: [consistency(self.render(T, K), labels, weights) for T in poses]


@numba.njit(cache=True, nogil=True)
def _splat(
    grid: np.ndarray,
    points: np.ndarray,
    rows: np.ndarray,
    radius: np.ndarray,
    R: np.ndarray,
    c: np.ndarray,
    fx: float,
    fy: float,
    cx: float,
    cy: float,
    stride: int,
    min_depth: float,
    max_half: float,
) -> None:
    """Draw every point in front of the camera (R, c: camera-to-world rotation and centre) as a square of
    cells of half-width ``radius`` (metres) at its depth, at most ``max_half`` pixels, with its landmark
    row: a z-buffer where the nearest point wins each cell (the later one among equally near). A loop,
    because a point covers a few cells and a vectorised form spent its time on temporaries of every point."""
    h, w = grid.shape
    depth = np.full((h, w), np.inf)
    for i in range(len(points)):
        d0, d1, d2 = points[i, 0] - c[0], points[i, 1] - c[1], points[i, 2] - c[2]
        z = d0 * R[0, 2] + d1 * R[1, 2] + d2 * R[2, 2]  # R^T (p - c)
        if not z > min_depth:
            continue
        x = d0 * R[0, 0] + d1 * R[1, 0] + d2 * R[2, 0]
        y = d0 * R[0, 1] + d1 * R[1, 1] + d2 * R[2, 1]
        u, v = fx * x / z + cx, fy * y / z + cy
        r = min(radius[i] * fx / z, max_half)  # pixels
        u0, u1 = np.floor((u - r) / stride), np.floor((u + r) / stride)
        v0, v1 = np.floor((v - r) / stride), np.floor((v + r) / stride)
        if u1 < 0 or u0 >= w or v1 < 0 or v0 >= h:
            continue
        for cv in range(max(int(v0), 0), min(int(v1), h - 1) + 1):
            for cu in range(max(int(u0), 0), min(int(u1), w - 1) + 1):
                if z <= depth[cv, cu]:
                    depth[cv, cu] = z
                    grid[cv, cu] = rows[i]


def _spacing(points: np.ndarray) -> float:
    """Median distance from each point to its nearest neighbour (0 for fewer than two points)."""
    if len(points) < 2:
        return 0.0
    return float(np.median(cKDTree(points).query(points, k=2)[0][:, 1]))


def query_labels(masks: list[np.ndarray], stride: int) -> np.ndarray:
    """The query segmentation sampled at cell centres: (H/stride, W/stride) mask index, -1 where none."""
    h, w = masks[0].shape
    grid = np.full((h // stride, w // stride), -1, np.int64)
    c = stride // 2
    for k, m in enumerate(masks):
        grid[np.asarray(m, bool)[c::stride, c::stride][: grid.shape[0], : grid.shape[1]]] = k
    return grid


def candidate_weights(similarity: np.ndarray, cfg: ConsistencyConfig) -> np.ndarray:
    """(Q, N) weight of each mask-landmark pair from the (Q, N) visual similarities: 1 within each
    object's top ``candidates``, ``off_candidate_weight`` elsewhere."""
    rank = np.argsort(np.argsort(-similarity, axis=1, kind="stable"), axis=1, kind="stable")
    return np.where(rank < cfg.candidates, 1.0, cfg.off_candidate_weight)


def consistency(drawn: np.ndarray, labels: np.ndarray, weights: np.ndarray) -> float:
    """Sum over the optimal one-to-one assignment of query masks to drawn landmarks of weight x IoU
    (``drawn``, ``labels``: label grids; ``weights``: (Q, N))."""
    nq, nl = weights.shape
    both = (labels >= 0) & (drawn >= 0)
    joint = np.bincount(labels[both] * nl + drawn[both], minlength=nq * nl).reshape(nq, nl)
    area_q = np.bincount(labels[labels >= 0], minlength=nq)
    area_l = np.bincount(drawn[drawn >= 0], minlength=nl)
    score = weights * joint / np.maximum(area_q[:, None] + area_l[None, :] - joint, 1)
    rows, cols = linear_sum_assignment(score, maximize=True)
    return float(score[rows, cols].sum())
