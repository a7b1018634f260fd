"""Convert real RGB-D recordings (ScanNet exports, TUM RGB-D sequences, 7-Scenes and 12-Scenes scenes)
into the scene layout.

The converted scene has a ``mapping`` and a ``query`` split, chosen by one of two protocols: ``stride``,
the paper's, on one sequence (mapping = frames 0, 20, 40...; query = 10, 30, 50...), and, for 7-Scenes
and 12-Scenes, ``splits``: the dataset's own training frames map and its test frames query, both
subsampled by the same rule (mapping frames 0, 20, 40... of the training sequences, query frames 10, 30,
50... of the test sequences). Depth is written as uint16 millimetres, with missing readings (0, the
uint16 maximum, NaN) and readings beyond ``max_depth`` as 0 (invalid); colour and depth at one
resolution, the intrinsics rescaled to it; ScanNet's ``instance-filt`` masks as instance images when the
export has them, and, when an aggregation file is found, an ``objects.json`` with each instance's label
and a box fitted to its masked depth. A folder of another layout than the format's is refused in one
line saying what it holds. The scene is written beside ``--out`` and takes its place when complete (a
failed import leaves no partial scene; two imports into one ``--out`` cannot both succeed).
``source_frames.txt`` maps each frame name to the frame of the recording it came from (ScanNet frame
number, TUM colour timestamp, ``seq-XX/frame-XXXXXX`` or ``data/frame-XXXXXX``).
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from openreloc_bench import geometry
from openreloc_bench.data import io, paths
from openreloc_bench.data.scannet import read_scannet, stride_split
from openreloc_bench.data.scene import STRUCTURAL_CATEGORIES, ObjectInfo, SceneWriter, frame_id
from openreloc_bench.data.sevenscenes import read_7scenes, read_split_file, sequences
from openreloc_bench.data.tum import read_tum
from openreloc_bench.data.twelvescenes import FRAMES, read_12scenes, read_test_frames
from openreloc_bench.data.types import SceneSequence
from openreloc_bench.errors import ConfigError, DataError

FORMATS = ("scannet", "tum", "7scenes", "12scenes")
PROTOCOLS = ("stride", "splits")
"""The paper's stride split of one sequence; a dataset's own training / test split (7-Scenes, 12-Scenes)."""
SPLIT_FORMATS = ("7scenes", "12scenes")
"""The formats that come with a training / test split."""
CONVERTER_VERSION = 2
"""Bumped when the converter's output changes, so a re-import of the same recording changes the spec hash.
2: depth beyond ``max_depth`` or at the uint16 maximum written as invalid."""
MAX_DEPTH_M = 10.0
"""Depth beyond this is written as invalid: past the range of indoor RGB-D sensors (Kinect, Structure,
about 4-8 m) a reading is noise."""
BOX_PERCENTILES = (2.0, 98.0)
"""An object's box spans these percentiles of its masked depth points: masks of real data bleed onto
the background at their borders, and a min/max box would take those points in."""
BOX_PIXEL_STEP = 4
"""Every 4th pixel (in x and y) of a mask is lifted to 3D for the object's box."""


@dataclass
class ImportReport:
    """What one import wrote."""

    scene: Path
    frames: dict[str, int]
    """Frames per split."""
    skipped: dict[str, str] = field(default_factory=dict)
    """Recording frames left out (invalid pose, no depth in time), id -> reason."""
    objects: int = 0
    """Entries of ``objects.json`` (0: none written)."""


@dataclass(frozen=True)
class Layout:
    """What a format's folder holds, so that a folder of another layout is refused in one line."""

    what: str
    expected: str
    patterns: tuple[str, ...]
    """Globs that must each match something in the folder (a trailing ``/``: a folder)."""

    def matches(self, root: Path) -> bool:
        return all(next(root.glob(pattern), None) is not None for pattern in self.patterns)


