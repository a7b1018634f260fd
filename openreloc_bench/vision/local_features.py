"""Local features: SIFT keypoints with uint8 descriptors, RootSIFT, and world points from depth.

What the structure-based baselines and OpenReLoc's object-anchored keypoints share: OpenCV's SIFT
(Lowe's detector and descriptor), RootSIFT for matching with Euclidean distance, and the lifting of
keypoints to world points through a frame's metric depth and pose.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from openreloc_bench import geometry


@dataclass
class Keypoints:
    """Local features of one image."""

    xy: np.ndarray
    """(N, 2) float32 pixel coordinates (integers at pixel centres)."""
    descriptors: np.ndarray
    """(N, D) uint8: SIFT histograms (D = 128) or ORB bit strings (D = 32 bytes)."""
    octaves: np.ndarray | None = None
    """(N,) int8 pyramid level of each keypoint (kept only by methods that use it, e.g. ORB's)."""
    angles: np.ndarray | None = None
    """(N,) float32 orientation in degrees [0, 360) (likewise)."""

    def __len__(self) -> int:
        return len(self.xy)

    def take(self, index: np.ndarray) -> Keypoints:
        def pick(a: np.ndarray | None) -> np.ndarray | None:
            return None if a is None else a[index]

        return Keypoints(self.xy[index], self.descriptors[index], pick(self.octaves), pick(self.angles))


@dataclass
class SiftConfig:
    """OpenCV SIFT (Lowe's detector and descriptor)."""

    max_keypoints: int = 4000
    """Keypoints kept per image, strongest first (OpenCV's ``nfeatures``)."""
    contrast_threshold: float = 0.005
    """DoG contrast threshold; far below OpenCV's 0.04 because rendered surfaces are weakly textured."""
    edge_threshold: float = 10.0
    """Rejects edge-like DoG extrema (ratio of principal curvatures), Lowe's value."""

    def __post_init__(self) -> None:
        if self.max_keypoints < 1:
            raise ValueError(f"max_keypoints must be >= 1, got {self.max_keypoints}")
        if self.contrast_threshold <= 0 or self.edge_threshold <= 0:
            raise ValueError("contrast_threshold and edge_threshold must be > 0")


def grey(rgb: np.ndarray) -> np.ndarray:
    return cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY) if rgb.ndim == 3 else rgb


def from_cv(kps: tuple[cv2.KeyPoint, ...], desc: np.ndarray | None, dim: int, oriented: bool) -> Keypoints:
    """OpenCV's keypoints and descriptors (None: none found) as :class:`Keypoints`; ``oriented`` keeps
    octaves and angles."""
    n = len(kps) if desc is not None else 0
    return Keypoints(
        np.array([k.pt for k in kps[:n]], np.float32).reshape(n, 2),
        np.zeros((0, dim), np.uint8) if desc is None else np.ascontiguousarray(desc, dtype=np.uint8),
        np.array([k.octave for k in kps[:n]], np.int8) if oriented else None,
        np.array([k.angle for k in kps[:n]], np.float32) % 360.0 if oriented else None,
    )


def extract_sift(rgb: np.ndarray, cfg: SiftConfig) -> Keypoints:
    """SIFT keypoints with uint8 descriptors (OpenCV's SIFT values are integers in [0, 255])."""
    sift = cv2.SIFT_create(
        nfeatures=cfg.max_keypoints,
        nOctaveLayers=3,
        contrastThreshold=cfg.contrast_threshold,
        edgeThreshold=cfg.edge_threshold,
        sigma=1.6,
        descriptorType=cv2.CV_8U,
    )
    kps, desc = sift.detectAndCompute(grey(rgb), None)
    n = min(len(kps), cfg.max_keypoints)  # OpenCV may keep ties beyond nfeatures
    return from_cv(kps[:n], None if desc is None else desc[:n], 128, oriented=False)


def root_sift(descriptors: np.ndarray) -> np.ndarray:
    """RootSIFT (Arandjelovic & Zisserman 2012): L1-normalise, then square root. The result has unit
    L2 norm, so Euclidean distance on it is the Hellinger kernel on the SIFT histograms."""
    d = descriptors.astype(np.float32)
    d /= np.maximum(d.sum(axis=1, keepdims=True), 1e-6)
    return np.sqrt(d)


def lift(
    xy: np.ndarray, depth: np.ndarray, K: np.ndarray, T_wc: np.ndarray, max_depth_step: float
) -> tuple[np.ndarray, np.ndarray]:
    """World points of keypoints from a metric depth image: ``(points (N, 3) float32, valid (N,))``.

    A keypoint is valid when its pixel and its 8 neighbours have depth and that depth varies by at
    most ``max_depth_step`` times its own: keypoints on depth edges (common for blobs and corners at
    object outlines) would otherwise take the depth of whichever side the pixel falls on.
    """
    h, w = depth.shape
    u = np.clip(np.round(xy[:, 0]).astype(int), 0, w - 1)
    v = np.clip(np.round(xy[:, 1]).astype(int), 0, h - 1)
    offsets = np.array([(dv, du) for dv in (-1, 0, 1) for du in (-1, 0, 1)])
    patch = depth[np.clip(v[:, None] + offsets[:, 0], 0, h - 1), np.clip(u[:, None] + offsets[:, 1], 0, w - 1)]
    d = depth[v, u]
    valid = np.all(np.isfinite(patch) & (patch > 0), axis=1) & (np.ptp(patch, axis=1) <= max_depth_step * d)
    points = geometry.transform_points(T_wc, geometry.unproject(K, xy, d))
    return points.astype(np.float32), valid
