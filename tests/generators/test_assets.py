"""Asset library: every category samples valid, metric, centred, described, deterministic meshes."""

from __future__ import annotations

import numpy as np
import pytest

from generators.assets import (
    CATEGORIES,
    PLACEMENTS,
    ROOM_KINDS,
    SIZES,
    Asset,
    categories_for_room,
    sample_asset,
)
from generators.materials import COLOURS, MATERIALS
from openreloc_bench.errors import ConfigError

SEEDS = (0, 1, 2)
NAMES = sorted(CATEGORIES)
# (min, max) bounding-box size in metres per placement, per axis (x width, y depth, z height).
PLAUSIBLE = {
    "floor": ((0.05, 0.05, 0.005), (2.8, 2.8, 2.2)),
    "wall": ((0.2, 0.2, 0.3), (2.6, 2.4, 2.4)),
    "surface": ((0.02, 0.02, 0.02), (1.6, 0.7, 1.0)),
    "wall_mounted": ((0.1, 0.005, 0.1), (1.9, 0.2, 1.6)),
    "ceiling": ((0.1, 0.1, 0.05), (1.0, 1.0, 1.3)),
}
MAX_TRIANGLES = 3000


@pytest.fixture(scope="module", params=SEEDS)
def seed(request) -> int:
    return request.param


@pytest.mark.parametrize("name", NAMES)
def test_category_samples_valid_metric_mesh(name, seed):
    a = sample_asset(name, np.random.default_rng(seed))
    assert isinstance(a, Asset) and a.category == name and a.parts
    assert a.placement == CATEGORIES[name].placement
    for p in a.parts:
        assert p.material in MATERIALS
        assert len(p.rgb) == 3 and all(0.0 <= c <= 1.0 for c in p.rgb)
        assert isinstance(p.texture_seed, int) and p.texture_seed >= 0
        assert np.all(np.isfinite(p.mesh.vertices)) and len(p.mesh.faces) > 0
        assert p.mesh.is_watertight, f"{name}: a {p.material} part is not closed"
        assert np.all(p.mesh.area_faces > 0), f"{name}: degenerate triangles"
    mesh = a.to_trimesh()
    lo, hi = mesh.bounds
    assert abs(lo[2]) < 1e-9, "base must sit at z = 0"
    assert np.allclose((lo[:2] + hi[:2]) / 2, 0.0, atol=1e-9), "footprint must be centred"
    np.testing.assert_allclose(a.extent, hi - lo)
    lo_ok, hi_ok = PLAUSIBLE[a.placement]
    assert np.all(a.extent >= lo_ok) and np.all(a.extent <= hi_ok), f"{name} extent {a.extent.round(3)}"
    assert len(mesh.faces) <= MAX_TRIANGLES
    assert all(0 < h <= a.extent[2] + 1e-9 for h in a.surface_heights)


@pytest.mark.parametrize("name", NAMES)
def test_attributes_and_description(name, seed):
    a = sample_asset(name, np.random.default_rng(seed))
    assert set(a.attributes) == {"colour", "material", "size", "style"}
    assert a.attributes["colour"] in COLOURS and a.attributes["material"] in MATERIALS
    assert a.attributes["size"] in SIZES
    d = a.description
    assert d.startswith(("a ", "an ")) and "  " not in d and len(d) < 140
    assert a.attributes["colour"] in d


@pytest.mark.parametrize("name", NAMES)
def test_deterministic_in_rng_state(name):
    a, b = (sample_asset(name, np.random.default_rng(7)) for _ in range(2))
    c = sample_asset(name, np.random.default_rng(8))
    assert a.description == b.description and a.attributes == b.attributes
    assert [p.texture_seed for p in a.parts] == [p.texture_seed for p in b.parts]
    assert np.array_equal(a.to_trimesh().vertices, b.to_trimesh().vertices)
    assert not np.array_equal(a.to_trimesh().vertices, c.to_trimesh().vertices) or a.attributes != c.attributes


@pytest.mark.parametrize("name", NAMES)
def test_forced_attributes_give_near_duplicates(name):
    first = sample_asset(name, np.random.default_rng(11))
    forced = dict(first.attributes)
    twin = sample_asset(name, np.random.default_rng(12), **forced)
    assert twin.attributes == forced
    ratio = twin.extent / first.extent
    assert np.all(ratio > 0.6) and np.all(ratio < 1.65), f"{name}: {ratio.round(2)}"
    a, b = first.to_trimesh(), twin.to_trimesh()
    assert len(a.vertices) != len(b.vertices) or not np.allclose(a.vertices, b.vertices)


def test_forced_colour_material_size_are_used():
    a = sample_asset("armchair", np.random.default_rng(0), colour="red", material="leather", size="large")
    assert a.attributes["colour"] == "red" and a.attributes["material"] == "leather"
    assert a.attributes["size"] == "large" and "red" in a.description
    small = sample_asset("armchair", np.random.default_rng(0), colour="red", material="leather", size="small")
    assert small.extent[0] < a.extent[0]


@pytest.mark.parametrize(
    ("kwargs", "word"),
    [
        ({"category": "flux_capacitor"}, "flux_capacitor"),
        ({"colour": "octarine"}, "octarine"),
        ({"material": "adamant"}, "adamant"),
        ({"size": "huge"}, "huge"),
        ({"style": "baroque"}, "baroque"),
    ],
)
def test_bad_arguments_raise_config_error(kwargs, word):
    args = {"category": "mug"} | kwargs
    with pytest.raises(ConfigError, match=word):
        sample_asset(args.pop("category"), np.random.default_rng(0), **args)


def test_library_size_and_long_tail():
    assert len(CATEGORIES) >= 60
    weights = sorted(s.weight for s in CATEGORIES.values())
    assert weights[-1] / weights[0] >= 10
    assert all(s.placement in PLACEMENTS and s.rooms and set(s.rooms) <= set(ROOM_KINDS) for s in CATEGORIES.values())


@pytest.mark.parametrize("room", ROOM_KINDS)
def test_every_room_kind_has_furniture_items_and_lights(room):
    specs = categories_for_room(room)
    placements = {s.placement for s in specs}
    assert "ceiling" in placements and placements & {"floor", "wall"}
    if room != "corridor":
        assert "surface" in placements
    assert all(s.placement == "wall" for s in categories_for_room(room, "wall"))


def test_categories_for_room_rejects_unknown_names():
    with pytest.raises(ConfigError, match="garage"):
        categories_for_room("garage")
    with pytest.raises(ConfigError, match="roof"):
        categories_for_room("living", "roof")


def test_descriptions_vary_across_instances():
    texts = {sample_asset("armchair", np.random.default_rng(s)).description for s in range(20)}
    assert len(texts) >= 10
