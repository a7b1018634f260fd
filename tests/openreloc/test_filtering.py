"""Invalid-object filtering by reference-frame frequency (global and co-visibility-local)."""

from __future__ import annotations

import numpy as np
import pytest

from openreloc_bench.openreloc.filtering import FilterConfig, invalid_landmarks, reference_frequency
from openreloc_bench.openreloc.map import ReferenceFrame


def rfs(contents: list[list[int]]) -> list[ReferenceFrame]:
    return [ReferenceFrame(k, np.eye(4), {i: np.zeros(4, np.float32) for i in ids}) for k, ids in enumerate(contents)]


# two rooms: room A (wall 1, chair 2, table 3), room B (wall 4, bed 5), never seen together
TWO_ROOMS = rfs([[1, 2], [1, 3], [1, 2], [1], [4, 5], [4], [4, 5], [4]])


def test_global_frequency() -> None:
    f = reference_frequency(TWO_ROOMS, [1, 2, 3, 4, 5], "global")
    assert f == pytest.approx({1: 0.5, 2: 0.25, 3: 0.125, 4: 0.5, 5: 0.25})


def test_local_frequency_is_per_neighbourhood() -> None:
    f = reference_frequency(TWO_ROOMS, [1, 2, 3, 4, 5], "local")
    assert f == pytest.approx({1: 1.0, 2: 0.5, 3: 0.25, 4: 1.0, 5: 0.5})
    bad, _ = invalid_landmarks(TWO_ROOMS, [1, 2, 3, 4, 5], FilterConfig(max_frequency=0.75))
    assert bad == {1, 4}  # the walls; globally (0.5) they would look like furniture


def test_disabled_filter_keeps_everything() -> None:
    bad, freq = invalid_landmarks(TWO_ROOMS, [1, 2], FilterConfig(enabled=False))
    assert bad == set() and freq[1] == 1.0


def _box_points(size: tuple[float, float, float], yaw_deg: float = 0.0, n: int = 4000) -> np.ndarray:
    rng = np.random.default_rng(0)
    p = rng.uniform(-0.5, 0.5, (n, 3)) * np.asarray(size)
    a = np.radians(yaw_deg)
    R = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    return p @ R.T


@pytest.mark.parametrize(
    "name, size, yaw, slab",
    [
        ("wall", (4.0, 0.1, 2.7), 0, True),
        ("oblique wall", (4.0, 0.1, 2.7), 33, True),
        ("short wall piece", (0.6, 0.1, 2.7), 0, True),
        ("floor", (5.0, 4.0, 0.05), 0, True),
        ("runner rug", (2.44, 0.78, 0.013), 0, False),
        ("sofa", (2.2, 0.9, 0.8), 0, False),
        ("bookshelf", (0.9, 0.35, 2.0), 0, False),
    ],
)
def test_shape_cue_marks_slabs(name, size, yaw, slab) -> None:
    from openreloc_bench.openreloc.filtering import is_slab

    assert is_slab(_box_points(size, yaw), FilterConfig()) is slab, name


def test_shape_cue_in_invalid_landmarks_and_paper_literal_switch() -> None:
    pts = {1: _box_points((4.0, 0.1, 2.7)), 2: _box_points((0.5, 0.5, 0.8))}
    frames = rfs([[1, 2], [2], [1], [2]])
    bad, _ = invalid_landmarks(frames, [1, 2], FilterConfig(max_frequency=0.9), pts)
    assert bad == {1}
    bad, _ = invalid_landmarks(frames, [1, 2], FilterConfig(max_frequency=0.9, shape_filter=False), pts)
    assert bad == set()
