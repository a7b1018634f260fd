"""Layouts: room counts, structural instances, no interpenetration, repeated identical assets."""

from __future__ import annotations

import numpy as np
import pytest

from generators.layout import build_layout
from generators.spec import SceneSpec
from openreloc_bench.data.scene import STRUCTURAL_CATEGORIES

SPECS = {
    "single": SceneSpec(name="s", seed=3, objects_per_room=14, room_side_min=4.0, room_side_max=5.0),
    "multi": SceneSpec(name="m", kind="multi-room", seed=5, rooms=5, objects_per_room=8),
    "floors": SceneSpec(name="f", kind="multi-floor", seed=6, rooms=2, floors=2, objects_per_room=6, room_side_max=5.0),
}


@pytest.fixture(scope="module", params=list(SPECS))
def layout_and_spec(request):
    spec = SPECS[request.param]
    return build_layout(spec), spec


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


def test_objects_inside_rooms_without_overlap(layout_and_spec) -> None:
    layout, spec = layout_and_spec
    objs = [i for i in layout.instances if not i.structural]
    per_room = {r.name: sum(o.room == r.name for o in objs) for r in layout.rooms}
    assert sum(per_room.values()) >= 0.6 * spec.objects_per_room * len(layout.rooms)
    rooms = {r.name: r for r in layout.rooms}
    for o in objs:
        box, r = o.aabb, rooms[o.room]
        assert r.rect[0] - 1e-6 <= box[0, 0] and box[1, 0] <= r.rect[2] + 1e-6
        assert r.rect[1] - 1e-6 <= box[0, 1] and box[1, 1] <= r.rect[3] + 1e-6
        assert r.z0 - 1e-6 <= box[0, 2] and box[1, 2] <= r.z0 + r.height + 1e-6
    for a in objs:
        for b in objs:
            if a.id < b.id and b.support != a.id and a.support != b.id and a.room == b.room:
                A, B = a.aabb, b.aabb
                overlap = np.all(A[0] < B[1] - 1e-3) and np.all(B[0] < A[1] - 1e-3)
                assert not overlap, (a.category, b.category)
    for o in objs:
        if o.placement == "surface":
            sup = layout.by_id()[o.support]
            assert o.aabb[0, 2] >= sup.aabb[0, 2]


def test_deterministic_and_seed_dependent() -> None:
    spec = SPECS["single"]
    a, b = build_layout(spec), build_layout(spec)
    assert [o.description for o in a.instances] == [o.description for o in b.instances]
    assert all(np.array_equal(x.transform, y.transform) for x, y in zip(a.instances, b.instances))
    c = build_layout(SceneSpec(**{**spec.__dict__, "seed": spec.seed + 1}))
    assert [o.category for o in c.instances] != [o.category for o in a.instances] or not np.allclose(
        a.instances[-1].transform, c.instances[-1].transform
    )


def test_repeated_identical_instances() -> None:
    layout = build_layout(SceneSpec(name="r", kind="multi-room", seed=11, rooms=4, objects_per_room=20))
    objs = [i for i in layout.instances if not i.structural]
    shared = {}
    for o in objs:
        shared.setdefault(id(o.parts[0]), []).append(o)
    twins = [v for v in shared.values() if len(v) > 1]
    assert twins, "expected identical copies sharing one asset"
    assert all(len({o.description for o in v}) == 1 for v in twins)


def test_object_info_roundtrip(layout_and_spec) -> None:
    layout, _ = layout_and_spec
    infos = layout.objects()
    assert len(infos) == len(layout.instances)
    for info, inst in zip(infos, layout.instances):
        assert info.id == inst.id and info.structural == inst.structural
        assert np.allclose(info.aabb_array, inst.aabb, atol=1e-4)
