"""Where OpenReLoc loses, stage by stage, on scenes with ground truth (``openreloc-bench diagnose``).

Per scene, for one track:
- **query segmentation** (the segmenter the method's config names): mean best IoU, AP50 and over- /
  under-segmentation over the objects covering >= 1% of the image, and the boundary F-score at 2 px,
  on ``frames`` evenly spaced frames of each split;
- **the map**: 3D instance precision / recall at IoU 0.5 and 0.25 and each true object's error by size
  (:mod:`reconstruction.instance_eval`), as the map recorded them when it was built;
- **localization** over every query of each split: recall at 50 / 25 cm, and the association
  precision (accepted matches whose landmark and query segment lie mostly on the same true object;
  the method never sees that truth);
- with ``swap`` on the predicted track: localization again with the dataset-mask map and predicted
  query segments, and with the predicted map and dataset query masks, to say which side costs more.

Maps are built into ``work_dir`` and reused while their config is unchanged.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from openreloc_bench.bars import tqdm
from openreloc_bench.data.scene import Scene
from openreloc_bench.data.types import SceneSequence
from openreloc_bench.errors import ConfigError
from openreloc_bench.harness.cache import cached_map, map_folder, map_key
from openreloc_bench.harness.metrics import summarize
from openreloc_bench.harness.pose_stages import map_summary, pool_stages, query_stages, summarize_stages
from openreloc_bench.harness.query_picture import draw_query
from openreloc_bench.methods import Failure, PoseEstimate, QueryFrame, create_method
from openreloc_bench.openreloc.map import ObjectMap
from openreloc_bench.reconstruction.instance_eval import box_point_labels, boxed_objects
from openreloc_bench.tracks import DEFAULT_TRACK, ORACLE_MASK, PREDICTED, Track
from openreloc_bench.vision import create_segmenter
from openreloc_bench.vision.base import ObjectMask, Segmenter, label_image
from openreloc_bench.vision.segmenter_training import frame_metrics
from openreloc_bench.vision.segmenter_training import summarize as summarize_segments

RECALLS = ("recall_50cm", "recall_25cm", "recall_25cm_5deg")
MIN_OBJECT_SHARE = 0.01
"""Objects covering less of the image neither count nor penalise the segmentation scores."""
BOUNDARY_TOLERANCE_PX = 2


@dataclass
class DiagnoseOptions:
    """What ``diagnose`` measures."""

    track: Track = DEFAULT_TRACK
    """'predicted' (the method's segmenter on map and queries) or 'oracle-mask' (the dataset's masks)."""
    splits: tuple[str, ...] = ("query",)
    """Query splits to segment and localize."""
    frames: int = 12
    """Frames per split whose segmentation is scored (evenly spaced)."""
    localize: bool = True
    """Localize every query (else segmentation and map only: minutes less per scene)."""
    swap: bool = False
    """Predicted track: also localize with one side's masks swapped for the dataset's."""
    pictures: int = 0
    """Queries drawn per split (the farthest from the truth): segments, and the matched landmarks at
    the estimated and the true pose; written under ``--out``."""


def boundary_counts(pred: np.ndarray, truth: np.ndarray, tolerance: int) -> np.ndarray:
    """(matched predicted, predicted, matched true, true) boundary pixels of one frame; a boundary pixel
    is matched within ``tolerance`` px of the other's boundary."""

    def edges(labels: np.ndarray) -> np.ndarray:
        e = np.zeros(labels.shape, bool)
        e[:, 1:] |= labels[:, 1:] != labels[:, :-1]
        e[1:, :] |= labels[1:, :] != labels[:-1, :]
        return e

    p, t = edges(pred), edges(truth)
    near_t = cv2.distanceTransform((~t).astype(np.uint8), cv2.DIST_L2, 3) <= tolerance
    near_p = cv2.distanceTransform((~p).astype(np.uint8), cv2.DIST_L2, 3) <= tolerance
    return np.array([(p & near_t).sum(), p.sum(), (t & near_p).sum(), t.sum()], np.int64)


def boundary_f(counts: np.ndarray) -> float:
    precision = counts[0] / max(counts[1], 1)
    recall = counts[2] / max(counts[3], 1)
    return float(2 * precision * recall / max(precision + recall, 1e-12))


def segmentation_quality(seq: SceneSequence, segmenter: Segmenter, frames: int) -> dict[str, Any]:
    """Segment quality of ``frames`` evenly spaced frames (needs their instance images)."""
    stats, counts = [], np.zeros(4, np.int64)
    for i in np.unique(np.linspace(0, len(seq) - 1, min(frames, len(seq))).round().astype(int)):
        f = seq[int(i)]
        masks = segmenter.segment(f.color)
        labels = label_image(masks, f.instance.shape)
        stats.append(frame_metrics(labels, f.instance, np.array([m.score for m in masks]), MIN_OBJECT_SHARE))
        counts += boundary_counts(labels, f.instance, BOUNDARY_TOLERANCE_PX)
    return {**summarize_segments(stats), "boundary_f": boundary_f(counts), "boundary_counts": counts.tolist()}


