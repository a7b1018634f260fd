"""The project's scene dataset layout (ScanNet-export style plus ``scene.json`` / ``objects.json``).

::

    <scene>/scene.json                 spec hash, seed, generator version, intrinsics, floors, rooms
    <scene>/objects.json               per instance: id, category, description, attributes, room,
                                       floor, structural, aabb [[min],[max]], transform
    <scene>/<split>/color/<i>.png      RGB
    <scene>/<split>/depth/<i>.png      uint16 mm
    <scene>/<split>/instance/<i>.png   uint16 instance id (0 = none)
    <scene>/<split>/pose/<i>.txt       4x4 T_wc
    <scene>/<split>/intrinsic/intrinsic_color.txt
    <scene>/query_displaced/displacements.json

Frames are named by six-digit zero-padded ids. The writer writes each file atomically and the
pose file last, so a frame counts as finished exactly when its pose file exists (resume relies on it).
"""

from __future__ import annotations

import hashlib
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from openreloc_bench import geometry
from openreloc_bench.data import io
from openreloc_bench.data.types import FrameRecord, SceneSequence, check_intrinsics
from openreloc_bench.errors import DataError

SPLITS = ("mapping", "query", "query_light1", "query_light2", "query_light3", "query_light4", "query_displaced")
QUERY_SPLITS = SPLITS[1:]
STRUCTURAL_CATEGORIES = frozenset(
    {"wall", "floor", "ceiling", "door", "doorway", "window", "stairs", "railing", "baseboard", "column"}
)


def frame_id(i: int) -> str:
    return f"{i:06d}"


@dataclass
class ObjectInfo:
    """One instance of ``objects.json``."""

    id: int
    """Instance id (>= 1), the value in instance images."""
    category: str
    description: str = ""
    """Short natural description, e.g. 'a small red radio with a silver antenna'."""
    attributes: dict[str, Any] = field(default_factory=dict)
    """Colour name, material, size class, style..."""
    room: str | None = None
    floor: int = 0
    structural: bool = False
    """Walls, floors, ceilings, doors, windows, stairs: not landmarks for relocalization."""
    aabb: list[list[float]] = field(default_factory=lambda: [[0.0] * 3, [0.0] * 3])
    """World-frame axis-aligned box [[xmin,ymin,zmin],[xmax,ymax,zmax]] in metres."""
    transform: list[list[float]] = field(default_factory=lambda: np.eye(4).tolist())
    """Mesh-to-world 4x4 transform."""

    @classmethod
    def from_dict(cls, d: dict[str, Any], path: Path) -> ObjectInfo:
        try:
            obj = cls(**{k: d[k] for k in cls.__dataclass_fields__ if k in d})
        except TypeError as e:
            raise DataError(path, f"malformed object entry ({e})") from None
        if not isinstance(obj.id, int) or obj.id < 1:
            raise DataError(path, f"object id must be an integer >= 1, got {obj.id!r}")
        box = np.asarray(obj.aabb, dtype=float)
        if box.shape != (2, 3) or np.any(box[0] > box[1]):
            raise DataError(path, f"object {obj.id}: aabb must be [[min xyz],[max xyz]] with min <= max")
        return obj

    @property
    def aabb_array(self) -> np.ndarray:
        return np.asarray(self.aabb, dtype=np.float64)


class Scene:
    """Read access to one generated (or converted) scene directory."""

    def __init__(self, root: Path | str):
        self.root = Path(root)
        if not self.root.is_dir():
            raise DataError(self.root, "scene directory not found")
        self.info: dict[str, Any] = io.read_json(self.root / "scene.json")
        objects_path = self.root / "objects.json"
        raw = io.read_json(objects_path) if objects_path.exists() else []
        if not isinstance(raw, list):
            raise DataError(objects_path, "expected a list of objects")
        self.objects: dict[int, ObjectInfo] = {}
        for d in raw:
            o = ObjectInfo.from_dict(d, objects_path)
            if o.id in self.objects:
                raise DataError(objects_path, f"duplicate object id {o.id}")
            self.objects[o.id] = o

    @property
    def name(self) -> str:
        return self.root.name

    @property
    def spec_hash(self) -> str:
        """The generator's spec hash; for converted real data, a hash of its ``scene.json``."""
        own = self.info.get("spec_hash")
        return str(own) if own else "file:" + hashlib.sha256((self.root / "scene.json").read_bytes()).hexdigest()[:12]

    def splits(self) -> list[str]:
        return [s for s in SPLITS if (self.root / s / "pose").is_dir()] + sorted(
            p.name for p in self.root.iterdir() if p.is_dir() and p.name not in SPLITS and (p / "pose").is_dir()
        )

    def sequence(self, split: str) -> SceneSequence:
        """One split, checked against ``scene.json`` (frame count, image size, intrinsics) where it says them."""
        seq = read_split(self.root / split, split)
        self._check_against_info(seq)
        return seq

    def _check_against_info(self, seq: SceneSequence) -> None:
        where = self.root / seq.split
        splits = self.info.get("splits")
        expected = splits.get(seq.split) if isinstance(splits, dict) else None
        if expected is not None and len(seq) != expected:
            raise DataError(
                where,
                f"has {len(seq)} of the {expected} frames scene.json lists: the scene is incomplete "
                "(finish it with `openreloc-bench generate SUITE --resume`)",
            )
        intr = self.info.get("intrinsics")
        if not isinstance(intr, dict):
            return
        if (intr.get("width"), intr.get("height")) != (seq.width, seq.height):
            raise DataError(
                where, f"images are {seq.width}x{seq.height}, scene.json says {intr.get('width')}x{intr.get('height')}"
            )
        if "K" in intr and not np.allclose(np.asarray(intr["K"], dtype=float), seq.K, rtol=1e-6, atol=1e-6):
            raise DataError(where / "intrinsic" / "intrinsic_color.txt", "intrinsics differ from scene.json's")

    def displacements(self) -> list[dict[str, Any]]:
        p = self.root / "query_displaced" / "displacements.json"
        return io.read_json(p) if p.exists() else []


