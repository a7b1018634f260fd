"""Lighting variants and object displacements."""

from __future__ import annotations

import numpy as np

from generators.layout import build_layout
from generators.spec import SceneSpec
from generators.variants import CHANGE_KINDS, Lighting, hidden, query_lighting, sample_displacements
from openreloc_bench.data.splits import LIGHT, QUERY_SPLITS, split_names

SPEC = SceneSpec(name="v", seed=9, objects_per_room=16, displaced_share=0.25, removed_share=0.125, added_share=0.0625)


def test_light_variants_progressive() -> None:
    v = query_lighting(SPEC, 8)
    assert list(v) == list(QUERY_SPLITS)
    light = split_names(LIGHT)
    levels = [v[s].level for s in light]
    assert levels == SPEC.light_levels == sorted(levels, reverse=True) and levels[0] < 1.0
    off = [len(v[s].lights_off) for s in light]
    assert off[0] == 0 and off[-1] > 0 and off == sorted(off) and max(off) < 8
    assert v["query_light2"].tint != v["query_light1"].tint
    assert query_lighting(SPEC, 1)["query_light4"].lights_off == ()  # never every light off
    heads = [v[s].headlight for s in light]
    assert heads[0] and not heads[-1] and heads == sorted(heads, reverse=True)  # dark splits: no camera light
    assert all(v[s] == Lighting() for s in QUERY_SPLITS if s not in light)  # the others: the mapping's


def test_a_suite_sets_the_light_levels() -> None:
    levels = [v / 2 for v in SPEC.light_levels]
    dim = query_lighting(SceneSpec(name="v", seed=9, light_levels=levels), 8)
    assert [dim[s].level for s in split_names(LIGHT)] == levels
    assert [dim[s].lights_off for s in QUERY_SPLITS] == [v.lights_off for v in query_lighting(SPEC, 8).values()]


def test_displacements_valid() -> None:
    layout = build_layout(SPEC)
    keep = np.array([[2.0, 2.0, 1.5]])
    changes = sample_displacements(layout, SPEC, keep, {})
    kinds = [c.kind for c in changes]
    assert kinds.count("removed") == 2 and kinds.count("added") == 1  # 1/8 and 1/16 of 16 objects
    assert len(changes) - 3 == 4  # a quarter moved or rotated
    assert set(kinds) <= set(CHANGE_KINDS)
    assert len({m.id for m in changes}) == len(changes)
    by_id = layout.by_id()
    others = {i.id: i.aabb for i in layout.instances if not i.structural}
    moves = [m for m in changes if m.kind not in ("removed", "added")]
    for m in changes:
        assert not by_id[m.id].structural
        assert m.shown_in_mapping == (m.kind != "added") and m.shown_displaced == (m.kind != "removed")
    for m in moves:
        inst = by_id[m.id]
        after = np.asarray(m.aabb_after)
        assert np.linalg.norm(m.translation) > 0 or abs(m.yaw_deg) >= 30
        T = np.asarray(m.transform_after)
        assert np.allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-6)
        assert np.isclose(T[2, 3], inst.transform[2, 3])  # stays on its floor / support
        for j, box in others.items():
            if j not in (m.id, inst.support) and j not in {x.id for x in moves}:
                assert not (np.all(after[0] < box[1] - 1e-3) and np.all(box[0] < after[1] - 1e-3))
        assert not np.all((keep[0] > after[0] - 0.2) & (keep[0] < after[1] + 0.2))
    again = sample_displacements(layout, SPEC, keep, {})
    assert [m.id for m in again] == [m.id for m in changes]


def test_displacements_drawn_among_seen_objects() -> None:
    """Changes touch the objects the queries see first: with 6 seen objects and 7 changes to make, the
    six seen ones are all changed."""
    layout = build_layout(SPEC)
    movable = [
        c.id
        for c in sample_displacements(
            layout,
            SceneSpec(**{**vars(SPEC), "displaced_share": 1.0, "removed_share": 0.0, "added_share": 0.0}),
            np.empty((0, 3)),
            {},
        )
    ]
    seen = {i: 3 for i in movable[-6:]}  # objects the unweighted draw took last
    changed = {c.id for c in sample_displacements(layout, SPEC, np.empty((0, 3)), seen)}
    assert set(seen) <= changed


def test_hidden_moves_out_of_sight() -> None:
    T = np.eye(4)
    assert hidden(T)[2, 3] < -100 and T[2, 3] == 0.0