class _WatchedSegmenter(Segmenter):
    """The method's segmenter, its last masks kept (for pictures) and, where the truth is known, each
    labelled with the dataset object under most of its pixels (``ObjectMask.instance_id``, which the
    method only copies into its diagnostics)."""

    def __init__(self, inner: Segmenter):
        self.inner, self.truth = inner, None
        self.name = inner.name
        self.last: list[ObjectMask] = []

    def segment(self, rgb: np.ndarray, instance: np.ndarray | None = None) -> list[ObjectMask]:
        masks = self.inner.segment(rgb, instance)
        if self.truth is not None:
            for m in masks:
                ids, n = np.unique(self.truth[m.mask], return_counts=True)
                m.instance_id = int(ids[np.argmax(n)]) if len(ids) else None
        self.last = masks
        return masks


def landmark_objects(m: ObjectMap, scene: Scene, margin: float) -> dict[int, int]:
    """Landmark id -> the true object holding most of its points (0: none)."""
    objects = boxed_objects(scene.objects)
    out = {}
    for i, lm in m.landmarks.items():
        ids, n = np.unique(box_point_labels(lm.points, objects, margin), return_counts=True)
        out[int(i)] = int(ids[np.argmax(n)]) if len(ids) else 0
    return out


def localization_quality(
    method: Any,
    map_dir: Path,
    scene: Scene,
    split: str,
    query_masks: str,
    progress: bool,
    pictures: int = 0,
    picture_dir: Path | None = None,
) -> dict[str, Any]:
    """Recall, the pose stages (:mod:`.pose_stages`) and, where the scene has instance labels, the
    association precision of ``method`` over a split; ``query_masks``: 'dataset' hands the method each
    query's instance image, 'predicted' does not. The ``pictures`` queries farthest from the truth are
    drawn into ``picture_dir``."""
    method.load_map(map_dir)
    seq = scene.sequence(split)
    labelled = seq.has_instances and bool(scene.objects)
    owner = landmark_objects(method.map, scene, method.config.mapping.instances.gt_box_margin) if labelled else {}
    watched = getattr(method, "segmenter", None)
    if isinstance(watched, Segmenter) and not isinstance(watched, _WatchedSegmenter):
        method.segmenter = watched = _WatchedSegmenter(watched)
    correct, accepted = 0, 0
    stages, diags, estimates = [], [], []
    for i in tqdm(range(len(seq)), desc=f"{scene.name} {split} ({query_masks} masks)", disable=not progress):
        f = seq[i]
        if isinstance(watched, _WatchedSegmenter):
            watched.truth = f.instance if labelled else None
        res = method.localize(QueryFrame.from_frame(f, ORACLE_MASK if query_masks == "dataset" else PREDICTED))
        diag = res.diagnostics if isinstance(res, PoseEstimate | Failure) else {}
        for mt in diag.get("matches", []):
            if mt.get("query_instance") is not None:
                accepted += 1
                correct += int(owner.get(int(mt["landmark"]), 0) == mt["query_instance"] != 0)
        estimate = res.T_wc if isinstance(res, PoseEstimate) else None
        reason = res.reason if isinstance(res, Failure) else None
        stages.append(query_stages(diag, estimate, f.T_wc, method.map, reason))
        diags.append(diag)
        estimates.append(estimate)
    t_err = np.array([q.final[0] for q in stages])
    if pictures and picture_dir is not None:  # the farthest estimates first, then the failures
        for i in np.argsort(np.where(np.isfinite(t_err), -t_err, np.inf), kind="stable")[:pictures]:
            f = seq[int(i)]
            if query_masks == "dataset":
                masks = method.gt_segmenter.segment(f.color, f.instance)
            else:
                masks = watched.inner.segment(f.color) if isinstance(watched, _WatchedSegmenter) else []
            draw_query(f, masks, diags[i], estimates[i], method.map, picture_dir / f"{f.name.replace('/', '_')}.png")
    s = summarize(t_err, np.array([q.final[1] for q in stages]))
    return {
        "queries": len(seq),
        "recall_50cm": s["recall_50cm"],
        "recall_25cm": s["recall_25cm"],
        "recall_25cm_5deg": s["recall_25cm_5deg"],
        "association_precision": correct / accepted if accepted else None,
        "accepted_matches": accepted,
        "stages": summarize_stages(stages),
        "per_query": [q.to_dict() for q in stages],
    }


def _map(scene: Scene, overrides: dict[str, Any], masks: str, work_dir: Path) -> tuple[Any, Path, dict[str, Any]]:
    """The method and its map of ``scene`` from the dataset's masks or the segmenter's, cached as eval's."""
    method = create_method("openreloc", **overrides)
    track = ORACLE_MASK if masks == "dataset" else PREDICTED
    map_dir = map_folder(work_dir, method.name, map_key(method, track), scene.name)
    cached_map(method, scene, track, map_dir, {"scene": scene.name})
    return method, map_dir, ObjectMap.load(map_dir).stats


