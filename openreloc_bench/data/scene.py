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
    <scene>/difficulty.csv             per query frame: viewpoint gap, light level, objects in view

Frames are named by six-digit zero-padded ids. The writer writes each file atomically and the
pose file last, so a frame counts as finished exactly when its pose file exists (resume relies on it).
"""

from __future__ import annotations

import hashlib
import re
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from openreloc_bench import geometry
from openreloc_bench.data import io
from openreloc_bench.data.splits import SPLITS
from openreloc_bench.data.types import FrameRecord, SceneSequence, check_intrinsics
from openreloc_bench.errors import DataError
from openreloc_bench.tracks import ORACLE_MASK, RecordedTrack

DATA_VERSION = 3
"""Version of the generated benchmark data, recorded in ``scene.json`` as ``data_version``; a reader
refuses generated scenes of another version rather than mixing them in one result. 1: textures repeated
exactly every 0.5 m. 2: no surface repeats (each part's texture covers it whole, with a random rotation,
scale and offset, and metre-scale wear); a ``query_near`` split along the mapping path; ``difficulty.csv``.
3: a structured-light sensor model (noisy, quantised depth with missing returns; colour noise growing as
light falls, vignetting, JPEG); queries without a minimum of visible objects; changes among the objects
the queries see (moved, removed, added); the dark splits without the camera's own light; a ``query_walk``
split, the frames of a second walk through the rooms."""

DIFFICULTY_COLUMNS = (
    "split",
    "frame",
    "gap_m",
    "gap_deg",
    "light_level",
    "visible_objects",
    "object_area",
    "displaced_in_view",
    "lookalikes_in_view",
)
"""Columns of ``difficulty.csv``: per query frame, the distance (m) to the nearest mapping camera and the
smallest rotation (deg) to a mapping frame within 1 m, the split's light level (1 = mapping lighting),
the non-structural objects covering at least 0.5% of the image, the image share all of them cover, how
many changes the view holds (``query_displaced``: moved or added objects it shows, removed ones it would show) and how many have an identical twin in the
scene."""
DIFFICULTY_AXES = DIFFICULTY_COLUMNS[2:]
"""The difficulty columns of the per-query tables, joined from each scene's ``difficulty.csv``."""
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
        if not isinstance(d, dict):
            raise DataError(path, f"malformed object entry (expected a mapping, got {type(d).__name__})")
        try:
            obj = cls(**{k: d[k] for k in cls.__dataclass_fields__ if k in d})
        except TypeError as e:
            raise DataError(path, f"malformed object entry ({e})") from None
        if isinstance(obj.id, bool) or not isinstance(obj.id, int) or obj.id < 1:
            raise DataError(path, f"object id must be an integer >= 1, got {obj.id!r}")
        box = _finite_array(obj.aabb, (2, 3))
        if box is None or np.any(box[0] > box[1]):
            raise DataError(path, f"object {obj.id}: aabb must be [[min xyz],[max xyz]] of finite numbers, min <= max")
        if _finite_array(obj.transform, (4, 4)) is None:
            raise DataError(path, f"object {obj.id}: transform must be a 4x4 matrix of finite numbers")
        return obj

    @property
    def model(self) -> tuple:
        """Category, description and attributes: equal for identical copies of one asset (look-alikes
        that appearance alone cannot tell apart)."""
        return self.category, self.description, tuple(sorted(self.attributes.items()))

    @property
    def aabb_array(self) -> np.ndarray:
        return np.asarray(self.aabb, dtype=np.float64)


def _finite_array(value: Any, shape: tuple[int, ...]) -> np.ndarray | None:
    """``value`` as a float array of ``shape`` with finite entries, or None."""
    try:
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        return None
    return a if a.shape == shape and np.all(np.isfinite(a)) else None


