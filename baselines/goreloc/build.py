"""Building GOReloc's map from posed RGB-D mapping frames.

GOReloc maps with ORB-SLAM2 + OA-SLAM: ellipsoids reconstructed from detections, a label histogram
per object, and a graph per keyframe. With RGB-D frames and known poses, the same map is built from
the project's reconstruction (:mod:`openreloc_bench.reconstruction`):

1. TSDF fusion of the frames into a scene point cloud, and a depth-tested projection of the cloud into
   every frame, during which each frame's masks (dataset instance masks, or the segmenter's) are
   turned into filtered closed-vocabulary detections (:func:`.detect.detect`, mapping thresholds);
2. 3D objects, by the reconstruction's instance step (:mod:`openreloc_bench.reconstruction.instances`
   with its :class:`InstanceConfig`): per-point voting of the instance masks, or view-consensus
   clustering of the segmenter's masks; a detection belongs to the object most of its mask's points
   were lifted to;
3. per object: the ellipsoid fitted to its points, its label counts over its detections;
4. the object graph: objects whose detections were linked in a frame's graph (each detection to its
   ``keyframe_neighbours`` nearest box centres) plus each object's ``nearest_objects`` nearest objects
   by ellipsoid centre. Every mapping frame acts as a keyframe.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np

from baselines.goreloc.detect import Detection, DetectionFilterConfig, Labeller, TableLabeller, detect
from baselines.goreloc.ellipsoid import fit_ellipsoid
from baselines.goreloc.graph import knn_adjacency
from baselines.goreloc.map import GORelocMap
from baselines.goreloc.vocabulary import N_CLASSES, coco_label
from openreloc_bench import config as cfglib
from openreloc_bench.bars import tqdm
from openreloc_bench.data.scene import Scene
from openreloc_bench.data.types import SceneSequence
from openreloc_bench.errors import ConfigError, DataError
from openreloc_bench.reconstruction.fusion import FusionConfig, fuse_tsdf
from openreloc_bench.reconstruction.gravity import estimate_up
from openreloc_bench.reconstruction.instances import InstanceConfig, label_instances
from openreloc_bench.reconstruction.observation import FrameObservation, ObservationConfig, observe
from openreloc_bench.tracks import ORACLE_MASK
from openreloc_bench.vision.base import ObjectMask, Segmenter, create_segmenter


@dataclass
class GORelocMappingConfig:
    """How the map is built (everything recorded in the map)."""

    instances_from: Literal["auto", "masks", "segmenter"] = "auto"
    """'masks': the dataset's instance masks, labelled through the COCO table (oracle-mask track);
    'segmenter': the configured segmenter's masks, labelled zero-shot (predicted track); 'auto': the
    masks on the oracle-mask track (the mapping sequence's), else the segmenter."""
    detection: DetectionFilterConfig = field(default_factory=lambda: DetectionFilterConfig(min_score=0.2))
    """The detection filter while mapping (GOReloc's mapping thresholds: score 0.2)."""
    keyframe_neighbours: int = 4
    """Each detection of a mapping frame is linked to this many nearest box centres (GOReloc: 4)."""
    nearest_objects: int = 3
    """Each object is also linked to this many nearest objects by centre (GOReloc: 3)."""
    min_detections: int = 2
    """Objects detected (after filtering) in fewer mapping frames are dropped: single-view
    detections are mostly segmentation noise, and OA-SLAM needs several views per ellipsoid."""
    min_mask_share: float = 0.5
    """A detection belongs to an object when this share of its mask's seen points were lifted to it."""
    ellipsoid_trim: float = 0.01
    """Ellipsoid extents span the trim and 1 - trim quantiles of the object's points per axis."""
    ellipsoid_scale: float = 1.0
    """Semi-axes are this times the half-extents (1 = the ellipsoid inscribed in the object's box)."""
    fusion: FusionConfig = field(default_factory=FusionConfig)
    """TSDF fusion of the mapping frames."""
    observation: ObservationConfig = field(default_factory=ObservationConfig)
    """When a scene point counts as seen by a frame."""
    instances: InstanceConfig = field(default_factory=InstanceConfig)
    """Lifting masks to 3D objects (voting for instance masks, clustering for segmenter masks)."""

    def __post_init__(self) -> None:
        cfglib.check_ranges(
            self,
            positive=("ellipsoid_scale",),
            non_negative=("keyframe_neighbours", "nearest_objects"),
            at_least_one=("min_detections",),
            share=("min_mask_share", "ellipsoid_trim"),
        )
        if self.ellipsoid_trim >= 0.5:
            raise ValueError(f"'ellipsoid_trim' must be below 0.5, got {self.ellipsoid_trim!r}")


def instance_source(seq: SceneSequence, cfg: GORelocMappingConfig) -> str:
    """'masks' or 'segmenter', resolving 'auto' by the sequence's track (the masks on the oracle-mask track)."""
    if cfg.instances_from == "masks" and not seq.has_instances:
        raise ConfigError("goreloc mapping: instances_from is 'masks' but the mapping frames have no instance masks")
    if cfg.instances_from == "auto":
        return "masks" if seq.track == ORACLE_MASK else "segmenter"
    return cfg.instances_from


def dataset_categories(seq: SceneSequence) -> dict[int, str]:
    """Instance id -> category from the scene's ``objects.json`` (empty when the scene has none)."""
    scene_dir = Path(seq.records[0].color_path).parent.parent.parent
    if not (scene_dir / "objects.json").is_file():
        return {}
    return {i: o.category for i, o in Scene(scene_dir).objects.items()}


class _DetectingSegmenter(Segmenter):
    """Hands a segmenter's masks to :func:`observe` unchanged and keeps each frame's filtered
    detections (observe calls it once per frame, in the order of its observations)."""

    def __init__(self, inner: Segmenter, labeller: Labeller, cfg: DetectionFilterConfig):
        self.inner, self.labeller, self.cfg = inner, labeller, cfg
        self.frames: list[list[Detection]] = []

    def segment(self, rgb: np.ndarray, instance: np.ndarray | None = None) -> list[ObjectMask]:
        masks = self.inner.segment(rgb, instance)
        self.frames.append(detect(rgb, masks, self.labeller, self.cfg))
        return masks


def build_goreloc_map(
    seq: SceneSequence,
    cfg: GORelocMappingConfig,
    segmenter: Segmenter | None = None,
    labeller: Labeller | None = None,
    encoder_info: dict[str, Any] | None = None,
    progress: bool = True,
) -> GORelocMap:
    """The map of a mapping sequence. With instance masks (see :func:`instance_source`) the labels come
    from the COCO table; otherwise ``segmenter`` and ``labeller`` (zero-shot, made by ``encoder_info``'s
    encoder) are required."""
    t0 = time.perf_counter()
    categories = dataset_categories(seq)
    instance_labels = {i: lab for i, c in categories.items() if (lab := coco_label(c)) is not None}
    source = instance_source(seq, cfg)
    if source == "masks":
        if not categories:
            raise DataError(
                Path(seq.records[0].color_path).parent.parent.parent / "objects.json",
                "labelling instance masks needs the objects' categories (objects.json); map with a segmenter instead",
            )
        segmenter, labeller, encoder_info = create_segmenter("gt"), TableLabeller(instance_labels), None
    elif segmenter is None or labeller is None:
        raise ConfigError("goreloc mapping from a segmenter needs the segmenter and the zero-shot labeller")
    detecting = _DetectingSegmenter(segmenter, labeller, cfg.detection)
    rec = fuse_tsdf(seq, cfg.fusion, progress)
    up = estimate_up(seq.poses[rec.usable], rec.points, cfg.fusion.voxel_size)
    obs = observe(seq, rec.points, rec.usable, cfg.observation, detecting, progress)
    segmented, cameras, voxel = source == "segmenter", seq.poses[:, :3, 3], cfg.fusion.voxel_size
    point_ids, sets = label_instances(rec.points, obs, cfg.instances, segmented, up, cameras, voxel)

    counts: dict[int, np.ndarray] = {}
    linked: set[tuple[int, int]] = set()
    n_dets = 0
    for o, dets in tqdm(zip(obs, detecting.frames), total=len(obs), desc="goreloc graphs", disable=not progress):
        owners = [_owner(o, d, point_ids, cfg.min_mask_share) for d in dets]
        n_dets += len(dets)
        for d, owner in zip(dets, owners):
            if owner in sets:
                counts.setdefault(owner, np.zeros(N_CLASSES, np.int64))[d.label] += 1
        if len(dets) > 1:
            centres = np.array([(d.box[:2] + d.box[2:]) / 2 for d in dets])
            for a, b in zip(*np.nonzero(np.triu(knn_adjacency(centres, cfg.keyframe_neighbours)))):
                if owners[a] is not None and owners[b] is not None and owners[a] != owners[b]:
                    linked.add((min(owners[a], owners[b]), max(owners[a], owners[b])))

    ids = np.array(sorted(i for i, c in counts.items() if c.sum() >= cfg.min_detections), np.int64)
    fits = [fit_ellipsoid(rec.points[sets[i]], cfg.ellipsoid_trim, cfg.ellipsoid_scale, up) for i in ids]
    centres = np.array([f[0] for f in fits]).reshape(-1, 3)
    index = {int(i): k for k, i in enumerate(ids)}
    adj = knn_adjacency(centres, cfg.nearest_objects)
    for a, b in linked:
        if a in index and b in index:
            adj[index[a], index[b]] = adj[index[b], index[a]] = True
    edges = np.argwhere(np.triu(adj))
    by_id = source == "masks"
    return GORelocMap(
        ids=ids,
        centres=centres,
        rotations=np.array([f[1] for f in fits]).reshape(-1, 3, 3),
        axes=np.array([f[2] for f in fits]).reshape(-1, 3),
        label_counts=np.array([counts[int(i)] for i in ids]).reshape(-1, N_CLASSES),
        edges=edges,
        instance_labels=instance_labels,
        K=np.asarray(seq.K, np.float64),
        width=seq.width,
        height=seq.height,
        encoder=encoder_info,
        categories=[categories.get(int(i)) if by_id else None for i in ids],
        config=cfglib.to_dict(cfg),
        stats={
            "instances_from": source,
            "frames_total": len(seq),
            "frames_fused": int(rec.usable.sum()),
            "frames_skipped": rec.skipped,
            "detections": n_dets,
            "objects_lifted": len(sets),
            "objects": len(ids),
            "graph_edges": len(edges),
            "covisibility_edges": len(linked),
            "mapping_s": round(time.perf_counter() - t0, 2),
        },
    )


def _owner(o: FrameObservation, d: Detection, point_ids: np.ndarray, min_share: float) -> int | None:
    """The object most of a detection's seen mask points were lifted to, if it holds ``min_share``."""
    seen = point_ids[o.point_idx[o.masks[d.mask_index]]]
    if len(seen) == 0:
        return None
    ids, n = np.unique(seen[seen > 0], return_counts=True)
    if len(ids) == 0 or n.max() < min_share * len(seen):
        return None
    return int(ids[n.argmax()])
