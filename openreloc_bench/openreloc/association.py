"""Landmark association: query objects -> map landmarks (paper section 3.2, Eqs. 3-5).

The query's masks (:func:`segment_query`) become objects, are associated and reported by
:class:`Associator`:

1. Uniqueness ``gamma = Var_i cos(f_vis, f3d_i)`` of each query object against all landmarks: an
   object that is about equally similar to every landmark (a blank wall, a blurry patch) cannot be
   matched reliably. Kept: ``gamma >= max(min_uniqueness, uniqueness_ratio * median(gamma))`` over the
   query's objects -- relative, so the rule does not depend on the encoder's similarity scale.
2. Top-k candidates by the visual embedding (O_vis) and by the describer's phrase encoded by the
   text tower (O_text). Equal top-1s are accepted. Otherwise the candidate set
   ``U = (O_vis & O_text) | {v1} | {t1}`` is resolved by sub-graph matching: the query object's 2D
   subgraph (its nearest object and every object whose box intersects its own) against each
   candidate's breadth-first 3D subgraph (``hops`` edges, eta = 1) in the scene graph; similarity =
   the optimal assignment (``scipy.optimize.linear_sum_assignment``) of neighbour embeddings to
   neighbour descriptors, summed, plus the candidate's own visual similarity as a tie-breaker.
3. Objects whose choice is an invalid landmark (filtered wall/floor) are dropped, not re-matched.
4. One landmark is matched at most once: matches are granted in order of confidence (agreed before
   resolved, then visual similarity); a loser falls back to its next untaken candidate.

Ablations: without language O_text is empty, so U = {v1} (every object takes its visual top-1);
without the scene graph an ambiguous object keeps its visual top-1.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import networkx as nx
import numpy as np
from scipy.optimize import linear_sum_assignment

from openreloc_bench.config import check_ranges
from openreloc_bench.methods import Failure
from openreloc_bench.openreloc.descriptors import pad_box
from openreloc_bench.openreloc.timing import Stage
from openreloc_bench.vision.base import Describer, ImageTextEncoder, ObjectMask, Segmenter


@dataclass
class AssociationConfig:
    """Settings of landmark association."""

    top_k: int = 3
    """Candidates per modality (paper: 3)."""
    uniqueness_ratio: float = 0.3
    """Keep query objects whose uniqueness is at least this share of the query's median uniqueness.
    0.3 rather than 0.5: at 0.5 the filter dropped objects that would have matched (chosen on the
    validation suite; docs/experiments.md)."""
    min_uniqueness: float = 1e-5
    """Absolute floor on uniqueness (variance of cosines): below it an object is never unique."""
    hops: int = 1
    """Path length eta of the breadth-first 3D subgraph (paper: 1)."""
    oracle: bool = False
    """DIAGNOSTIC ONLY, not a method setting: match each query object to the landmark whose id equals its
    dataset instance id (with oracle masks, landmark ids are instance ids), skipping encoding, uniqueness,
    language and the scene graph. It measures the geometric stages (verification pose, coarse prior,
    refinement) independently of the encoder. Needs the oracle-mask track; results made with it are not OpenReLoc's."""

    def __post_init__(self) -> None:
        check_ranges(self, at_least_one=("top_k",), non_negative=("uniqueness_ratio", "min_uniqueness", "hops"))


@dataclass
class QueryObject:
    """One detected object of the query image with its embeddings."""

    mask: np.ndarray
    """bool (H, W)."""
    box: np.ndarray
    """[x0, y0, x1, y1] pixels (exclusive ends)."""
    visual: np.ndarray
    """(D,) unit visual embedding of its crop."""
    text: np.ndarray | None = None
    """(D,) unit text embedding of its phrase (None without the language modality)."""
    phrase: str | None = None
    """The describer's phrase."""
    instance_id: int | None = None
    """Ground-truth instance id when the segmenter knows it (diagnostics only)."""
    uniqueness: float = 0.0