def check_scene_info(info: Any, path: Path) -> dict[str, Any]:
    """``scene.json``'s content, checked where readers rely on it: a mapping whose ``splits`` (if
    given) maps split names to frame counts and whose ``intrinsics`` (if given) hold positive integer
    ``width``/``height`` and a finite 3x3 ``K``. DataError naming the file otherwise."""
    if not isinstance(info, dict):
        raise DataError(path, f"expected a JSON object, got {type(info).__name__}")
    splits = info.get("splits")
    if splits is not None and not (
        isinstance(splits, dict)
        and all(isinstance(n, int) and not isinstance(n, bool) and n >= 0 for n in splits.values())
    ):
        raise DataError(path, "'splits' must map each split name to its number of frames")
    intr = info.get("intrinsics")
    if intr is not None:
        size_ok = isinstance(intr, dict) and all(
            isinstance(intr.get(k), int) and not isinstance(intr.get(k), bool) and intr[k] > 0
            for k in ("width", "height")
        )
        if not size_ok or ("K" in intr and _finite_array(intr["K"], (3, 3)) is None):
            raise DataError(path, "'intrinsics' must hold positive integers 'width' and 'height' and a finite 3x3 'K'")
    layout = {  # the generator's layout, as the previews draw it: each entry's fields and their shapes
        "floors": {"z": ()},
        "rooms": {"rect": (4,), "floor": (), "name": None, "kind": None},
    }
    for key, fields in layout.items():
        entries = info.get(key)
        if entries is None:
            continue
        if not isinstance(entries, list) or not all(
            isinstance(e, dict) and all(_field_ok(e.get(f), shape) for f, shape in fields.items()) for e in entries
        ):
            raise DataError(path, f"'{key}' must be a list of entries with {', '.join(fields)}")
    return info


def _field_ok(value: Any, shape: tuple[int, ...] | None) -> bool:
    """A text field (``shape`` None) or a finite number / array of ``shape``."""
    return isinstance(value, str) if shape is None else _finite_array(value, shape) is not None


def generated_data_version(info: dict[str, Any]) -> int | None:
    """The benchmark data version of a generated scene's ``scene.json`` (1 where it predates versions);
    None for data that was not generated (imported recordings)."""
    return info.get("data_version", 1) if "generator_version" in info else None


def other_version(version: int) -> str:
    """Why a scene of benchmark data ``version`` is not read, for one-line errors."""
    return f"generated as benchmark data v{version}, this openreloc-bench reads v{DATA_VERSION}"


class Scene:
    """Read access to one generated (or converted) scene directory."""

    def __init__(self, root: Path | str):
        self.root = Path(root)
        if not self.root.is_dir():
            raise DataError(self.root, "scene directory not found")
        info_path = self.root / "scene.json"
        self.info: dict[str, Any] = check_scene_info(io.read_json(info_path), info_path)
        named = self.info.get("data_version")
        if named is not None and (isinstance(named, bool) or not isinstance(named, int)):
            raise DataError(info_path, f"'data_version' must be an integer, got {named!r}")
        version = generated_data_version(self.info)
        if version not in (None, DATA_VERSION):
            raise DataError(
                self.root, other_version(version) + ": regenerate it (`openreloc-bench generate SUITE --out DIR`)"
            )
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
    def data_version(self) -> int | None:
        """The benchmark data version ``scene.json`` names (None: not named, e.g. imported data)."""
        return self.info.get("data_version")

    @property
    def spec_hash(self) -> str:
        """The generator's spec hash; for converted real data, a hash of its ``scene.json``."""
        own = self.info.get("spec_hash")
        return str(own) if own else "file:" + hashlib.sha256((self.root / "scene.json").read_bytes()).hexdigest()[:12]

    def splits(self) -> list[str]:
        return [s for s in SPLITS if (self.root / s / "pose").is_dir()] + sorted(
            p.name for p in self.root.iterdir() if p.is_dir() and p.name not in SPLITS and (p / "pose").is_dir()
        )

    def sequence(self, split: str, track: RecordedTrack | None = None) -> SceneSequence:
        """One split, checked against ``scene.json`` (frame count, image size, intrinsics) where it says them.

        With ``track``, the frames as that track gives them to a method: with the dataset's instance images
        on the oracle-mask track (DataError unless every frame has one), without on the others; without
        ``track``, with those that exist."""
        seq = read_split(self.root / split, split)
        self._check_against_info(seq)
        if track == ORACLE_MASK:
            self._check_masks(seq)
        seq.opened_for = track
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

    def difficulty(self) -> pd.DataFrame | None:
        """``difficulty.csv`` (one row per query frame, :data:`DIFFICULTY_COLUMNS`), or None for a
        scene without one (imported real data). DataError naming the file where a column is missing, a
        value is no number or a frame has two rows."""
        path = self.root / "difficulty.csv"
        if not path.exists():
            return None
        try:
            table = pd.read_csv(path, dtype={"split": str, "frame": str})
        except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as e:
            raise DataError(path, f"not a readable CSV ({str(e).splitlines()[0]})") from None
        missing = [c for c in DIFFICULTY_COLUMNS if c not in table.columns]
        if missing:
            raise DataError(path, f"missing column(s) {', '.join(missing)}")
        wrong = [c for c in DIFFICULTY_COLUMNS[2:] if not pd.api.types.is_numeric_dtype(table[c])]
        if wrong:
            raise DataError(path, f"column '{wrong[0]}' holds a value that is no number")
        twice = table[table.duplicated(["split", "frame"])]
        if len(twice):
            raise DataError(path, f"frame {twice['frame'].iloc[0]} of split '{twice['split'].iloc[0]}' has two rows")
        return table

    def _check_masks(self, seq: SceneSequence) -> None:
        """DataError unless every frame of ``seq`` has its instance image: on the oracle-mask track a frame
        without one would be a method's failure or an unmasked map frame."""
        missing = [r.frame_id for r in seq.records if r.instance_path is None]
        if missing:
            raise DataError(
                self.root / seq.split,
                f"{len(missing)} of {len(seq)} frames have no instance image (first: {missing[0]}); "
                "the oracle-mask track needs every one: use --track predicted",
            )

    def displacements(self) -> list[dict[str, Any]]:
        """The moved objects of ``query_displaced`` (each names an object of ``objects.json``)."""
        p = self.root / "query_displaced" / "displacements.json"
        moved = io.read_json(p) if p.exists() else []
        if not isinstance(moved, list) or not all(
            isinstance(d, dict)
            and isinstance(d.get("id"), int)
            and d["id"] in self.objects
            and _finite_array(d.get("aabb_after"), (2, 3)) is not None
            for d in moved
        ):
            raise DataError(p, "expected a list of moved objects, each with an object 'id' and its 'aabb_after'")
        return moved


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
    return SceneSequence(split, K, w, h, records, root=split_dir.parent)


