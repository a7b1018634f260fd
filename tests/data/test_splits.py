"""The split table: every split list, the robustness rows, the plot ticks and the spec's light levels
derive from its rows."""

from __future__ import annotations

from dataclasses import fields

from generators.spec import SceneSpec, validate_scene
from generators.variants import Lighting
from openreloc_bench.data.splits import (
    DISPLACED,
    DISPLACED_SPLIT,
    LIGHT,
    LIGHT_SPLITS,
    NEAR,
    OWN_POSE_SPLITS,
    PLAIN,
    PLAIN_SPLIT,
    QUERY_SPLIT_BY_NAME,
    QUERY_SPLIT_TABLE,
    QUERY_SPLITS,
    SPLITS,
    WALK,
    split_names,
)
from openreloc_bench.harness.ablations import ROBUSTNESS_ROWS
from openreloc_bench.harness.leaderboard.plots import LIGHT_LABELS


def test_the_split_lists_derive_from_the_table() -> None:
    assert SPLITS == ("mapping", *QUERY_SPLITS) and QUERY_SPLITS == tuple(s.name for s in QUERY_SPLIT_TABLE)
    assert len(set(SPLITS)) == len(SPLITS) and set(QUERY_SPLIT_BY_NAME) == set(QUERY_SPLITS)
    assert {s.kind for s in QUERY_SPLIT_TABLE} == {PLAIN, LIGHT, DISPLACED, NEAR, WALK}
    assert (PLAIN_SPLIT, DISPLACED_SPLIT) == ("query", "query_displaced")
    assert OWN_POSE_SPLITS == ("query", "query_near", "query_walk")  # the variants share query's poses
    assert LIGHT_SPLITS == (PLAIN_SPLIT, *split_names(LIGHT))


def test_the_splits_keep_the_sensor_seeds_of_the_generated_scenes() -> None:
    """A split's index in SPLITS seeds its sensor noise (generators/generate.py: record): a new row goes last."""
    assert SPLITS[:9] == (
        "mapping",
        "query",
        "query_light1",
        "query_light2",
        "query_light3",
        "query_light4",
        "query_displaced",
        "query_near",
        "query_walk",
    )


def test_boards_and_plots_name_the_splits_by_their_rows() -> None:
    assert [(r.key, r.title) for r in ROBUSTNESS_ROWS] == [
        (s.name, s.title) for s in QUERY_SPLIT_TABLE if s.kind not in (NEAR, WALK)
    ]
    assert LIGHT_LABELS == tuple(QUERY_SPLIT_BY_NAME[s].label for s in LIGHT_SPLITS)
    assert LIGHT_LABELS[:2] == ("original", "light 1")


def test_only_the_lighting_variants_are_lit_otherwise() -> None:
    """The other rows keep the mapping's lighting, which ``Lighting()`` is."""
    mapping = Lighting()
    lit = {f.name for f in fields(Lighting)} - {"lights_off"}
    for s in QUERY_SPLIT_TABLE:
        same = all(getattr(s, k) == getattr(mapping, k) for k in lit) and s.lights_off == 0
        assert same == (s.kind != LIGHT), s.name


def test_the_spec_takes_one_light_level_per_lighting_variant() -> None:
    spec = SceneSpec(name="a")
    assert spec.light_levels == [QUERY_SPLIT_BY_NAME[s].level for s in split_names(LIGHT)]
    assert spec.light_levels[:2] == [0.7, 0.5]
    validate_scene(spec)
