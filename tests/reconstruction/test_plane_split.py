from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

from openreloc_bench.reconstruction import affinity_grouping as A
from openreloc_bench.reconstruction.observation import FrameObservation
from openreloc_bench.reconstruction.plane_split import (
    PlaneSplitConfig,
    SupportSplitConfig,
    split_off_planes,
    split_off_supported,
)

STEP = 0.02


def floor(side: float) -> np.ndarray:
    x, y = np.meshgrid(np.arange(0, side, STEP), np.arange(0, side, STEP))
    return np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], 1)


def box_surface(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Points on the five faces of a box standing on the floor (no bottom face), at the grid step."""
    axes = [np.arange(lo[k], hi[k] + 1e-9, STEP) for k in range(3)]
    pts = set()
    for k in range(3):
        for side in (lo[k], hi[k]) if k < 2 else (hi[k],):
            a, b = [axes[m] for m in range(3) if m != k]
            u, v = np.meshgrid(a, b)
            p = np.zeros((u.size, 3))
            p[:, [m for m in range(3) if m != k]] = np.stack([u.ravel(), v.ravel()], 1)
            p[:, k] = side
            pts.update(map(tuple, np.round(p, 4)))
    return np.array(sorted(pts))


def floor_with_box(side: float, box: float = 0.3) -> tuple[np.ndarray, np.ndarray]:
    """A square floor of ``side`` m with a ``box`` m cube standing in its middle; (points, true ids 1 / 2)."""
    f = floor(side)
    lo = np.array([side / 2 - box / 2, side / 2 - box / 2, STEP])
    b = box_surface(lo, lo + box)
    return np.concatenate([f, b]).astype(np.float32), np.r_[np.ones(len(f), int), np.full(len(b), 2)]


def neighbours(points: np.ndarray) -> np.ndarray:
    return cKDTree(points).query_pairs(1.5 * STEP, output_type="ndarray")


def test_an_object_grouped_with_the_floor_is_split_off_and_the_floor_keeps_its_id() -> None:
    points, truth = floor_with_box(3.0)
    regions = np.zeros(len(points), np.int64)  # the views held floor and box together
    out = split_off_planes(points, regions, neighbours(points), PlaneSplitConfig(), STEP)
    assert (out[truth == 1] == 0).all()
    box = out[truth == 2]
    # the box's bottom rim lies in the floor's band; the rest of it is one new region
    assert np.mean(box == 0) < 0.1
    ids, n = np.unique(box[box != 0], return_counts=True)
    assert len(ids) == 1 and ids[0] == 1 and n[0] > 0.9 * len(box)


def test_a_plane_too_small_for_structure_keeps_its_region_whole() -> None:
    points, _ = floor_with_box(1.2)  # a 1.2 m table top with a box on it: under min_area and min_extent
    regions = np.zeros(len(points), np.int64)
    out = split_off_planes(points, regions, neighbours(points), PlaneSplitConfig(), STEP)
    np.testing.assert_array_equal(out, regions)
    wide = PlaneSplitConfig(min_area=1.0, min_extent=1.0)
    assert len(np.unique(split_off_planes(points, regions, neighbours(points), wide, STEP))) == 2


def test_other_regions_and_unassigned_points_are_left_alone() -> None:
    points, truth = floor_with_box(3.0)
    regions = np.where(truth == 2, 7, 3)  # already apart: the floor region holds no object
    regions[:10] = -1
    out = split_off_planes(points, regions, neighbours(points), PlaneSplitConfig(), STEP)
    np.testing.assert_array_equal(out, regions)
    off = split_off_planes(
        points, np.zeros(len(points), np.int64), neighbours(points), PlaneSplitConfig(enabled=False), STEP
    )
    assert (off == 0).all()


def test_separate_objects_on_one_plane_become_separate_regions() -> None:
    points, truth = floor_with_box(3.0)
    other = box_surface(np.array([0.3, 0.3, STEP]), np.array([0.6, 0.6, 0.3 + STEP]))
    points = np.concatenate([points, other]).astype(np.float32)
    truth = np.r_[truth, np.full(len(other), 3)]
    out = split_off_planes(points, np.zeros(len(points), np.int64), neighbours(points), PlaneSplitConfig(), STEP)
    main = [np.bincount(out[truth == k]).argmax() for k in (2, 3)]
    assert len({0, *main}) == 3


def table_with_mug(top_z: float = 0.7) -> tuple[np.ndarray, np.ndarray]:
    """A 1 x 0.8 m table (top and four legs as 4 cm posts) with a 10 cm mug on it and a 0.6 m high
    panel rising from its back edge (the table's own, like a desk's hutch); (points, ids: table 1, mug 2)."""
    top = floor(1.0)[:, :2]
    top = np.c_[top[top[:, 1] < 0.8], np.full(int((top[:, 1] < 0.8).sum()), top_z)]
    legs = [
        box_surface(np.array([x, y, 0.0]), np.array([x + 0.04, y + 0.04, top_z - STEP]))
        for x in (0, 0.94)
        for y in (0, 0.74)
    ]
    panel = np.stack(
        np.meshgrid(np.arange(0, 1.0, STEP), [0.78], np.arange(top_z + STEP, top_z + 0.6, STEP)), -1
    ).reshape(-1, 3)
    mug = box_surface(np.array([0.45, 0.35, top_z + STEP]), np.array([0.55, 0.45, top_z + 0.1]))
    table = np.concatenate([top, *legs, panel])
    return np.concatenate([table, mug]).astype(np.float32), np.r_[np.ones(len(table), int), np.full(len(mug), 2)]


def test_a_small_object_on_a_table_top_is_split_off_and_the_tables_own_parts_stay() -> None:
    points, truth = table_with_mug()
    regions = np.zeros(len(points), np.int64)
    out = split_off_supported(points, regions, neighbours(points), SupportSplitConfig(), STEP)
    assert (out[truth == 1] == 0).all()  # legs below the top, the panel too large to be an object
    mug = out[truth == 2]  # all but its bottom rim, which lies in the top's band
    ids, n = np.unique(mug[mug != 0], return_counts=True)
    assert len(ids) == 1 and n[0] > 0.7 * len(mug)
    # a larger max_size takes the panel too; disabled, nothing moves
    big = split_off_supported(points, regions, neighbours(points), SupportSplitConfig(max_size=1.5), STEP)
    assert len(np.unique(big)) == 3
    off = split_off_supported(points, regions, neighbours(points), SupportSplitConfig(enabled=False), STEP)
    np.testing.assert_array_equal(off, regions)


def test_a_region_without_a_large_enough_top_keeps_what_stands_on_it() -> None:
    points, _ = table_with_mug()
    regions = np.zeros(len(points), np.int64)
    out = split_off_supported(points, regions, neighbours(points), SupportSplitConfig(min_area=1.0), STEP)
    np.testing.assert_array_equal(out, regions)


def test_affinity_grouping_splits_what_every_view_merges_with_the_floor() -> None:
    points, truth = floor_with_box(3.0, box=0.2)
    every = np.arange(len(points), dtype=np.int32)
    obs = [FrameObservation(0, every, np.zeros((len(points), 2), np.int16), masks=[every])] * 4
    geometry_off = A.AffinityConfig(planes=PlaneSplitConfig(enabled=False), supports=SupportSplitConfig(enabled=False))
    assert len(np.unique(A.lift_by_affinity(points, obs, geometry_off, STEP))) == 1
    for cfg in (A.AffinityConfig(), A.AffinityConfig(planes=PlaneSplitConfig(enabled=False))):
        split = A.lift_by_affinity(points, obs, cfg, STEP)  # the floor is the box's support too
        floor_id, box_id = np.bincount(split[truth == 1]).argmax(), np.bincount(split[truth == 2]).argmax()
        assert floor_id != box_id and np.mean(split[truth == 2] == box_id) > 0.8


@pytest.mark.parametrize("bad", [{"min_area": 0.0}, {"distance_spacings": -1.0}, {"iterations": 0}])
def test_plane_config_refuses_out_of_range_values(bad: dict) -> None:
    with pytest.raises(ValueError):
        PlaneSplitConfig(**bad)


@pytest.mark.parametrize("bad", [{"min_area": -1.0}, {"max_size": 0.0}, {"horizontal_degrees": 90.0}])
def test_support_config_refuses_out_of_range_values(bad: dict) -> None:
    with pytest.raises(ValueError):
        SupportSplitConfig(**bad)
