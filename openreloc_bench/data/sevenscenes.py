"""Reader for Microsoft's 7-Scenes (Shotton et al., CVPR 2013), recorded with a Kinect v1.

::

    <scene>/seq-XX/frame-XXXXXX.color.png   640x480 RGB
    <scene>/seq-XX/frame-XXXXXX.depth.png   640x480 uint16 mm; 0 and 65535 = no reading
    <scene>/seq-XX/frame-XXXXXX.pose.txt    4x4 camera-to-world of the depth camera (KinectFusion)
    <scene>/TrainSplit.txt, TestSplit.txt   lines ``sequence1``, ``sequence2``...: the standard split

Colour and depth are not registered: they come from two cameras about 2.5 cm apart with different
focal lengths, and the dataset gives no calibration (only the depth camera's KinectFusion defaults).
Frames are served as the colour camera sees them: each depth map is re-projected into it and each pose
moved onto it, with the calibration DSAC* and ACE use for 7-Scenes (:data:`DEPTH_K`, :data:`COLOR_K`,
:data:`T_COLOR_DEPTH`, ACE's "calibrated" depth and poses). That calibration is nominal, not this
Kinect's own, and the two streams are not synchronised, so colour and depth stay a few pixels apart
(more during fast motion). Taking colour as a camera with the depth camera's f = 585 instead would put
it some 30 px off at the left and right borders and bias every pose estimated from colour.
"""

from __future__ import annotations

import re
from dataclasses import replace
from pathlib import Path

import numpy as np

from openreloc_bench import geometry
from openreloc_bench.data import io
from openreloc_bench.data.types import (
    INVALID_POSE,
    FrameRecord,
    SceneSequence,
    check_intrinsics,
    read_recorded_pose,
)
from openreloc_bench.errors import DataError

CALIBRATION_SIZE = (640, 480)
"""Width and height the intrinsics below are given at; images of another size scale them."""
DEPTH_K = geometry.intrinsics(585.0, 585.0, 320.0, 240.0)
"""The depth camera's intrinsics: the KinectFusion defaults the dataset's page gives."""
COLOR_K = geometry.intrinsics(525.0, 525.0, 320.0, 240.0)
"""The colour camera's: the Kinect's nominal focal length, which DSAC* and ACE use for 7-Scenes."""
T_COLOR_DEPTH = np.array(
    [
        [9.9996518012567637e-01, 2.6765126468950343e-03, -7.9041012313000904e-03, -2.5558943178152542e-02],
        [-2.7409311281316700e-03, 9.9996302803027592e-01, -8.1504520778013286e-03, 1.0109636268061706e-04],
        [7.8819942130445332e-03, 8.1718328771890631e-03, 9.9993554558014031e-01, 2.0318321729487039e-03],
        [0.0, 0.0, 0.0, 1.0],
    ]
)
"""Depth camera to colour camera (``x_colour = T @ x_depth``): the LIRIS Kinect calibration that ACE
(Brachmann et al., CVPR 2023) applies to 7-Scenes' depth and poses."""
FRAME_POSE = re.compile(r"frame-(\d+)\.pose\.txt")


def sequences(root: Path) -> list[str]:
    """The ``seq-XX`` folders of a 7-Scenes scene, in order."""
    return sorted(p.name for p in root.glob("seq-*") if p.is_dir())


def read_split_file(path: Path) -> list[str]:
    """The sequences ``TrainSplit.txt`` or ``TestSplit.txt`` lists (``sequence1`` -> ``seq-01``)."""
    names = []
    for lineno, parts in io.data_lines(path):
        match = re.fullmatch(r"sequence(\d+)", " ".join(parts))
        if match is None:
            raise DataError(path, f"line {lineno}: expected 'sequenceN', got '{' '.join(parts)}'")
        names.append(f"seq-{int(match[1]):02d}")
    if not names:
        raise DataError(path, "lists no sequence")
    return names


def read_frames(folder: Path, color_suffix: str, name: str) -> tuple[list[FrameRecord], dict[str, str]]:
    """The frames of a folder of ``frame-XXXXXX.{color,depth,pose}`` files (7-Scenes' naming, which
    12-Scenes keeps), ids the frame numbers; frames with an invalid pose are left out and returned keyed
    ``<name>/frame-XXXXXX``."""
    records, skipped = [], {}
    for pose_path in sorted(folder.glob("frame-*.pose.txt")):
        match = FRAME_POSE.fullmatch(pose_path.name)
        if match is None:
            raise DataError(pose_path, "expected a name frame-XXXXXX.pose.txt")
        stem = pose_path.name.removesuffix(".pose.txt")
        T = read_recorded_pose(pose_path)
        if T is None:
            skipped[f"{name}/{stem}"] = INVALID_POSE
            continue
        color, depth = folder / f"{stem}.{color_suffix}", folder / f"{stem}.depth.png"
        for path in (color, depth):
            if not path.is_file():
                raise DataError(path, "file not found (pose exists for this frame)")
        records.append(FrameRecord(str(int(match[1])), color, T, depth))
    return records, skipped


def read_7scenes(root: Path | str, sequence: str, K: np.ndarray | None = None) -> SceneSequence:
    """The frames of one sequence with a valid pose, as the colour camera sees them (``K``: its
    intrinsics, default :data:`COLOR_K` at the images' size). The split is named after the sequence."""
    root = Path(root)
    folder = root / sequence
    if not folder.is_dir():
        raise DataError(folder, f"no such sequence; the scene has {', '.join(sequences(root)) or 'none'}")
    records, skipped = read_frames(folder, "color.png", sequence)
    if not records:
        raise DataError(folder, "no frame with a valid pose")
    h, w = io.read_rgb(records[0].color_path).shape[:2]
    K = check_intrinsics(at_size(COLOR_K, (h, w)) if K is None else K, "--intrinsics")
    T_depth_color = geometry.invert(T_COLOR_DEPTH)
    on_colour = [replace(r, T_wc=r.T_wc @ T_depth_color) for r in records]
    return _ColourCameraSequence(sequence, K, w, h, on_colour, skipped=skipped)


def at_size(K: np.ndarray, hw: tuple[int, int]) -> np.ndarray:
    """Intrinsics given at :data:`CALIBRATION_SIZE`, scaled to images of ``hw``."""
    scale = np.diag([hw[1] / CALIBRATION_SIZE[0], hw[0] / CALIBRATION_SIZE[1], 1.0])
    return scale @ K


class _ColourCameraSequence(SceneSequence):
    """7-Scenes frames whose depth is re-projected into the colour camera on read."""

    def depth(self, i: int) -> np.ndarray:
        raw = io.read_depth(self.records[i].depth_path, self.depth_scale)  # type: ignore[arg-type]
        return geometry.reproject_depth(
            raw, at_size(DEPTH_K, raw.shape), self.K, T_COLOR_DEPTH, (self.height, self.width)
        )
