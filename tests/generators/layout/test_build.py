"""build_layout: rooms on every floor joined by doors, structural instances, ids, determinism, objects.json."""

from __future__ import annotations

import numpy as np

from generators.layout import build_layout
from generators.spec import SceneSpec
from openreloc_bench.data.scene import STRUCTURAL_CATEGORIES


def test_rooms_floors_and_structure(layout_and_spec) -> None:
    layout, spec = layout_and_spec
    assert len(layout.rooms) == spec.rooms * spec.floors
    assert len(layout.floor_z) == spec.floors
    cats = {i.category for i in layout.instances if i.structural}
    assert {"wall", "floor", "ceiling"} <= cats
    assert cats <= STRUCTURAL_CATEGORIES
    assert all((i.category in STRUCTURAL_CATEGORIES) == i.structural for i in layout.instances)
    assert sum(i.category == "floor" for i in layout.instances) == len(layout.rooms)
    if spec.kind != "single-room":
        assert "door" in cats
        import networkx as nx

        g = layout.room_graph()
        for f in range(spec.floors):
            assert nx.is_connected(g.subgraph(r.name for r in layout.rooms_on(f)))
    if spec.kind == "multi-floor":
        assert "stairs" in cats and "railing" in cats
    ids = [i.id for i in layout.instances]
    assert ids == list(range(1, len(ids) + 1))


def test_deterministic_and_seed_dependent(layout_specs) -> None:
    spec = layout_specs["single"]
    a, b = build_layout(spec), build_layout(spec)
    assert [o.description for o in a.instances] == [o.description for o in b.instances]
    assert all(np.array_equal(x.transform, y.transform) for x, y in zip(a.instances, b.instances))
    c = build_layout(SceneSpec(**{**spec.__dict__, "seed": spec.seed + 1}))
    assert [o.category for o in c.instances] != [o.category for o in a.instances] or not np.allclose(
        a.instances[-1].transform, c.instances[-1].transform
    )


def test_object_info_roundtrip(layout_and_spec) -> None:
    layout, _ = layout_and_spec
    infos = layout.objects()
    assert len(infos) == len(layout.instances)
    for info, inst in zip(infos, layout.instances):
        assert info.id == inst.id and info.structural == inst.structural
        assert np.allclose(info.aabb_array, inst.aabb, atol=1e-4)