def diagnose_scene(
    scene_dir: Path,
    overrides: dict[str, Any],
    options: DiagnoseOptions,
    work_dir: Path,
    progress: bool = True,
    out_dir: Path | None = None,
) -> dict[str, Any]:
    """Every stage's numbers for one scene (see the module docstring). A scene without instance images
    (a real recording) gets the stages that need none: the map's landmarks and the pose stages."""
    scene = Scene(scene_dir)
    labelled = all(scene.sequence(s).has_instances for s in ("mapping", *options.splits))
    if options.track == ORACLE_MASK and not labelled:
        raise ConfigError(f"{scene.name} has no instance images: diagnose it with --track {PREDICTED}")
    if options.swap and not labelled:
        raise ConfigError(f"--swap needs the dataset's instance images, which {scene.name} has not")
    masks = "predicted" if options.track == PREDICTED else "dataset"
    method, map_dir, stats = _map(scene, overrides, masks, work_dir)
    out: dict[str, Any] = {"scene": scene.name, "track": options.track, "map": stats.get("instance_quality") or {}}
    out["map"]["seconds"] = stats.get("timings_s", {}).get("total")
    out["landmarks"] = map_summary(ObjectMap.load(map_dir))
    if options.track == PREDICTED and labelled:
        segmenter = create_segmenter(method.config.segmenter, **method.config.segmenter_options)
        out["segmentation"] = {
            split: segmentation_quality(scene.sequence(split), segmenter, options.frames) for split in options.splits
        }
    if options.localize:
        pictures = out_dir / "pictures" / scene.name if out_dir is not None else None
        out["localization"] = {
            split: localization_quality(method, map_dir, scene, split, masks, progress, options.pictures, pictures)
            for split in options.splits
        }
    if options.swap and options.track == PREDICTED:
        other, other_dir, _ = _map(scene, overrides, "dataset", work_dir)
        out["swap"] = {
            "dataset map + predicted queries": {
                s: localization_quality(other, other_dir, scene, s, "predicted", progress) for s in options.splits
            },
            "predicted map + dataset queries": {
                s: localization_quality(method, map_dir, scene, s, "dataset", progress) for s in options.splits
            },
        }
    return out


def pool(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Scene rows pooled: map counts summed, segmentation and localization weighted by their sizes."""
    maps = [r["map"] for r in rows if "n_pred" in r["map"]]
    out: dict[str, Any] = {"scenes": [r["scene"] for r in rows]}
    if maps:
        n_pred = sum(m["n_pred"] for m in maps)
        n_gt = sum(m["n_gt"] for m in maps)
        out["map"] = {
            "precision": sum(m["precision"] * m["n_pred"] for m in maps) / max(n_pred, 1),
            "recall": sum(m["recall"] * m["n_gt"] for m in maps) / max(n_gt, 1),
            "precision_25": sum(m["precision_25"] * m["n_pred"] for m in maps) / max(n_pred, 1),
            "recall_25": sum(m["recall_25"] * m["n_gt"] for m in maps) / max(n_gt, 1),
            "n_pred": n_pred,
            "n_gt": n_gt,
            "objects": _sum_nested([m["objects"] for m in maps]),
            "instances": _sum_nested([m["instances"] for m in maps]),
        }
    if all("segmentation" in r for r in rows) and rows:
        out["segmentation"] = {}
        for split in rows[0]["segmentation"]:
            parts = [r["segmentation"][split] for r in rows]
            n = sum(p["objects"] for p in parts)
            out["segmentation"][split] = {
                k: sum(p[k] * p["objects"] for p in parts) / max(n, 1)
                for k in ("mean_best_iou", "ap50", "over_segmentation", "under_segmentation")
            }
            out["segmentation"][split]["boundary_f"] = boundary_f(np.sum([p["boundary_counts"] for p in parts], 0))
            out["segmentation"][split]["objects"] = n
    for key in ("localization",):
        if all(key in r for r in rows) and rows:
            out[key] = _pool_localization([r[key] for r in rows])
    if all("swap" in r for r in rows) and rows:
        out["swap"] = {k: _pool_localization([r["swap"][k] for r in rows]) for k in rows[0]["swap"]}
    return out


def _pool_localization(parts: list[dict[str, dict[str, Any]]]) -> dict[str, dict[str, Any]]:
    out = {}
    for split in parts[0]:
        ps = [p[split] for p in parts]
        n = sum(p["queries"] for p in ps)
        acc = sum(p["accepted_matches"] for p in ps)
        out[split] = {
            "queries": n,
            **{k: sum(p[k] * p["queries"] for p in ps) / max(n, 1) for k in RECALLS if all(k in p for p in ps)},
            "association_precision": (
                sum(p["association_precision"] * p["accepted_matches"] for p in ps if p["accepted_matches"]) / acc
                if acc
                else None
            ),
            "accepted_matches": acc,
        }
        if all("per_query" in p for p in ps):
            out[split]["stages"] = pool_stages([p["per_query"] for p in ps])
    return out


def _sum_nested(parts: list[dict[str, Any]]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for p in parts:
        for k, v in p.items():
            out[k] = _sum_nested([out.get(k, {}), v]) if isinstance(v, dict) else out.get(k, 0) + v
    return out
