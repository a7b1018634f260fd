"""Lifting the frames' 2D masks to 3D instances of the scene point cloud (paper section 3.1, "Instance
Segmentation"), from what each frame sees of it (:mod:`.observation`):

- :func:`lift_by_voting` (oracle masks): every point takes the instance id it was seen under most
  often, if that id has enough votes and a large enough share of the point's views;
- :func:`lift_by_clustering` (noisy / predicted masks), after MaskClustering (Yan et al., CVPR
  2024): 2D masks are graph nodes; a frame *observes* a mask only where one of its masks contains
  it (a frame that missed or split the object neither observes nor supports it); masks split in
  many frames are under-segmented and dropped; two nodes are linked when a large share
  ("consensus rate") of their observers contain both in one mask; merging repeats with a
  decreasing requirement on the number of observers; finally each cluster keeps the points its
  masks detect in most of its frames (drops what dilated masks took from the background).
  All consensus counts are sparse-matrix products (masks x points incidence), not Python loops.

:mod:`.instances` chooses among them (and affinity grouping with repair) as a method configures it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from openreloc_bench.config import check_ranges
from openreloc_bench.reconstruction.incidence import incidence, sets_matrix, view_evidence
from openreloc_bench.reconstruction.observation import FrameObservation


@dataclass
class VotingConfig:
    """Oracle-mask lifting: per-point majority vote over the frames that see the point."""

    min_votes: int = 2
    """A point needs at least this many frames seeing it under the winning instance id."""
    min_share: float = 0.5
    """...and the winning id must hold at least this share of the point's views (background included)."""

    def __post_init__(self) -> None:
        check_ranges(self, at_least_one=("min_votes",), share=("min_share",))


@dataclass
class ClusteringConfig:
    """View-consensus clustering of 2D masks (MaskClustering-style, see :func:`lift_by_clustering`)."""

    min_mask_points: int = 10
    """2D masks covering fewer seen scene points are dropped (too small to lift reliably)."""
    visible_share: float = 0.3
    """A mask is visible in another frame when this share of its points lie inside that frame's masks."""
    containment: float = 0.8
    """...and contained there when one mask of that frame holds this share of them (else it is split)."""
    undersegment_share: float = 0.3
    """Masks split in more than this share of the frames they are visible in span several objects
    (under-segmentation): they are dropped and neither observe nor support other masks."""
    consensus: float = 0.9
    """Link two nodes when at least this share of the frames observing both contain them in one mask."""
    observer_percentiles: tuple[float, ...] = tuple(float(p) for p in range(95, -5, -5))
    """Merging rounds: a pair needs at least this percentile of all pairs' observer counts (decreasing)."""
    min_observers: int = 1
    """Never link two nodes observed together by fewer frames than this."""
    min_masks: int = 2
    """Final clusters made of fewer 2D masks are dropped (single-view noise)."""
    point_support: float = 0.5
    """A cluster keeps a point when the cluster's masks hold it in more than this share of the
    cluster's frames that see it (drops points that dilated masks picked up from the background)."""
    split_distance: float = 0.0
    """Clusters are split into parts connected at this distance (m); 0 (default) keeps them whole: on
    the smoke scene a 0.1 m split cut a table apart (precision 0.85 vs 0.89 whole) and on the box room
    it cut the floor at occlusion gaps (0.47 vs 0.80)."""
    min_part_share: float = 0.1
    """...and parts smaller than this share of the cluster's largest part are dropped as fragments."""
    nested_share: float = 0.8
    """A cluster with more than this share of its points inside a larger cluster is dropped."""

    def __post_init__(self) -> None:
        check_ranges(
            self,
            at_least_one=("min_masks",),
            non_negative=("min_mask_points", "min_observers", "split_distance"),
            share=(
                "visible_share",
                "containment",
                "undersegment_share",
                "consensus",
                "point_support",
                "min_part_share",
                "nested_share",
            ),
        )
        if any(not 0 <= p <= 100 for p in self.observer_percentiles):
            raise ValueError(f"'observer_percentiles' must be percentiles in [0, 100], got {self.observer_percentiles}")


