"""``build_object_map``: posed RGB-D mapping frames -> the OpenReLoc map suite (paper section 3.1).

Steps, each timed in ``ObjectMap.stats["timings_s"]``: TSDF fusion -> observation (depth-tested
projection of the scene cloud into every frame) -> instances (oracle voting, or view-consensus
clustering of a segmenter's masks) -> reference frames -> descriptors -> the landmarks' keypoints
(beyond the paper, :mod:`.anchors`) -> invalid-object filtering -> scene graph. The 3D instance precision/recall at IoU 0.5 is recorded in ``stats["instance_quality"]``
against ground truth independent of any mask: the points inside each object's box of the scene's
``objects.json`` (``reference: "object boxes"``); scenes without boxes (real ScanNet exports) fall back
to the per-point vote of the dataset masks (``reference: "mask voting"``), which the oracle track
matches by construction.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
import open3d as o3d

from openreloc_bench import config as cfg_mod
from openreloc_bench.config import check_ranges
from openreloc_bench.data.scene import Scene
from openreloc_bench.data.types import SceneSequence
from openreloc_bench.errors import ConfigError
from openreloc_bench.openreloc.anchors import AnchorBuildConfig, Anchors, build_anchors
from openreloc_bench.openreloc.descriptors import DescriptorConfig, compute_descriptors
from openreloc_bench.openreloc.filtering import FilterConfig, invalid_landmarks
from openreloc_bench.openreloc.map import Landmark, ObjectMap
from openreloc_bench.openreloc.reference_frames import ReferenceFrameConfig, landmark_sightings, select_reference_frames
from openreloc_bench.openreloc.scene_graph import GraphConfig, build_scene_graph
from openreloc_bench.reconstruction.fusion import FusionConfig, Reconstruction, fuse_tsdf
from openreloc_bench.reconstruction.gravity import estimate_up
from openreloc_bench.reconstruction.instance_eval import box_point_labels, boxed_objects, instance_report
from openreloc_bench.reconstruction.instances import GroupedInstanceConfig, label_instances
from openreloc_bench.reconstruction.lifting import instance_sets, lift_by_voting
from openreloc_bench.reconstruction.observation import FrameObservation, ObservationConfig, observe
from openreloc_bench.vision.base import ImageTextEncoder, Segmenter

log = logging.getLogger(__name__)


@dataclass
class MappingConfig:
    """Every choice of the mapping stage (all recorded in the map)."""

    instances_from: Literal["auto", "masks", "segmenter"] = "auto"
    """'masks': vote the dataset instance masks (oracle track); 'segmenter': cluster the segmenter's
    masks; 'auto': the dataset masks on the oracle-mask track (the mapping sequence's), else the
    segmenter's (predicted track)."""
    landmark_voxel: float = 0.04
    """Landmark points kept in the map are voxel-downsampled to this spacing (m)."""
    max_landmark_points: int = 1500
    """...and capped at this many (seeded random subset), which bounds the map size per landmark."""
    seed: int = 0
    """Seed of the point subsampling."""
    fusion: FusionConfig = field(default_factory=FusionConfig)
    observation: ObservationConfig = field(default_factory=ObservationConfig)
    instances: GroupedInstanceConfig = field(default_factory=GroupedInstanceConfig)
    reference_frames: ReferenceFrameConfig = field(default_factory=ReferenceFrameConfig)
    descriptors: DescriptorConfig = field(default_factory=DescriptorConfig)
    filtering: FilterConfig = field(default_factory=FilterConfig)
    graph: GraphConfig = field(default_factory=GraphConfig)
    anchors: AnchorBuildConfig = field(default_factory=AnchorBuildConfig)
    """Beyond the paper: the landmarks' keypoints (:mod:`.anchors`)."""

    def __post_init__(self) -> None:
        check_ranges(self, positive=("landmark_voxel",), at_least_one=("max_landmark_points",), non_negative=("seed",))


class _Timer:
    def __init__(self) -> None:
        self.times: dict[str, float] = {}

    @contextmanager
    def __call__(self, name: str) -> Iterator[None]:
        t = time.perf_counter()
        yield
        self.times[name] = round(time.perf_counter() - t, 4)


def build_object_map(
    mapping_seq: SceneSequence,
    config: MappingConfig,
    encoder: ImageTextEncoder,
    segmenter: Segmenter | None = None,
    progress: bool = True,
) -> ObjectMap:
    """Build the object-oriented map suite from posed RGB-D frames."""
    source = config.instances_from if config.instances_from != "auto" else ("segmenter" if segmenter else "masks")
    if source == "segmenter" and segmenter is None:
        raise ConfigError("mapping: instances_from is 'segmenter' but no segmenter is configured")
    if source == "masks" and not mapping_seq.has_instances:
        raise ConfigError("mapping: the mapping frames have no instance masks and no segmenter is configured")
    timer = _Timer()
    inst = lift_instances(mapping_seq, config, segmenter if source == "segmenter" else None, progress, timer)
    rec, obs, labels, sets = inst.reconstruction, inst.observations, inst.labels, inst.sets
    n = len(rec.points)
    with timer("ground_truth"):
        gt_labels, reference = _reference_labels(
            mapping_seq, rec.points, obs, labels if source == "masks" else None, config
        )
        quality = None
        if gt_labels is not None:
            truth = instance_sets(gt_labels, config.instances.min_points)
            quality = {**instance_report(rec.points, sets, truth), "reference": reference}
    with timer("reference_frames"):
        sightings = landmark_sightings(obs, labels, config.reference_frames)
        rfs = select_reference_frames(sightings, mapping_seq.poses, config.reference_frames)
    ids = sorted(set(int(i) for i in sightings.landmark))  # landmarks never seen well enough are dropped
    with timer("descriptors"):
        described = compute_descriptors(mapping_seq, sightings, ids, encoder, config.descriptors, progress)
    with timer("anchors"):
        anchors = (
            build_anchors(
                mapping_seq,
                rec.points,
                np.where(np.isin(labels, ids), labels, 0),
                config.anchors,
                progress,
            )
            if config.anchors.enabled
            else Anchors.empty()
        )
    with timer("filtering"):
        invalid, freq = invalid_landmarks(rfs, ids, config.filtering, {i: rec.points[sets[i]] for i in ids})
    # ground-truth categories name oracle landmarks in explanations; a predicted map carries none
    categories = _categories(mapping_seq, sets) if source == "masks" else {}
    rng = np.random.default_rng(config.seed)
    landmarks = {}
    for i in ids:
        pts = rec.points[sets[i]]
        kept = _downsample(pts, config.landmark_voxel, config.max_landmark_points, rng)
        landmarks[i] = Landmark(
            id=i,
            points=kept,
            box_min=pts.min(0).astype(np.float64),
            box_max=pts.max(0).astype(np.float64),
            center=pts.mean(0).astype(np.float64),
            descriptor=described.descriptors[i],
            valid=i not in invalid,
            category=categories.get(i),
            n_views=int((sightings.landmark == i).sum()),
        )
    with timer("graph"):
        graph = build_scene_graph(landmarks, config.graph)
    stats = {
        "frames_total": len(mapping_seq),
        "frames_fused": int(rec.usable.sum()),
        "frames_skipped": rec.skipped,
        "reference_frames": len(rfs),
        "scene_points": n,
        "landmarks": len(landmarks),
        "landmarks_invalid": sorted(invalid),
        "invalid_categories": sorted({categories.get(i) or "?" for i in invalid}),
        "reference_frequency": {i: round(f, 4) for i, f in freq.items()},
        "crops_per_landmark": described.crops,
        "cross_view_recall": described.cross_view_recall,
        "anchors": len(anchors),
        "instances_from": source,
        "instance_quality": quality,
        "graph_edges": graph.number_of_edges(),
        "timings_s": {**timer.times, "total": round(sum(timer.times.values()), 4)},
    }
    encoder_info = encoder.config()
    encoder_info["fingerprint"] = encoder.weights_fingerprint(**encoder_info)  # load_map checks it
    return ObjectMap(
        landmarks,
        rfs,
        graph,
        np.asarray(mapping_seq.K, dtype=np.float64),
        mapping_seq.width,
        mapping_seq.height,
        encoder_info,
        cfg_mod.to_dict(config),
        stats,
        anchors,
        inst.up,
    )


@dataclass
class Instances:
    """The scene cloud, what every frame sees of it, and its 3D instances."""

    reconstruction: Reconstruction
    observations: list[FrameObservation]
    labels: np.ndarray
    """(N,) instance id per scene point (0 = none); instances below ``min_points`` already removed."""
    sets: dict[int, np.ndarray]
    """Instance id -> its point indices."""
    up: np.ndarray
    """(3,) the world's up, established from the cameras and the cloud (:mod:`reconstruction.gravity`)."""


def lift_instances(
    mapping_seq: SceneSequence,
    config: MappingConfig,
    segmenter: Segmenter | None,
    progress: bool = True,
    timer: _Timer | None = None,
    boundaries: bool = False,
) -> Instances:
    """Fusion, observation and 3D instances (:func:`~openreloc_bench.reconstruction.instances.label_instances`):
    the dataset masks voted (no segmenter), or the segmenter's masks grouped and repaired. The observations
    keep the segmenter's boundaries and colours when the repair merges, or with ``boundaries``."""
    timer = timer or _Timer()
    with timer("fusion"):
        rec = fuse_tsdf(mapping_seq, config.fusion, progress)
        up = estimate_up(mapping_seq.poses[rec.usable], rec.points, config.fusion.voxel_size)
    with timer("observation"):
        keep = boundaries or config.instances.repair.merge
        obs = observe(mapping_seq, rec.points, rec.usable, config.observation, segmenter, progress, keep)
    with timer("instances"):
        cameras, voxel = mapping_seq.poses[:, :3, 3], config.fusion.voxel_size
        labels, sets = label_instances(rec.points, obs, config.instances, segmenter is not None, up, cameras, voxel)
        labels = np.where(np.isin(labels, list(sets)), labels, 0)
    return Instances(rec, obs, labels, sets, up)


def _downsample(points: np.ndarray, voxel: float, cap: int, rng: np.random.Generator) -> np.ndarray:
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points.astype(np.float64)))
    pts = np.asarray(pcd.voxel_down_sample(voxel).points, dtype=np.float32)
    pts = pts[np.lexsort(pts.T[::-1])]
    if len(pts) > cap:
        pts = pts[np.sort(rng.choice(len(pts), cap, replace=False))]
    return pts


def _objects(seq: SceneSequence) -> dict:
    """The scene's ``objects.json`` entries (empty for scenes without one, e.g. ScanNet exports)."""
    root = seq.root
    return Scene(root).objects if root is not None and (root / "objects.json").exists() else {}


def _reference_labels(
    seq: SceneSequence, points: np.ndarray, obs: list, voted: np.ndarray | None, config: MappingConfig
) -> tuple[np.ndarray | None, str | None]:
    """Ground-truth point labels for scoring instances: object boxes if the scene has them, else the
    vote of the dataset masks (reusing the oracle labels when they were just computed)."""
    objects = boxed_objects(_objects(seq))
    if objects:
        return box_point_labels(points, objects, config.instances.gt_box_margin), "object boxes"
    if all(o.gt_ids is not None for o in obs):
        return (
            voted if voted is not None else lift_by_voting(len(points), obs, config.instances.voting)
        ), "mask voting"
    return None, None


def _categories(seq: SceneSequence, sets: dict[int, np.ndarray]) -> dict[int, str]:
    """Landmark -> its dataset instance's category (oracle landmarks carry the dataset id)."""
    objects = _objects(seq)
    return {i: objects[i].category for i in sets if i in objects}
