"""Absolute camera pose from 2D-3D matches: pycolmap's LO-RANSAC with non-linear refinement.

COLMAP's estimator (P3P minimal solver, locally optimised RANSAC, then Levenberg-Marquardt on the
inliers with a robust loss) is what hloc localizes with. Pixel coordinates and intrinsics are passed
in the same (OpenCV, pixel-centre) convention, so COLMAP's half-pixel offset cancels.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pycolmap

from openreloc_bench import geometry
from openreloc_bench.config import check_ranges


@dataclass
class AbsolutePoseConfig:
    """LO-RANSAC of :func:`estimate_absolute_pose`."""

    max_error_px: float = 8.0
    """Reprojection error (pixels) under which a match is an inlier."""
    confidence: float = 0.99999
    """RANSAC stops once it is this confident of having drawn an all-inlier sample."""
    max_iterations: int = 10_000
    """Upper bound on RANSAC iterations."""
    seed: int = 0
    """RANSAC random seed (localization is reproducible)."""

    def __post_init__(self) -> None:
        check_ranges(self, positive=("max_error_px",), non_negative=("seed",), at_least_one=("max_iterations",))
        if not 0 < self.confidence < 1:
            raise ValueError(f"'confidence' must be in (0, 1), got {self.confidence!r}")


@dataclass
class AbsolutePose:
    """A pose estimate with its inliers."""

    T_wc: np.ndarray
    """4x4 camera-to-world pose."""
    inliers: np.ndarray
    """(N,) bool: which matches agree with the pose."""

    @property
    def n_inliers(self) -> int:
        return int(self.inliers.sum())


def estimate_absolute_pose(
    points2d: np.ndarray, points3d: np.ndarray, K: np.ndarray, width: int, height: int, cfg: AbsolutePoseConfig
) -> AbsolutePose | None:
    """LO-RANSAC + refinement of a pinhole camera's pose from ``points2d`` (N, 2) pixels matched to
    ``points3d`` (N, 3) world points; None when fewer than 4 matches or no model is found."""
    if len(points2d) < 4:
        return None
    camera = pycolmap.Camera(
        model="PINHOLE", width=int(width), height=int(height), params=[K[0, 0], K[1, 1], K[0, 2], K[1, 2]]
    )
    options = pycolmap.AbsolutePoseEstimationOptions()
    options.ransac.max_error = cfg.max_error_px
    options.ransac.confidence = cfg.confidence
    options.ransac.max_num_trials = cfg.max_iterations
    options.ransac.random_seed = cfg.seed
    result = pycolmap.estimate_and_refine_absolute_pose(
        np.asarray(points2d, np.float64), np.asarray(points3d, np.float64), camera, options
    )
    if result is None:
        return None
    T_cw = np.eye(4)
    T_cw[:3] = result["cam_from_world"].matrix()
    return AbsolutePose(geometry.invert(T_cw), np.asarray(result["inlier_mask"], bool))