LAYOUTS = {
    "scannet": Layout(
        "a ScanNet export", "color/, depth/, pose/ and intrinsic/ (SensReader's output)", ("color/", "depth/", "pose/")
    ),
    "tum": Layout("a TUM RGB-D sequence", "rgb.txt, depth.txt and groundtruth.txt", ("rgb.txt", "depth.txt")),
    "7scenes": Layout(
        "a 7-Scenes scene",
        "seq-XX/ folders of frame-XXXXXX.color.png, .depth.png and .pose.txt",
        ("seq-*/frame-*.pose.txt",),
    ),
    "12scenes": Layout(
        "a 12-Scenes scene",
        f"info.txt and {FRAMES}/ of frame-XXXXXX.color.jpg, .depth.png and .pose.txt",
        ("info.txt", f"{FRAMES}/frame-*.pose.txt"),
    ),
}


def check_layout(src: Path, fmt: str) -> None:
    """Refuse ``src`` in one line unless it has the layout of ``fmt``, saying what it holds instead."""
    layout = LAYOUTS[fmt]
    if not src.is_dir():
        raise DataError(src, f"{'not a' if src.exists() else 'no such'} folder (expected {layout.what})")
    if layout.matches(src):
        return
    other = next((name for name, known in LAYOUTS.items() if name != fmt and known.matches(src)), None)
    found = f"it looks like {LAYOUTS[other].what} (`import {other}`)" if other else f"it holds {_contents(src)}"
    raise DataError(src, f"not {layout.what}: expected {layout.expected}; {found}")


def _contents(folder: Path, shown: int = 6) -> str:
    names = sorted(p.name + "/" * p.is_dir() for p in folder.iterdir() if not p.name.startswith("."))
    if not names:
        return "nothing"
    more = f" and {len(names) - shown} more" if len(names) > shown else ""
    unpack = " (unpack the .zip files first)" if any(n.endswith(".zip") for n in names) else ""
    return ", ".join(names[:shown]) + more + unpack


def import_scannet(
    src: Path,
    out: Path,
    stride: int = 20,
    offset: int = 10,
    aggregation: Path | None = None,
    max_depth: float = MAX_DEPTH_M,
) -> ImportReport:
    """A ScanNet export (``color/``, ``depth/``, ``pose/``, ``intrinsic/``, optional ``instance-filt/``)
    as a scene; ``aggregation`` (default: ``<scene>.aggregation.json`` found in or next to ``src``)
    gives the instances' labels."""
    settings = _settings("stride", stride, offset, max_depth)
    check_layout(src, "scannet")
    seq = read_scannet(src)
    agg = aggregation if aggregation is not None else find_aggregation(src)
    labels = read_aggregation_labels(agg) if agg is not None else None
    source = {"format": "scannet", "name": src.resolve().name, **settings}
    if agg is not None:
        source["aggregation"] = agg.name
    splits = [_named(split, str) for split in stride_split(seq, stride, offset)]
    return _write_scene(splits, out, source, [src] + ([agg] if agg else []), seq.skipped, labels)


def import_tum(
    src: Path,
    out: Path,
    stride: int = 20,
    offset: int = 10,
    K: np.ndarray | None = None,
    max_dt: float = 0.02,
    max_depth: float = MAX_DEPTH_M,
) -> ImportReport:
    """A TUM RGB-D sequence (``rgb.txt``, ``depth.txt``, ``groundtruth.txt``) as a scene: colour frames
    associated with depth and ground truth within ``max_dt`` seconds, numbered in time order."""
    settings = _settings("stride", stride, offset, max_depth)
    check_layout(src, "tum")
    seq = read_tum(src, K=K, max_dt=max_dt)
    stamps = [r.frame_id for r in seq.records]
    numbered = replace(seq, records=[replace(r, frame_id=str(i)) for i, r in enumerate(seq.records)])
    splits = [_named(split, lambda fid: stamps[int(fid)]) for split in stride_split(numbered, stride, offset)]
    source = {"format": "tum", "name": src.resolve().name, "max_dt": max_dt, **settings}
    return _write_scene(splits, out, source, [src], seq.skipped)