@dataclass
class Match:
    """A query object associated with a landmark."""

    query: int
    """Index into the list of query objects."""
    landmark: int
    visual_sim: float
    text_sim: float | None
    how: str
    """'agree' (both top-1s equal), 'graph' (resolved by sub-graph matching), 'visual' (visual top-1),
    or 'fallback' (its first choice was taken by a more confident object)."""
    graph_score: float | None = None
    candidates: list[int] = field(default_factory=list)
    """The candidate set U (ranked) this match came from."""


def uniqueness(visual: np.ndarray, descriptors: np.ndarray) -> np.ndarray:
    """(Q,) variance of each query embedding's cosine similarities to all landmark descriptors (Eq. 3)."""
    if descriptors.shape[0] == 0:
        return np.zeros(len(visual))
    return np.var(np.asarray(visual) @ np.asarray(descriptors).T, axis=1)


def unique_mask(gammas: np.ndarray, cfg: AssociationConfig) -> np.ndarray:
    """Which objects are unique enough to match (see the module docstring for the rule)."""
    gammas = np.asarray(gammas, dtype=np.float64)
    if gammas.size == 0:
        return np.zeros(0, dtype=bool)
    limit = max(cfg.min_uniqueness, cfg.uniqueness_ratio * float(np.median(gammas)))
    return gammas >= limit


def query_neighbours(boxes: np.ndarray) -> list[list[int]]:
    """The 2D query subgraph: for each box, its nearest box (by centre distance) and every box that
    intersects it."""
    boxes = np.asarray(boxes, dtype=np.float64).reshape(-1, 4)
    n = len(boxes)
    if n < 2:
        return [[] for _ in range(n)]
    centres = (boxes[:, :2] + boxes[:, 2:]) / 2
    dist = np.linalg.norm(centres[:, None] - centres[None], axis=-1)
    np.fill_diagonal(dist, np.inf)
    ix = np.minimum(boxes[:, None, 2], boxes[None, :, 2]) > np.maximum(boxes[:, None, 0], boxes[None, :, 0])
    iy = np.minimum(boxes[:, None, 3], boxes[None, :, 3]) > np.maximum(boxes[:, None, 1], boxes[None, :, 1])
    inter = ix & iy
    np.fill_diagonal(inter, False)
    return [sorted(set(np.flatnonzero(inter[i]).tolist()) | {int(np.argmin(dist[i]))}) for i in range(n)]


def landmark_neighbours(graph: nx.Graph, landmark: int, hops: int, allowed: set[int]) -> list[int]:
    """The breadth-first 3D subgraph of ``landmark`` (within ``hops`` edges), without itself,
    restricted to ``allowed`` landmarks."""
    if landmark not in graph:
        return []
    reach = nx.single_source_shortest_path_length(graph, landmark, cutoff=hops)
    return sorted(n for n in reach if n != landmark and n in allowed)


def subgraph_similarity(query_feats: np.ndarray, landmark_feats: np.ndarray) -> float:
    """Total cosine similarity of the optimal one-to-one assignment between the two neighbour sets."""
    if len(query_feats) == 0 or len(landmark_feats) == 0:
        return 0.0
    sim = np.asarray(query_feats) @ np.asarray(landmark_feats).T
    rows, cols = linear_sum_assignment(sim, maximize=True)
    return float(sim[rows, cols].sum())