def lift_by_voting(n_points: int, obs: list[FrameObservation], cfg: VotingConfig) -> np.ndarray:
    """(N,) int64 label per scene point (0 = unassigned) by majority over the frames that see it: the
    instance id seen most often (the smallest among equally frequent ones; background never wins), kept
    with at least ``min_votes`` and ``min_share`` of the point's views (background included)."""
    if not obs:
        return np.zeros(n_points, np.int64)
    pts = np.concatenate([o.point_idx for o in obs]).astype(np.int64)
    ids = np.concatenate([o.gt_ids for o in obs]).astype(np.int64)  # type: ignore[misc]
    return _vote(pts, ids, n_points, cfg.min_votes, cfg.min_share)


@numba.njit(cache=True, nogil=True)
def _vote(pts: np.ndarray, ids: np.ndarray, n_points: int, min_votes: int, min_share: float) -> np.ndarray:
    """:func:`lift_by_voting` over the (point, id) observations: grouped by point with a counting sort,
    then each point's few dozen ids counted in order. Compiled: a sparse (point x id) vote matrix over
    tens of millions of observations spent seconds in ``np.unique`` and its row-wise argmax."""
    views = np.zeros(n_points, np.int64)
    for p in pts:
        views[p] += 1
    start = np.zeros(n_points + 1, np.int64)
    start[1:] = np.cumsum(views)
    fill = start[:-1].copy()
    grouped = np.empty(len(ids), np.int64)
    for k in range(len(pts)):
        grouped[fill[pts[k]]] = ids[k]
        fill[pts[k]] += 1
    out = np.zeros(n_points, np.int64)
    for p in range(n_points):
        seen = np.sort(grouped[start[p] : start[p + 1]])
        best_id, best_n, i = 0, 0, 0
        while i < len(seen):
            j = i
            while j < len(seen) and seen[j] == seen[i]:
                j += 1
            if seen[i] != 0 and j - i > best_n:  # ascending ids: the smallest wins a tie
                best_id, best_n = seen[i], j - i
            i = j
        if best_n >= min_votes and best_n >= min_share * max(views[p], 1):
            out[p] = best_id
    return out


def lift_by_clustering(points: np.ndarray, obs: list[FrameObservation], cfg: ClusteringConfig) -> np.ndarray:
    """(N,) int64 cluster label per scene point (0 = unassigned), by view-consensus mask clustering.

    Steps (after MaskClustering, Yan et al. CVPR 2024): per-mask statistics over every frame
    (:func:`_mask_frame_stats`: where each mask is visible and which mask of that frame contains it;
    masks split in too many frames are under-segmented and removed), iterative merging with a
    decreasing observer threshold (:func:`_merge_nodes`), then per cluster: keep points detected in
    enough of the cluster's frames, split spatially disconnected parts, drop clusters nested in others.
    """
    n_points = len(points)
    views = view_evidence(n_points, obs, cfg.min_mask_points)
    n_masks = len(views.mask_frame)
    if not n_masks:
        return np.zeros(n_points, np.int64)
    visible, contained, keep = _mask_frame_stats(views.masks, views.mask_frame, len(obs), cfg)
    groups, visible = _merge_nodes(visible[keep], contained[keep], cfg)
    groups = groups @ incidence(np.arange(keep.sum()), np.flatnonzero(keep), (int(keep.sum()), n_masks))
    return _cluster_points(points, groups.tocsr(), visible.tocsr(), views.masks, views.seen, cfg)


