from __future__ import annotations

import numpy as np
import pytest

from openreloc_bench.data.scene import ObjectInfo
from openreloc_bench.reconstruction.instance_eval import box_point_labels, instance_report


def line(n: int, length: float) -> np.ndarray:
    return np.c_[np.linspace(0, length, n), np.zeros(n), np.zeros(n)]


def test_instance_report_counts_iou_matches_at_both_thresholds() -> None:
    points = line(400, 4.0)
    truth = {1: np.arange(0, 100), 2: np.arange(100, 200)}
    pred = {7: np.arange(0, 90), 8: np.arange(150, 300), 9: np.arange(300, 310)}
    q = instance_report(points, pred, truth)
    assert q["precision"] == pytest.approx(1 / 3) and q["recall"] == pytest.approx(1 / 2)
    assert q["precision_25"] == pytest.approx(2 / 3) and q["recall_25"] == pytest.approx(1.0)


def test_instance_report_names_each_objects_error_by_size() -> None:
    points = line(1000, 10.0)  # 1 cm apart: 100 points span ~1 m (medium), 30 points 0.3 m (small)
    truth = {
        1: np.arange(0, 100),  # found
        2: np.arange(100, 200),  # split into three pieces
        3: np.arange(200, 230),  # merged: one instance holds it and much more
        4: np.arange(400, 430),  # missed: nothing holds it
        5: np.arange(500, 700),  # large, found
    }
    pred = {
        1: np.arange(0, 95),
        2: np.arange(100, 140),
        3: np.arange(140, 170),
        4: np.arange(170, 200),
        6: np.arange(200, 330),
        5: np.arange(500, 700),
    }
    q = instance_report(points, pred, truth)
    assert q["objects"]["found"] == {"small": 0, "medium": 1, "large": 1}
    assert q["objects"]["split"] == {"small": 0, "medium": 1, "large": 0}
    assert q["objects"]["merged"] == {"small": 1, "medium": 0, "large": 0}
    assert q["objects"]["missed"] == {"small": 1, "medium": 0, "large": 0}
    assert q["instances"] == {"matched": 2, "fragment": 3, "merge": 0, "background": 1}


def test_instance_report_of_an_empty_map_misses_everything() -> None:
    q = instance_report(line(50, 1.0), {}, {1: np.arange(50)})
    assert q["precision"] == q["recall"] == 0.0 and q["objects"]["missed"]["medium"] == 1


def test_box_point_labels_prefer_the_smallest_box_and_absorb_surface_noise() -> None:
    objects = {
        1: ObjectInfo(1, "floor", aabb=[[-2, -2, -0.1], [2, 2, 0.0]], structural=True),
        2: ObjectInfo(2, "table", aabb=[[0, 0, 0], [1, 1, 0.8]]),
        3: ObjectInfo(3, "lamp", aabb=[[0.4, 0.4, 0.8], [0.6, 0.6, 1.2]]),
    }
    pts = np.array(
        [
            [-1, -1, 0.01],  # floor with surface noise above it: only within the margin of the floor
            [0.5, 0.5, 0.79],  # table top
            [0.5, 0.5, 0.81],  # lamp base (inside the table box's margin too: the strict lamp box wins)
            [0.5, 0.5, -0.005],  # floor under the table: strictly inside the floor only
            [3, 3, 3],  # nowhere
        ]
    )
    np.testing.assert_array_equal(box_point_labels(pts, objects, 0.03), [1, 2, 3, 1, 0])
