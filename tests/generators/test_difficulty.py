"""Per-query difficulty: look-alike groups, viewpoint gaps and per-frame counts on hand-made inputs."""

from __future__ import annotations

import numpy as np
import pytest

from generators.difficulty import changes_in_view, frame_difficulty, lookalike_ids, measure_difficulty, viewpoint_gap
from openreloc_bench import geometry
from openreloc_bench.data.scene import DIFFICULTY_COLUMNS, ObjectInfo


def _obj(i: int, category: str, description: str = "", structural: bool = False, **attributes) -> ObjectInfo:
    return ObjectInfo(id=i, category=category, description=description, structural=structural, attributes=attributes)


def test_lookalikes_are_identical_models_only() -> None:
    objects = [
        _obj(1, "wall", "a white wall", structural=True),
        _obj(2, "wall", "a white wall", structural=True),
        _obj(3, "chair", "a red chair", colour="red"),
        _obj(4, "chair", "a red chair", colour="red"),
        _obj(5, "chair", "a red chair", colour="blue"),  # same words, other attributes: another model
        _obj(6, "stool", "a red chair", colour="red"),
    ]
    assert lookalike_ids(objects) == {3, 4}


def test_viewpoint_gap_uses_nearby_frames_for_rotation() -> None:
    mapping = np.stack([geometry.look_at([0, 0, 1], [1, 0, 1]), geometry.look_at([0.8, 0, 1], [0.8, 1, 1])])
    query = geometry.look_at([0.5, 0, 1], [0.5, 1, 1])[None]  # 0.3 m from the second frame, looking its way
    gap_m, gap_deg = viewpoint_gap(query, mapping)
    assert gap_m[0] == pytest.approx(0.3) and gap_deg[0] == pytest.approx(0.0, abs=1e-6)
    far = geometry.look_at([5, 0, 1], [5, 1, 1])[None]  # no frame within 1 m: the smallest rotation overall
    gap_m, gap_deg = viewpoint_gap(far, mapping)
    assert gap_m[0] == pytest.approx(4.2) and gap_deg[0] == pytest.approx(0.0, abs=1e-6)


def test_frame_difficulty_counts_visible_objects() -> None:
    inst = np.zeros((100, 100), np.int32)
    inst[:50] = 1  # structural
    inst[50:60, :10] = 2  # 1% of the image
    inst[60:61, :20] = 3  # 0.2%: too small to count as visible
    inst[70:80, :30] = 4
    out = frame_difficulty(inst, structural={1}, lookalikes={2, 3}, changes=1)
    assert out == {"visible_objects": 2, "object_area": 0.042, "displaced_in_view": 1, "lookalikes_in_view": 1}


def test_changes_in_view_counts_shown_and_removed_objects() -> None:
    """A moved object counts where the changed view shows it; a removed one where the unchanged view did."""
    before, after = np.zeros((2, 20, 20), np.int32)
    before[:10] = 3  # removed: seen before, gone after
    after[10:] = 4  # moved into view
    after[:1, :1] = 5  # moved, but too small to count as seen
    objects = [_obj(3, "lamp"), _obj(4, "chair"), _obj(5, "cup")]
    assert changes_in_view([after, after], [before, np.zeros_like(before)], {4, 5}, {3}, objects) == [2, 1]


def test_measure_difficulty_rows_per_split_and_frame() -> None:
    mapping = np.stack([geometry.look_at([0, 0, 1], [1, 0, 1])])
    poses = np.stack([geometry.look_at([0, 0.5, 1], [1, 0.5, 1]), geometry.look_at([0, 2, 1], [1, 2, 1])])
    inst = np.zeros((10, 10), np.int32)
    inst[:5] = 7
    splits = {"query": (poses, 1.0, [inst, inst], None), "query_light4": (poses, 0.2, [inst, inst], None)}
    table = measure_difficulty(mapping, splits, [_obj(7, "lamp")])
    assert tuple(table.columns) == DIFFICULTY_COLUMNS
    assert list(table["split"]) == ["query", "query", "query_light4", "query_light4"]
    assert list(table["frame"]) == ["000000", "000001"] * 2
    assert list(table["light_level"]) == [1.0, 1.0, 0.2, 0.2]
    assert table["gap_m"].tolist() == pytest.approx([0.5, 2.0, 0.5, 2.0])
    assert (table["visible_objects"] == 1).all() and (table["object_area"] == 0.5).all()
