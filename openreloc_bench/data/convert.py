"""Convert real RGB-D recordings (ScanNet exports, TUM RGB-D sequences) into the scene layout.

The converted scene has a ``mapping`` and a ``query`` split made by the paper's stride protocol
(mapping = frames 0, 20, 40...; query = 10, 30, 50...), depth as uint16 millimetres, colour at the
depth resolution with the intrinsics rescaled to it, ScanNet's ``instance-filt`` masks as instance
images when the export has them, and, when an aggregation file is found, an ``objects.json`` with
each instance's label and a box fitted to its masked depth. The scene is written beside ``--out`` and
takes its place when complete (a failed import leaves no partial scene; two imports into one ``--out``
cannot both succeed). ``source_frames.txt`` maps each frame name to the
frame of the recording it came from (ScanNet frame number, TUM colour timestamp).
"""

from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from openreloc_bench import geometry
from openreloc_bench.data import io, paths
from openreloc_bench.data.scannet import read_scannet, stride_split
from openreloc_bench.data.scene import STRUCTURAL_CATEGORIES, ObjectInfo, SceneWriter, frame_id
from openreloc_bench.data.tum import read_tum
from openreloc_bench.data.types import SceneSequence
from openreloc_bench.errors import ConfigError, DataError

FORMATS = ("scannet", "tum")
CONVERTER_VERSION = 1
"""Bumped when the converter's output changes, so a re-import of the same recording changes the spec hash."""
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


def import_scannet(
    src: Path, out: Path, stride: int = 20, offset: int = 10, aggregation: Path | None = None
) -> ImportReport:
    """A ScanNet export (``color/``, ``depth/``, ``pose/``, ``intrinsic/``, optional ``instance-filt/``)
    as a scene; ``aggregation`` (default: ``<scene>.aggregation.json`` found in or next to ``src``)
    gives the instances' labels."""
    seq = read_scannet(src)
    agg = aggregation if aggregation is not None else find_aggregation(src)
    labels = read_aggregation_labels(agg) if agg is not None else None
    source = {"format": "scannet", "name": src.resolve().name}
    if agg is not None:
        source["aggregation"] = agg.name
    return _write_scene(seq, out, stride, offset, source, labels, [src] + ([agg] if agg else []))


def import_tum(
    src: Path, out: Path, stride: int = 20, offset: int = 10, K: np.ndarray | None = None, max_dt: float = 0.02
) -> ImportReport:
    """A TUM RGB-D sequence (``rgb.txt``, ``depth.txt``, ``groundtruth.txt``) as a scene: colour frames
    associated with depth and ground truth within ``max_dt`` seconds, numbered in time order."""
    seq = read_tum(src, K=K, max_dt=max_dt)
    stamps = [r.frame_id for r in seq.records]
    numbered = replace(seq, records=[replace(r, frame_id=str(i)) for i, r in enumerate(seq.records)])
    source = {"format": "tum", "name": src.resolve().name, "max_dt": max_dt}
    return _write_scene(numbered, out, stride, offset, source, None, [src], stamps)


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
        labels[g["objectId"] + 1] = g["label"]
    return labels


def _write_scene(
    seq: SceneSequence,
    out: Path,
    stride: int,
    offset: int,
    source: dict[str, Any],
    labels: dict[int, str] | None,
    inputs: list[Path],
    source_ids: list[str] | None = None,
) -> ImportReport:
    if stride < 2 or not 0 < offset < stride:
        raise ConfigError(f"need --stride >= 2 and 0 < --offset < --stride, got stride {stride}, offset {offset}")
    out = paths.check_output(out, inputs, "--out")
    mapping, query = stride_split(seq, stride, offset)
    for split in (mapping, query):
        if not len(split):
            raise DataError(inputs[0], f"no frame for the '{split.split}' split (stride {stride}, offset {offset})")
    not_empty = f"--out {out} is not empty; converting writes a new scene directory"
    source = {**source, "stride": stride, "offset": offset, "converter_version": CONVERTER_VERSION}
    with paths.new_directory(out, "openreloc-bench import", not_empty) as stage:
        info, n_objects = _write_frames(SceneWriter(stage), seq, mapping, query, source, labels, source_ids)
    return ImportReport(out, dict(info["splits"]), dict(seq.skipped), n_objects)


def _write_frames(
    writer: SceneWriter,
    seq: SceneSequence,
    mapping: SceneSequence,
    query: SceneSequence,
    source: dict[str, Any],
    labels: dict[int, str] | None,
    source_ids: list[str] | None,
) -> tuple[dict[str, Any], int]:
    """Write the converted scene through ``writer``; its ``scene.json`` info and number of objects."""
    points: dict[int, list[np.ndarray]] = defaultdict(list)
    names = []
    with tqdm(total=len(mapping) + len(query), desc="import", unit="frame") as bar:
        for split in (mapping, query):
            writer.write_intrinsics(split.split, split.K)
            for k, frame in enumerate(split):
                fid = split.records[k].frame_id
                T_wc = _orthonormal(frame.T_wc)
                writer.write_frame(split.split, int(fid), frame.color, frame.depth, frame.instance, T_wc)
                source_id = source_ids[int(fid)] if source_ids is not None else fid
                names.append(f"{split.split}/{frame_id(int(fid))} {source_id}")
                if labels is not None and frame.instance is not None and frame.depth is not None:
                    _collect_points(frame.instance, frame.depth, split.K, T_wc, points)
                bar.update()
    objects = _objects(labels, points) if labels is not None else []
    if labels is not None:
        writer.write_objects(objects)
    io.atomic_write_text(writer.root / "source_frames.txt", "# name source_frame\n" + "\n".join(names) + "\n")
    info = {
        "source": source,
        "intrinsics": {"width": seq.width, "height": seq.height, "K": np.asarray(seq.K).tolist()},
        "splits": {"mapping": len(mapping), "query": len(query)},
        "skipped": seq.skipped,
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
