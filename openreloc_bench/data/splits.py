"""The splits of a generated scene: the mapping split and one table of query splits.

Each row of :data:`QUERY_SPLIT_TABLE` says what its split is (its kind), how it is lit and how the
tables and plots name it. The generator renders the query splits from it (``generators/variants.py``,
``generators/generate.py``), the spec's ``light_levels`` default to its levels, and the split lists, the
robustness rows and the lighting plot derive from it: a new lighting variant is a row here (and a split
in ``leaderboard/plan.yaml`` to put it on the boards).
"""

from __future__ import annotations

from dataclasses import dataclass

PLAIN = "plain"
"""The query poses under the mapping's lighting: the headline split."""
LIGHT = "light"
"""The query poses under another lighting."""
DISPLACED = "displaced"
"""The query poses with some objects moved, rotated, removed or added."""
NEAR = "near"
"""Poses of its own, along the mapping camera's path between two mapping frames."""
WALK = "walk"
"""Poses of its own: the frames of a second, separate walk through the rooms (a sequence, as 7-Scenes'
and 12-Scenes' test recordings are)."""


@dataclass(frozen=True)
class QuerySplit:
    """One query split of a generated scene."""

    name: str
    """Its folder in the scene, and its name in results."""
    kind: str
    """What it tests: :data:`PLAIN`, :data:`LIGHT`, :data:`DISPLACED`, :data:`NEAR` or :data:`WALK`."""
    title: str
    """Its row in the robustness tables."""
    label: str
    """Its tick in the plots."""
    level: float = 1.0
    """Brightness relative to the mapping lighting (a lighting variant's is the default of
    ``SceneSpec.light_levels``, which a suite may change)."""
    tint: tuple[float, float, float] = (1.0, 1.0, 1.0)
    """Colour of the lights (RGB factors)."""
    lights_off: float = 0.0
    """Share of the room lights switched off (never all of them)."""
    headlight: bool = True
    """Whether the camera's own light is on (off in the dark splits: darkness is not a dimmer)."""

    @property
    def shares_query_poses(self) -> bool:
        """Whether it is the plain query split or a variant of it (same poses, the robustness rows)."""
        return self.kind in (PLAIN, LIGHT, DISPLACED)


QUERY_SPLIT_TABLE: tuple[QuerySplit, ...] = (
    QuerySplit("query", PLAIN, "Original", "original"),
    QuerySplit("query_light1", LIGHT, "Lighting 1", "light 1", 0.7, (1.0, 0.97, 0.92)),
    QuerySplit("query_light2", LIGHT, "Lighting 2", "light 2", 0.5, (1.0, 0.86, 0.70)),
    QuerySplit("query_light3", LIGHT, "Lighting 3", "light 3", 0.35, (0.78, 0.86, 1.0), 0.25, False),
    QuerySplit("query_light4", LIGHT, "Lighting 4", "light 4", 0.2, (1.0, 0.72, 0.52), 0.5, False),
    QuerySplit("query_displaced", DISPLACED, "Displaced objects", "displaced"),
    QuerySplit("query_near", NEAR, "Near the mapping path", "near"),
    QuerySplit("query_walk", WALK, "A second walk", "walk"),
)
"""Every query split, in the order of :data:`SPLITS`. The lighting variants follow the paper's four levels
of decay: each dimmer than the last, the colour drifting warm / cool, the last two with a growing share of
the room lights off and no camera light. A split's position seeds its sensor noise, so a new row goes
last (inserted before others, it would change their frames); the lists of a kind keep the table's order."""

QUERY_SPLIT_BY_NAME = {s.name: s for s in QUERY_SPLIT_TABLE}


def split_names(*kinds: str) -> tuple[str, ...]:
    """The query splits of these kinds, in the table's order."""
    return tuple(s.name for s in QUERY_SPLIT_TABLE if s.kind in kinds)


MAPPING_SPLIT = "mapping"
"""The frames, posed, a method builds its map from."""
SPLITS = (MAPPING_SPLIT, *(s.name for s in QUERY_SPLIT_TABLE))
"""Every split of a generated scene; its index seeds the split's sensor noise."""
QUERY_SPLITS = SPLITS[1:]
LIGHT_SPLITS = split_names(PLAIN, LIGHT)
"""The query split under the mapping's lighting, then its variants under the decayed lightings."""
(PLAIN_SPLIT,) = split_names(PLAIN)
(DISPLACED_SPLIT,) = split_names(DISPLACED)
"""The one split of each of these kinds (the generator measures the others' views against them)."""
OWN_POSE_SPLITS = tuple(s.name for s in QUERY_SPLIT_TABLE if s.kind == PLAIN or not s.shares_query_poses)
"""The query splits with poses of their own: the plain query split (its variants share its poses), then
``query_near`` and ``query_walk``; the dataset card describes their viewpoints."""
