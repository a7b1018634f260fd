"""Grouping the scene points into instances by how often the views' masks hold neighbours together.

The predicted track's alternative to view-consensus clustering (:func:`.lifting.lift_by_clustering`),
in the spirit of superpoint methods (SAI3D, Open3DIS) but with the scene's own points as atoms:

1. **Edge evidence** (:func:`edge_evidence`): for every pair of neighbouring scene points, count the
   frames that see both and the frames where one 2D mask holds both. Their ratio is the pair's
   *affinity*. A segmenter that cuts an object at varying places in
   different views still holds most neighbouring pairs together in most views; a true object border
   separates them in most views.
2. **Seeds**: points joined by edges of affinity >= ``seed_affinity`` (seen together at least
   ``seed_min_views`` times) form seed regions: pure, but many and small.
3. **Agglomeration** (:func:`agglomerate`): adjacent regions merge best first while the affinity
   pooled over all edges of their shared border (sum of "held together" over sum of "seen together")
   stays >= ``merge_affinity``. Pooling over the whole border makes a few leaking edges harmless,
   which connected components at one threshold are not (one chain of bad edges joins two objects).
4. **Structural planes** (:mod:`plane_split`): regions holding a wall or floor plane keep it, and
   what stands out of it (a sink the views never cut from its wall) becomes regions of its own.
5. **Absorption**: regions smaller than ``min_region_area`` (slivers along mask borders) join the
   large neighbour they have the highest pooled affinity with, or are left unassigned if they touch
   none.
6. **Supports** (:mod:`plane_split`): small parts standing on a region's top surface (a mug the views
   never cut from its cabinet) become regions of their own, after the absorption, which would hand
   them back.

Every point the views see in masks ends in an instance, so nothing is lost to consensus filters. What
the segmenter never separates in any view stays merged unless the geometry separates it (steps 4
and 6), and parts of one object that no view sees side by side (a floor broken by furniture where the walk-through
is sparse) stay apart: the evidence is only between neighbouring points, so the grouping needs the
dense views of a walk-through (hundreds of frames), not a handful.
"""

from __future__ import annotations

import heapq
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from openreloc_bench.config import check_ranges
from openreloc_bench.reconstruction.plane_split import (
    PlaneSplitConfig,
    SupportSplitConfig,
    split_off_planes,
    split_off_supported,
)


@dataclass
class AffinityConfig:
    """Affinity grouping of the segmenter's masks: two neighbouring scene points belong together in the
    share of the views seeing both where one mask holds both; regions grow while that share, pooled
    over their whole border, stays high."""

    neighbour_spacings: float = 1.5
    """Scene points closer than this many point spacings (the fusion voxel) are neighbours whose
    affinity is counted: 1.5 takes the diagonal neighbours of the point grid."""
    min_mask_points: int = 10
    """2D masks holding fewer seen scene points count as holding none (too small to trust)."""
    seed_affinity: float = 0.97
    """Neighbours held together in at least this share of the frames seeing both start one region."""
    seed_min_views: int = 3
    """...when at least this many frames see both."""
    merge_affinity: float = 0.8
    """Adjacent regions merge while the affinity pooled over their shared border is at least this
    (lower: fewer, larger instances; chosen on the validation scenes, ``docs/experiments.md``)."""
    min_region_area: float = 0.08
    """Regions of fewer points than cover this area (m^2) at the point spacing join their best large
    neighbour (slivers along mask borders)."""
    planes: PlaneSplitConfig = field(default_factory=PlaneSplitConfig)
    """Splitting objects off the structural planes (walls, floors) they were grouped with."""
    supports: SupportSplitConfig = field(default_factory=SupportSplitConfig)
    """Splitting small objects off the furniture tops they stand on."""

    def __post_init__(self) -> None:
        check_ranges(
            self,
            positive=("neighbour_spacings",),
            non_negative=("min_mask_points", "seed_min_views", "min_region_area"),
            share=("seed_affinity", "merge_affinity"),
        )


def lift_by_affinity(points: np.ndarray, obs: list, cfg: AffinityConfig, spacing: float) -> np.ndarray:
    """(N,) int64 instance label per scene point (0 = unassigned), numbered 1.. in order of first point;
    ``spacing``: the scene cloud's point spacing (m), the fusion voxel."""
    if len(points) == 0:
        return np.zeros(0, np.int64)
    edges = cKDTree(points).query_pairs(cfg.neighbour_spacings * spacing, output_type="ndarray")
    both, same = edge_evidence(len(points), obs, edges, cfg.min_mask_points)
    strong = (same >= cfg.seed_affinity * both) & (both >= max(cfg.seed_min_views, 1))
    seeds = sp.coo_matrix((np.ones(int(strong.sum())), edges[strong].T), shape=(len(points),) * 2)
    regions = connected_components(seeds, directed=False)[1]
    regions = agglomerate(regions, edges, both, same, cfg.merge_affinity)
    regions = split_off_planes(points, regions, edges, cfg.planes, spacing)
    regions = absorb_small(regions, edges, both, same, round(cfg.min_region_area / spacing**2))
    regions = split_off_supported(points, regions, edges, cfg.supports, spacing)
    labels = np.zeros(len(points), np.int64)
    kept = regions >= 0
    _, first, inverse = np.unique(regions[kept], return_index=True, return_inverse=True)
    labels[kept] = np.argsort(np.argsort(first))[inverse] + 1
    return labels


