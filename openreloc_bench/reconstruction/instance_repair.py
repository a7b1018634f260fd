"""Repairing the predicted track's 3D instances with every view and the fused geometry.

View-consensus clustering (:func:`.lifting.lift_by_clustering`) keeps only what a segmenter's masks
agree on across views. On a learned segmenter's masks that leaves objects in pure but partial pieces
(a desk as its top and legs, a wall cut at a doorway) and a sixth of the object points unassigned:
on the validation apartments most clusters are pieces of one object. Two optional steps repair it
(both off by default, where affinity grouping, :mod:`affinity_grouping`, makes the instances):

1. **fill** (:func:`fill_from_masks`): every 2D mask whose clustered points mostly belong to one
   instance votes that instance onto all of its points; a point joins the instance that most of the
   masks holding it vote for. Points cut off by the clustering's filters come back where the views
   agree on them. It helps clustering; after affinity grouping it hurts.
2. **merge** (:func:`merge_instances`): instances that touch in 3D are joined where a classifier over
   their shared border says they are one object. The features (:data:`FEATURES`) use what mapping
   has and a query does not: how often one mask holds both across the views that see both, the
   segmenter's boundary strength along the border averaged over every view, the border's shape
   (normals, convex or concave), colour, and the two instances' sizes. The classifier is a logistic
   regression trained on training-range scenes, where the true instances are free
   (:mod:`openreloc_bench.harness.merger_training`, ``train-merger``); rounds of merging and filling
   repeat until nothing changes. Off by default: on the validation apartments it raised instance precision but joined
   objects that localization needs apart (``docs/experiments.md``).

Measured with ``openreloc-bench diagnose``: with either grouping, objects merged into a neighbour
(mostly small ones the segmenter never separates from their support) are the largest error. The
masks hold no evidence against such merges; affinity grouping splits objects off walls and floors
with the depth's (:mod:`plane_split`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import scipy.sparse as sp
from scipy.optimize import minimize
from scipy.spatial import cKDTree

from openreloc_bench.config import check_ranges
from openreloc_bench.data import mapfile
from openreloc_bench.errors import DataError
from openreloc_bench.reconstruction.incidence import ViewEvidence, incidence, view_evidence
from openreloc_bench.reconstruction.plane_split import point_normals

MERGER_FORMAT = ("openreloc-merger", 1)
MERGER_FILE = "merger.json"
DEFAULT_MERGER = Path(__file__).parent.parent / "vision" / "weights" / "merger"

FEATURES = (
    "mask_support",
    "log_co_observers",
    "boundary_border",
    "boundary_contrast",
    "normal_alignment",
    "convex_share",
    "concave_share",
    "colour_border",
    "colour_instances",
    "log_size_small",
    "log_size_large",
    "contact_share",
    "thickness_small",
    "thickness_large",
    "extent_small",
    "extent_large",
    "height_overlap",
)
"""Per pair of touching instances, in this order (see :func:`border_features`)."""


@dataclass
class RepairConfig:
    """Repairing grouped instances (predicted track): fill, then classifier merges."""

    fill: bool = False
    """Re-vote every point through the 2D masks that hold it (see :func:`fill_from_masks`). Off: it
    repairs view-consensus clustering (``grouping: clustering``), which leaves points unassigned, but
    after affinity grouping, which assigns them all, it hands small objects to the masks that merge
    them into their support (docs/experiments.md)."""
    fill_purity: float = 0.6
    """A mask votes for an instance when this share of its clustered points belong to it."""
    fill_share: float = 0.5
    """A point joins an instance when at least this share of the masks holding it vote for it."""
    merge: bool = False
    """Join touching instances the merge classifier calls one object. Off: on the validation
    apartments it raises the map's instance precision but merges objects that localization needs
    apart (docs/experiments.md)."""
    merge_threshold: float = 0.85
    """...when its probability is above this."""
    merge_rounds: int = 12
    """At most this many rounds of merge + fill (features are recomputed on the merged instances)."""
    merger: str = ""
    """Directory of the merge classifier (``merger.json``); empty: the shipped one."""
    contact_radius: float = 0.045
    """Points of two instances closer than this (m) form their shared border (~2 fusion voxels)."""
    min_seen: int = 20
    """An instance counts as seen by a frame with at least this many of its points in view."""
    hold_share: float = 0.5
    """A mask holds an instance in a frame when it contains this share of the instance's seen points."""

    def __post_init__(self) -> None:
        check_ranges(
            self,
            share=("fill_purity", "fill_share", "merge_threshold", "hold_share"),
            positive=("contact_radius",),
            non_negative=("merge_rounds", "min_seen"),
        )


