"""GOReloc (Wang, Jiang and Chen, RA-L 2024) as a :class:`~openreloc_bench.methods.Relocalizer`.

Query: detections (masks -> COCO labels -> GOReloc's filter) -> frame graph (each detection linked
to its ``min(5, n - 1)`` nearest box centres) -> node descriptors -> candidates (same label, cosine
above 0.01, best 3) -> RANSAC over graph-consistent triples with P3P and NGWD scoring -> final P3P /
LM on the inliers. No coarse prior, as in GOReloc. Its two bugs are fixed (:mod:`.graph`).

Tracks: with the dataset's instance masks (oracle-mask track) an object's label is its category's
COCO class from the committed table (:mod:`.vocabulary`); without them (predicted track) the
configured segmenter finds the masks and the project's image-text encoder labels them zero-shot.
GOReloc's own success criterion is "a pose was returned": every answer says it in its diagnostics
(``returned_pose``), beside the harness's recall.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from baselines.goreloc.build import GORelocMappingConfig, build_goreloc_map, instance_source
from baselines.goreloc.detect import DetectionFilterConfig, TableLabeller, ZeroShotLabeller, detect
from baselines.goreloc.ellipsoid import dual_quadrics, ellipses_from_boxes
from baselines.goreloc.graph import (
    frame_descriptors,
    knn_adjacency,
    label_frequencies,
    map_descriptors,
    match_candidates,
)
from baselines.goreloc.localize import Frame, MapGeometry, RansacConfig, search_pose
from baselines.goreloc.map import GORelocMap
from baselines.goreloc.vocabulary import COCO_CLASSES, background_nouns
from openreloc_bench import config as cfglib
from openreloc_bench.data.types import SceneSequence
from openreloc_bench.errors import DataError
from openreloc_bench.methods import Failure, MapPoints, PoseEstimate, QueryFrame
from openreloc_bench.vision.base import check_backend, create_encoder, create_segmenter, encoder_fingerprint


@dataclass
class GORelocConfig:
    """Every setting of GOReloc (recorded with each result); defaults are its code's unless said."""

    segmenter: str = "learned"
    """Segmenter of the predicted track (the project's default, as for ``openreloc``). The oracle-mask
    track always uses the dataset masks."""
    segmenter_options: dict[str, Any] = field(default_factory=dict)
    """Keyword arguments of the segmenter."""
    encoder: str = "offline"
    """Image-text encoder of the zero-shot labels (predicted track)."""
    encoder_options: dict[str, Any] = field(default_factory=dict)
    """Keyword arguments of the encoder."""
    zero_shot_scale: float = 100.0
    """Logit scale of the zero-shot softmax (CLIP's 100); the score is the winning class's probability."""
    background_prompts: list[str] = field(default_factory=background_nouns)
    """Not GOReloc's: nouns competing with the 80 COCO names, the zero-shot stand-in for a detector's
    background class (a crop one of them wins is no detection). Default: structural parts and the
    generator's categories without a COCO class, so that on both tracks the same objects are outside
    the vocabulary (against structural nouns alone, most crops of non-COCO objects win a COCO name)."""
    detection: DetectionFilterConfig = field(default_factory=DetectionFilterConfig)
    """The detection filter of queries (GOReloc's relocalisation thresholds)."""
    frame_neighbours: int = 5
    """Each query detection is linked to its ``min(frame_neighbours, n - 1)`` nearest box centres."""
    min_frame_nodes: int = 4
    """Queries with fewer detections fail."""
    min_candidate_nodes: int = 3
    """Queries with fewer detections that have a candidate fail."""
    candidates: int = 3
    """Candidates per detection (same label, best descriptor cosine first)."""
    min_cosine: float = 0.01
    """Candidates need a descriptor cosine above this."""
    ransac: RansacConfig = field(default_factory=RansacConfig)
    """The pose search."""
    mapping: GORelocMappingConfig = field(default_factory=GORelocMappingConfig)
    """Map building."""
    seed: int = 0
    """Seed of the RANSAC's draws (every query starts from it: results do not depend on query order)."""

    def __post_init__(self) -> None:
        cfglib.check_ranges(
            self,
            positive=("zero_shot_scale",),
            at_least_one=("frame_neighbours", "candidates"),
            non_negative=("min_cosine", "seed"),
        )
        for kind in ("encoder", "segmenter"):
            check_backend(kind, getattr(self, kind), getattr(self, f"{kind}_options"), partial=True)
        if self.min_frame_nodes < 3 or self.min_candidate_nodes < 3:
            raise ValueError("min_frame_nodes and min_candidate_nodes must be >= 3 (P3P needs three objects)")


