"""Furnishing: objects inside their rooms without interpenetration, identical copies sharing one asset."""

from __future__ import annotations

import numpy as np

from generators.layout import build_layout
from generators.spec import SceneSpec


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


def test_repeated_identical_instances() -> None:
    layout = build_layout(SceneSpec(name="r", kind="multi-room", seed=11, rooms=4, objects_per_room=20))
    objs = [i for i in layout.instances if not i.structural]
    shared = {}
    for o in objs:
        shared.setdefault(id(o.parts[0]), []).append(o)
    twins = [v for v in shared.values() if len(v) > 1]
    assert twins, "expected identical copies sharing one asset"
    assert all(len({o.description for o in v}) == 1 for v in twins)