@dataclass
class PointAttributes:
    """What every view says about each scene point, averaged over the views that see it."""

    boundary: np.ndarray
    """(N,) mean segmenter boundary strength at the point's pixel."""
    rgb: np.ndarray
    """(N, 3) mean colour."""
    normals: np.ndarray
    """(N, 3) unit normals, facing a camera that saw the point."""


def point_attributes(points: np.ndarray, obs: list, camera_centres: np.ndarray) -> PointAttributes:
    """Boundary strength and colour averaged over the views (observations need ``boundary`` and ``rgb``),
    and normals from 16 neighbours, oriented towards a camera that saw the point."""
    n = len(points)
    idx = np.concatenate([o.point_idx for o in obs]).astype(np.int64)
    count = np.maximum(np.bincount(idx, minlength=n), 1).astype(np.float64)
    boundary = np.bincount(idx, np.concatenate([o.boundary for o in obs]).astype(np.float64), n) / count
    colour = np.concatenate([o.rgb for o in obs]).astype(np.float64)
    rgb = np.stack([np.bincount(idx, colour[:, c], n) for c in range(3)], 1) / count[:, None]
    normals = point_normals(points)
    cam = np.zeros((n, 3))
    for o in obs:
        cam[o.point_idx] = camera_centres[o.index]
    normals[np.einsum("ij,ij->i", cam - points, normals) < 0] *= -1
    return PointAttributes(boundary, rgb, normals)


def fill_from_masks(labels: np.ndarray, views: ViewEvidence, purity: float, share: float) -> np.ndarray:
    """Labels re-voted through the masks: a mask votes for the instance holding ``purity`` of its
    labelled points; a point takes the instance with the most votes when they are at least ``share`` of
    the masks holding it (else it is unassigned). Instance ids are kept."""
    onehot, ids = _onehot(labels)
    if len(ids) == 0 or views.masks.shape[0] == 0:
        return labels.copy()
    per_mask = (views.masks @ onehot).tocsr()  # masks x instances: labelled points held
    total = np.asarray(per_mask.sum(axis=1)).ravel()
    best = np.asarray(per_mask.argmax(axis=1)).ravel()
    top = np.asarray(per_mask.max(axis=1).todense()).ravel()
    votes_for = np.flatnonzero((total > 0) & (top >= purity * total))
    vote = incidence(votes_for, best[votes_for], (len(total), len(ids)))
    votes = (views.masks.T @ vote).tocsr()  # points x instances
    held = np.asarray(views.masks.sum(axis=0)).ravel()
    most = np.asarray(votes.max(axis=1).todense()).ravel()
    winner = np.asarray(votes.argmax(axis=1)).ravel()
    return np.where((most > 0) & (most >= share * held), ids[winner], 0).astype(np.int64)


@dataclass
class BorderPairs:
    """The pairs of touching instances and their features."""

    first: np.ndarray
    """(P,) one instance id of each pair."""
    second: np.ndarray
    """(P,) the other instance id."""
    features: np.ndarray
    """(P, len(FEATURES)) float64."""


