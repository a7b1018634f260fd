"""Reader for Stanford's 12-Scenes (Valentin et al., 3DV 2016), recorded with a Structure sensor on an iPad.

::

    <scene>/info.txt                        the recording's header (SensReader's ``key = value`` lines):
                                            m_calibrationColorIntrinsic, m_depthShift, ...
    <scene>/split.txt                       first line ``sequence0 [frames=N] ...``: frames 0..N-1 are
                                            the test frames, the rest the training frames
    <scene>/data/frame-XXXXXX.color.jpg     1296x968 colour
    <scene>/data/frame-XXXXXX.depth.png     640x480 uint16 depth (m_depthShift units per metre)
    <scene>/data/frame-XXXXXX.pose.txt      4x4 camera-to-world; non-finite where tracking was lost

Depth is taken as registered to colour, like ScanNet's from the same kind of capture (ACE's 12-Scenes
set-up back-projects it with the colour focal length too): frames are served at the depth size, colour
resized to it and its intrinsics rescaled.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from openreloc_bench.data import io
from openreloc_bench.data.scannet import at_depth_size
from openreloc_bench.data.sevenscenes import read_frames
from openreloc_bench.data.types import SceneSequence, check_intrinsics
from openreloc_bench.errors import DataError

FRAMES = "data"
"""The folder holding the frames."""


def read_info(path: Path) -> dict[str, str]:
    """``info.txt``'s ``key = value`` lines."""
    info = {}
    for lineno, raw in enumerate(io.read_text(path).splitlines(), 1):
        key, sep, value = raw.partition("=")
        if raw.strip() and not sep:
            raise DataError(path, f"line {lineno}: expected 'key = value'")
        info[key.strip()] = value.strip()
    return info


def read_12scenes(root: Path | str, split: str = "12scenes") -> SceneSequence:
    """All frames of a 12-Scenes scene with a valid pose, at the depth resolution; ids are the frame numbers."""
    root = Path(root)
    info_path = root / "info.txt"
    info = read_info(info_path)
    try:
        K_color = np.array(info["m_calibrationColorIntrinsic"].split(), dtype=np.float64).reshape(4, 4)
        depth_scale = float(info.get("m_depthShift", io.DEPTH_SCALE_MM))
    except KeyError:
        raise DataError(info_path, "no m_calibrationColorIntrinsic line") from None
    except ValueError:
        raise DataError(info_path, "m_calibrationColorIntrinsic needs 16 numbers, m_depthShift one") from None
    if not depth_scale > 0:
        raise DataError(info_path, f"m_depthShift must be positive, got {depth_scale}")
    records, skipped = read_frames(root / FRAMES, "color.jpg", FRAMES)
    if not records:
        raise DataError(root / FRAMES, "no frame with a valid pose")
    K_color = check_intrinsics(K_color, info_path)
    return at_depth_size(split, K_color, records, skipped, depth_scale, root)


def read_test_frames(root: Path) -> int:
    """How many frames, from frame 0 on, ``split.txt`` gives to the test set."""
    path = root / "split.txt"
    match = re.search(r"\[frames=(\d+)\]", io.read_text(path))
    if match is None:
        raise DataError(path, "expected a first line 'sequence0 [frames=N] ...'")
    return int(match[1])