class GOReloc:
    """GOReloc, registered as ``goreloc``."""

    name = "goreloc"
    reference = "Wang, Jiang and Chen, GOReloc: Graph-based Object-Level Relocalization for Visual SLAM, RA-L 2024; https://github.com/yutongwangBIT/GOReloc"

    def __init__(self, **overrides: Any):
        self.config: GORelocConfig = cfglib.from_dict(GORelocConfig, overrides, "goreloc")
        self.map: GORelocMap | None = None

    # ------------------------------------------------------------------------------------ map

    def map_config(self) -> dict[str, Any]:
        """What the map depends on: the mapping section, plus the segmenter and the zero-shot labelling
        when the map may be built from a segmenter (so query-time settings share one map)."""
        cfg = self.config
        out: dict[str, Any] = {"mapping": dataclasses.asdict(cfg.mapping)}
        if cfg.mapping.instances_from != "masks":
            out.update(
                segmenter=cfg.segmenter,
                segmenter_options=cfg.segmenter_options,
                encoder=cfg.encoder,
                encoder_options=cfg.encoder_options,
                encoder_weights=encoder_fingerprint(cfg.encoder, cfg.encoder_options),
                zero_shot_scale=cfg.zero_shot_scale,
                background_prompts=cfg.background_prompts,
            )
        return out

    def build_map(self, mapping: SceneSequence, map_dir: Path) -> None:
        cfg = self.config
        segmenter = labeller = encoder_info = None
        if instance_source(mapping, cfg.mapping) == "segmenter":
            segmenter = create_segmenter(cfg.segmenter, **cfg.segmenter_options)
            encoder = create_encoder(cfg.encoder, **cfg.encoder_options)
            labeller = ZeroShotLabeller(encoder, cfg.background_prompts, cfg.zero_shot_scale)
            encoder_info = encoder.config()
            encoder_info["fingerprint"] = encoder.weights_fingerprint(**encoder_info)
        build_goreloc_map(mapping, cfg.mapping, segmenter, labeller, encoder_info).save(map_dir)

    def map_points(self, map_dir: Path) -> MapPoints:
        return GORelocMap.load(map_dir).drawn()

    def load_map(self, map_dir: Path) -> None:
        cfg = self.config
        self.map = m = GORelocMap.load(map_dir)
        if m.encoder is not None:
            enc = dict(m.encoder)
            built_with, name = enc.pop("fingerprint", None), enc.pop("name")
            if built_with != (now := encoder_fingerprint(name, enc)):
                raise DataError(
                    map_dir,
                    f"labelled with {name} encoder weights {built_with}, but the installed weights are {now}: rebuild the map",
                )
        else:
            name, enc = cfg.encoder, dict(cfg.encoder_options)
        # loaded now, not on the first predicted query, so that no query's latency pays for it
        self.zero_shot = ZeroShotLabeller(create_encoder(name, **enc), cfg.background_prompts, cfg.zero_shot_scale)
        self.labels = m.labels
        self.world = MapGeometry(
            quadrics=dual_quadrics(m.centres, m.rotations, m.axes),
            centres=m.centres,
            adjacency=m.adjacency(),
            weights=1.0 / np.maximum(label_frequencies(m.label_counts).max(axis=1, initial=0.0), 1e-9),
        )
        self.descriptors = map_descriptors(label_frequencies(m.label_counts), self.world.adjacency)
        self.table = TableLabeller(m.instance_labels)
        self.gt_segmenter = create_segmenter("gt")
        self.segmenter = create_segmenter(cfg.segmenter, **cfg.segmenter_options)

    # ------------------------------------------------------------------------------------ query

    def localize(self, query: QueryFrame) -> PoseEstimate | Failure:
        if self.map is None:
            raise RuntimeError("load_map() must be called before localize()")
        t0 = time.perf_counter()
        diag: dict[str, Any] = {"track": query.track, "returned_pose": False}
        try:
            result = self._localize(query, diag)
        finally:
            diag["time_s"] = round(time.perf_counter() - t0, 4)
        return result

    def _localize(self, query: QueryFrame, diag: dict[str, Any]) -> PoseEstimate | Failure:
        cfg, m = self.config, self.map
        assert m is not None
        rgb = np.asarray(query.color)
        if rgb.ndim != 3 or rgb.shape[:2] != (m.height, m.width):
            return Failure(f"query image is {rgb.shape[1::-1]}, the map's camera is {m.width}x{m.height}", diag)
        K = np.asarray(query.K, np.float64)
        if query.instance is not None:
            masks, labeller = self.gt_segmenter.segment(rgb, query.instance), self.table
        else:
            masks, labeller = self.segmenter.segment(rgb), self.zero_shot
        dets = detect(rgb, masks, labeller, cfg.detection)
        diag["masks"], diag["detections"] = len(masks), len(dets)
        if len(dets) < cfg.min_frame_nodes:
            return Failure(f"{len(dets)} COCO detection(s) pass the filter, GOReloc needs {cfg.min_frame_nodes}", diag)
        boxes = np.array([d.box for d in dets])
        labels = np.array([d.label for d in dets])
        adjacency = knn_adjacency((boxes[:, :2] + boxes[:, 2:]) / 2, cfg.frame_neighbours)
        cands = match_candidates(
            labels, frame_descriptors(labels, adjacency), self.labels, self.descriptors, cfg.min_cosine, cfg.candidates
        )
        n_cand = sum(len(c) > 0 for c in cands)
        diag["with_candidates"] = n_cand
        if n_cand < cfg.min_candidate_nodes:
            return Failure(f"{n_cand} detection(s) have map candidates, GOReloc needs {cfg.min_candidate_nodes}", diag)
        mu, S = ellipses_from_boxes(boxes)
        frame = Frame(boxes, mu, S, adjacency, cands)
        found = search_pose(frame, self.world, K, cfg.ransac, np.random.default_rng(cfg.seed))
        diag.update(matchings=found.matchings, hypotheses=found.hypotheses, inliers=len(found.matches))
        if found.T_wc is None:
            return Failure("no P3P hypothesis explains its detections (GOReloc returns no pose)", diag)
        diag["returned_pose"] = True
        diag["final"] = found.final
        diag["matches"] = [
            {
                "box": np.round(boxes[u], 1).tolist(),
                "label": COCO_CLASSES[int(labels[u])],
                "object": int(m.ids[o]),
                "category": m.categories[o],
            }
            for u, o in sorted(found.matches.items())
        ]
        return PoseEstimate(found.T_wc, diag)