def import_7scenes(
    src: Path,
    out: Path,
    stride: int = 20,
    offset: int = 10,
    protocol: str = "stride",
    sequence: str | None = None,
    K: np.ndarray | None = None,
    max_depth: float = MAX_DEPTH_M,
) -> ImportReport:
    """A 7-Scenes scene (``seq-XX/`` folders) as a scene seen by the colour camera (depth re-projected into
    it, poses moved onto it: :mod:`~openreloc_bench.data.sevenscenes`; ``K``: its intrinsics). ``stride``:
    one sequence (``sequence``, default the first) split by the paper's protocol; ``splits``: mapping
    frames from the sequences ``TrainSplit.txt`` lists, query frames from those of ``TestSplit.txt``, each
    split numbered from 0 in sequence order."""
    settings = _settings(protocol, stride, offset, max_depth)
    if protocol == "splits" and sequence is not None:
        raise ConfigError("--sequence is for the stride protocol; splits reads the sequences of TrainSplit.txt")
    check_layout(src, "7scenes")
    source = {"format": "7scenes", "name": src.resolve().name, **settings}
    if protocol == "stride":
        sequence = sequence or sequences(src)[0]
        seq = read_7scenes(src, sequence, K)
        name = _frame_name(sequence)
        splits = [_named(split, name) for split in stride_split(seq, stride, offset)]
        return _write_scene(splits, out, {**source, "sequence": sequence}, [src], seq.skipped)
    skipped: dict[str, str] = {}
    splits = []
    for split, split_file, part in (("mapping", "TrainSplit.txt", 0), ("query", "TestSplit.txt", 1)):
        parts = []
        for name in read_split_file(src / split_file):
            seq = read_7scenes(src, name, K)
            skipped.update(seq.skipped)
            parts.append((src / name, stride_split(seq, stride, offset)[part]))
        splits.append(_joined(split, parts))
    return _write_scene(splits, out, source, [src], skipped)


def import_12scenes(
    src: Path,
    out: Path,
    stride: int = 20,
    offset: int = 10,
    protocol: str = "stride",
    max_depth: float = MAX_DEPTH_M,
) -> ImportReport:
    """A 12-Scenes scene (``info.txt``, ``data/``) as a scene at the depth resolution. ``stride``: all its
    frames split by the paper's protocol; ``splits``: mapping frames from its training frames, query
    frames from its test frames (the first ones, as many as ``split.txt`` says)."""
    settings = _settings(protocol, stride, offset, max_depth)
    check_layout(src, "12scenes")
    seq = read_12scenes(src)
    source = {"format": "12scenes", "name": src.resolve().name, **settings}
    if protocol == "stride":
        mapping, query = stride_split(seq, stride, offset)
    else:
        n_test = source["test_frames"] = read_test_frames(src)
        test = [int(r.frame_id) < n_test for r in seq.records]
        mapping = stride_split(seq.subset([i for i, t in enumerate(test) if not t]), stride, offset)[0]
        query = stride_split(seq.subset([i for i, t in enumerate(test) if t]), stride, offset)[1]
    name = _frame_name(FRAMES)
    return _write_scene([_named(mapping, name), _named(query, name)], out, source, [src], seq.skipped)


def find_aggregation(src: Path) -> Path | None:
    """ScanNet's instance labels for the export ``src``: ``<name>.aggregation.json`` (the file the 2D
    instance images were projected from) in ``src`` or its parent, else ``<name>_vh_clean.aggregation.json``."""
    name = src.resolve().name
    for fname in (f"{name}.aggregation.json", f"{name}_vh_clean.aggregation.json"):
        for folder in (src, src.resolve().parent):
            if (folder / fname).is_file():
                return folder / fname
    return None


