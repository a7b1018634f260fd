"""build_layout: rooms on every floor joined by doors, structural instances, ids, determinism, objects.json."""

from __future__ import annotations

import numpy as np

from generators.layout import build_layout
from generators.materials import COLOURS, photo_materials
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


def _surfaces(layout, structural: bool) -> list[str]:
    return [p.surface for i in layout.instances if i.structural == structural for p in i.parts]


def test_surface_shares_change_only_the_surfaces(layout_specs) -> None:
    """Bare walls and photographed parts follow their shares and move nothing else in the layout."""
    spec = layout_specs["multi"]
    plain = build_layout(SceneSpec(**{**spec.__dict__, "bare_wall_share": 0.0, "photo_share": 0.0}))
    dressed = build_layout(SceneSpec(**{**spec.__dict__, "bare_wall_share": 1.0, "photo_share": 1.0}))
    assert set(_surfaces(plain, True)) | set(_surfaces(plain, False)) == {"pattern"}
    walls = [p for i in dressed.instances if i.category == "wall" for p in i.parts if p.rgb != COLOURS["light grey"]]
    assert walls and all(p.surface == "bare" for p in walls)
    photographed = [p for i in dressed.instances if not i.structural for p in i.parts if p.surface == "photo"]
    assert photographed and all(p.material in photo_materials() for p in photographed)
    assert [(o.description, o.transform.tobytes()) for o in plain.instances] == [
        (o.description, o.transform.tobytes()) for o in dressed.instances
    ]
    eligible = [p for i in build_layout(spec).instances if not i.structural for p in i.parts]
    eligible = [p for p in eligible if p.image is None and p.material in photo_materials()]
    assert 0.25 < np.mean([p.surface == "photo" for p in eligible]) < 0.75  # the default share, 0.5


def test_object_info_roundtrip(layout_and_spec) -> None:
    layout, _ = layout_and_spec
    infos = layout.objects()
    assert len(infos) == len(layout.instances)
    for info, inst in zip(infos, layout.instances):
        assert info.id == inst.id and info.structural == inst.structural
        assert np.allclose(info.aabb_array, inst.aabb, atol=1e-4)
