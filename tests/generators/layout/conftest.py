"""The layouts the layout tests share, built once: a furnished single room, a five-room flat with a
corridor and a two-storey house."""

from __future__ import annotations

import pytest

from generators.layout import build_layout
from generators.spec import SceneSpec

SPECS = {
    "single": SceneSpec(name="s", seed=3, objects_per_room=14, room_side_min=4.0, room_side_max=5.0),
    "multi": SceneSpec(name="m", kind="multi-room", seed=5, rooms=5, objects_per_room=8),
    "floors": SceneSpec(name="f", kind="multi-floor", seed=6, rooms=2, floors=2, objects_per_room=6, room_side_max=5.0),
}


@pytest.fixture(scope="session")
def layout_specs() -> dict[str, SceneSpec]:
    return SPECS


@pytest.fixture(scope="session", params=list(SPECS))
def layout_and_spec(request):
    spec = SPECS[request.param]
    return build_layout(spec), spec