def read_aggregation_labels(path: Path) -> dict[int, str]:
    """{instance id: label} from a ScanNet aggregation file; the instance images hold ``objectId + 1``."""
    data = io.read_json(path)
    groups = data.get("segGroups") if isinstance(data, dict) else None
    if not isinstance(groups, list):
        raise DataError(path, "no 'segGroups' list: not a ScanNet aggregation file")
    labels = {}
    for g in groups:
        if not (isinstance(g, dict) and isinstance(g.get("objectId"), int) and isinstance(g.get("label"), str)):
            raise DataError(path, "every segGroups entry needs an integer 'objectId' and a text 'label'")
        if g["objectId"] < 0:
            raise DataError(path, f"objectId {g['objectId']} is negative (ScanNet's object ids start at 0)")
        if g["objectId"] + 1 in labels:
            raise DataError(path, f"objectId {g['objectId']} is listed twice")
        labels[g["objectId"] + 1] = g["label"]
    return labels


def _settings(protocol: str, stride: int, offset: int, max_depth: float) -> dict[str, Any]:
    """How an import chooses and cleans its frames, as ``scene.json`` records it; refused in one line when
    the splits would be empty or share frames, or the depth limit is not one uint16 millimetres hold."""
    if protocol not in PROTOCOLS:
        raise ConfigError(f"--protocol must be one of {', '.join(PROTOCOLS)}, got '{protocol}'")
    min_offset = 1 if protocol == "stride" else 0  # the stride protocol takes both splits from one sequence
    if stride < min_offset + 1 or not min_offset <= offset < stride:
        raise ConfigError(
            f"the {protocol} protocol needs --stride >= {min_offset + 1} and {min_offset} <= --offset < --stride, "
            f"got stride {stride}, offset {offset}"
        )
    if not 0 < max_depth <= (io.NO_DEPTH - 1) / io.DEPTH_SCALE_MM:
        raise ConfigError(f"--max-depth must be in (0, 65.534] metres, got {max_depth}")
    return {"protocol": protocol, "stride": stride, "offset": offset, "max_depth": max_depth}


def _frame_name(folder: str) -> Callable[[str], str]:
    """The recording's name of a frame of ``folder`` (7-Scenes and 12-Scenes naming) from its number."""
    return lambda fid: f"{folder}/frame-{int(fid):06d}"


def _named(split: SceneSequence, source_name: Callable[[str], str]) -> tuple[SceneSequence, list[str]]:
    """A split with the recording's name of each of its frames (``source_frames.txt``)."""
    return split, [source_name(r.frame_id) for r in split.records]


def _joined(split: str, parts: list[tuple[Path, SceneSequence]]) -> tuple[SceneSequence, list[str]]:
    """The frames of several sequences (folder, frames) as one split numbered from 0, with their names."""
    first_folder, first = parts[0]
    records, names = [], []
    for folder, seq in parts:
        if (seq.width, seq.height) != (first.width, first.height):
            size, first_size = f"{seq.width}x{seq.height}", f"{first.width}x{first.height}"
            raise DataError(folder, f"images are {size}, those of {first_folder.name} {first_size}")
        names += [_frame_name(folder.name)(r.frame_id) for r in seq.records]
        records += [replace(r, frame_id=str(len(records) + k)) for k, r in enumerate(seq.records)]
    return replace(first, split=split, records=records), names


def _write_scene(
    splits: list[tuple[SceneSequence, list[str]]],
    out: Path,
    source: dict[str, Any],
    inputs: list[Path],
    skipped: dict[str, str],
    labels: dict[int, str] | None = None,
) -> ImportReport:
    """Write the ``mapping`` and ``query`` splits (each with its frames' source names) as the scene ``out``."""
    out = paths.check_output(out, inputs, "--out")
    for split, _ in splits:
        if not len(split):
            settings = ", ".join(f"{k} {source[k]}" for k in ("protocol", "stride", "offset"))
            raise DataError(inputs[0], f"no frame for the '{split.split}' split ({settings})")
    not_empty = f"--out {out} is not empty; converting writes a new scene directory"
    source = {**source, "converter_version": CONVERTER_VERSION}
    with paths.new_directory(out, "openreloc-bench import", not_empty) as stage:
        info, n_objects = _write_frames(SceneWriter(stage), splits, source, labels, skipped)
    return ImportReport(out, dict(info["splits"]), dict(skipped), n_objects)


