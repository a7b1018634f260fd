"""Association on hand-made descriptors: uniqueness, the 2D/3D subgraphs, and a repeated object
(two identical chairs) disambiguated by its neighbours in the scene graph."""

from __future__ import annotations

import networkx as nx
import numpy as np
import pytest

from openreloc_bench.openreloc.association import (
    AssociationConfig,
    QueryObject,
    associate,
    landmark_neighbours,
    query_neighbours,
    subgraph_similarity,
    unique_mask,
    uniqueness,
)

D = 8


def unit(i: int, noise: np.ndarray | None = None) -> np.ndarray:
    v = np.zeros(D, np.float32)
    v[i] = 1.0
    if noise is not None:
        v = v + noise
    return (v / np.linalg.norm(v)).astype(np.float32)


def obj(vis: np.ndarray, box: list[float], text: np.ndarray | None = None) -> QueryObject:
    return QueryObject(mask=np.zeros((4, 4), bool), box=np.array(box, float), visual=vis, text=text)


# landmarks: 1 chair (next to the table), 2 chair (next to the bed), 3 table, 4 bed, 5 lamp
DESC = np.stack([unit(0), unit(0), unit(1), unit(2), unit(3)])
IDS = [1, 2, 3, 4, 5]
GRAPH = nx.Graph([(1, 3), (2, 4), (3, 5)])


def test_uniqueness_is_the_variance_of_cosines() -> None:
    flat = np.full((1, D), 1 / np.sqrt(D), np.float32)  # equally similar to every landmark
    g = uniqueness(np.stack([unit(1), flat[0]]), DESC)
    assert g[0] == pytest.approx(np.var(DESC @ unit(1)))
    assert g[1] == pytest.approx(0.0, abs=1e-7)
    assert unique_mask(g, AssociationConfig()).tolist() == [True, False]


def test_query_subgraph_links_nearest_and_intersecting_boxes() -> None:
    boxes = np.array([[0, 0, 10, 10], [8, 8, 20, 20], [100, 0, 110, 10], [0, 50, 5, 55]], float)
    nb = query_neighbours(boxes)
    assert nb[0] == [1, 3] or nb[0] == [1]  # intersects 1; nearest is 1
    assert 0 in nb[1]
    assert nb[2] == [1]  # far away: only its nearest
    assert query_neighbours(boxes[:1]) == [[]]


def test_landmark_subgraph_and_assignment_score() -> None:
    assert landmark_neighbours(GRAPH, 3, 1, set(IDS)) == [1, 5]
    assert landmark_neighbours(GRAPH, 3, 1, {1}) == [1]
    assert landmark_neighbours(GRAPH, 99, 1, set(IDS)) == []
    q = np.stack([unit(1), unit(3)])
    assert subgraph_similarity(q, np.stack([unit(3), unit(1), unit(2)])) == pytest.approx(2.0)
    assert subgraph_similarity(q, np.zeros((0, D))) == 0.0


def test_repeated_chair_is_resolved_by_its_neighbours() -> None:
    # two near-identical chairs; the query sees one beside a bed. Vision leans to chair 1, the
    # phrase to chair 2: the disagreement is settled by the neighbours (chair 2 is next to the bed).
    desc = DESC.copy()
    desc[0], desc[1] = unit(0, 0.01 * unit(5)), unit(0, 0.01 * unit(6))
    chair = obj(unit(0, 0.03 * unit(5)), [0, 0, 10, 10], text=unit(0, 0.03 * unit(6)))
    bed = obj(unit(2), [9, 0, 30, 12], text=unit(2))
    lamp = obj(unit(3), [200, 0, 210, 10], text=unit(3))
    matches = {m.query: m for m in associate([chair, bed, lamp], IDS, desc, GRAPH, AssociationConfig())}
    assert matches[1].landmark == 4 and matches[1].how == "agree"
    assert matches[0].landmark == 2 and matches[0].how == "graph"
    assert matches[0].candidates[:2] == [2, 1]
    # without the scene graph the visual top-1 (the wrong chair) is kept
    no_graph = {m.query: m for m in associate([chair, bed, lamp], IDS, desc, None, AssociationConfig())}
    assert no_graph[0].landmark == 1 and no_graph[0].how == "visual"


def test_disagreement_goes_to_the_graph_and_without_graph_takes_visual_top1() -> None:
    chair = obj(unit(0), [0, 0, 10, 10], text=unit(1))  # vision: a chair; text: 'table'
    bed = obj(unit(2), [9, 0, 30, 12], text=unit(2))
    with_graph = associate([chair, bed], IDS, DESC, GRAPH, AssociationConfig())
    m = next(x for x in with_graph if x.query == 0)
    assert m.how == "graph" and m.landmark in (1, 2) and 3 in m.candidates
    no_graph = associate([chair, bed], IDS, DESC, None, AssociationConfig())
    assert next(x for x in no_graph if x.query == 0).how == "visual"


def test_a_landmark_is_matched_at_most_once() -> None:
    a = obj(unit(1), [0, 0, 5, 5], text=unit(1))
    b = obj(unit(1, np.full(D, 0.05, np.float32)), [50, 0, 55, 5], text=unit(1))
    matches = associate([a, b], IDS, DESC, GRAPH, AssociationConfig())
    assert len({m.landmark for m in matches}) == len(matches) == 2
    assert next(m for m in matches if m.query == 0).landmark == 3
    assert next(m for m in matches if m.query == 1).how == "fallback"


def test_without_language_every_object_takes_its_visual_top1() -> None:
    matches = associate(
        [obj(unit(3), [0, 0, 5, 5]), obj(unit(2), [9, 0, 20, 5])], IDS, DESC, GRAPH, AssociationConfig()
    )
    assert [(m.landmark, m.how, m.text_sim) for m in matches] == [(5, "visual", None), (4, "visual", None)]


def test_oracle_matches_use_instance_ids_and_skip_unknown_or_invalid() -> None:
    from openreloc_bench.openreloc.association import oracle_matches

    objects = [obj(unit(0), [0, 0, 1, 1]) for _ in range(4)]
    for o, inst in zip(objects, [3, 9, None, 5]):
        o.instance_id = inst
    got = oracle_matches(objects, IDS, invalid={5})
    assert [(m.query, m.landmark, m.how) for m in got] == [(0, 3, "oracle")]