def border_features(
    points: np.ndarray,
    labels: np.ndarray,
    attrs: PointAttributes,
    views: ViewEvidence,
    neighbours: np.ndarray,
    cfg: RepairConfig,
) -> BorderPairs:
    """Features (:data:`FEATURES`) of every pair of instances with points closer than the contact radius
    (``neighbours``: the (K, 2) point pairs within it)."""
    onehot, ids = _onehot(labels)
    col = np.searchsorted(ids, labels)  # instance column per labelled point
    i, j = neighbours[:, 0], neighbours[:, 1]
    cross = (labels[i] > 0) & (labels[j] > 0) & (labels[i] != labels[j])
    i, j = i[cross], j[cross]
    a, b = col[i], col[j]
    flip = a > b
    i, j = np.where(flip, j, i), np.where(flip, i, j)
    a, b = np.minimum(a, b), np.maximum(a, b)
    k = len(ids)
    keys, pair_of, contact = np.unique(a.astype(np.int64) * k + b, return_inverse=True, return_counts=True)
    A, B = keys // k, keys % k
    if len(keys) == 0:
        return BorderPairs(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, len(FEATURES))))

    def border_mean(v: np.ndarray) -> np.ndarray:
        return np.bincount(pair_of, v, len(keys)) / contact

    size = np.asarray(onehot.sum(axis=0)).ravel()
    inst_boundary = (onehot.T @ attrs.boundary) / size
    inst_rgb = (onehot.T @ attrs.rgb) / size[:, None]
    lo, hi = _instance_boxes(points, labels, col, k)
    ext = hi - lo
    thickness, extent = ext.min(axis=1), np.linalg.norm(ext, axis=1)
    nrm_i, nrm_j = attrs.normals[i], attrs.normals[j]
    d = points[i] - points[j]
    d /= np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-9)
    convexity = np.einsum("ij,ij->i", nrm_i - nrm_j, d)
    support, co_observers = _mask_support(onehot, views, cfg, A, B)
    small = np.where(size[A] <= size[B], A, B)
    large = np.where(size[A] <= size[B], B, A)
    border_boundary = border_mean((attrs.boundary[i] + attrs.boundary[j]) / 2)
    F = np.column_stack(
        [
            support,
            np.log1p(co_observers),
            border_boundary,
            border_boundary - (inst_boundary[A] + inst_boundary[B]) / 2,
            border_mean(np.abs(np.einsum("ij,ij->i", nrm_i, nrm_j))),
            border_mean((convexity > 0.05).astype(np.float64)),
            border_mean((convexity < -0.05).astype(np.float64)),
            border_mean(np.linalg.norm(attrs.rgb[i] - attrs.rgb[j], axis=1)) / 255,
            np.linalg.norm(inst_rgb[A] - inst_rgb[B], axis=1) / 255,
            np.log(size[small]),
            np.log(size[large]),
            contact / size[small],
            thickness[small],
            thickness[large],
            extent[small],
            extent[large],
            np.minimum(hi[A, 2], hi[B, 2]) - np.maximum(lo[A, 2], lo[B, 2]),
        ]
    )
    return BorderPairs(ids[A], ids[B], F)


