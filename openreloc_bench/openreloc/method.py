"""The OpenReLoc relocalizer: map suite -> association -> coarse prior -> dual-path 2D ICP.

Three stages go beyond the paper, each with a switch: geometric verification of the association
(:mod:`.verify`, ``verification.enabled``), the render-and-compare choice among refined hypotheses
(:mod:`.consistency`, ``consistency.enabled``), and restarts of the chosen refinement from orbiting
starts (basin hopping, ``refinement.restart_degrees``). :mod:`.hypotheses` builds, refines and chooses
among the pose hypotheses; this module runs the stages in order (:meth:`OpenReLoc._localize`).

``openreloc-paper`` (:mod:`.paper`) is this class with these three, and every other addition, switched off.

``OpenReLoc(**overrides)`` takes :class:`OpenReLocConfig` fields (nested sections as dicts), so the
harness, the CLI's ``--set`` and YAML configs all build it the same way. Every ablation of the
paper's table is a field: ``no_refine``, ``no_coarse``, ``no_scene_graph``, ``no_language``,
``retrieval: visibility`` and ``no_filtering`` (the keys of ``harness/ablations.py``).

A query the method cannot place returns :class:`~openreloc_bench.methods.Failure` with a reason
(too few objects, nothing unique, no co-visible reference frame, diverging refinement, an image of
another size than the map's camera) -- never an exception.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np
from threadpoolctl import ThreadpoolController

from openreloc_bench import config as cfglib
from openreloc_bench.config import check_ranges
from openreloc_bench.data.types import SceneSequence
from openreloc_bench.errors import DataError
from openreloc_bench.methods import Failure, MapPoints, PoseEstimate, QueryFrame
from openreloc_bench.openreloc.anchors import AnchorConfig, AnchorIndex, AnchorPose, refined_or_prior
from openreloc_bench.openreloc.association import AssociationConfig, Associator, Match, QueryObject, segment_query
from openreloc_bench.openreloc.build import MappingConfig, build_object_map
from openreloc_bench.openreloc.coarse_prior import CoarseConfig
from openreloc_bench.openreloc.consistency import ConsistencyConfig, LabelRenderer
from openreloc_bench.openreloc.explain import PlacedObject, explain_pose
from openreloc_bench.openreloc.hypotheses import (
    Hypothesis,
    RefinedBatch,
    anchor_pose,
    batch_diag,
    choose_hypothesis,
    coarse_hypotheses,
    refine_hypotheses,
    restart,
    rounded,
    screen_modes,
)
from openreloc_bench.openreloc.map import ObjectMap
from openreloc_bench.openreloc.refine import RefineConfig
from openreloc_bench.openreloc.timing import Stage, stage_timer, timed
from openreloc_bench.openreloc.verify import Verifier, VerifyConfig
from openreloc_bench.tracks import ORACLE_MASK
from openreloc_bench.vision.base import (
    ObjectMask,
    TextCache,
    check_backend,
    create_describer,
    create_encoder,
    create_segmenter,
    encoder_fingerprint,
    segmenter_fingerprint,
)
from openreloc_bench.vision.local_features import SiftConfig

STAGES = ("segment", "encode", "describe", "associate", "verify", "retrieve", "anchors", "refine", "compare")


@dataclass
class OpenReLocConfig:
    """Every choice of the OpenReLoc method (recorded with each result)."""

    encoder: str = "offline"
    """Image/text encoder used to build maps (queries always use the encoder recorded in the map)."""
    encoder_options: dict[str, Any] = field(default_factory=dict)
    """Keyword arguments of the encoder (e.g. ``weights`` or ``model``)."""
    describer: str = "offline"
    """Describer giving each query object a phrase (the paper's LLM); ``openai`` for an HTTP model."""
    describer_options: dict[str, Any] = field(default_factory=dict)
    """Keyword arguments of the describer (it is always given the map's encoder)."""
    segmenter: str = "learned"
    """Segmenter of the predicted track, for the query and, where the mapping frames carry no masks, for
    the map (the oracle-mask track always uses the dataset masks, ``gt``)."""
    segmenter_options: dict[str, Any] = field(default_factory=dict)
    """Keyword arguments of the predicted-track segmenter."""
    min_mask_frac: float = 0.0005
    """Query objects covering less than this share of the image are ignored (too small to crop, embed
    or align). A share, not a pixel count, so that low-resolution scenes keep their objects (the default
    is 154 px at 640x480, 10 px at 160x120, where a fixed pixel count dropped most objects)."""
    max_objects: int = 16
    """At most this many query objects (the most unique) are matched, which bounds latency. Walls are
    unique too and take places, so a smaller cap leaves furniture out."""
    min_objects: int = 3
    """Fewer detected (or unique) objects than this: the query fails (the pose is under-constrained)."""
    min_matches: int = 3
    """Fewer associated landmarks than this: the query fails."""
    association: AssociationConfig = field(default_factory=AssociationConfig)
    """Landmark association settings."""
    verification: VerifyConfig = field(default_factory=VerifyConfig)
    """Beyond the paper: object-level RANSAC that keeps only the matches one camera pose explains
    (``enabled: false`` = the paper's association as it is)."""
    coarse: CoarseConfig = field(default_factory=CoarseConfig)
    """Coarse-stage hypotheses (reference frames, PnP); ``top_frames=1, pnp=False`` is the paper's single prior."""
    refinement: RefineConfig = field(default_factory=RefineConfig)
    """Dual-path 2D ICP settings."""
    consistency: ConsistencyConfig = field(default_factory=ConsistencyConfig)
    """Beyond the paper: the refined hypotheses that best explain every query mask compete, and the
    lowest ICP loss among them wins, instead of the lowest loss over all, whose matches may be wrong."""
    anchors: AnchorConfig = field(default_factory=AnchorConfig)
    """Beyond the paper: the query's keypoints matched against those of the landmarks the object stages
    chose (:mod:`.anchors`); with enough inliers their pose is returned, else it joins the hypotheses."""
    mapping: MappingConfig = field(default_factory=MappingConfig)
    """Map building settings (used by ``build_map``)."""
    no_refine: bool = False
    """Ablation #1: return the coarse prior (the reference frame's pose) without ICP refinement."""
    no_coarse: bool = False
    """Ablation #2: refine from an uninformed start (map centroid, looking at the matched objects): no
    reference-frame and no PnP hypothesis."""
    no_scene_graph: bool = False
    """Ablation #3: ambiguous objects keep their visual top-1 instead of sub-graph matching."""
    no_language: bool = False
    """Ablation #4: drop the describer/text modality (every object takes its visual top-1)."""
    retrieval: Literal["diou", "visibility"] = "diou"
    """Coarse-prior ranking of co-visible reference frames: DIoU of boxes (paper) or, ablation #5, landmark visibility."""
    no_filtering: bool = False
    """Ablation #6: keep matches to landmarks that invalid-object filtering removed (walls, floors...);
    normally a query object whose best landmark is an invalid one is dropped."""
    seed: int = 0
    """Seed of the refinement's point/pixel subsampling."""

    def __post_init__(self) -> None:
        check_ranges(
            self,
            at_least_one=("max_objects",),
            non_negative=("min_objects", "min_matches", "seed"),
            share=("min_mask_frac",),
        )
        for kind in ("encoder", "describer", "segmenter"):
            check_backend(kind, getattr(self, kind), getattr(self, f"{kind}_options"), partial=True)


class OpenReLoc:
    """The OpenReLoc relocalizer (registered as ``openreloc``)."""

    name = "openreloc"
    reference = "Cui et al., OpenReLoc: Compact Object-Level Representations with Open-Vocabulary Understanding for Indoor Visual Relocalization, arXiv:2606.24767, with this project's additions (README)"

    def __init__(self, **overrides: Any):
        self.config: OpenReLocConfig = cfglib.from_dict(OpenReLocConfig, overrides, "openreloc")
        self.map: ObjectMap | None = None

    # ------------------------------------------------------------------------------------ map

    def map_config(self) -> dict[str, Any]:
        """What the map depends on (the harness shares maps across everything else: ablations of the
        query stages, refinement, verification)."""
        cfg = self.config
        out: dict[str, Any] = {
            "encoder": cfg.encoder,
            "encoder_options": cfg.encoder_options,
            "encoder_weights": encoder_fingerprint(cfg.encoder, cfg.encoder_options),
            "mapping": dataclasses.asdict(cfg.mapping),
        }
        if cfg.mapping.instances_from != "masks":  # the segmenter makes the map where frames carry no masks
            out.update(
                segmenter=cfg.segmenter,
                segmenter_options=cfg.segmenter_options,
                segmenter_weights=segmenter_fingerprint(cfg.segmenter, cfg.segmenter_options),
            )
        return out

    def build_map(self, mapping: SceneSequence, map_dir: Path) -> None:
        cfg = self.config
        encoder = create_encoder(cfg.encoder, **cfg.encoder_options)
        source = cfg.mapping.instances_from
        own_masks = source == "segmenter" or (source == "auto" and mapping.track != ORACLE_MASK)
        segmenter = create_segmenter(cfg.segmenter, **cfg.segmenter_options) if own_masks else None
        build_object_map(mapping, cfg.mapping, encoder, segmenter).save(map_dir)

    def map_points(self, map_dir: Path) -> MapPoints:
        return ObjectMap.load(map_dir).drawn()

    def load_map(self, map_dir: Path) -> None:
        cfg = self.config
        self.map = m = ObjectMap.load(map_dir)
        enc = dict(m.encoder)
        built_with = enc.pop("fingerprint", None)
        name = enc.pop("name")
        if built_with is None:  # maps from before fingerprints: their weights cannot be checked
            raise DataError(
                map_dir, f"records no {name} encoder weights fingerprint (built by an older version): rebuild the map"
            )
        if built_with != (now := encoder_fingerprint(name, enc)):
            raise DataError(
                map_dir,
                f"built with {name} encoder weights {built_with}, but the installed weights are "
                f"{now}: rebuild the map (descriptors from other weights cannot be compared)",
            )
        self.encoder = create_encoder(name, **enc)
        # the describer's vocabulary and the phrases it returns recur across objects and queries: embed each once
        self.text_encoder = TextCache(self.encoder)
        self.describer = None
        if not cfg.no_language:
            # every describer embeds its phrase choice (or its fallback) in the map's encoder space
            self.describer = create_describer(cfg.describer, encoder=self.text_encoder, **cfg.describer_options)
            self.describer.prepare()
        self.min_mask_area = max(1, math.ceil(cfg.min_mask_frac * m.width * m.height))
        # every segment, however small, occludes (as the predicted track's do); ``min_mask_area`` then
        # filters what is matched, on both tracks alike
        self.gt_segmenter = create_segmenter("gt", min_area=1)
        self.segmenter = create_segmenter(cfg.segmenter, **cfg.segmenter_options)
        self.ids = sorted(m.landmarks)
        self.descriptors = m.descriptor_matrix(self.ids)
        padding = float(m.config.get("descriptors", {}).get("padding", 0.1))
        graph = None if cfg.no_scene_graph else m.graph
        self.associator = Associator(
            self.ids,
            self.descriptors,
            graph,
            self.encoder,
            padding,
            self.describer,
            self.text_encoder,
            cfg.association,
            cfg.min_objects,
            cfg.max_objects,
        )
        oracle = cfg.association.oracle
        self.verifier = Verifier(m, self.ids, self.descriptors, cfg.verification, oracle, cfg.no_coarse, cfg.seed)
        # the landmarks each reference frame sees, and the map's keypoints with the SIFT that made them
        self.frame_landmarks = {f.index: set(f.boxes) for f in m.reference_frames}
        self.anchor_index = None
        if cfg.anchors.enabled and len(m.anchors):
            features = cfglib.from_dict(SiftConfig, m.config["anchors"]["features"], "map anchors.features")
            self.anchor_index = AnchorIndex(m.anchors, features)
        self.renderer = LabelRenderer(
            [m.landmarks[i].points for i in self.ids], m.width, m.height, cfg.consistency, seed=cfg.seed
        )

    # ------------------------------------------------------------------------------------ query

    def localize(self, query: QueryFrame) -> PoseEstimate | Failure:
        if self.map is None:
            raise RuntimeError("load_map() must be called before localize()")
        timings: dict[str, float] = {}
        diag: dict[str, Any] = {"track": query.track, "timings": timings}
        t_start = time.perf_counter()
        try:
            with _blas_controller().limit(limits=1, user_api="blas"):
                result = self._localize(query, diag, timings)
        finally:
            timings["total"] = round(time.perf_counter() - t_start, 4)
        return result

    def _localize(self, query: QueryFrame, diag: dict[str, Any], timings: dict[str, float]) -> PoseEstimate | Failure:
        """The pipeline: segment, associate, verify, retrieve (the coarse stage's hypotheses), anchors,
        refine, compare (render-and-compare), then the choice among the refined hypotheses."""
        cfg, m = self.config, self.map
        assert m is not None
        stage = stage_timer(timings)
        rgb, K = np.asarray(query.color), np.asarray(query.K, dtype=np.float64)
        if (unfit := self._unfit(rgb, K)) is not None:
            return Failure(unfit, diag)

        with stage("segment"):
            masks, occluders = segment_query(rgb, query.instance, self.segmenter, self.gt_segmenter, self.min_mask_area)
        diag["detected"] = len(masks)
        if len(masks) < cfg.min_objects:
            failure = Failure(f"{len(masks)} object(s) detected, need at least {cfg.min_objects}", diag)
            return self._few_objects(rgb, K, masks, failure, stage)

        invalid = frozenset() if cfg.no_filtering else frozenset(set(self.ids) - set(m.valid_ids()))
        associated = self.associator.associate(rgb, masks, query.track == ORACLE_MASK, invalid, diag, stage)
        if isinstance(associated, Failure):
            return self._few_objects(rgb, K, masks, associated, stage)
        objects, matches, appearance = associated

        verified: np.ndarray | None = None  # the verification's pose, when it finds one
        modes: list[Hypothesis] = []  # its further modes, each with its own matches
        if cfg.verification.enabled:
            with stage("verify"):
                matches, verified, modes = self.verifier.verify(matches, objects, invalid, K, diag)
        diag["matches"] = [_match_diag(mt, objects, m) for mt in matches]
        if len(matches) < cfg.min_matches:
            failure = Failure(f"{len(matches)} landmark(s) associated, need at least {cfg.min_matches}", diag)
            return self._few_objects(rgb, K, masks, failure, stage)

        with stage("retrieve"):
            hypotheses = coarse_hypotheses(matches, objects, m, K, cfg.coarse, cfg.retrieval, cfg.no_coarse, diag)
            # (without the verified pose as a hypothesis, the verification searched no further modes)
            if hypotheses and verified is not None and cfg.verification.hypothesis and not cfg.no_coarse:
                hypotheses.append(Hypothesis("verified", verified, matches))
        if not hypotheses:
            return Failure("no reference frame shares a matched landmark", diag)
        anchored = None
        if self.anchor_index is not None:
            with stage("anchors"):
                anchored = anchor_pose(
                    self.anchor_index, rgb, K, hypotheses + modes, self.frame_landmarks, cfg.anchors, cfg.seed, diag
                )
            if anchored is not None and anchored.inliers >= cfg.anchors.min_inliers:
                diag["chosen"] = "anchors"
                keypoints = Hypothesis("anchors", anchored.T_wc, matches)
                return self._estimate(anchored.T_wc, keypoints, objects, diag, anchored.inliers)
            if anchored is not None and anchored.inliers >= cfg.anchors.seed_inliers:
                hypotheses.append(Hypothesis("anchors", anchored.T_wc, matches))
        compare = timed(stage, "compare", self.renderer.compare([mk.mask for mk in masks], appearance, K))
        room = max(0, cfg.verification.refined_modes - 1)
        hypotheses += screen_modes(modes, room, compare if cfg.consistency.enabled else None, diag)
        if cfg.no_refine and len(hypotheses) == 1:  # the prior itself: nothing to refine or to choose from
            diag["chosen"] = hypotheses[0].source
            return self._estimate(hypotheses[0].T_wc, hypotheses[0], objects, diag)

        # without refinement, several hypotheses are scored at their starts (no step) to choose one
        rcfg = cfg.refinement if not cfg.no_refine else dataclasses.replace(cfg.refinement, max_iterations=0)
        with stage("refine" if not cfg.no_refine else "retrieve"):
            batch = refine_hypotheses(hypotheses, objects, m, K, rcfg, cfg.seed, occluders)
        explained = [0.0] * len(hypotheses)
        if cfg.consistency.enabled:
            drawn = compare([r.T_wc for r in batch.results])
            explained = [e if np.isfinite(r.loss) else 0.0 for r, e in zip(batch.results, drawn)]
        return self._choose(batch, explained, matches, objects, K, diag, stage, anchored)

    def _choose(
        self,
        batch: RefinedBatch,
        explained: list[float],
        matches: list[Match],
        objects: list[QueryObject],
        K: np.ndarray,
        diag: dict[str, Any],
        stage: Stage,
        anchored: AnchorPose | None,
    ) -> PoseEstimate | Failure:
        """The refined hypothesis that render-and-compare and the ICP loss choose, restarted
        (``refinement.restart_degrees``), or its prior where refinement leaves the keypoint evidence
        (:func:`.anchors.refined_or_prior`); without refinement, its starting pose."""
        cfg, m = self.config, self.map
        assert m is not None
        best = choose_hypothesis([r.loss for r in batch.results], explained, cfg.consistency.tie_share)
        chosen, res = batch.hypotheses[best], batch.results[best]
        if not cfg.no_refine and cfg.refinement.restart_degrees > 0 and np.isfinite(res.loss):
            with stage("refine"):
                res = restart(batch, best, m, K, cfg.refinement, cfg.seed, diag)
        if chosen.matches is not matches:  # a further verification mode won: its matches explain the pose
            diag["matches"] = [_match_diag(mt, objects, m) for mt in chosen.matches]
        diag["hypotheses"] = batch_diag(batch, explained)
        diag["chosen"] = chosen.source
        if cfg.no_refine:
            T_wc, confidence = refined_or_prior(anchored, chosen.T_wc, chosen.T_wc, K, cfg.anchors)
            return self._estimate(T_wc, chosen, objects, diag, confidence)
        diag["refine"] = {
            "iterations": res.iterations,
            "initial_loss": rounded(res.initial_loss),
            "loss": rounded(res.loss),
            "object_losses": {str(k): rounded(v) for k, v in res.object_losses.items()},
            "outliers": res.outliers,
        }
        if res.reason is not None:
            return Failure(res.reason, diag)
        T_wc, confidence = refined_or_prior(anchored, chosen.T_wc, res.T_wc, K, cfg.anchors)
        diag["refine"]["kept_prior"] = T_wc is chosen.T_wc
        return self._estimate(T_wc, chosen, objects, diag, confidence)

    def _estimate(
        self,
        T_wc: np.ndarray,
        chosen: Hypothesis,
        objects: list[QueryObject],
        diag: dict[str, Any],
        confidence: float = float("nan"),
    ) -> PoseEstimate:
        """The pose and its confidence, with the chosen hypothesis' start and a placement among its
        matched objects."""
        m = self.map
        assert m is not None
        diag["prior_T_wc"] = np.round(chosen.T_wc, 6).tolist()
        placed = []
        for mt in chosen.matches:
            lm = m.landmarks[mt.landmark]
            placed.append(PlacedObject(lm.center, lm.box_min, lm.box_max, lm.category, objects[mt.query].phrase))
        diag["explanation"] = explain_pose(T_wc, placed, m.up)
        return PoseEstimate(T_wc, diag, confidence)

    def _unfit(self, rgb: np.ndarray, K: np.ndarray) -> str | None:
        """Why a query image and its intrinsics do not fit the map's camera, if they do not."""
        m = self.map
        assert m is not None
        if rgb.ndim != 3 or rgb.shape[:2] != (m.height, m.width):
            shape = rgb.shape[1::-1] if rgb.ndim >= 2 else rgb.shape
            return f"query image is {shape}, the map's camera is {m.width}x{m.height}"
        if K.shape != (3, 3) or not (0 <= K[0, 2] <= m.width and 0 <= K[1, 2] <= m.height) or K[0, 0] <= 0:
            return "query intrinsics do not fit the image size (principal point outside the image)"
        return None

    def _few_objects(
        self, rgb: np.ndarray, K: np.ndarray, masks: list[ObjectMask], failure: Failure, stage: Stage
    ) -> PoseEstimate | Failure:
        """Too few objects to place the camera by them (``failure`` says why): the keypoints of the
        landmarks the detected segments look like, and of those a reference frame sees with them, may
        still place it. The segments retrieve, as in the full pipeline; without any, ``failure``."""
        if self.anchor_index is None or not masks or not self.ids:
            return failure
        with stage("encode"):
            sims = self.associator.embed(rgb, masks) @ self.descriptors.T
        k = min(self.config.association.top_k, len(self.ids))
        rows = np.unique(np.argsort(-sims, axis=1, kind="stable")[:, :k])
        rows = np.flatnonzero(self.verifier.covisible[rows].any(axis=0) | np.isin(np.arange(len(self.ids)), rows))
        diag = failure.diagnostics
        diag["anchors"] = {}
        with stage("anchors"):
            anchored = self.anchor_index.localize(
                rgb, K, {self.ids[r] for r in rows}, [], self.config.anchors, self.config.seed, diag["anchors"]
            )
        if anchored is None or anchored.inliers < self.config.anchors.min_inliers:
            return failure
        diag["chosen"] = "anchors"
        diag["prior_T_wc"] = np.round(anchored.T_wc, 6).tolist()
        return PoseEstimate(anchored.T_wc, diag, anchored.inliers)


@functools.cache
def _blas_controller() -> ThreadpoolController:
    """numpy's and scipy's BLAS libraries, limited to one thread during a query: a query's BLAS calls are
    small (hundreds of rows), but OpenBLAS's idle workers busy-wait after each call and take the cores
    from torch (the text encoder's forward pass then runs at less than half its speed)."""
    return ThreadpoolController()


def _match_diag(mt: Match, objects: list[QueryObject], m: ObjectMap) -> dict[str, Any]:
    o = objects[mt.query]
    return {
        "landmark": mt.landmark,
        "category": m.landmarks[mt.landmark].category,
        "query_instance": o.instance_id,
        "box": [int(v) for v in o.box],
        "phrase": o.phrase,
        "how": mt.how,
        "visual_sim": rounded(mt.visual_sim),
        "text_sim": None if mt.text_sim is None else round(mt.text_sim, 4),
        "graph_score": None if mt.graph_score is None else round(mt.graph_score, 4),
        "uniqueness": round(o.uniqueness, 6),
    }


class OpenReLocOracleAssociation(OpenReLoc):
    """DIAGNOSTIC upper bound, registered as ``openreloc-oracle-association``: OpenReLoc with the
    ground-truth landmark association (``association.oracle``; oracle-mask track only). It isolates the
    geometric stages (the verification RANSAC on the true matches, retrieval, refinement, the choice)
    from the encoder and describer, so a leaderboard can show how much of OpenReLoc's error is
    association. Not a relocalization method in its own right."""

    name = "openreloc-oracle-association"
    reference = "a diagnostic: openreloc given the true landmark association (an upper bound of what follows it)"

    def __init__(self, **overrides: Any):
        association = {**(overrides.pop("association", None) or {}), "oracle": True}
        super().__init__(association=association, **overrides)
