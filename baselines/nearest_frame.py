"""``nearest-frame``: the pose of the mapping frame whose thumbnail is closest to the query's.

The simplest honest method and the floor of every leaderboard: global-image retrieval without
geometry, on 32x32 grey thumbnails. :mod:`baselines.image_retrieval` is the retrieval baseline proper.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from openreloc_bench import config
from openreloc_bench.bars import tqdm
from openreloc_bench.data import mapfile
from openreloc_bench.data.types import SceneSequence
from openreloc_bench.errors import DataError
from openreloc_bench.methods import Failure, PoseEstimate, QueryFrame


@dataclass
class NearestFrameConfig:
    """Config of :class:`NearestFrame`."""

    thumb_size: int = 32
    """Side of the square grey thumbnail each mapping frame is reduced to (pixels, 4-256)."""

    def __post_init__(self) -> None:
        if not 4 <= self.thumb_size <= 256:
            raise ValueError(f"'thumb_size' must be in [4, 256], got {self.thumb_size}")


class NearestFrame:
    """Returns the pose of the mapping frame whose thumbnail is closest to the query's.

    A floor for every leaderboard: what pure global-image retrieval without geometry achieves.
    The thumbnail is zero-mean, unit-norm grey so global brightness changes cost little.
    """

    name = "nearest-frame"
    reference = "the floor: the pose of the most similar mapping thumbnail (no paper)"
    uses_masks = False
    """Never reads a mask: its maps and results serve both tracks."""
    map_format = ("nearest-frame-map", 1)

    def __init__(self, **overrides: Any):
        self.config = config.from_dict(NearestFrameConfig, overrides, "nearest-frame")
        self._thumbs: np.ndarray | None = None
        self._poses: np.ndarray | None = None

    def _thumb(self, rgb: np.ndarray) -> np.ndarray:
        s = self.config.thumb_size
        grey = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)
        t = cv2.resize(grey, (s, s), interpolation=cv2.INTER_AREA).astype(np.float32).ravel()
        t -= t.mean()
        return t / max(float(np.linalg.norm(t)), 1e-6)

    def build_map(self, mapping: SceneSequence, map_dir: Path) -> None:
        thumbs = np.stack([self._thumb(f.color) for f in tqdm(mapping, desc="nearest-frame map", leave=False)])
        arrays = {"thumbs": thumbs.astype(np.float16), "poses": mapping.poses}
        payload = {"thumbs.npz": mapfile.npz_bytes(arrays), "config.json": mapfile.json_bytes(asdict(self.config))}
        mapfile.write_file_set(map_dir, *self.map_format, payload)

    def load_map(self, map_dir: Path) -> None:
        path = Path(map_dir) / "thumbs.npz"
        blobs = mapfile.read_file_set(map_dir, *self.map_format, {"thumbs.npz", "config.json"})
        built = mapfile.load_json(blobs["config.json"], Path(map_dir) / "config.json")
        if built != asdict(self.config):
            raise DataError(
                Path(map_dir) / "config.json", f"map built with {built}, this method has {asdict(self.config)}"
            )
        a = mapfile.load_npz(blobs["thumbs.npz"], path)
        thumbs, poses = a.get("thumbs"), a.get("poses")
        s = self.config.thumb_size
        if thumbs is None or poses is None or thumbs.shape[1:] != (s * s,) or poses.shape != (len(thumbs), 4, 4):
            raise DataError(path, "malformed map arrays (expected thumbs (N, thumb_size^2) and poses (N, 4, 4))")
        self._thumbs, self._poses = thumbs.astype(np.float32), poses

    def localize(self, query: QueryFrame) -> PoseEstimate | Failure:
        if self._thumbs is None or self._poses is None:
            raise RuntimeError("load_map() must be called before localize()")
        scores = self._thumbs @ self._thumb(query.color)
        best = int(np.argmax(scores))
        return PoseEstimate(self._poses[best].copy(), {"mapping_index": best, "score": float(scores[best])})
