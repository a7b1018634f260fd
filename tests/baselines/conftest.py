"""Two tiny generated rooms shared by the baseline tests: one to map, one that is another scene."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

from generators.generate import generate_scene
from generators.spec import SceneSpec
from openreloc_bench.data.scene import Scene
from openreloc_bench.methods import create_method

TINY = dict(
    width=320,
    height=240,
    objects_per_room=15,
    room_side_min=3.5,
    room_side_max=4.0,
    mapping_step_m=0.5,
    mapping_step_deg=30.0,
    max_mapping_frames=16,
    n_query=3,
    displaced_share=0.2,
)


@pytest.fixture(scope="session")
def scenes(tmp_path_factory: pytest.TempPathFactory) -> tuple[Scene, Scene]:
    """(the mapped room, another room)."""
    root = tmp_path_factory.mktemp("baseline-scenes")
    return tuple(
        Scene(generate_scene(SceneSpec(name=f"room{s}", seed=s, **TINY), root, progress=False)) for s in (5, 6)
    )


CHEAP: dict[str, dict] = {
    "posenet": {"steps": 10, "batch_size": 4, "input_width": 48, "input_height": 36, "hidden": 32}
}
"""Per method, settings that make its default map fast enough for unit tests (a short training)."""


@pytest.fixture(scope="session")
def built_map(scenes: tuple[Scene, Scene], tmp_path_factory: pytest.TempPathFactory) -> Callable[[str], Path]:
    """``built_map(method name)``: the directory of that method's map of the first room (default
    settings, or :data:`CHEAP` ones), built once."""
    maps: dict[str, Path] = {}

    def build(name: str) -> Path:
        if name not in maps:
            maps[name] = tmp_path_factory.mktemp(name)
            create_method(name, **CHEAP.get(name, {})).build_map(scenes[0].sequence("mapping"), maps[name])
        return maps[name]

    return build
