"""``retrieval``: the pose of the best-matching mapping images, no geometry.

Mapping: a whole-image descriptor of every mapping frame (:mod:`baselines.global_descriptors`),
stored with the frames' poses. Query: the ``top_k`` mapping frames by cosine similarity; the answer
is the best one's pose (``top_k: 1``) or an interpolation of the retrieved poses, weighted by inverse
squared descriptor distance (Shepard's weights: a query identical to a mapping frame gets that
frame's pose), as DenseVLAD-style baselines interpolate the poses of their top-ranked images.
``interpolation_radius_m`` optionally keeps only the retrieved frames near the best one. Rotations
are averaged by scipy's quaternion mean.

Masks are ignored (``uses_masks = False``); a pose is always returned, as retrieval has no test of
its own answer.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from baselines.frame_retrieval import Vlad, top_k
from baselines.global_descriptors import GlobalDescriptor, GlobalDescriptorConfig, encoder_fingerprint, single_threaded
from openreloc_bench import config as cfglib
from openreloc_bench.bars import tqdm
from openreloc_bench.data import mapfile
from openreloc_bench.data.types import SceneSequence
from openreloc_bench.errors import DataError
from openreloc_bench.methods import PoseEstimate, QueryFrame

MAP_FORMAT = "retrieval-map"
MAP_VERSION = 1


@dataclass
class ImageRetrievalConfig:
    """Every setting of :class:`ImageRetrieval`; the defaults were chosen on the validation suite."""

    descriptor: GlobalDescriptorConfig = field(default_factory=GlobalDescriptorConfig)
    """Whole-image descriptor of mapping frames and queries."""
    top_k: int = 10
    """Mapping frames retrieved per query and interpolated; 1 returns the best one's pose."""
    interpolation_radius_m: float | None = None
    """If set, only the retrieved frames whose camera lies within this distance (metres) of the best
    one's are interpolated (None: all ``top_k``)."""

    def __post_init__(self) -> None:
        cfglib.check_ranges(self, at_least_one=("top_k",))
        if self.interpolation_radius_m is not None:
            cfglib.check_ranges(self, non_negative=("interpolation_radius_m",))


def interpolate_poses(poses: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """Weighted mean of camera-to-world poses (N, 4, 4): arithmetic for the centres, scipy's
    quaternion mean (the chordal L2 mean) for the rotations."""
    w = np.asarray(weights, np.float64)
    out = np.eye(4)
    out[:3, :3] = Rotation.from_matrix(poses[:, :3, :3]).mean(weights=w).as_matrix()
    out[:3, 3] = (w[:, None] * poses[:, :3, 3]).sum(axis=0) / w.sum()
    return out


class ImageRetrieval:
    """Global-descriptor retrieval with best-frame or interpolated poses (see the module doc)."""

    name = "retrieval"
    reference = "Torii et al., 24/7 Place Recognition by View Synthesis (DenseVLAD), CVPR 2015"
    uses_masks = False
    """Query instance masks (oracle-mask track) are never read."""

    def __init__(self, **overrides: Any):
        self.config: ImageRetrievalConfig = cfglib.from_dict(ImageRetrievalConfig, overrides, "retrieval")
        self._describer: GlobalDescriptor | None = None
        self._database = np.zeros((0, 0), np.float32)
        self._poses = np.zeros((0, 4, 4))

    def map_config(self) -> dict[str, Any]:
        """What the map depends on; ``top_k`` and the interpolation share maps."""
        return {"descriptor": dataclasses.asdict(self.config.descriptor)}

    def build_map(self, mapping: SceneSequence, map_dir: Path) -> None:
        describer = GlobalDescriptor(self.config.descriptor)
        frames = tqdm(mapping, desc="retrieval map", leave=False)
        if describer.needs_fit:
            locals_ = [describer.local(f.color) for f in frames]
            describer.fit(locals_)
            database = np.stack([describer.aggregate(d) for d in locals_])
        else:
            database = np.stack([describer.describe(f.color) for f in frames])
        arrays = {**describer.to_arrays(), "descriptors": database.astype(np.float16), "poses": mapping.poses}
        meta = {"config": self.map_config(), "encoder": encoder_fingerprint(), "frames": len(mapping)}
        mapfile.write_arrays(map_dir, MAP_FORMAT, MAP_VERSION, arrays, meta)

    def load_map(self, map_dir: Path) -> None:
        arrays, meta = mapfile.read_arrays(map_dir, MAP_FORMAT, MAP_VERSION)
        meta_path = Path(map_dir) / mapfile.META
        if meta.get("config") != self.map_config():
            raise DataError(meta_path, f"map built with {meta.get('config')}, this method has {self.map_config()}")
        if meta.get("encoder") != encoder_fingerprint():
            raise DataError(meta_path, "map built with other image encoder weights than this installation's")
        database, poses = arrays.get("descriptors"), arrays.get("poses")
        cfg = self.config.descriptor
        vlad = Vlad.from_arrays(arrays) if cfg.kind.endswith("vlad") and "vlad_centres" in arrays else None
        if (
            database is None
            or poses is None
            or database.ndim != 2
            or poses.shape != (len(database), 4, 4)
            or (cfg.kind.endswith("vlad") and (vlad is None or vlad.centres.size != database.shape[1]))
        ):
            raise DataError(
                Path(map_dir) / mapfile.ARRAYS,
                "malformed map arrays (descriptors (N, D), poses (N, 4, 4), VLAD centres of D values)",
            )
        self._describer = GlobalDescriptor(cfg, vlad)
        self._database, self._poses = database.astype(np.float32), poses

    def localize(self, query: QueryFrame) -> PoseEstimate:
        if self._describer is None:
            raise RuntimeError("load_map() must be called before localize()")
        c = self.config
        with single_threaded():
            q = self._describer.describe(query.color)
            scores = self._database @ q
            best = top_k(self._database, q, c.top_k)
        used = best
        if c.interpolation_radius_m is not None:
            near = np.linalg.norm(self._poses[best, :3, 3] - self._poses[best[0], :3, 3], axis=1)
            used = best[near <= c.interpolation_radius_m]
        diag = {"retrieved": best.tolist(), "scores": scores[best].round(4).tolist(), "interpolated": used.tolist()}
        if len(used) == 1:
            return PoseEstimate(self._poses[used[0]].copy(), diag)
        distance2 = np.maximum(2.0 - 2.0 * scores[used], 0.0)  # squared distance of unit vectors
        return PoseEstimate(interpolate_poses(self._poses[used], 1.0 / np.maximum(distance2, 1e-12)), diag)
