"""Reader for real ScanNet exports (the output of ScanNet's ``SensReader``).

::

    <scene>/color/<i>.jpg          1296x968 colour (or .png)
    <scene>/depth/<i>.png          640x480 uint16 mm
    <scene>/pose/<i>.txt           4x4 camera-to-world (may be -inf for frames without tracking)
    <scene>/intrinsic/intrinsic_color.txt, intrinsic_depth.txt
    <scene>/instance-filt/<i>.png  optional instance ids (from ScanNet's 2D export)

Frame ids are unpadded integers. Colour and depth differ in size in ScanNet, so frames are served
at one resolution: images are resized on read to the depth size and the colour intrinsics are
rescaled accordingly (what ScanNet-based relocalization pipelines do). Frames with invalid poses
are dropped and recorded in ``SceneSequence.skipped``.

The paper's protocol splits one sequence into mapping frames {0, 20, 40, ...} and query frames
{10, 30, 50, ...}: see :func:`stride_split`.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from openreloc_bench.data import io
from openreloc_bench.data.types import (
    INVALID_POSE,
    Frame,
    FrameRecord,
    SceneSequence,
    check_intrinsics,
    read_recorded_pose,
)
from openreloc_bench.errors import DataError

COLOR_EXTS = (".jpg", ".png", ".jpeg")


def read_scannet(root: Path | str, split: str = "scannet") -> SceneSequence:
    """All frames of a ScanNet export with a valid pose, at the depth resolution."""
    root = Path(root)
    for sub in ("color", "depth", "pose"):
        if not (root / sub).is_dir():
            raise DataError(root / sub, "directory not found (is this a ScanNet export?)")
    Kc_path = root / "intrinsic" / "intrinsic_color.txt"
    Kc = check_intrinsics(io.read_matrix(Kc_path), Kc_path)
    inst_dir = root / "instance-filt"
    records, skipped = [], {}
    for pose_path in sorted((root / "pose").glob("*.txt"), key=lambda p: int(p.stem) if p.stem.isdigit() else -1):
        fid = pose_path.stem
        if not fid.isdigit():
            raise DataError(pose_path, "frame ids must be integers")
        T = read_recorded_pose(pose_path)
        if T is None:
            skipped[fid] = INVALID_POSE
            continue
        color = next(
            (root / "color" / f"{fid}{e}" for e in COLOR_EXTS if (root / "color" / f"{fid}{e}").exists()), None
        )
        if color is None:
            raise DataError(root / "color" / f"{fid}.jpg", "file not found (pose exists for this frame)")
        depth = root / "depth" / f"{fid}.png"
        if not depth.exists():
            raise DataError(depth, "file not found (pose exists for this frame)")
        inst = inst_dir / f"{fid}.png"
        records.append(FrameRecord(fid, color, T, depth, inst if inst.exists() else None))
    if not records:
        raise DataError(root / "pose", "no frames with a valid pose")
    return at_depth_size(split, Kc, records, skipped, root=root)


def at_depth_size(
    split: str,
    K_color: np.ndarray,
    records: list[FrameRecord],
    skipped: dict[str, str],
    depth_scale: float = io.DEPTH_SCALE_MM,
    root: Path | None = None,
) -> ResizingSequence:
    """Frames of a sensor whose depth is registered to a larger colour image (ScanNet's and 12-Scenes'
    Structure sensor): served at the depth size, with the colour intrinsics rescaled to it."""
    dh, dw = io.read_depth(records[0].depth_path).shape  # type: ignore[arg-type]
    ch, cw = io.read_rgb(records[0].color_path).shape[:2]
    K = np.array(K_color, dtype=np.float64)
    K[0] *= dw / cw
    K[1] *= dh / ch
    return ResizingSequence(split, K, dw, dh, records, depth_scale, skipped=skipped, root=root)


class ResizingSequence(SceneSequence):
    """A SceneSequence whose colour and instance images are resized to the depth size on read."""

    def __getitem__(self, i: int) -> Frame:
        r = self.records[i]
        color = io.read_rgb(r.color_path)
        if color.shape[:2] != (self.height, self.width):
            color = cv2.resize(color, (self.width, self.height), interpolation=cv2.INTER_AREA)
        inst = None
        if r.instance_path is not None and self.load_instances:
            inst = io.read_instance(r.instance_path)
            if inst.shape != (self.height, self.width):
                inst = cv2.resize(inst, (self.width, self.height), interpolation=cv2.INTER_NEAREST)
        return Frame(f"{self.split}/{r.frame_id}", r.T_wc, self.K, color, self.depth(i), inst)


def stride_split(seq: SceneSequence, stride: int = 20, offset: int = 10) -> tuple[SceneSequence, SceneSequence]:
    """The paper's ScanNet protocol: mapping = frame ids 0, stride, 2*stride...; query = offset + k*stride.

    Selection is by frame id (not by list position), so frames dropped for invalid poses do not shift
    the two sets into each other.
    """
    if stride <= 0 or not 0 <= offset < stride:
        raise ValueError("need stride > 0 and 0 <= offset < stride")
    ids = [int(r.frame_id) for r in seq.records]
    mapping = seq.subset([i for i, f in enumerate(ids) if f % stride == 0])
    query = seq.subset([i for i, f in enumerate(ids) if f % stride == offset])
    mapping.split, query.split = "mapping", "query"
    return mapping, query