def associate(
    objects: list[QueryObject],
    landmark_ids: list[int],
    descriptors: np.ndarray,
    graph: nx.Graph | None,
    cfg: AssociationConfig,
    invalid: frozenset[int] | set[int] = frozenset(),
) -> list[Match]:
    """Match query objects (already filtered for uniqueness) to landmarks ``landmark_ids`` whose
    descriptors are the rows of ``descriptors``. ``graph=None`` disables sub-graph matching; objects
    without ``text`` use the visual modality only. Returns at most one match per object and landmark.

    ``invalid`` landmarks (removed by invalid-object filtering) still compete, but an object whose
    choice is one of them is dropped (it is a wall or floor itself) and fallbacks never pick them."""
    if not objects or not landmark_ids:
        return []
    ids = np.asarray(landmark_ids)
    row_of = {int(lid): r for r, lid in enumerate(landmark_ids)}
    allowed = set(row_of)
    k = min(cfg.top_k, len(ids))
    vis_sim = np.stack([o.visual for o in objects]) @ descriptors.T  # (Q, N)
    neighbours = query_neighbours(np.stack([o.box for o in objects]))

    proposals: list[tuple[tuple[int, float], Match]] = []
    for qi, obj in enumerate(objects):
        o_vis = [int(i) for i in ids[np.argsort(-vis_sim[qi], kind="stable")[:k]]]
        txt = None if obj.text is None else descriptors @ obj.text
        o_txt = [] if txt is None else [int(i) for i in ids[np.argsort(-txt, kind="stable")[:k]]]
        v1 = o_vis[0]
        graph_score = None
        if o_txt and o_txt[0] == v1:
            ranked, how = o_vis, "agree"
        else:
            u = sorted(set(o_vis) & set(o_txt) | {v1} | set(o_txt[:1]), key=lambda i: -vis_sim[qi, row_of[i]])
            if len(u) == 1 or graph is None:
                ranked, how = u, "visual"
            else:
                qfeats = (
                    np.stack([objects[j].visual for j in neighbours[qi]])
                    if neighbours[qi]
                    else np.zeros((0, descriptors.shape[1]))
                )
                scores = {
                    c: vis_sim[qi, row_of[c]]
                    + subgraph_similarity(
                        qfeats, descriptors[[row_of[n] for n in landmark_neighbours(graph, c, cfg.hops, allowed)]]
                    )
                    for c in u
                }
                ranked, how = sorted(u, key=lambda c: -scores[c]), "graph"
                graph_score = float(scores[ranked[0]])
        # the fallback order after the chosen set: the rest of the visual ranking
        fallback = [int(i) for i in ids[np.argsort(-vis_sim[qi], kind="stable")] if int(i) not in ranked]
        match = Match(
            query=qi,
            landmark=ranked[0],
            visual_sim=float(vis_sim[qi, row_of[ranked[0]]]),
            text_sim=None if txt is None else float(txt[row_of[ranked[0]]]),
            how=how,
            graph_score=graph_score,
            candidates=ranked + fallback[: max(0, cfg.top_k - len(ranked))],
        )
        if match.landmark in invalid:
            continue
        match.candidates = [c for c in match.candidates if c not in invalid]
        proposals.append(((int(how == "agree"), match.visual_sim), match))

    taken: set[int] = set()
    out: list[Match] = []
    for _, m in sorted(proposals, key=lambda p: (-p[0][0], -p[0][1], p[1].query)):
        choice = next((c for c in m.candidates if c not in taken), None)
        if choice is None:
            continue
        if choice != m.landmark:
            obj = objects[m.query]
            m = Match(
                query=m.query,
                landmark=choice,
                visual_sim=float(vis_sim[m.query, row_of[choice]]),
                text_sim=None if obj.text is None else float(descriptors[row_of[choice]] @ obj.text),
                how="fallback",
                candidates=m.candidates,
            )
        taken.add(choice)
        out.append(m)
    return sorted(out, key=lambda m: m.query)


def oracle_matches(
    objects: list[QueryObject], landmark_ids: list[int], invalid: frozenset[int] | set[int] = frozenset()
) -> list[Match]:
    """DIAGNOSTIC: the ground-truth association (``AssociationConfig.oracle``): each object whose
    dataset instance id is a (valid) landmark id is matched to it. Objects without an instance id,
    or whose instance is not in the map, stay unmatched."""
    known = set(landmark_ids) - set(invalid)
    return [
        Match(
            query=qi,
            landmark=int(o.instance_id),
            visual_sim=float("nan"),
            text_sim=None,
            how="oracle",
            candidates=[int(o.instance_id)],
        )
        for qi, o in enumerate(objects)
        if o.instance_id is not None and int(o.instance_id) in known
    ]


def segment_query(
    rgb: np.ndarray, instance: np.ndarray | None, segmenter: Segmenter, gt_segmenter: Segmenter, min_area: int
) -> tuple[list[ObjectMask], np.ndarray]:
    """The query's masks of at least ``min_area`` pixels, those to match (the dataset's on the oracle-mask
    track, else the segmenter's), and the union of all of them (every segment occludes)."""
    masks = gt_segmenter.segment(rgb, instance) if instance is not None else segmenter.segment(rgb)
    occluders = np.zeros(rgb.shape[:2], bool)
    for mk in masks:
        occluders |= mk.mask
    return [mk for mk in masks if int(mk.mask.sum()) >= min_area], occluders


