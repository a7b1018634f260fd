"""Geometric verification of the association (beyond the paper; ``VerifyConfig.enabled=False`` is literal).

The paper resolves ambiguous matches by appearance, language and the scene graph only. With an
encoder weaker than CLIP ViT-L/14 the true landmark is often among the visual top-5 but not the
top-1, and a single wrong match is enough to drag the 2D ICP away. Objects have positions and extents, though:
the true matches are the ones consistent with *one* camera pose. In the spirit of GOReloc's
object-level RANSAC, this stage samples three query objects, one candidate landmark each (the
association's choice most often; the further candidates favour the landmarks of the reference
frames that look most like the query: ``place_frames``; the second and third favour landmarks that a
reference frame sees with the first: ``covisible_weight``), solves P3P from mask centroids to landmark
centres (the likeliest triples' poses are also fitted to their three mask boxes: ``fitted_triples``),
and scores every pose by how well it explains the objects: the box of a candidate's projected extreme
points must overlap its mask's box (IoU >= ``min_iou``); the score sums each object's best IoU,
discounted by the candidate's rank (``rank_weight``). The best-scoring distinct poses are locally
optimised (LO-RANSAC): the pose is fitted to its inliers' mask boxes (:mod:`.box_fit`), the inliers
re-collected, and the poses ranked again by their score after it. The best one's inlier matches
replace the association's, with the pose added as a coarse hypothesis. ``VerifyConfig.modes`` > 1
keeps the next distinct consensus sets too; those whose pose renders closest to the query
(``refined_modes``) become hypotheses refined against their own matches.

Why the box fit: P3P on centroids is biased, because a mask's centroid is not where its landmark's
centre projects (the image border cuts the object, others occlude it, its back is unseen). So a
query for which three right matches are drawn may still get no sampled pose near the truth, and the
true pose may score higher than the winning one. Re-fitting the best poses to the mask boxes, and
drawing objects cut by the border less often, recovers many of those queries. The local optimisation
only starts from poses that already explain three masks, though, and a right triple's centroid pose
often explains only one or two: fitting the likeliest triples' poses to their own boxes before
scoring (``fitted_triples``) gives those starts.

Hand-written because OpenCV's ``solvePnPRansac`` assumes one correspondence per 2D point; here each
object brings several candidate landmarks, of which at most one may be used.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np
from scipy.spatial.transform import Rotation

from openreloc_bench import geometry
from openreloc_bench.config import check_ranges
from openreloc_bench.openreloc.association import Match, QueryObject
from openreloc_bench.openreloc.box_fit import extreme_points, fit_boxes_many
from openreloc_bench.openreloc.coarse_prior import place_landmarks, solve_pnp
from openreloc_bench.openreloc.hypotheses import Hypothesis
from openreloc_bench.openreloc.map import ObjectMap
from openreloc_bench.vision.preprocess import touches_border


@dataclass
class VerifyConfig:
    """Object-level RANSAC over candidate matches (see the module docstring)."""

    enabled: bool = True
    """Beyond the paper: verify the association geometrically (False = the paper's association only)."""
    candidates: int = 8
    """Candidate landmarks per query object: the association's choice, then its visual ranking (the true
    landmark is often a few ranks down; more candidates need more samples to be drawn right)."""
    samples: int = 3200
    """Minimal samples (three objects, one candidate each) drawn; each gives up to four P3P poses. A
    failed query often has four or more objects whose true landmark is a candidate, but ranked below
    first, so few random triples are all right: more samples find them, at a cost linear in the count."""
    min_iou: float = 0.3
    """An object is explained by a candidate when the image box of the landmark at the pose overlaps
    the mask's box by at least this IoU (occlusion shrinks masks, so it is lenient)."""
    min_inliers: int = 3
    """Fewer explained objects than this: verification gives up and the association stands (3: queries
    with four or five objects often have only three right candidates; the render-and-compare choice
    after refinement rejects a wrong three-object pose)."""
    refits: int = 2
    """Local optimisation rounds: re-fit the pose to the inliers and re-collect them."""
    box_fit: bool = True
    """Local optimisation fits the pose to the inliers' mask boxes (their projected extreme points onto
    each box's edges, robustly; sides cut by the image border only bound) instead of re-solving PnP on
    mask centroids. A centroid is not the projection of the landmark's centre (occlusion, the unseen
    back of the object), so a P3P pose from three right matches is often a metre off."""
    lo_poses: int = 32
    """Best-scoring sampled poses (at least ``mode_separation`` apart) given local optimisation; the
    modes are chosen among them by their score after it. Each costs a local optimisation; the right
    pose is sometimes not among the first few best-scoring raw poses."""
    rank_weight: float = 0.8
    """An object's overlap with its k-th candidate counts ``rank_weight ** k`` in a pose's score and in the
    choice of its inlier (1 = every candidate alike). With eight candidates per object, almost any pose
    finds *some* look-alike overlapping most masks, and a wrong consensus of deep candidates outscored
    the right one built on the association's choices. Fewer poses then reach the local optimisation's
    score bar, which also saves time."""
    fitted_triples: int = 64
    """The first distinct triples drawn (the likeliest: mostly the association's choices) whose P3P poses
    are also fitted to the triple's three mask boxes (:func:`fit_boxes_many`) and scored besides: P3P on
    mask centroids is biased, and a right triple's raw pose often explains too few masks to be among
    the ``lo_poses`` starts of the local optimisation. Each fit is a small Gauss-Newton solve, so only
    the likeliest triples get one."""
    place_frames: int = 3
    """A place prior on the candidates: after the association's choice (``place_keeps_choice``), rank each
    object's candidates by appearance plus ``place_bonus`` for the landmarks that the ``place_frames``
    reference frames looking most like the query see (:func:`~.coarse_prior.place_landmarks`); 0 = the
    association's candidates, then the visual cosine. A look-alike in another room is the usual wrong
    candidate, and the place ranking puts the true landmark first more often than the visual cosine or
    the association's choice do, so more missed queries get three right candidates to draw."""
    place_bonus: float = 0.1
    """Added to the appearance score of a candidate that one of the ``place_frames`` frames sees (cosines
    of right and wrong candidates differ by a few hundredths; 0.2 ranked the true landmark lower)."""
    place_keeps_choice: bool = True
    """With ``place_frames`` > 0, the association's first candidate (its choice, unless another object took
    that landmark) stays each object's first, the place prior's ranking following it (False: the ranking
    alone, which follows a wrongly retrieved place all the way: on val3 a 4-inlier consensus of
    another room's look-alikes beat the association's own 8-inlier one)."""
    text_weight: float = 0.3
    """Weight of the describer's phrase (text cosine) beside the visual cosine in the place prior's
    candidate ranking and frame scores (the phrase separates look-alikes of another colour or material)."""
    covisible_weight: float = 0.1
    """Guided sampling: a triple's second and third candidates are drawn with their chance times this factor
    unless some reference frame sees them together with the triple's earlier ones (1 = unguided). A
    query's objects are in view together, so some reference frame almost always sees its true landmarks
    together, and far less often a look-alike from another room with them: the guided draw makes an
    all-right triple likelier. It also repeats triples more often, and each distinct one is solved once."""
    truncated_weight: float = 0.25
    """Relative chance of drawing an object cut by the image border into a sample: its mask centroid is
    far from where its landmark's centre projects, so P3P on it is biased."""
    box_scale: float = 10.0
    """Pixels: box-edge residuals beyond this count linearly (Huber), so an occluded side does not drag."""
    modes: int = 16
    """Poses kept from the RANSAC, each with its own inliers: the best after local optimisation, then the
    next best whose camera is at least ``mode_separation`` from every kept one and whose inliers differ
    from every kept one's. With ``hypothesis``, the best and the ``refined_modes`` - 1 further ones that
    render-and-compare best are refined against their own matches (in the coarse hypotheses' batch:
    :func:`~.refine.refine_poses`' ``target_sets``) and compete in the render-and-compare choice. It adds
    coverage where the best consensus is a wrong set of look-alikes: on failed queries the truth is more
    often near one of the best few modes than near the best one. 1 = the best consensus only. The local
    optimisation keeps at most ``lo_poses`` poses, so modes beyond it add nothing."""
    refined_modes: int = 3
    """Modes refined: the best one always, then the further modes whose *unrefined* pose explains the query
    masks best by render-and-compare (``consistency``; with it off, the RANSAC's next best). Drawing a
    pose is far cheaper than refining it, so many modes can be screened for the price of a few. A mode's
    local optimisation already fits its boxes, so its drawing is close to its refined one's."""
    mode_separation: float = 1.0
    """Metres between the camera centres of two kept modes (a closer pose refines into the same one)."""
    hypothesis: bool = True
    """Add the verified pose to the coarse stage's hypotheses. False keeps only its matches: with
    ``coarse.top_frames: 1, coarse.pnp: false`` the refinement then starts from the paper's single
    reference-frame prior, so the retrieval ranking decides (the single-prior ablation rows)."""

    def __post_init__(self) -> None:
        check_ranges(
            self,
            positive=("box_scale",),
            at_least_one=("candidates", "samples", "min_inliers", "lo_poses", "modes", "refined_modes"),
            non_negative=(
                "refits",
                "fitted_triples",
                "place_frames",
                "place_bonus",
                "text_weight",
                "truncated_weight",
                "mode_separation",
            ),
            share=("min_iou", "rank_weight"),
        )
        # zero or negative chances would draw padding or nonsense triples without any error
        if not 0.0 < self.covisible_weight <= 1.0:
            raise ValueError(f"covisible_weight must be in (0, 1], got {self.covisible_weight}")


@dataclass
class Verification:
    """The verified matches and the pose that explains them."""

    assignment: dict[int, int]
    """Query object index -> landmark row (into the landmark arrays given to :func:`verify_matches`)."""
    T_wc: np.ndarray
    """(4, 4) camera-to-world pose consistent with every assigned match."""
    hypotheses: int
    """P3P poses scored."""
    alternatives: list[Verification] = field(default_factory=list)
    """The next modes (``VerifyConfig.modes`` - 1 at most), best first; each explains its own matches."""

    @property
    def inliers(self) -> int:
        return len(self.assignment)


@dataclass
class ObjectEvidence:
    """What verification needs from one query object."""

    mask: np.ndarray
    """bool (H, W)."""
    candidates: list[int]
    """Landmark rows, most likely first."""


class Verifier:
    """The verification ready for queries: a map's landmarks as rows (``ids``, their ``descriptors``) with
    their centres and extreme points, which landmarks each reference frame sees (the place prior) and
    which pairs some reference frame sees together (the guided sampling); and the settings: ``cfg``,
    ``oracle`` (the association is the true one, whose matches are certain: the RANSAC only finds the pose
    they support, and no look-alikes), ``no_coarse`` (the ablation without the coarse stage's hypotheses)
    and the RANSAC's ``seed``."""

    def __init__(
        self,
        m: ObjectMap,
        ids: list[int],
        descriptors: np.ndarray,
        cfg: VerifyConfig,
        oracle: bool,
        no_coarse: bool,
        seed: int,
    ):
        self.ids, self.descriptors = ids, descriptors
        self.cfg, self.oracle, self.no_coarse, self.seed = cfg, oracle, no_coarse, seed
        self.centers = np.array([m.landmarks[i].center for i in ids], dtype=np.float64).reshape(-1, 3)
        self.extremes = np.array([extreme_points(m.landmarks[i].points) for i in ids]).reshape(len(ids), -1, 3)
        # (frames, landmarks): which landmarks each reference frame sees (the place prior)
        self.frame_visibility = np.array([[i in f.boxes for i in ids] for f in m.reference_frames], dtype=bool).reshape(
            len(m.reference_frames), len(ids)
        )
        # (landmarks, landmarks): which pairs some reference frame sees together (the guided sampling)
        seen = self.frame_visibility.astype(np.float32)
        self.covisible = (seen.T @ seen) > 0

    def verify(
        self,
        matches: list[Match],
        objects: list[QueryObject],
        invalid: frozenset[int],
        K: np.ndarray,
        diag: dict[str, Any],
    ) -> tuple[list[Match], np.ndarray | None, list[Hypothesis]]:
        """Object-level RANSAC over the matched objects' candidates (:func:`verification_evidence`): the
        matches one pose explains, and that pose; the association unchanged when none does. Third: the
        further modes, each with its own matches, with ``modes`` > 1."""
        cfg = self.cfg
        matched = {mt.query: mt for mt in matches}
        sims = np.stack([o.visual for o in objects]) @ self.descriptors.T
        n_candidates = 1 if self.oracle else cfg.candidates
        place = cfg.place_frames > 0 and not self.oracle
        evidence = verification_evidence(
            objects,
            matched,
            self.place_scores(objects, sims, invalid) if place else sims,
            self.ids,
            invalid,
            n_candidates,
            lead=int(cfg.place_keeps_choice) if place else None,
        )
        if not cfg.hypothesis or self.no_coarse:  # further modes come only with the verified pose: skip their search
            cfg = dataclasses.replace(cfg, modes=1)
        result = verify_matches(evidence, self.centers, self.extremes, K, cfg, seed=self.seed, covisible=self.covisible)
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

    def place_scores(self, objects: list[QueryObject], sims: np.ndarray, invalid: frozenset[int]) -> np.ndarray:
        """(objects, landmarks) candidate scores with the place prior (``place_frames``): visual plus
        weighted text cosine, plus ``place_bonus`` where one of the reference frames looking most like the
        query sees the landmark."""
        cfg = self.cfg
        scores = sims.astype(np.float64)
        if all(o.text is not None for o in objects):
            scores = scores + cfg.text_weight * (np.stack([o.text for o in objects]) @ self.descriptors.T)
        scores[:, [r for r, i in enumerate(self.ids) if i in invalid]] = -np.inf
        return scores + cfg.place_bonus * place_landmarks(scores, self.frame_visibility, cfg.place_frames)


def verification_evidence(
    objects: list[QueryObject],
    matched: dict[int, Match],
    scores: np.ndarray,
    ids: list[int],
    invalid: frozenset[int],
    n_candidates: int,
    lead: int | None = None,
) -> list[ObjectEvidence]:
    """Each query object's candidate landmark rows for the verification (``matched``: query index -> its
    association match): the first ``lead`` of its association candidates (all with None), then its ranking
    by ``scores`` (object x landmark row: the visual cosine, or the place prior's), without invalid
    landmarks. Objects the association left out get none: it drops an object whose best landmark is a
    filtered wall or floor (the object is one), and the verification must not give it a look-alike
    instead (a wall re-matched to a fan or a window drags the pose)."""
    row_of = {lid: r for r, lid in enumerate(ids)}
    out = []
    for q, o in enumerate(objects):
        rows: list[int] = []
        if q in matched:
            first = [row_of[c] for c in matched[q].candidates[:lead]]
            ranked = dict.fromkeys(first + np.argsort(-scores[q], kind="stable").tolist())
            rows = [r for r in ranked if ids[r] not in invalid][:n_candidates]
        out.append(ObjectEvidence(o.mask, rows))
    return out


def verify_matches(
    objects: list[ObjectEvidence],
    centers: np.ndarray,
    extremes: np.ndarray,
    K: np.ndarray,
    cfg: VerifyConfig,
    seed: int = 0,
    covisible: np.ndarray | None = None,
) -> Verification | None:
    """Object-level RANSAC; ``centers`` (N, 3) and ``extremes`` (N, E, 3) describe the landmarks,
    indexed by the rows in ``ObjectEvidence.candidates``, and ``covisible`` (N, N) bool which of them a
    reference frame sees together (for ``covisible_weight``). None when no pose explains ``min_inliers``."""
    usable = [q for q, o in enumerate(objects) if o.candidates and o.mask.any()]
    if len(usable) < max(3, cfg.min_inliers):
        return None
    K = np.asarray(K, dtype=np.float64)
    table = _CandidateTable(objects, usable, cfg.candidates, centers, extremes, K, cfg)
    R, t = _sample_poses(table, K, cfg.samples, np.random.default_rng(seed), covisible)
    if not len(R):
        return None
    iou = table.overlaps(R, t)
    scores = table.score(iou)
    cameras = -np.einsum("kji,kj->ki", R, t)  # camera centres in the world
    starts: list[int] = []  # the best-scoring poses, each at least mode_separation from every better one
    for k in np.argsort(-scores, kind="stable"):
        # below this score fewer than min_inliers objects are explained, or only by lower-ranked
        # candidates (each inlier adds at least min_iou times its rank weight)
        if len(starts) >= max(1, cfg.lo_poses) or scores[k] < cfg.min_inliers * cfg.min_iou:
            break
        if all(np.linalg.norm(cameras[k] - cameras[j]) >= cfg.mode_separation for j in starts):
            starts.append(k)
    optimised = [c for c in _consensus(table, iou[starts], scores[starts], R[starts], t[starts], centers, K, cfg) if c]
    kept: list[Verification] = []
    for assignment, T_wc, _ in sorted(optimised, key=lambda c: -c[2]):
        if len(kept) >= max(1, cfg.modes):
            break
        if all(
            assignment != v.assignment and np.linalg.norm(T_wc[:3, 3] - v.T_wc[:3, 3]) >= cfg.mode_separation
            for v in kept
        ):  # local optimisation can land two starts on one mode
            kept.append(Verification(assignment, T_wc, hypotheses=len(R)))
    if not kept:
        return None
    kept[0].alternatives = kept[1:]
    return kept[0]


def _consensus(
    table: _CandidateTable,
    iou: np.ndarray,
    scores: np.ndarray,
    R: np.ndarray,
    t: np.ndarray,
    centers: np.ndarray,
    K: np.ndarray,
    cfg: VerifyConfig,
) -> list[tuple[dict[int, int], np.ndarray, float] | None]:
    """(assignment, T_wc, score) of each sampled pose k (R[k], t[k] world to camera, ``iou[k]`` its row of
    overlaps, ``scores[k]`` its score): its inliers, the pose re-fitted to them while that raises the
    score (LO-RANSAC); None below ``min_inliers``. The poses' refits run side by side, one batch a round."""
    assignments = [table.assign(row) for row in iou]
    score = [float(v) for v in scores]
    R, t = R.copy(), t.copy()
    going = list(range(len(R)))  # poses whose last refit raised their score
    for _ in range(cfg.refits):
        if cfg.box_fit:
            ready = [k for k in going if len(assignments[k]) >= 3]
            fits = table.fit_boxes([table.flat_indices(assignments[k]) for k in ready], R[ready], t[ready])
        else:
            ready = [k for k in going if len(assignments[k]) >= 4]
            fits = []
            for k in ready:
                a = assignments[k]
                T = solve_pnp(centers[list(a.values())], np.array([table.centroid[q] for q in a]), K)
                fits.append(None if T is None else (T[:3, :3], T[:3, 3]))
        refit = [(k, fit) for k, fit in zip(ready, fits) if fit is not None]
        if not refit:
            break
        new_iou = table.overlaps(np.stack([fit[0] for _, fit in refit]), np.stack([fit[1] for _, fit in refit]))
        new_scores = table.score(new_iou)
        going = []
        for (k, fit), row, new_score in zip(refit, new_iou, new_scores):
            if float(new_score) > score[k]:
                assignments[k], (R[k], t[k]), score[k] = table.assign(row), fit, float(new_score)
                going.append(k)
    return [
        (a, geometry.invert(geometry.make_pose(R[k], t[k])), score[k]) if len(a) >= cfg.min_inliers else None
        for k, a in enumerate(assignments)
    ]


class _CandidateTable:
    """All (object, candidate landmark) pairs flattened, with what scoring needs per pair."""

    def __init__(
        self,
        objects: list[ObjectEvidence],
        usable: list[int],
        k: int,
        centers: np.ndarray,
        extremes: np.ndarray,
        K: np.ndarray,
        cfg: VerifyConfig,
    ):
        h, w = objects[usable[0]].mask.shape
        self.K, self.size, self.cfg = K, (w, h), cfg
        self.centroid: dict[int, np.ndarray] = {}
        self.truncated: dict[int, bool] = {}
        rows, obj, rank, boxes = [], [], [], []
        for q in usable:
            ys, xs = np.nonzero(objects[q].mask)
            self.centroid[q] = np.array([xs.mean(), ys.mean()])
            self.truncated[q] = touches_border(objects[q].mask)
            for r, c in enumerate(objects[q].candidates[:k]):
                rows.append(c)
                obj.append(q)
                rank.append(r)
                boxes.append([xs.min(), ys.min(), xs.max() + 1, ys.max() + 1])
        self.rows, self.obj, self.rank = np.array(rows), np.array(obj), np.array(rank)
        self.weight = cfg.rank_weight**self.rank
        self.box = np.array(boxes, dtype=np.float64)
        self.X = np.asarray(centers, np.float64)[self.rows]
        self.E = np.asarray(extremes, np.float64)[self.rows]
        self.E_by_extreme = np.ascontiguousarray(self.E.transpose(2, 1, 0)).reshape(3, -1)  # (3, E*M)
        self.by_object = {q: np.flatnonzero(self.obj == q) for q in usable}
        self.pair = {(q, r): m for m, (q, r) in enumerate(zip(obj, rows))}  # (object, landmark row) -> flat index
        self.usable = usable

    def fit_boxes(
        self, flat: list[np.ndarray], R: np.ndarray, t: np.ndarray
    ) -> list[tuple[np.ndarray, np.ndarray] | None]:
        """For each start s: (R, t) world to camera, started at (R[s], t[s]), whose projected boxes of the
        candidates ``flat[s]`` (flat indices) best fit their masks' boxes (:func:`fit_boxes_many`)."""
        if not flat:
            return []
        idx = np.zeros((len(flat), max(len(f) for f in flat)), np.int64)
        valid = np.zeros(idx.shape, bool)
        for s, f in enumerate(flat):
            idx[s, : len(f)], valid[s, : len(f)] = f, True
        R_fit, t_fit, ok = fit_boxes_many(
            self.E[idx], self.box[idx], valid, self.K, self.size, R, t, self.cfg.box_scale
        )
        return [(R_fit[s], t_fit[s]) if ok[s] else None for s in range(len(flat))]

    def flat_indices(self, assignment: dict[int, int]) -> np.ndarray:
        """The flat candidate indices of an assignment (object -> landmark row)."""
        return np.array([self.pair[q, row] for q, row in assignment.items()])

    def overlaps(self, R: np.ndarray, t: np.ndarray, chunk: int = 64) -> np.ndarray:
        """(H, M) IoU of each candidate's projected box with its mask's box at each pose (R, t world to
        camera), times the candidate's rank weight; 0 below ``min_iou`` or when the landmark reaches
        behind the camera."""
        out = np.zeros((len(R), len(self.rows)))
        w, h = self.size
        (fx, cx), (fy, cy) = self.K[0, [0, 2]], self.K[1, [1, 2]]
        n_ext, n_cand = self.E.shape[1], self.E.shape[0]
        for s in range(0, len(R), chunk):
            # (h, 3, E, M) camera coordinates by one matrix product, the extreme points' axis before the
            # candidates': the min / max over it combine contiguous rows (over a last axis of 14 they took
            # half the time); ~2 MB chunks, which stay in cache.
            n = min(chunk, len(R) - s)
            Xc = (
                (R[s : s + chunk].reshape(-1, 3) @ self.E_by_extreme).reshape(n, 3, -1) + t[s : s + chunk, :, None]
            ).reshape(n, 3, n_ext, n_cand)
            z = Xc[:, 2]
            ahead = z > 0.05
            front = ahead.all(1)
            zs = np.where(ahead, z, 1.0)
            # the principal point is added after the min / max: rounding is monotonic, so the box is the same
            u, v = fx * Xc[:, 0] / zs, fy * Xc[:, 1] / zs
            x0, x1 = np.clip(u.min(1) + cx, 0, w), np.clip(u.max(1) + cx, 0, w)
            y0, y1 = np.clip(v.min(1) + cy, 0, h), np.clip(v.max(1) + cy, 0, h)
            b = self.box
            inter = np.clip(np.minimum(x1, b[:, 2]) - np.maximum(x0, b[:, 0]), 0, None) * np.clip(
                np.minimum(y1, b[:, 3]) - np.maximum(y0, b[:, 1]), 0, None
            )
            union = (x1 - x0) * (y1 - y0) + (b[:, 2] - b[:, 0]) * (b[:, 3] - b[:, 1]) - inter
            iou = np.where(front, inter / np.maximum(union, 1e-9), 0.0)
            out[s : s + chunk] = np.where(iou >= self.cfg.min_iou, iou, 0.0) * self.weight
        return out

    def score(self, iou: np.ndarray) -> np.ndarray:
        """(H,) sum over objects of their best candidate's (rank-weighted) IoU."""
        return sum((iou[:, idx].max(1) for idx in self.by_object.values()), np.zeros(len(iou)))

    def assign(self, iou: np.ndarray) -> dict[int, int]:
        """Object -> landmark row at one pose: each object's best-overlapping candidate (rank-weighted),
        each landmark used once (largest overlap first)."""
        out: dict[int, int] = {}
        used: set[int] = set()
        for m in np.argsort(-iou, kind="stable"):
            if iou[m] <= 0:
                break
            q, row = int(self.obj[m]), int(self.rows[m])
            if q in out or row in used:
                continue
            out[q] = row
            used.add(row)
        return out


def draw_triples(
    table: _CandidateTable, samples: int, rng: np.random.Generator, covisible: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """``samples`` random triples: (samples, 3) indices into ``table.usable`` and (samples, 3) flat
    candidate indices. Objects are drawn in proportion to their weight (``truncated_weight``), each one's
    candidate with probability halving per rank (the association's choice about half the time); the
    second and third candidates' chances are multiplied by ``covisible_weight`` unless ``covisible`` (N, N)
    says some reference frame sees them with the earlier ones. Vectorised: per-sample ``rng.choice``
    was half of the verification."""
    usable = table.usable
    k = max(len(table.by_object[q]) for q in usable)
    slots = np.zeros((len(usable), k), np.int64)  # per usable object: its flat candidate indices, padded
    prob = np.zeros((len(usable), k))  # their unnormalised chances, 0 on padding
    for i, q in enumerate(usable):
        idx = table.by_object[q]
        slots[i, : len(idx)] = idx
        prob[i, : len(idx)] = 0.5 ** table.rank[idx]
    weight = np.array([table.cfg.truncated_weight if table.truncated[q] else 1.0 for q in usable])
    # three distinct objects, drawn with probability proportional to weight (Gumbel top-k)
    objs = np.argsort(-(np.log(weight) + rng.gumbel(size=(samples, len(usable)))), axis=1)[:, :3]
    draws = rng.random((samples, 3))
    guided = covisible is not None and table.cfg.covisible_weight != 1.0
    flat = np.empty((samples, 3), np.int64)
    for j in range(3):
        p = prob[objs[:, j]]  # (samples, k)
        if guided and j:
            rows = table.rows[slots[objs[:, j]]]  # (samples, k) landmark rows
            seen = np.logical_and.reduce([covisible[table.rows[flat[:, i]][:, None], rows] for i in range(j)])
            p = p * np.where(seen, 1.0, table.cfg.covisible_weight)
        cdf = np.cumsum(p, axis=1)
        pick = (draws[:, j, None] * cdf[:, -1:] >= cdf).sum(1)
        flat[:, j] = slots[objs[:, j], np.minimum(pick, (p > 0).sum(1) - 1)]  # never a padded slot
    return objs, flat


def _sample_poses(
    table: _CandidateTable, K: np.ndarray, samples: int, rng: np.random.Generator, covisible: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """P3P poses, R_cw (H, 3, 3) and t_cw (H, 3), from :func:`draw_triples`; only the P3P solves loop.
    The poses of the first ``fitted_triples`` distinct triples drawn come a second time, fitted to the
    triple's three mask boxes."""
    usable = table.usable
    objs, flat = draw_triples(table, samples, rng, covisible)
    rows = table.rows[flat]
    X = table.X[flat]
    distinct = (rows[:, 0] != rows[:, 1]) & (rows[:, 0] != rows[:, 2]) & (rows[:, 1] != rows[:, 2])
    spread = np.linalg.norm(np.cross(X[:, 1] - X[:, 0], X[:, 2] - X[:, 0]), axis=1) >= 1e-4  # not collinear
    valid = np.flatnonzero(distinct & spread)
    _, first = np.unique(np.sort(flat[valid], axis=1), axis=0, return_index=True)
    to_fit = set(valid[np.sort(first)][: table.cfg.fitted_triples].tolist())  # the likeliest distinct triples
    centroids = np.stack([table.centroid[q] for q in usable])
    poses: list[tuple[np.ndarray, np.ndarray] | int] = []  # (rvec, tvec), or the index of a box fit to come
    fit_from: list[tuple[int, np.ndarray, np.ndarray]] = []  # (sample, R, t) starts of the box fits
    solved: set[tuple[int, ...]] = set()
    for s in valid:
        if (triple := tuple(flat[s].tolist())) in solved:  # drawn again: the same poses, solved and scored once
            continue
        solved.add(triple)
        try:
            n, rv, tv = cv2.solveP3P(
                X[s].reshape(-1, 1, 3), centroids[objs[s]].reshape(-1, 1, 2), K, None, flags=cv2.SOLVEPNP_P3P
            )
        except cv2.error:
            continue
        poses += [(r.reshape(1, 3), v.reshape(1, 3)) for r, v in zip(rv[:n], tv[:n])]
        if s in to_fit:
            for r, v in zip(rv[:n], tv[:n]):
                if np.isfinite(r).all() and np.isfinite(v).all():
                    poses.append(len(fit_from))
                    fit_from.append((s, cv2.Rodrigues(r)[0], v.reshape(3)))
    fits = table.fit_boxes(
        [flat[s] for s, _, _ in fit_from],
        np.array([R for _, R, _ in fit_from]).reshape(-1, 3, 3),
        np.array([t for _, _, t in fit_from]).reshape(-1, 3),
    )
    rvecs, tvecs = [np.zeros((0, 3))], [np.zeros((0, 3))]
    for pose in poses:
        if isinstance(pose, int):
            if fits[pose] is None:
                continue
            pose = cv2.Rodrigues(fits[pose][0])[0].reshape(1, 3), fits[pose][1].reshape(1, 3)
        rvecs.append(pose[0])
        tvecs.append(pose[1])
    rv, tv = np.concatenate(rvecs), np.concatenate(tvecs)
    finite = np.isfinite(rv).all(1) & np.isfinite(tv).all(1)
    return Rotation.from_rotvec(rv[finite]).as_matrix().reshape(-1, 3, 3), tv[finite]
