"""Reader for TUM RGB-D sequences (``rgb.txt``, ``depth.txt``, ``groundtruth.txt``).

Colour, depth and ground truth are recorded at different times; frames are formed TUM-style by
associating each colour stamp with the nearest depth and ground-truth stamps within ``max_dt``
seconds (the benchmark's ``associate.py`` default is 0.02 s). Depth PNGs store 5000 units per metre.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from openreloc_bench import geometry
from openreloc_bench.data import io
from openreloc_bench.data.results import read_tum_trajectory
from openreloc_bench.data.types import FrameRecord, SceneSequence, check_intrinsics
from openreloc_bench.errors import DataError

TUM_DEPTH_SCALE = 5000.0
# The ROS default calibration the TUM benchmark recommends when a sequence's own is not given.
TUM_DEFAULT_K = geometry.intrinsics(525.0, 525.0, 319.5, 239.5)


def _read_list(path: Path) -> tuple[np.ndarray, list[str]]:
    """Timestamps and files of ``rgb.txt`` or ``depth.txt``; a timestamp listed twice is refused (it would
    shift every later frame's place in a stride split)."""
    stamps, files, seen = [], [], {}
    for lineno, parts in io.data_lines(path):
        try:
            stamps.append(float(parts[0]))
        except (ValueError, IndexError):
            raise DataError(path, f"line {lineno}: expected 'timestamp filename'") from None
        if len(parts) != 2:
            raise DataError(path, f"line {lineno}: expected 'timestamp filename'")
        if (first := seen.setdefault(stamps[-1], lineno)) != lineno:
            raise DataError(path, f"line {lineno}: timestamp {parts[0]} is listed twice (first on line {first})")
        files.append(parts[1])
    return np.array(stamps), files


def _nearest(src: np.ndarray, ref: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For each ``src`` stamp, the index of the nearest ``ref`` stamp and the time gap."""
    order = np.argsort(ref)
    r = ref[order]
    pos = np.searchsorted(r, src)
    lo, hi = np.clip(pos - 1, 0, len(r) - 1), np.clip(pos, 0, len(r) - 1)
    pick = np.where(np.abs(src - r[lo]) <= np.abs(src - r[hi]), lo, hi)
    return order[pick], np.abs(r[pick] - src)


def read_tum(root: Path | str, K: np.ndarray | None = None, max_dt: float = 0.02, split: str = "tum") -> SceneSequence:
    """Associated, posed RGB-D frames of a TUM sequence. Frame ids are the colour timestamps."""
    root = Path(root)
    rgb_t, rgb_f = _read_list(root / "rgb.txt")
    dep_t, dep_f = _read_list(root / "depth.txt")
    gt_t, gt_T = read_tum_trajectory(root / "groundtruth.txt")
    if len(rgb_t) == 0 or len(dep_t) == 0 or len(gt_t) == 0:
        raise DataError(root, "empty rgb.txt, depth.txt or groundtruth.txt")
    di, ddt = _nearest(rgb_t, dep_t)
    gi, gdt = _nearest(rgb_t, gt_t)
    records, skipped = [], {}
    for k, (stamp, f) in enumerate(zip(rgb_t, rgb_f)):
        fid = f"{stamp:.6f}"
        if ddt[k] > max_dt or gdt[k] > max_dt:
            skipped[fid] = "no depth or ground truth within max_dt"
            continue
        color, depth = root / f, root / dep_f[di[k]]
        for p in (color, depth):
            if not p.exists():
                raise DataError(p, "file not found (listed in rgb.txt/depth.txt)")
        records.append(FrameRecord(fid, color, gt_T[gi[k]], depth))
    if not records:
        raise DataError(root, f"no colour frame has depth and ground truth within {max_dt} s")
    h, w = io.read_rgb(records[0].color_path).shape[:2]
    K = check_intrinsics(TUM_DEFAULT_K if K is None else K, root / "calibration")
    return SceneSequence(split, K, w, h, records, depth_scale=TUM_DEPTH_SCALE, skipped=skipped, root=root)