def _mask_support(
    onehot: sp.csr_matrix, views: ViewEvidence, cfg: RepairConfig, A: np.ndarray, B: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Per pair: share of the frames seeing both in which one mask holds both, and that frame count."""
    seen = (views.seen @ onehot).tocsr()  # frames x instances: points in view
    held = (views.masks @ onehot).tocoo()  # masks x instances
    in_view = np.asarray(seen[views.mask_frame[held.row], held.col]).ravel()
    ok = (held.data >= cfg.hold_share * in_view) & (in_view >= cfg.min_seen)
    H = incidence(held.row[ok], held.col[ok], held.shape)
    visible = seen.copy()
    visible.data = (visible.data >= cfg.min_seen).astype(np.float32)
    visible.eliminate_zeros()
    both_held = np.asarray((H.T @ H).tocsr()[A, B]).ravel()
    co_observers = np.asarray((visible.T @ visible).tocsr()[A, B]).ravel()
    return both_held / np.maximum(co_observers, 1), co_observers


def _instance_boxes(points: np.ndarray, labels: np.ndarray, col: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    fg = np.flatnonzero(labels > 0)
    lo, hi = np.full((k, 3), np.inf), np.full((k, 3), -np.inf)
    np.minimum.at(lo, col[fg], points[fg])
    np.maximum.at(hi, col[fg], points[fg])
    return lo, hi


@dataclass
class MergeClassifier:
    """Logistic regression over standardised :data:`FEATURES`: p(one object | border features)."""

    mean: np.ndarray
    scale: np.ndarray
    weights: np.ndarray
    bias: float
    card: dict[str, Any]
    """How it was trained (scenes, pairs, held-out accuracy)."""

    def probability(self, features: np.ndarray) -> np.ndarray:
        z = ((features - self.mean) / self.scale) @ self.weights + self.bias
        return 1.0 / (1.0 + np.exp(-z))

    def save(self, directory: Path) -> None:
        body = {
            "features": list(FEATURES),
            "mean": self.mean.tolist(),
            "scale": self.scale.tolist(),
            "weights": self.weights.tolist(),
            "bias": self.bias,
            "card": self.card,
        }
        mapfile.write_file_set(directory, *MERGER_FORMAT, {MERGER_FILE: mapfile.json_bytes(body)})

    @classmethod
    def load(cls, directory: Path) -> MergeClassifier:
        hint = "train one with `openreloc-bench train-merger --out DIR`"
        try:
            blobs = mapfile.read_file_set(directory, *MERGER_FORMAT, {MERGER_FILE})
        except DataError as e:
            raise DataError(e.path, f"{e.problem}; {hint}") from None
        body = mapfile.load_json(blobs[MERGER_FILE], directory / MERGER_FILE)
        if body.get("features") != list(FEATURES):
            raise DataError(directory / MERGER_FILE, f"made for other features than this version's; {hint}")
        return cls(
            np.asarray(body["mean"], np.float64),
            np.asarray(body["scale"], np.float64),
            np.asarray(body["weights"], np.float64),
            float(body["bias"]),
            dict(body.get("card", {})),
        )


def fit_merger(features: np.ndarray, same: np.ndarray, l2: float = 1.0) -> MergeClassifier:
    """Logistic regression (L2 on the weights, classes weighted to equal total) by L-BFGS."""
    mean = features.mean(axis=0)
    scale = np.where(features.std(axis=0) > 1e-9, features.std(axis=0), 1.0)
    X = (features - mean) / scale
    y = same.astype(np.float64)
    w_pos = 0.5 / max(y.mean(), 1e-9)
    w_neg = 0.5 / max(1 - y.mean(), 1e-9)
    sample_w = np.where(y > 0, w_pos, w_neg) / len(y)

    def loss(theta: np.ndarray) -> tuple[float, np.ndarray]:
        z = X @ theta[:-1] + theta[-1]
        p = 1.0 / (1.0 + np.exp(-z))
        nll = np.sum(sample_w * (np.logaddexp(0, z) - y * z))
        g = sample_w * (p - y)
        grad = np.r_[X.T @ g + l2 * theta[:-1] / len(y), g.sum()]
        return nll + 0.5 * l2 * theta[:-1] @ theta[:-1] / len(y), grad

    theta = minimize(loss, np.zeros(X.shape[1] + 1), jac=True, method="L-BFGS-B").x
    return MergeClassifier(mean, scale, theta[:-1], float(theta[-1]), {})


def merge_instances(
    points: np.ndarray,
    labels: np.ndarray,
    attrs: PointAttributes,
    views: ViewEvidence,
    classifier: MergeClassifier,
    cfg: RepairConfig,
) -> np.ndarray:
    """Rounds of greedy merging: the pairs the classifier calls one object, most likely first, each
    instance joined at most once per round (so no chain of pairs merges in one step, and every merge
    is judged again on the merged instances' features next round), then fill; until no pair merges or
    ``merge_rounds`` is reached."""
    neighbours = cKDTree(points).query_pairs(cfg.contact_radius, output_type="ndarray")
    for _ in range(cfg.merge_rounds):
        pairs = border_features(points, labels, attrs, views, neighbours, cfg)
        p = classifier.probability(pairs.features)
        into: dict[int, int] = {}
        for k in np.argsort(-p, kind="stable"):
            if p[k] <= cfg.merge_threshold:
                break
            a, b = int(pairs.first[k]), int(pairs.second[k])
            if a not in into and b not in into:
                into[a] = into[b] = min(a, b)  # the merged instance keeps the smaller id
        if not into:
            break
        ids = np.unique(labels)
        new_id = np.array([into.get(int(i), int(i)) for i in ids], np.int64)
        labels = new_id[np.searchsorted(ids, labels)]
        if cfg.fill:
            labels = fill_from_masks(labels, views, cfg.fill_purity, cfg.fill_share)
    return labels


def repair_instances(
    points: np.ndarray,
    labels: np.ndarray,
    obs: list,
    camera_centres: np.ndarray,
    cfg: RepairConfig,
    min_mask_points: int,
) -> np.ndarray:
    """Fill, then merge (see the module docstring), as ``cfg`` enables them."""
    if not (cfg.fill or cfg.merge) or not obs:
        return labels
    views = view_evidence(len(points), obs, min_mask_points)
    if cfg.fill:
        labels = fill_from_masks(labels, views, cfg.fill_purity, cfg.fill_share)
    if cfg.merge:
        if any(o.boundary is None for o in obs):
            raise ValueError("merging instances needs the observations' boundary strength and colour")
        classifier = load_merger(cfg.merger)
        attrs = point_attributes(points, obs, camera_centres)
        labels = merge_instances(points, labels, attrs, views, classifier, cfg)
    return labels


def load_merger(directory: str) -> MergeClassifier:
    return MergeClassifier.load(Path(directory) if directory else DEFAULT_MERGER)


def _onehot(labels: np.ndarray) -> tuple[sp.csr_matrix, np.ndarray]:
    """(points x instances) incidence of the labelled points, and the instance ids of its columns."""
    fg = np.flatnonzero(labels > 0)
    ids, col = np.unique(labels[fg], return_inverse=True)
    return incidence(fg, col.ravel(), (len(labels), len(ids))), ids
