"""ORB features, and the versioned, checksummed file that stores every mapping frame's local features.

What the structure-based baselines share: keypoints and descriptors of every mapping frame (OpenCV
SIFT from :mod:`openreloc_bench.vision.local_features`, or ORB here), each lifted to a world point
through the frame's depth and pose, kept in one
:class:`FeatureMap` with the method's own arrays (retrieval vocabulary, co-visibility...) beside
them. On disk (``map_dir``), in the project's map layout::

    arrays.npz      keypoints, descriptors, world points, per-frame offsets, poses, method arrays
    meta.json       format name + version, image size, the method's config and stats
    manifest.json   written last: format name + version and the sha256 and size of every file

written and read by :mod:`openreloc_bench.data.mapfile`: a truncated or edited file fails its
checksum, a map of another method or format version is refused, each with a one-line
:class:`~openreloc_bench.errors.DataError` naming the file.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from openreloc_bench.data import mapfile
from openreloc_bench.data.types import SceneSequence
from openreloc_bench.errors import DataError
from openreloc_bench.methods import MapPoints
from openreloc_bench.vision.local_features import Keypoints, from_cv, grey, lift

# --------------------------------------------------------------------------------------------
# Extraction
# --------------------------------------------------------------------------------------------


@dataclass
class OrbConfig:
    """ORB as ORB-SLAM2's extractor runs it: a scale pyramid, FAST with a low-threshold fallback per
    cell, keypoints spread by a quadtree, oriented BRIEF."""

    max_keypoints: int = 1000
    """Keypoints per image, shared among the levels as a geometric series."""
    scale_factor: float = 1.2
    """Scale between pyramid levels."""
    levels: int = 8
    """Pyramid levels."""
    fast_threshold: int = 20
    """FAST threshold tried first in every cell."""
    fast_threshold_min: int = 7
    """FAST threshold used in cells where the first finds no corner (dark or flat regions)."""
    cell_px: int = 30
    """Side of the cells in which the fallback threshold is decided (pixels of each level)."""

    def __post_init__(self) -> None:
        if self.max_keypoints < 1 or self.levels < 1 or self.cell_px < 1:
            raise ValueError("max_keypoints, levels and cell_px must be >= 1")
        if self.scale_factor <= 1.0:
            raise ValueError(f"scale_factor must be > 1, got {self.scale_factor}")
        if not 0 < self.fast_threshold_min <= self.fast_threshold:
            raise ValueError("need 0 < fast_threshold_min <= fast_threshold")


def extract_orb(rgb: np.ndarray, cfg: OrbConfig) -> Keypoints:
    """ORB keypoints distributed as ORB-SLAM2's ``ORBextractor`` distributes them.

    OpenCV's ORB finds every FAST corner at the low threshold on each level (with ``FAST_SCORE`` the
    response is the FAST score) and computes orientation and descriptor on the 7x7, sigma 2 blurred
    level, as ORB-SLAM2 does. What ORB-SLAM2 adds, and OpenCV lacks, is done here: per cell, the
    corners passing the high threshold if there are any, else the low-threshold ones; then per level
    a quadtree split down to the level's share of ``max_keypoints``, keeping the best corner per node.
    """
    img = grey(rgb)
    s = cfg.scale_factor
    share = (1 - 1 / s) / (1 - (1 / s) ** cfg.levels) * (1 / s) ** np.arange(cfg.levels)
    quota = np.round(cfg.max_keypoints * share).astype(int)
    quota[-1] = max(cfg.max_keypoints - int(quota[:-1].sum()), 0)
    orb = cv2.ORB_create(
        nfeatures=50 * cfg.max_keypoints,  # keep every low-threshold corner; the quadtree selects
        scaleFactor=s,
        nlevels=cfg.levels,
        edgeThreshold=19,
        patchSize=31,
        fastThreshold=cfg.fast_threshold_min,
        scoreType=cv2.ORB_FAST_SCORE,
    )
    kps, desc = orb.detectAndCompute(img, None)
    feats = from_cv(kps, desc, 32, oriented=True)
    if not len(feats):
        return feats
    response = np.array([k.response for k in kps], np.float32)
    level_xy = feats.xy / (s ** feats.octaves.astype(np.float64))[:, None]
    cell = np.floor(level_xy / cfg.cell_px).astype(np.int64)
    key = (feats.octaves.astype(np.int64) * 100_000 + cell[:, 1]) * 100_000 + cell[:, 0]
    strong = response >= cfg.fast_threshold
    _, inverse = np.unique(key, return_inverse=True)
    cell_has_strong = np.bincount(inverse, weights=strong) > 0
    usable = strong | ~cell_has_strong[inverse]
    keep = [
        idx[_quadtree(level_xy[idx], response[idx], int(quota[lvl]))]
        for lvl in range(cfg.levels)
        if len(idx := np.flatnonzero(usable & (feats.octaves == lvl)))
    ]
    return feats.take(np.sort(np.concatenate(keep))) if keep else feats.take(np.zeros(0, int))


def _quadtree(xy: np.ndarray, response: np.ndarray, n: int) -> np.ndarray:
    """ORB-SLAM2's ``DistributeOctTree``: split nodes holding several points into quadrants (all of
    them per round; by decreasing size in the last round) until there are ``n`` nodes, then keep the
    strongest point of each. Indices into ``xy``. Written out because neither OpenCV nor scipy offers
    this response-aware spatial selection."""
    nodes = [(xy.min(axis=0), xy.max(axis=0) + 1e-3, np.arange(len(xy)))]
    while len(nodes) < n:
        big = sorted((k for k, nd in enumerate(nodes) if len(nd[2]) > 1), key=lambda k: -len(nodes[k][2]))
        if not big:
            break
        last_round = len(nodes) + 3 * len(big) > n
        unsplit = set(big)
        out = [nd for k, nd in enumerate(nodes) if k not in unsplit]
        for j, k in enumerate(big):
            if last_round and len(out) + len(big) - j >= n:
                out += [nodes[kk] for kk in big[j:]]
                break
            lo, hi, idx = nodes[k]
            mid = (lo + hi) / 2
            right, below = xy[idx, 0] >= mid[0], xy[idx, 1] >= mid[1]
            for qx in (False, True):
                for qy in (False, True):
                    sub = idx[(right == qx) & (below == qy)]
                    if len(sub):
                        out.append((np.where([qx, qy], mid, lo), np.where([qx, qy], hi, mid), sub))
        grew, nodes = len(out) > len(nodes), out
        if last_round or not grew:  # not grew: only coincident points were left to split
            break
    return np.array([nd[2][np.argmax(response[nd[2]])] for nd in nodes], dtype=int)


# --------------------------------------------------------------------------------------------
# The map: every mapping frame's features with world points, and the method's own arrays
# --------------------------------------------------------------------------------------------


@dataclass
class FeatureMap:
    """Mapping frames' keypoints with world points, plus what the method adds; see the module doc."""

    format: str
    """Map format name, one per method (e.g. ``sift-pnp-map``): a map is read only by its method."""
    version: int
    """Format version of that method; a map of another version is refused."""
    K: np.ndarray
    """(3, 3) intrinsics of the mapping camera."""
    width: int
    height: int
    poses: np.ndarray
    """(F, 4, 4) camera-to-world poses of the mapping frames."""
    offsets: np.ndarray
    """(F + 1,) int64: frame ``f``'s features are rows ``offsets[f]:offsets[f + 1]``."""
    features: Keypoints
    """Every kept keypoint of every frame, concatenated (only those with a valid world point)."""
    points: np.ndarray
    """(N, 3) float32 world point of each keypoint."""
    arrays: dict[str, np.ndarray] = field(default_factory=dict)
    """The method's own arrays (retrieval vocabulary, co-visibility...)."""
    meta: dict[str, Any] = field(default_factory=dict)
    """The method's config and stats (JSON)."""

    @property
    def n_frames(self) -> int:
        return len(self.poses)

    def frame_of(self) -> np.ndarray:
        """(N,) index of the frame each keypoint belongs to."""
        return np.repeat(np.arange(self.n_frames), np.diff(self.offsets))

    def rows(self, frames: np.ndarray | list[int]) -> np.ndarray:
        """Feature rows of the given frames, in that order."""
        frames = np.asarray(frames, dtype=int)
        if not len(frames):
            return np.zeros(0, dtype=np.int64)
        return np.concatenate([np.arange(self.offsets[f], self.offsets[f + 1]) for f in frames])

    def drawn(self) -> MapPoints:
        """The keypoints' world points, grouped by the mapping frame that saw them, and those frames."""
        n = np.diff(self.offsets)
        return MapPoints(
            points=self.points,
            group=self.frame_of(),
            labels={f: f"seen from mapping frame {f} ({n[f]} points)" for f in range(self.n_frames)},
            K=self.K,
            size=(self.width, self.height),
            cameras=self.poses,
            camera_labels=tuple(f"mapping frame {f}: {n[f]} points" for f in range(self.n_frames)),
            names=("points by mapping frame", "", "mapping frames"),
            summary=f"{len(self.points)} points from {self.n_frames} mapping frames",
        )

    def save(self, map_dir: Path | str) -> None:
        """Write ``arrays.npz`` and ``meta.json``, then ``manifest.json`` (checksums) last."""
        arrays = {
            "K": np.asarray(self.K, np.float64),
            "poses": np.asarray(self.poses, np.float64),
            "offsets": np.asarray(self.offsets, np.int64),
            "xy": self.features.xy,
            "descriptors": self.features.descriptors,
            "points": np.asarray(self.points, np.float32),
        }
        if self.features.octaves is not None:
            arrays.update(octaves=self.features.octaves, angles=self.features.angles)
        clash = set(arrays) & set(self.arrays)
        if clash:
            raise ValueError(f"method arrays may not reuse the names {sorted(clash)}")
        meta = {**self.meta, "width": int(self.width), "height": int(self.height)}
        mapfile.write_arrays(map_dir, self.format, self.version, {**arrays, **self.arrays}, meta)

    @classmethod
    def load(cls, map_dir: Path | str, format: str, version: int) -> FeatureMap:
        """Read a map written by :meth:`save`; a :class:`DataError` naming the file on any problem."""
        map_dir = Path(map_dir)
        arrays, meta = mapfile.read_arrays(map_dir, format, version)
        try:
            a = dict(arrays)
            features = Keypoints(a.pop("xy"), a.pop("descriptors"), a.pop("octaves", None), a.pop("angles", None))
            fmap = cls(
                format,
                version,
                a.pop("K"),
                int(meta["width"]),
                int(meta["height"]),
                a.pop("poses"),
                a.pop("offsets"),
                features,
                a.pop("points"),
                a,
                {k: v for k, v in meta.items() if k not in ("format", "version", "width", "height")},
            )
            n = len(fmap.points)
            consistent = (
                fmap.K.shape == (3, 3)
                and fmap.poses.shape[1:] == (4, 4)
                and len(fmap.offsets) == fmap.n_frames + 1
                and fmap.offsets[0] == 0
                and fmap.offsets[-1] == n
                and np.all(np.diff(fmap.offsets) >= 0)
                and len(features.xy) == len(features.descriptors) == n
            )
        except (KeyError, TypeError, ValueError, IndexError) as e:
            raise DataError(Path(map_dir) / mapfile.ARRAYS, f"malformed map arrays ({type(e).__name__}: {e})") from None
        if not consistent:
            raise DataError(Path(map_dir) / mapfile.ARRAYS, "malformed map arrays (inconsistent shapes)")
        return fmap


