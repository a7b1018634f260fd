"""Global scene graph (paper section 3.1): landmark nodes, edges to each landmark's k nearest
neighbours (by centre) and to every landmark whose 3D box overlaps its own.

kNN edges are computed among valid landmarks for valid ones (so a chair's neighbours are furniture,
not the wall behind it) and among all landmarks for invalid ones; ``graph.subgraph(valid_ids)`` is
then the graph the filtered method matches against. Overlap edges are kept between any two boxes
(an object on a table overlaps the table's box once ``margin`` absorbs reconstruction gaps).
"""

from __future__ import annotations

from dataclasses import dataclass

import networkx as nx
import numpy as np
from scipy.spatial import cKDTree

from openreloc_bench.config import check_ranges
from openreloc_bench.openreloc.map import Landmark


@dataclass
class GraphConfig:
    """Scene-graph edges."""

    knn: int = 4
    """Edges from each landmark to this many nearest landmark centres."""
    overlap_margin: float = 0.02
    """Boxes grown by this (m) before the overlap test, so touching objects connect."""

    def __post_init__(self) -> None:
        check_ranges(self, non_negative=("knn", "overlap_margin"))


def build_scene_graph(landmarks: dict[int, Landmark], cfg: GraphConfig) -> nx.Graph:
    g = nx.Graph()
    ids = sorted(landmarks)
    g.add_nodes_from(ids)
    if len(ids) < 2:
        return g
    centers = np.array([landmarks[i].center for i in ids], dtype=np.float64)
    valid = np.array([landmarks[i].valid for i in ids])
    for sources, pool in (
        (np.flatnonzero(valid), np.flatnonzero(valid)),
        (np.flatnonzero(~valid), np.arange(len(ids))),
    ):
        if len(sources) == 0 or len(pool) < 2:
            continue
        k = min(cfg.knn + 1, len(pool))
        _, nn = cKDTree(centers[pool]).query(centers[sources], k=k)
        for s, row in zip(sources, np.atleast_2d(nn)):
            for j in pool[row]:
                if j != s:
                    g.add_edge(ids[s], ids[j], kind="knn")
    lo = np.array([landmarks[i].box_min for i in ids]) - cfg.overlap_margin
    hi = np.array([landmarks[i].box_max for i in ids]) + cfg.overlap_margin
    overlap = np.all((lo[:, None] <= hi[None]) & (lo[None] <= hi[:, None]), axis=-1)
    for a, b in zip(*np.nonzero(np.triu(overlap, 1))):
        g.add_edge(ids[a], ids[b], kind="overlap")  # overlap wins over knn for the same pair
    return g