def _mask_frame_stats(
    M: sp.csr_matrix, mask_frame: np.ndarray, n_frames: int, cfg: ClusteringConfig
) -> tuple[sp.csr_matrix, sp.csr_matrix, np.ndarray]:
    """(visible: masks x frames, contained: masks x masks, keep: masks that are not under-segmented).

    Points inside two masks of one frame are mask boundaries and ignored here. Mask m is visible in
    frame f when ``visible_share`` of its points lie in masks of f; it is contained there when one
    mask of f holds ``containment`` of those. ``visible`` keeps only frames where m is contained
    (a frame that splits m neither observes nor supports it).
    """
    n_masks = M.shape[0]
    frame_ind = incidence(mask_frame, np.arange(n_masks), (n_frames, n_masks))
    per_frame = (frame_ind @ M).tocsc()
    per_frame.data = (per_frame.data > 1).astype(np.float32)  # >1 mask of one frame holds the point
    boundary = np.asarray(per_frame.max(axis=0).todense()).ravel() > 0
    Mv = sp.csr_matrix(M.multiply(~boundary[None, :]))
    size = np.asarray(Mv.sum(axis=1)).ravel()
    C = (Mv @ Mv.T).tocoo()  # shared valid points of every mask pair
    m, k, n = C.row, C.col, C.data
    f = mask_frame[k]
    key = m.astype(np.int64) * n_frames + f
    order = np.lexsort((-n, key))
    key, m, k, n, f = key[order], m[order], k[order], n[order], f[order]
    start = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
    covered = np.add.reduceat(n, start)
    gm, gf, gk, best = m[start], f[start], k[start], n[start]  # first of each group = best mask
    vis = covered >= cfg.visible_share * size[gm]
    con = vis & (best >= cfg.containment * covered)
    n_vis = np.bincount(gm[vis], minlength=n_masks)
    n_split = np.bincount(gm[vis & ~con], minlength=n_masks)
    under = (n_vis == 0) | (n_split > cfg.undersegment_share * n_vis)
    con &= ~under[gk]  # an under-segmented mask neither observes nor supports the masks it holds
    visible = incidence(gm[con], gf[con], (n_masks, n_frames))
    contained = incidence(gm[con], gk[con], (n_masks, n_masks))
    return visible, contained, ~under


def _merge_nodes(
    visible: sp.csr_matrix, contained: sp.csr_matrix, cfg: ClusteringConfig
) -> tuple[sp.csr_matrix, sp.csr_matrix]:
    """Iterative view-consensus merging; returns (nodes x input masks membership, nodes x frames visible).

    Observers of a pair = frames where both are visible (contained); supporters = masks containing
    both. Pairs with consensus >= ``consensus`` merge; the observer-count requirement falls from the
    95th percentile of all pairs' counts to 0, so that well-observed pairs are decided first.
    """
    groups = sp.identity(visible.shape[0], format="csr", dtype=np.float32)
    observers = (visible @ visible.T).tocsr()
    counts = observers.data[observers.data > 0]
    if len(counts) == 0:
        return groups, visible
    thresholds = []
    for q in cfg.observer_percentiles:
        t = float(np.percentile(counts, q))
        if t <= 1:
            if q < 50:
                break
            t = 1.0
        thresholds.append(max(t, float(cfg.min_observers)))
    for thr in thresholds:
        observers = (visible @ visible.T).tocsr()
        S = (contained @ contained.T).tocsr()
        observers.data[observers.data < thr] = 0
        observers.eliminate_zeros()
        # link where supporters >= consensus * observers, on pairs with enough observers
        observers = observers.tocoo()
        sup = np.asarray(S[observers.row, observers.col]).ravel()
        ok = (observers.row != observers.col) & (sup >= cfg.consensus * observers.data)
        if not ok.any():
            continue
        link = sp.coo_matrix((np.ones(int(ok.sum())), (observers.row[ok], observers.col[ok])), shape=observers.shape)
        n_comp, comp = connected_components(link, directed=False)
        merge = incidence(comp, np.arange(len(comp)), (n_comp, len(comp)))
        groups = _binary(merge @ groups)
        visible = _binary(merge @ visible)
        contained = _binary(merge @ contained)
    return groups, visible


