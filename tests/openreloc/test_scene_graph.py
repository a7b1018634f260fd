"""Scene graph: kNN edges by centre, overlap edges by 3D boxes, invalid landmarks kept out of kNN."""

from __future__ import annotations

import numpy as np

from openreloc_bench.openreloc.map import Landmark
from openreloc_bench.openreloc.scene_graph import GraphConfig, build_scene_graph


def lm(i: int, lo: list[float], hi: list[float], valid: bool = True) -> Landmark:
    lo_, hi_ = np.array(lo, float), np.array(hi, float)
    return Landmark(i, np.zeros((1, 3), np.float32), lo_, hi_, (lo_ + hi_) / 2, np.ones(2, np.float32), valid)


def test_knn_and_overlap_edges() -> None:
    lms = {
        1: lm(1, [0, 0, 0], [1, 1, 1]),
        2: lm(2, [0.2, 0.2, 1.0], [0.5, 0.5, 1.3]),  # sits on 1: overlap
        3: lm(3, [5, 0, 0], [6, 1, 1]),
        4: lm(4, [10, 0, 0], [11, 1, 1]),
        9: lm(9, [-1, -1, -0.1], [12, 2, 0], valid=False),  # floor under everything
    }
    g = build_scene_graph(lms, GraphConfig(knn=1, overlap_margin=0.0))
    kinds = {tuple(sorted(e)): d["kind"] for *e, d in g.edges(data=True)}
    assert kinds[(1, 2)] == "overlap"
    assert kinds[(3, 4)] == "knn" and kinds[(1, 3)] == "knn"
    assert kinds[(1, 9)] == "overlap"
    # among valid landmarks, kNN never points at the invalid floor
    assert all(kind == "overlap" for (a, b), kind in kinds.items() if 9 in (a, b))
    assert set(g.nodes) == {1, 2, 3, 4, 9}
