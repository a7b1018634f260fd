"""Lighting variants and object displacements."""

from __future__ import annotations

import numpy as np

from generators.layout import build_layout
from generators.spec import SceneSpec
from generators.variants import LIGHT_SPLITS, light_variants, sample_displacements

SPEC = SceneSpec(name="v", seed=9, objects_per_room=16, n_displaced=4)


def test_light_variants_progressive() -> None:
    v = light_variants(SPEC, 8)
    assert list(v) == list(LIGHT_SPLITS)
    levels = [v[s].level for s in LIGHT_SPLITS]
    assert levels == sorted(levels, reverse=True) and levels[0] < 1.0
    off = [len(v[s].lights_off) for s in LIGHT_SPLITS]
    assert off[0] == 0 and off[-1] > 0 and off == sorted(off) and max(off) < 8
    assert v["query_light2"].tint != v["query_light1"].tint
    assert light_variants(SPEC, 1)["query_light4"].lights_off == ()  # never every light off


def test_displacements_valid() -> None:
    layout = build_layout(SPEC)
    keep = np.array([[2.0, 2.0, 1.5]])
    moves = sample_displacements(layout, SPEC, keep)
    assert len(moves) == SPEC.n_displaced
    assert len({m.id for m in moves}) == len(moves)
    by_id = layout.by_id()
    others = {i.id: i.aabb for i in layout.instances if not i.structural}
    for m in moves:
        inst = by_id[m.id]
        assert not inst.structural
        assert m.kind in ("moved", "rotated", "moved+rotated")
        after = np.asarray(m.aabb_after)
        assert np.linalg.norm(m.translation) > 0 or abs(m.yaw_deg) >= 30
        T = np.asarray(m.transform_after)
        assert np.allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-6)
        assert np.isclose(T[2, 3], inst.transform[2, 3])  # stays on its floor / support
        for j, box in others.items():
            if j not in (m.id, inst.support) and j not in {x.id for x in moves}:
                assert not (np.all(after[0] < box[1] - 1e-3) and np.all(box[0] < after[1] - 1e-3))
        assert not np.all((keep[0] > after[0] - 0.2) & (keep[0] < after[1] + 0.2))
    again = sample_displacements(layout, SPEC, keep)
    assert [m.id for m in again] == [m.id for m in moves]