def _cluster_points(
    points: np.ndarray,
    groups: sp.csr_matrix,
    visible: sp.csr_matrix,
    M: sp.csr_matrix,
    seen: sp.csr_matrix,
    cfg: ClusteringConfig,
) -> np.ndarray:
    """Point labels from mask clusters: detection-ratio filter, connectivity split, nesting removal."""
    n_masks_per = np.asarray(groups.sum(axis=1)).ravel()
    seen_pf = seen.T.tocsr()  # points x frames
    objects: list[tuple[np.ndarray, np.ndarray]] = []  # (point idx, detection ratio)
    for c in np.flatnonzero(n_masks_per >= cfg.min_masks):
        hits = groups[c] @ M  # 1 x points: how many of the cluster's masks hold each point
        idx = hits.indices
        frames = visible[c].indices
        den = np.asarray(seen_pf[idx][:, frames].sum(axis=1)).ravel()
        ratio = hits.data / np.maximum(den, 1)
        ok = ratio > cfg.point_support
        idx, ratio = idx[ok], ratio[ok]
        parts = _connected_parts(points[idx], cfg.split_distance)
        largest = max((len(p) for p in parts), default=0)
        objects += [(idx[p], ratio[p]) for p in parts if len(p) >= cfg.min_part_share * largest]
    objects = _drop_nested(objects, cfg.nested_share)
    best = np.zeros(len(points))
    labels = np.zeros(len(points), np.int64)
    for lab, (idx, ratio) in enumerate(objects, start=1):
        win = ratio > best[idx]
        labels[idx[win]] = lab
        best[idx[win]] = ratio[win]
    return labels


def _connected_parts(pts: np.ndarray, eps: float) -> list[np.ndarray]:
    """Index sets of the parts of a point set connected at about distance ``eps`` (all when eps <= 0).

    Connectivity is computed on occupied cells of edge eps/2 (linked when their centres are within
    eps), not on the points: a 40k-point floor has a few thousand cells.
    """
    if eps <= 0 or len(pts) < 2:
        return [np.arange(len(pts))]
    cells, inv = np.unique(np.floor(pts / (eps / 2)).astype(np.int64), axis=0, return_inverse=True)
    inv = inv.ravel()
    pairs = cKDTree(cells.astype(np.float64)).query_pairs(2.0 + 1e-6, output_type="ndarray")
    g = sp.coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(len(cells), len(cells)))
    n, comp = connected_components(g, directed=False)
    point_comp = comp[inv]
    order = np.argsort(point_comp, kind="stable")
    return np.split(order, np.flatnonzero(np.diff(point_comp[order])) + 1)


def _drop_nested(objects: list[tuple[np.ndarray, np.ndarray]], share: float) -> list[tuple[np.ndarray, np.ndarray]]:
    """Drop objects whose points lie mostly (> ``share``) inside another, larger object."""
    if len(objects) < 2:
        return objects
    n_points = 1 + max(int(o[0].max(initial=0)) for o in objects)
    A = sets_matrix([o[0] for o in objects], n_points)
    inter = (A @ A.T).tocoo()
    size = np.array([len(o[0]) for o in objects])
    i, j, n = inter.row, inter.col, inter.data
    nested = (i != j) & (n > share * size[i]) & ((size[i] < size[j]) | ((size[i] == size[j]) & (i > j)))
    drop = set(i[nested].tolist())
    return [o for k, o in enumerate(objects) if k not in drop]


def _binary(m: sp.spmatrix) -> sp.csr_matrix:
    m = sp.csr_matrix(m, dtype=np.float32)
    m.data[:] = 1.0
    return m


def instance_sets(labels: np.ndarray, min_points: int) -> dict[int, np.ndarray]:
    """Label -> sorted point indices, for labels with at least ``min_points`` points (one sort, not a scan per label)."""
    fg = np.flatnonzero(labels > 0)
    order = fg[np.argsort(labels[fg], kind="stable")]
    ids, start, count = np.unique(labels[order], return_index=True, return_counts=True)
    return {int(i): order[s : s + c] for i, s, c in zip(ids, start, count) if c >= min_points}