def read_split(split_dir: Path, split: str | None = None) -> SceneSequence:
    """Read one ``<split>/`` directory (color, depth, instance, pose, intrinsic)."""
    split = split or split_dir.name
    if not split_dir.is_dir():
        raise DataError(split_dir, "split directory not found")
    K_path = split_dir / "intrinsic" / "intrinsic_color.txt"
    K = check_intrinsics(io.read_matrix(K_path), K_path)
    pose_dir = split_dir / "pose"
    if not pose_dir.is_dir():
        raise DataError(pose_dir, "pose directory not found")
    records = []
    for pose_path in sorted(pose_dir.glob("*.txt"), key=lambda p: _id_key(p.stem)):
        fid = pose_path.stem
        T = io.read_matrix(pose_path)
        if not geometry.is_rigid(T):
            raise DataError(
                pose_path, "pose is not a rigid transform (NaN/inf, non-orthonormal rotation or bad last row)"
            )
        color = split_dir / "color" / f"{fid}.png"
        if not color.exists():
            raise DataError(color, "file not found (pose exists for this frame)")
        depth = split_dir / "depth" / f"{fid}.png"
        inst = split_dir / "instance" / f"{fid}.png"
        records.append(FrameRecord(fid, color, T, depth if depth.exists() else None, inst if inst.exists() else None))
    if not records:
        raise DataError(pose_dir, "no frames (no pose files)")
    w, h = _image_size(records[0].color_path)
    return SceneSequence(split, K, w, h, records)


def _id_key(stem: str) -> tuple[int, str]:
    return (int(stem), stem) if stem.isdigit() else (1 << 62, stem)


def _image_size(path: Path) -> tuple[int, int]:
    img = io.read_rgb(path)
    return img.shape[1], img.shape[0]


class SceneWriter:
    """Writes a scene in the layout above; each frame's pose file is written last (resume marker)."""

    def __init__(self, root: Path | str):
        self.root = Path(root)

    def write_scene_info(self, info: dict[str, Any]) -> None:
        io.write_json(self.root / "scene.json", info)

    def write_objects(self, objects: list[ObjectInfo]) -> None:
        io.write_json(self.root / "objects.json", [asdict(o) for o in sorted(objects, key=lambda o: o.id)])

    def write_intrinsics(self, split: str, K: np.ndarray) -> None:
        K4 = np.eye(4)
        K4[:3, :3] = K
        io.atomic_write_text(self.root / split / "intrinsic" / "intrinsic_color.txt", io.format_matrix(K4))

    def has_frame(self, split: str, i: int, images: tuple[str, ...] = ("color", "depth", "instance")) -> bool:
        """Whether frame ``i`` is finished: its pose file (written last) and complete ``images`` PNGs exist."""
        fid = frame_id(i)
        d = self.root / split
        return (d / "pose" / f"{fid}.txt").is_file() and all(io.is_complete_png(d / k / f"{fid}.png") for k in images)

    def write_frame(
        self,
        split: str,
        i: int,
        color: np.ndarray,
        depth_m: np.ndarray | None,
        instance: np.ndarray | None,
        T_wc: np.ndarray,
    ) -> None:
        fid = frame_id(i)
        T_wc = geometry.check_pose(T_wc, f"{split}/{fid}")
        d = self.root / split
        io.write_png(d / "color" / f"{fid}.png", np.ascontiguousarray(color, dtype=np.uint8))
        if depth_m is not None:
            io.write_png(d / "depth" / f"{fid}.png", io.depth_to_png(depth_m))
        if instance is not None:
            if instance.max(initial=0) > 65535 or instance.min(initial=0) < 0:
                raise ValueError("instance ids must fit in uint16")
            io.write_png(d / "instance" / f"{fid}.png", instance.astype(np.uint16))
        io.atomic_write_text(d / "pose" / f"{fid}.txt", io.format_matrix(T_wc))

    def write_displacements(self, displacements: list[dict[str, Any]]) -> None:
        io.write_json(self.root / "query_displaced" / "displacements.json", displacements)
