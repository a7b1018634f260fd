"""A mapping sequence's frames as reconstruction reads them: the pose (checked rigid), depth, colour and
instance image of frame ``i``."""

from __future__ import annotations

import numpy as np

from openreloc_bench import geometry
from openreloc_bench.data import io
from openreloc_bench.data.types import SceneSequence
from openreloc_bench.errors import DataError


def frame_pose(seq: SceneSequence, i: int) -> np.ndarray:
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
