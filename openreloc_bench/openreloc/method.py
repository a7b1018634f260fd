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
from openreloc_bench.openreloc.association import (
    AssociationConfig,
    Match,
    QueryObject,
    associate,
    oracle_matches,
    unique_mask,
    uniqueness,
    verification_evidence,
)
from openreloc_bench.openreloc.box_fit import extreme_points
from openreloc_bench.openreloc.build import MappingConfig, build_object_map
from openreloc_bench.openreloc.coarse_prior import CoarseConfig, place_landmarks
from openreloc_bench.openreloc.consistency import (
    ConsistencyConfig,
    LabelRenderer,
    candidate_weights,
    consistency,
    query_labels,
)
from openreloc_bench.openreloc.descriptors import pad_box
from openreloc_bench.openreloc.explain import PlacedObject, explain_pose
from openreloc_bench.openreloc.hypotheses import (
    Compare,
    Hypothesis,
    RefinedBatch,
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
from openreloc_bench.openreloc.verify import VerifyConfig, verify_matches
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
        own_masks = source == "segmenter" or (source == "auto" and not mapping.has_instances)
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
        self.centers = np.array([m.landmarks[i].center for i in self.ids], dtype=np.float64).reshape(-1, 3)
        self.extremes = np.array([extreme_points(m.landmarks[i].points) for i in self.ids]).reshape(
            len(self.ids), -1, 3
        )
        # (frames, landmarks): which landmarks each reference frame sees (the verification's place prior)
        self.frame_visibility = np.array(
            [[i in f.boxes for i in self.ids] for f in m.reference_frames], dtype=bool
        ).reshape(len(m.reference_frames), len(self.ids))
        # (landmarks, landmarks): which pairs some reference frame sees together (the RANSAC's guided sampling)
        seen = self.frame_visibility.astype(np.float32)
        self.covisible = (seen.T @ seen) > 0
        self.crop_padding = float(m.config.get("descriptors", {}).get("padding", 0.1))
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
        """The pipeline: segment, associate, verify, retrieve (the coarse stage's hypotheses), refine,
        compare (render-and-compare), then the choice among the refined hypotheses."""
        cfg, m = self.config, self.map
        assert m is not None
        stage = stage_timer(timings)
        rgb, K = np.asarray(query.color), np.asarray(query.K, dtype=np.float64)
        if (unfit := self._unfit(rgb, K)) is not None:
            return Failure(unfit, diag)

        with stage("segment"):
            masks, occluders = self._segment(rgb, query.instance)
        diag["detected"] = len(masks)
        if len(masks) < cfg.min_objects:
            failure = Failure(f"{len(masks)} object(s) detected, need at least {cfg.min_objects}", diag)
            return self._few_objects(rgb, K, masks, failure, stage)

        invalid = frozenset() if cfg.no_filtering else frozenset(set(self.ids) - set(m.valid_ids()))
        associated = self._associate(rgb, masks, query.instance is not None, invalid, diag, stage)
        if isinstance(associated, Failure):
            return self._few_objects(rgb, K, masks, associated, stage)
        objects, matches, appearance = associated

        verified: np.ndarray | None = None  # the verification's pose, when it finds one
        modes: list[Hypothesis] = []  # its further modes, each with its own matches
        if cfg.verification.enabled:
            with stage("verify"):
                matches, verified, modes = self._verify(matches, objects, invalid, K, diag)
        diag["matches"] = [_match_diag(mt, objects, m) for mt in matches]
        if len(matches) < cfg.min_matches:
            failure = Failure(f"{len(matches)} landmark(s) associated, need at least {cfg.min_matches}", diag)
            return self._few_objects(rgb, K, masks, failure, stage)

        with stage("retrieve"):
            hypotheses = coarse_hypotheses(matches, objects, m, K, cfg.coarse, cfg.retrieval, cfg.no_coarse, diag)
            # (without the verified pose as a hypothesis, _verify searched no further modes)
            if hypotheses and verified is not None and cfg.verification.hypothesis and not cfg.no_coarse:
                hypotheses.append(Hypothesis("verified", verified, matches))
        if not hypotheses:
            return Failure("no reference frame shares a matched landmark", diag)
        anchored = None
        if self.anchor_index is not None:
            with stage("anchors"):
                anchored = self._anchor_pose(rgb, K, hypotheses + modes, diag)
            if anchored is not None and anchored.inliers >= cfg.anchors.min_inliers:
                diag["chosen"] = "anchors"
                keypoints = Hypothesis("anchors", anchored.T_wc, matches)
                return self._estimate(anchored.T_wc, keypoints, objects, diag, anchored.inliers)
            if anchored is not None and anchored.inliers >= cfg.anchors.seed_inliers:
                hypotheses.append(Hypothesis("anchors", anchored.T_wc, matches))
        compare = timed(stage, "compare", self._explainer(masks, appearance, K))
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

    def _segment(self, rgb: np.ndarray, instance: np.ndarray | None) -> tuple[list[ObjectMask], np.ndarray]:
        """The query's masks large enough to match (the dataset's on the oracle-mask track, else the
        segmenter's), and the union of all of them (every segment occludes)."""
        m = self.map
        assert m is not None
        masks = self.gt_segmenter.segment(rgb, instance) if instance is not None else self.segmenter.segment(rgb)
        occluders = np.zeros((m.height, m.width), bool)
        for mk in masks:
            occluders |= mk.mask
        return [mk for mk in masks if int(mk.mask.sum()) >= self.min_mask_area], occluders

    def _associate(
        self,
        rgb: np.ndarray,
        masks: list[ObjectMask],
        has_instances: bool,
        invalid: frozenset[int],
        diag: dict[str, Any],
        stage: Stage,
    ) -> tuple[list[QueryObject], list[Match], np.ndarray | None] | Failure:
        """The query objects, their matches to landmarks, and every mask's visual similarity to every
        landmark (none for the oracle association, which matches by instance id)."""
        cfg, m = self.config, self.map
        assert m is not None
        if cfg.association.oracle:
            if not has_instances:
                return Failure("association.oracle (a diagnostic) needs the oracle-mask track", diag)
            largest = sorted(range(len(masks)), key=lambda i: -int(masks[i].mask.sum()))[: cfg.max_objects]
            zero = np.zeros(self.descriptors.shape[1], np.float32)
            objects = [_query_object(masks[i], zero, 0.0) for i in sorted(largest)]
            diag["unique"] = len(objects)
            with stage("associate"):
                return objects, oracle_matches(objects, self.ids, invalid), None
        described = self._objects(rgb, masks, diag, stage)
        if isinstance(described, Failure):
            return described
        objects, appearance = described
        with stage("associate"):
            graph = None if cfg.no_scene_graph else m.graph
            # association sees every landmark; filtered ones (walls, floor) only veto the query
            # objects that look most like them, instead of forcing those onto a valid look-alike
            return objects, associate(objects, self.ids, self.descriptors, graph, cfg.association, invalid), appearance

    def _few_objects(
        self, rgb: np.ndarray, K: np.ndarray, masks: list[ObjectMask], failure: Failure, stage: Stage
    ) -> PoseEstimate | Failure:
        """Too few objects to place the camera by them (``failure`` says why): the keypoints of the
        landmarks the detected segments look like, and of those a reference frame sees with them, may
        still place it. The segments retrieve, as in the full pipeline; without any, ``failure``."""
        if self.anchor_index is None or not masks or not self.ids:
            return failure
        with stage("encode"):
            sims = self._embed(rgb, masks) @ self.descriptors.T
        k = min(self.config.association.top_k, len(self.ids))
        rows = np.unique(np.argsort(-sims, axis=1, kind="stable")[:, :k])
        rows = np.flatnonzero(self.covisible[rows].any(axis=0) | np.isin(np.arange(len(self.ids)), rows))
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

    def _embed(self, rgb: np.ndarray, masks: list[ObjectMask]) -> np.ndarray:
        """(masks, D) image embeddings of the masks' padded crops."""
        m = self.map
        assert m is not None
        crops = [
            rgb[y0:y1, x0:x1]
            for x0, y0, x1, y1 in (pad_box(mk.box, self.crop_padding, m.width, m.height) for mk in masks)
        ]
        return self.encoder.encode_images(crops)

    def _anchor_pose(
        self, rgb: np.ndarray, K: np.ndarray, hypotheses: list[Hypothesis], diag: dict[str, Any]
    ) -> AnchorPose | None:
        """The keypoint pose from the landmarks the object stages chose: every hypothesis' matched
        landmarks and those its reference frame sees."""
        assert self.anchor_index is not None
        landmarks = {mt.landmark for h in hypotheses for mt in h.matches}
        for h in hypotheses:
            if h.frame is not None:
                landmarks |= self.frame_landmarks[h.frame]
        diag["anchors"] = {}
        views = [h.T_wc for h in hypotheses]
        return self.anchor_index.localize(
            rgb, K, landmarks, views, self.config.anchors, self.config.seed, diag["anchors"]
        )

    def _explainer(self, masks: list[ObjectMask], appearance: np.ndarray | None, K: np.ndarray) -> Compare:
        """The render-and-compare score (:mod:`.consistency`) of camera-to-world poses against all query
        masks, the query's label grid and pair weights computed once; without appearance (the oracle
        diagnostic) every mask-landmark pair weighs 1."""
        labels = query_labels([mk.mask for mk in masks], self.config.consistency.stride)
        weights = (
            np.ones((len(masks), len(self.ids)))
            if appearance is None
            else candidate_weights(appearance, self.config.consistency)
        )
        return lambda poses: [consistency(self.renderer.render(T, K), labels, weights) for T in poses]

    def _objects(
        self, rgb: np.ndarray, masks: list[ObjectMask], diag: dict[str, Any], stage: Stage
    ) -> tuple[list[QueryObject], np.ndarray] | Failure:
        """Embed the query objects, keep the unique ones and describe them (paper section 3.2); also
        every mask's visual similarity to every landmark."""
        cfg, m = self.config, self.map
        assert m is not None
        with stage("encode"):
            visual = self._embed(rgb, masks)
            gammas = uniqueness(visual, self.descriptors)
            keep = np.flatnonzero(unique_mask(gammas, cfg.association))
            keep = keep[np.argsort(-gammas[keep], kind="stable")][: cfg.max_objects]
        objects = [_query_object(masks[i], visual[i], float(gammas[i])) for i in sorted(keep.tolist())]
        diag["unique"] = len(objects)
        if len(objects) < cfg.min_objects:
            return Failure(
                f"{len(objects)} of {len(masks)} object(s) unique enough to match, need {cfg.min_objects}", diag
            )
        with stage("describe"):
            if self.describer is not None:
                phrases = self.describer.describe_many(rgb, [o.mask for o in objects])
                for o, p, e in zip(objects, phrases, self.text_encoder.encode_texts(phrases)):
                    o.phrase, o.text = p, e
        return objects, visual @ self.descriptors.T

    def _verify(
        self,
        matches: list[Match],
        objects: list[QueryObject],
        invalid: frozenset[int],
        K: np.ndarray,
        diag: dict[str, Any],
    ) -> tuple[list[Match], np.ndarray | None, list[Hypothesis]]:
        """Object-level RANSAC over the matched objects' candidates (:func:`verification_evidence`): the
        matches one pose explains, and that pose; the association unchanged when none does. Third: the
        further modes, each with its own matches, with ``verification.modes`` > 1."""
        cfg = self.config
        matched = {mt.query: mt for mt in matches}
        vcfg = cfg.verification
        sims = np.stack([o.visual for o in objects]) @ self.descriptors.T
        # the oracle's matches are certain: the RANSAC only finds the pose they support, and no look-alikes
        n_candidates = 1 if cfg.association.oracle else vcfg.candidates
        place = vcfg.place_frames > 0 and not cfg.association.oracle
        evidence = verification_evidence(
            objects,
            matched,
            self._place_ranking(objects, sims, invalid) if place else sims,
            self.ids,
            invalid,
            n_candidates,
            lead=int(vcfg.place_keeps_choice) if place else None,
        )
        if not vcfg.hypothesis or cfg.no_coarse:  # further modes come only with the verified pose: skip their search
            vcfg = dataclasses.replace(vcfg, modes=1)
        result = verify_matches(evidence, self.centers, self.extremes, K, vcfg, seed=cfg.seed, covisible=self.covisible)
        if result is None:
            diag["verification"] = {"inliers": 0, "kept": "association"}
            return matches, None, []

        def as_matches(assignment: dict[int, int]) -> list[Match]:
            """The association's match where the RANSAC agrees with it, a 'verified' one where not."""
            out = []
            for q, row in sorted(assignment.items()):
                lid, o = self.ids[row], objects[q]
                out.append(
                    matched[q]
                    if matched[q].landmark == lid
                    else Match(
                        query=q,
                        landmark=lid,
                        visual_sim=float(sims[q, row]),
                        text_sim=None if o.text is None else float(self.descriptors[row] @ o.text),
                        how="verified",
                        candidates=[self.ids[r] for r in evidence[q].candidates],
                    )
                )
            return out

        out = as_matches(result.assignment)
        changed = sum(mt.how == "verified" for mt in out)
        diag["verification"] = {
            "inliers": result.inliers,
            "hypotheses": result.hypotheses,
            "changed": changed,
            "dropped": len(matches) - (len(out) - changed),
        }
        if result.alternatives:
            diag["verification"]["modes"] = 1 + len(result.alternatives)
        return (
            out,
            result.T_wc,
            [
                Hypothesis(f"verified:{j}", a.T_wc, as_matches(a.assignment))
                for j, a in enumerate(result.alternatives, start=2)
            ],
        )

    def _place_ranking(self, objects: list[QueryObject], sims: np.ndarray, invalid: frozenset[int]) -> np.ndarray:
        """(objects, landmarks) candidate scores of the verification with its place prior
        (``verification.place_frames``): visual plus weighted text cosine, plus ``place_bonus`` where one of
        the reference frames looking most like the query sees the landmark."""
        vcfg = self.config.verification
        scores = sims.astype(np.float64)
        if all(o.text is not None for o in objects):
            scores = scores + vcfg.text_weight * (np.stack([o.text for o in objects]) @ self.descriptors.T)
        scores[:, [r for r, i in enumerate(self.ids) if i in invalid]] = -np.inf
        return scores + vcfg.place_bonus * place_landmarks(scores, self.frame_visibility, vcfg.place_frames)


@functools.cache
def _blas_controller() -> ThreadpoolController:
    """numpy's and scipy's BLAS libraries, limited to one thread during a query: a query's BLAS calls are
    small (hundreds of rows), but OpenBLAS's idle workers busy-wait after each call and take the cores
    from torch (the text encoder's forward pass then runs at less than half its speed)."""
    return ThreadpoolController()


def _query_object(mk: ObjectMask, visual: np.ndarray, gamma: float) -> QueryObject:
    return QueryObject(
        mask=mk.mask,
        box=np.asarray(mk.box, dtype=np.float64),
        visual=visual,
        instance_id=mk.instance_id,
        uniqueness=gamma,
    )


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