def build_feature_map(
    mapping: SceneSequence,
    extract: Callable[[np.ndarray], Keypoints],
    max_depth_step: float,
    format: str,
    version: int,
    desc: str = "features",
) -> FeatureMap:
    """Extract features on every mapping frame and keep those with a valid world point (:func:`lift`)."""
    from openreloc_bench.bars import tqdm

    if not mapping.has_depth:
        raise DataError(mapping.split, "the mapping frames need depth (world points of the keypoints come from it)")
    kept, points, counts = [], [], []
    for frame in tqdm(mapping, total=len(mapping), desc=desc, leave=False):
        feats = extract(frame.color)
        pts, valid = lift(feats.xy, frame.depth, frame.K, frame.T_wc, max_depth_step)
        kept.append(feats.take(valid))
        points.append(pts[valid])
        counts.append(int(valid.sum()))
    features = Keypoints(
        np.concatenate([k.xy for k in kept]),
        np.concatenate([k.descriptors for k in kept]),
        np.concatenate([k.octaves for k in kept]) if kept and kept[0].octaves is not None else None,
        np.concatenate([k.angles for k in kept]) if kept and kept[0].angles is not None else None,
    )
    return FeatureMap(
        format,
        version,
        np.asarray(mapping.K, np.float64),
        mapping.width,
        mapping.height,
        mapping.poses,
        np.concatenate([[0], np.cumsum(counts)]).astype(np.int64),
        features,
        np.concatenate(points),
    )