def _write_frames(
    writer: SceneWriter,
    splits: list[tuple[SceneSequence, list[str]]],
    source: dict[str, Any],
    labels: dict[int, str] | None,
    skipped: dict[str, str],
) -> tuple[dict[str, Any], int]:
    """Write the converted scene through ``writer``; its ``scene.json`` info and number of objects."""
    points: dict[int, list[np.ndarray]] = defaultdict(list)
    names = []
    with tqdm(total=sum(len(split) for split, _ in splits), desc="import", unit="frame") as bar:
        for split, source_names in splits:
            writer.write_intrinsics(split.split, split.K)
            for k, frame in enumerate(split):
                fid = int(split.records[k].frame_id)
                T_wc = _orthonormal(frame.T_wc)
                depth = None if frame.depth is None else np.where(frame.depth <= source["max_depth"], frame.depth, 0)
                writer.write_frame(split.split, fid, frame.color, depth, frame.instance, T_wc)
                names.append(f"{split.split}/{frame_id(fid)} {source_names[k]}")
                if labels is not None and frame.instance is not None and depth is not None:
                    _collect_points(frame.instance, depth, split.K, T_wc, points)
                bar.update()
    objects = _objects(labels, points) if labels is not None else []
    if labels is not None:
        writer.write_objects(objects)
    io.atomic_write_text(writer.root / "source_frames.txt", "# name source_frame\n" + "\n".join(names) + "\n")
    mapping = splits[0][0]
    info = {
        "source": source,
        "intrinsics": {"width": mapping.width, "height": mapping.height, "K": np.asarray(mapping.K).tolist()},
        "splits": {split.split: len(split) for split, _ in splits},
        "skipped": skipped,
    }
    writer.write_scene_info(info)
    return info, len(objects)


def _orthonormal(T_wc: np.ndarray) -> np.ndarray:
    """``T_wc`` with its rotation projected onto SO(3): recorded poses carry rounding that the readers
    tolerate and the scene layout does not."""
    U, _, Vt = np.linalg.svd(T_wc[:3, :3])
    T = np.array(T_wc, dtype=np.float64)
    T[:3, :3] = U @ Vt
    return T


def _collect_points(
    instance: np.ndarray, depth: np.ndarray, K: np.ndarray, T_wc: np.ndarray, points: dict[int, list[np.ndarray]]
) -> None:
    s = BOX_PIXEL_STEP
    sub_inst, sub_depth = instance[::s, ::s], depth[::s, ::s]
    valid = (sub_inst > 0) & np.isfinite(sub_depth) & (sub_depth > 0)
    v, u = np.nonzero(valid)
    if not len(v):
        return
    pts = geometry.transform_points(T_wc, geometry.unproject(K, np.stack([u * s, v * s], -1), sub_depth[v, u]))
    ids = sub_inst[v, u]
    for i in np.unique(ids):
        points[int(i)].append(pts[ids == i])


def _objects(labels: dict[int, str], points: dict[int, list[np.ndarray]]) -> list[ObjectInfo]:
    """One entry per labelled instance; an instance no frame shows keeps an empty (zero) box."""
    objects = []
    for i, label in sorted(labels.items()):
        obj = ObjectInfo(id=i, category=label, structural=label.lower() in STRUCTURAL_CATEGORIES)
        if points.get(i):
            lo, hi = np.percentile(np.concatenate(points[i]), BOX_PERCENTILES, axis=0)
            obj.aabb = [lo.tolist(), hi.tolist()]
        objects.append(obj)
    return objects