def _id_key(stem: str) -> tuple[int, str]:
    return (int(stem), stem) if stem.isdigit() else (1 << 62, stem)


def _image_size(path: Path) -> tuple[int, int]:
    img = io.read_rgb(path)
    return img.shape[1], img.shape[0]


SCENE_FILES = ("scene.json", "objects.json", "difficulty.csv", "query_displaced/displacements.json")
FRAME_FOLDERS = ("color", "depth", "instance", "pose", "intrinsic", "pose_truth")
"""Folders of a split; ``pose_truth``: the true mapping poses where ``pose`` holds estimated ones."""


def foreign_files(root: Path | str) -> list[Path]:
    """The files under a generated scene that :class:`SceneWriter` does not write (the user's notes, a
    README in a frame folder), sorted: regenerating the scene must not delete them."""
    root = Path(root)
    written = re.compile(r"\d{6}\.(png|txt)|intrinsic_color\.txt|\..*\.tmp")  # frames, intrinsics, temps
    foreign = []
    for p in sorted(root.rglob("*")):
        rel = p.relative_to(root)
        if p.is_dir():
            ok = (len(rel.parts) == 1 and rel.parts[0] in SPLITS) or (
                len(rel.parts) == 2 and rel.parts[0] in SPLITS and rel.parts[1] in FRAME_FOLDERS
            )
        else:
            ok = rel.as_posix() in SCENE_FILES or (
                len(rel.parts) == 3 and rel.parts[1] in FRAME_FOLDERS and written.fullmatch(rel.parts[2]) is not None
            )
        if not ok:
            foreign.append(p)
    return [p for p in foreign if not any(q in p.parents for q in foreign)]


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

    def write_poses(self, split: str, poses: np.ndarray, folder: str = "pose") -> None:
        """Write every frame's pose of ``split`` into ``folder`` (e.g. estimated poses over rendered ones)."""
        for i, T in enumerate(poses):
            fid = frame_id(i)
            T = geometry.check_pose(T, f"{split}/{fid}")
            io.atomic_write_text(self.root / split / folder / f"{fid}.txt", io.format_matrix(T))

    def write_difficulty(self, table: pd.DataFrame) -> None:
        io.atomic_write_text(self.root / "difficulty.csv", table.to_csv(index=False))

    def write_displacements(self, displacements: list[dict[str, Any]]) -> None:
        io.write_json(self.root / "query_displaced" / "displacements.json", displacements)