class Associator:
    """The association ready for queries: the map's landmarks (``ids``, their ``descriptors`` as rows) and
    scene graph (None: the no-scene-graph ablation), the map's encoder with the padding of its crops, the
    describer (None: the no-language ablation) with the text encoder of its phrases, and the settings:
    ``cfg``, and the fewest and most query objects matched."""

    def __init__(
        self,
        ids: list[int],
        descriptors: np.ndarray,
        graph: nx.Graph | None,
        encoder: ImageTextEncoder,
        padding: float,
        describer: Describer | None,
        text_encoder: ImageTextEncoder,
        cfg: AssociationConfig,
        min_objects: int,
        max_objects: int,
    ):
        self.ids, self.descriptors, self.graph = ids, descriptors, graph
        self.encoder, self.padding = encoder, padding
        self.describer, self.text_encoder = describer, text_encoder
        self.cfg, self.min_objects, self.max_objects = cfg, min_objects, max_objects

    def embed(self, rgb: np.ndarray, masks: list[ObjectMask]) -> np.ndarray:
        """(masks, D) image embeddings of the masks' padded crops."""
        h, w = rgb.shape[:2]
        crops = [rgb[y0:y1, x0:x1] for x0, y0, x1, y1 in (pad_box(mk.box, self.padding, w, h) for mk in masks)]
        return self.encoder.encode_images(crops)

    def associate(
        self,
        rgb: np.ndarray,
        masks: list[ObjectMask],
        oracle_track: bool,
        invalid: frozenset[int],
        diag: dict[str, Any],
        stage: Stage,
    ) -> tuple[list[QueryObject], list[Match], np.ndarray | None] | Failure:
        """The query objects (at most ``max_objects``), their matches to landmarks, and every mask's visual
        similarity to every landmark (none for the oracle association, which matches by instance id, on
        the oracle-mask track only). A Failure with fewer than ``min_objects`` unique objects."""
        if self.cfg.oracle:
            if not oracle_track:
                return Failure("association.oracle (a diagnostic) needs the oracle-mask track", diag)
            largest = sorted(range(len(masks)), key=lambda i: -int(masks[i].mask.sum()))[: self.max_objects]
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
            # association sees every landmark; filtered ones (walls, floor) only veto the query
            # objects that look most like them, instead of forcing those onto a valid look-alike
            matches = associate(objects, self.ids, self.descriptors, self.graph, self.cfg, invalid)
        return objects, matches, appearance

    def _objects(
        self, rgb: np.ndarray, masks: list[ObjectMask], diag: dict[str, Any], stage: Stage
    ) -> tuple[list[QueryObject], np.ndarray] | Failure:
        """Embed the query objects, keep the most unique ones and describe them (paper section 3.2); also
        every mask's visual similarity to every landmark."""
        with stage("encode"):
            visual = self.embed(rgb, masks)
            gammas = uniqueness(visual, self.descriptors)
            keep = np.flatnonzero(unique_mask(gammas, self.cfg))
            keep = keep[np.argsort(-gammas[keep], kind="stable")][: self.max_objects]
        objects = [_query_object(masks[i], visual[i], float(gammas[i])) for i in sorted(keep.tolist())]
        diag["unique"] = len(objects)
        if len(objects) < self.min_objects:
            need = self.min_objects
            return Failure(f"{len(objects)} of {len(masks)} object(s) unique enough to match, need {need}", diag)
        with stage("describe"):
            if self.describer is not None:
                phrases = self.describer.describe_many(rgb, [o.mask for o in objects])
                for o, p, e in zip(objects, phrases, self.text_encoder.encode_texts(phrases)):
                    o.phrase, o.text = p, e
        return objects, visual @ self.descriptors.T


def _query_object(mk: ObjectMask, visual: np.ndarray, gamma: float) -> QueryObject:
    return QueryObject(
        mask=mk.mask,
        box=np.asarray(mk.box, dtype=np.float64),
        visual=visual,
        instance_id=mk.instance_id,
        uniqueness=gamma,
    )