def edge_evidence(n_points: int, obs: list, edges: np.ndarray, min_mask_points: int) -> tuple[np.ndarray, np.ndarray]:
    """Per edge (pair of point indices): frames seeing both ends, and frames where one mask holds both.

    ``obs``: :class:`.observation.FrameObservation` with the segmenter's masks. A seen point outside every
    (large enough) mask is seen but held by no mask: it counts against its edges."""
    both = np.zeros(len(edges), np.int32)
    same = np.zeros(len(edges), np.int32)
    mask_of = np.full(n_points, -1, np.int32)  # per frame: -1 unseen, 0 seen in no mask, k mask k
    i, j = edges[:, 0], edges[:, 1]
    for o in obs:
        mask_of[o.point_idx] = 0
        for k, m in enumerate(o.masks, start=1):
            if len(m) >= min_mask_points:
                mask_of[o.point_idx[m]] = k
        mi, mj = mask_of[i], mask_of[j]
        seen = (mi >= 0) & (mj >= 0)
        both += seen
        same += seen & (mi == mj) & (mi > 0)
        mask_of[o.point_idx] = -1
    return both, same


def border_counts(
    regions: np.ndarray, edges: np.ndarray, both: np.ndarray, same: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Pairs of adjacent regions (first < second) with the sums of ``same`` and ``both`` over the edges
    of their shared border."""
    n = int(regions.max(initial=0)) + 1
    a, b = regions[edges[:, 0]], regions[edges[:, 1]]
    cross = (a != b) & (a >= 0) & (b >= 0)
    lo, hi = np.minimum(a[cross], b[cross]), np.maximum(a[cross], b[cross])
    keys, inverse = np.unique(lo.astype(np.int64) * n + hi, return_inverse=True)
    return (
        keys // n,
        keys % n,
        np.bincount(inverse, same[cross], len(keys)),
        np.bincount(inverse, both[cross], len(keys)),
    )


def agglomerate(regions: np.ndarray, edges: np.ndarray, both: np.ndarray, same: np.ndarray, stop: float) -> np.ndarray:
    """Merge adjacent regions, highest pooled border affinity first, while it is >= ``stop``; returns
    each point's final region (the id of one of its merged seeds).

    Written here because what it needs is average linkage on a sparse region graph whose linkage is a
    ratio of sums: scipy's hierarchy needs all pairwise distances (10^9 for 40k seeds), and
    scikit-image's RAG merging, which custom callbacks could bend to it, is not a dependency and walks
    a networkx graph in Python per merge."""
    first, second, s, b = border_counts(regions, edges, both, same)
    border: dict[int, dict[int, list[float]]] = {}
    for x, y, sx, bx in zip(first.tolist(), second.tolist(), s.tolist(), b.tolist()):
        border.setdefault(x, {})[y] = border.setdefault(y, {})[x] = [sx, bx]
    heap = [(-sx / bx, x, y) for x, y, sx, bx in zip(first.tolist(), second.tolist(), s.tolist(), b.tolist()) if bx > 0]
    heapq.heapify(heap)
    parent = np.arange(int(regions.max(initial=0)) + 1)
    while heap:
        neg, x, y = heapq.heappop(heap)
        if -neg < stop:
            break
        e = border.get(x, {}).get(y)
        if e is None or e[0] / e[1] != -neg:  # merged away, or the border grew since it was queued
            continue
        parent[y] = x  # y's neighbours become x's, their borders summed
        del border[x][y]
        for z, (sz, bz) in border.pop(y).items():
            if z == x:
                continue
            del border[z][y]
            ex = border[x].get(z)
            if ex is None:
                ex = border[x][z] = border[z][x] = [0.0, 0.0]
            ex[0] += sz
            ex[1] += bz
            if ex[1] > 0:
                heapq.heappush(heap, (-ex[0] / ex[1], min(x, z), max(x, z)))
    while True:  # every seed to its final root
        root = parent[parent]
        if np.array_equal(root, parent):
            break
        parent = root
    return parent[regions]


def absorb_small(
    regions: np.ndarray, edges: np.ndarray, both: np.ndarray, same: np.ndarray, min_points: int
) -> np.ndarray:
    """Regions under ``min_points`` points join the large neighbour of highest pooled border affinity;
    those touching no large region become -1 (unassigned)."""
    size = np.bincount(regions)
    small = size < min_points
    if not small.any():
        return regions
    first, second, s, b = border_counts(regions, edges, both, same)
    # both directions: (small region, large neighbour, affinity)
    src = np.r_[first, second]
    dst = np.r_[second, first]
    aff = np.r_[s, s] / np.maximum(np.r_[b, b], 1)
    ok = small[src] & ~small[dst]
    src, dst, aff = src[ok], dst[ok], aff[ok]
    order = np.lexsort((dst, -aff, src))  # per small region: best affinity first (ties: lower id)
    src, dst = src[order], dst[order]
    head = np.ones(len(src), bool)
    head[1:] = src[1:] != src[:-1]
    target = np.where(small, -1, np.arange(len(size)))
    target[src[head]] = dst[head]
    return target[regions]
