"""Typed frames and lazily loaded sequences, shared by every reader (own layout, ScanNet, TUM, 7-Scenes,
12-Scenes).

A :class:`SceneSequence` keeps only paths and poses in memory and decodes images on access, so a
1000-frame scene costs kilobytes until a method actually reads it.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Self

import numpy as np

from openreloc_bench import geometry
from openreloc_bench.data import io
from openreloc_bench.errors import DataError
from openreloc_bench.tracks import ORACLE_MASK, PREDICTED, RecordedTrack


@dataclass
class Frame:
    """One posed RGB-D frame (depth and instances optional)."""

    name: str
    """``<split>/<frame id>``, the key used in result files."""
    T_wc: np.ndarray
    """4x4 camera-to-world pose, OpenCV axes."""
    K: np.ndarray
    """3x3 intrinsics."""
    color: np.ndarray
    """RGB uint8 (H, W, 3)."""
    depth: np.ndarray | None = None
    """Metric depth float32 (H, W), 0 = invalid."""
    instance: np.ndarray | None = None
    """Instance ids int32 (H, W), 0 = none."""


@dataclass
class FrameRecord:
    """Where one frame lives on disk; decoded only when the frame is requested."""

    frame_id: str
    color_path: Path
    T_wc: np.ndarray
    depth_path: Path | None = None
    instance_path: Path | None = None


@dataclass
class SceneSequence:
    """An ordered split of posed frames (e.g. a scene's ``mapping`` or ``query`` split): what a method's
    ``build_map`` receives. Iterating or indexing it gives :class:`Frame` objects, decoded on access;
    ``poses``, ``names`` and ``K`` decode no image. Opened for the predicted track, or for a method that
    reads no masks (``load_instances`` off), every ``Frame.instance`` is None."""

    split: str
    K: np.ndarray
    width: int
    height: int
    records: list[FrameRecord]
    depth_scale: float = io.DEPTH_SCALE_MM
    """Depth PNG units per metre (1000 for ScanNet/this project, 5000 for TUM)."""
    skipped: dict[str, str] = field(default_factory=dict)
    """Frames the reader dropped (e.g. invalid ScanNet poses), id -> reason."""
    root: Path | None = None
    """The folder the sequence was read from: a generated scene's (its ``objects.json`` and ``scene.json``
    lie there) or a recording's own; None for a sequence made in memory."""
    opened_for: RecordedTrack | None = None
    """The track :meth:`~openreloc_bench.data.scene.Scene.sequence` opened it for; None: opened without
    one, giving every instance image there is (see :attr:`track`)."""

    def __len__(self) -> int:
        return len(self.records)

    def __iter__(self) -> Iterator[Frame]:
        for i in range(len(self)):
            yield self[i]

    def __getitem__(self, i: int) -> Frame:
        r = self.records[i]
        hw = (self.height, self.width)
        return Frame(
            name=f"{self.split}/{r.frame_id}",
            T_wc=r.T_wc,
            K=self.K,
            color=io.read_rgb(r.color_path, expect_hw=hw),
            depth=self.depth(i),
            instance=io.read_instance(r.instance_path, expect_hw=hw)
            if (r.instance_path and self.load_instances)
            else None,
        )

    def depth(self, i: int) -> np.ndarray | None:
        """Frame ``i``'s metric depth alone (no colour decoded), as ``self[i].depth``; None without one."""
        r = self.records[i]
        return (
            io.read_depth(r.depth_path, self.depth_scale, expect_hw=(self.height, self.width)) if r.depth_path else None
        )

    @property
    def names(self) -> list[str]:
        return [f"{self.split}/{r.frame_id}" for r in self.records]

    @property
    def poses(self) -> np.ndarray:
        """(N, 4, 4) camera-to-world poses, without decoding any image."""
        return np.stack([r.T_wc for r in self.records]) if self.records else np.zeros((0, 4, 4))

    @property
    def has_depth(self) -> bool:
        return bool(self.records) and all(r.depth_path is not None for r in self.records)

    @property
    def track(self) -> RecordedTrack:
        """The track a method is given the sequence for, which its ``build_map`` reads rather than guess it:
        the one it was opened for; opened without one (by hand: plugins, tests), the oracle-mask track when
        every frame gives its instance image, else the predicted track."""
        if self.opened_for is not None:
            return self.opened_for
        return ORACLE_MASK if self.has_instances else PREDICTED

    @property
    def load_instances(self) -> bool:
        """Whether frames give their instance images: opened for the oracle-mask track, or for none."""
        return self.opened_for in (None, ORACLE_MASK)

    @property
    def has_instances(self) -> bool:
        """Whether every frame gives its instance image (not when ``load_instances`` is off: predicted track)."""
        return self.load_instances and bool(self.records) and all(r.instance_path is not None for r in self.records)

    def subset(self, indices: list[int] | range) -> Self:
        """A view on some frames (e.g. the ScanNet stride split), sharing paths, not copies; a reader's
        subclass (one that decodes its frames its own way) stays that subclass."""
        return replace(self, records=[self.records[i] for i in indices], skipped=dict(self.skipped))


def check_intrinsics(K: np.ndarray, path: Path | str) -> np.ndarray:
    """Validate a 3x3 K (finite, positive focal lengths); raise a DataError naming ``path``."""
    K = np.asarray(K, dtype=np.float64)
    if K.shape == (4, 4):
        K = K[:3, :3]
    if K.shape != (3, 3) or not np.all(np.isfinite(K)) or K[0, 0] <= 0 or K[1, 1] <= 0:
        raise DataError(path, "invalid intrinsics (need finite fx, fy > 0)")
    return K


INVALID_POSE = "invalid pose (inf/NaN or not rigid)"
"""Why a reader leaves a recorded frame out (``SceneSequence.skipped``)."""


def read_recorded_pose(path: Path) -> np.ndarray | None:
    """A recorded frame's 4x4 pose, or None where the recording marks it invalid: non-finite numbers
    (``-inf``, ``nan``, or MSVC's ``-1.#INF`` / ``-1.#IND``, which some Windows-made datasets hold) or a
    matrix that is not rigid."""
    if re.search(r"inf|nan|#ind", io.read_text(path), re.IGNORECASE):
        return None
    T = io.read_matrix(path)
    return T if geometry.is_rigid(T, tol=1e-3) else None
