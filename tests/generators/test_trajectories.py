"""Occupancy grid, mapping scan and query sampling."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy import ndimage

from generators.layout import build_layout
from generators.render import create_renderer
from generators.spec import SceneSpec, load_suite
from generators.trajectories import (
    QUERY_HEIGHT,
    mapping_path,
    mapping_trajectory,
    occupancy_grid,
    sample_near_queries,
    sample_queries,
    sample_walk,
    walkable_region,
)
from openreloc_bench import geometry

SUITES = Path(__file__).resolve().parents[2] / "scenes"

SPEC = SceneSpec(
    name="t",
    kind="multi-room",
    seed=21,
    rooms=3,
    objects_per_room=10,
    width=96,
    height=72,
    n_query=5,
    mapping_step_m=0.25,
    mapping_step_deg=15.0,
)


@pytest.fixture(scope="module")
def scene():
    layout = build_layout(SPEC)
    mapping = mapping_trajectory(layout, SPEC)
    return layout, mapping


def test_occupancy_excludes_objects(scene) -> None:
    layout, _ = scene
    occ = occupancy_grid(layout, 0)
    assert occ.free.any()
    for inst in layout.instances:
        if not inst.structural and inst.aabb[0, 2] < 1.9 and inst.aabb[1, 2] > 0.05:
            c = inst.aabb.mean(axis=0)[:2]
            assert not occ.is_free(c[None])[0], inst.category


# sc6 of the multi-room suite under gen1: a pendant light and one-cell gaps cut its corridor in three,
# so five of eight rooms were never mapped but still got queries
def _suite_scene(name: str) -> SceneSpec:
    """A scene spec of the shipped multi-room suite, read when the test runs (not at collection)."""
    return next(s for s in load_suite(SUITES / "multi-room.yaml").scene_specs() if s.name == name)


@pytest.mark.parametrize("name", ["small", "sc6"])
def test_every_room_is_in_the_walkable_region(name: str) -> None:
    layout = build_layout(SPEC if name == "small" else _suite_scene(name))
    occ = occupancy_grid(layout, 0)
    region = walkable_region(occ)
    for k, room in enumerate(occ.rooms):
        free = occ.free & (occ.room_index == k)
        assert (region & free).sum() >= 0.9 * free.sum(), room.name


def test_mapping_scan(scene) -> None:
    layout, mapping = scene
    assert geometry.is_rigid(mapping)
    occ = occupancy_grid(layout, 0)
    assert occ.is_free(mapping[:, :2, 3]).all()
    h = mapping[:, 2, 3]
    assert h.min() >= 1.2 - 1e-6 and h.max() <= 1.7 + 1e-6
    step = np.linalg.norm(np.diff(mapping[:, :3, 3], axis=0), axis=1)
    turn = geometry.rotation_error(mapping[:-1], mapping[1:])
    assert np.median(step) <= 0.3 and np.percentile(turn, 95) <= 20  # ~0.25 m / ~15 deg per frame
    assert np.percentile(step, 99) < 0.6  # smooth: no jumps through walls
    visited = {occ.rooms[k].name for k in occ.room_index[occ.cell(mapping[:, :2, 3])]}
    assert visited == {r.name for r in layout.rooms}
    # the camera is upright (no roll) in mapping: image x axis stays horizontal
    assert np.abs(mapping[:, 2, 0]).max() < 1e-6


def test_queries_change_viewpoint_and_see_objects(scene) -> None:
    layout, mapping = scene
    with create_renderer(layout, "mujoco", SPEC.width, SPEC.height) as r:
        poses, infos = sample_queries(layout, SPEC, mapping, r)
    assert len(poses) == SPEC.n_query and geometry.is_rigid(poses)
    boxes = np.array([i.aabb for i in layout.instances if not i.structural])
    for T, info in zip(poses, infos):
        eye = T[:3, 3]
        assert QUERY_HEIGHT[0] - 1e-6 <= eye[2] <= QUERY_HEIGHT[1] + 1e-6
        assert not np.any(np.all((eye > boxes[:, 0]) & (eye < boxes[:, 1]), axis=1))  # never inside an object
        d = np.linalg.norm(mapping[:, :3, 3] - eye, axis=1)
        assert d.min() >= SPEC.query_min_distance and info.distance_m == pytest.approx(d.min(), abs=1e-3)
        assert info.visible_objects >= SPEC.query_min_objects
    occ = occupancy_grid(layout, 0)
    assert walkable_region(occ)[occ.cell(poses[:, :2, 3])].all()  # only where the mapping sequence goes
    pitch = np.degrees(np.arcsin(-poses[:, 2, 2]))
    assert pitch.std() > 3  # varied pitch


def test_near_queries_lie_on_the_path_between_mapping_frames(scene) -> None:
    layout, mapping = scene
    path, frames = mapping_path(layout, SPEC)
    assert np.array_equal(path[frames], mapping)
    with create_renderer(layout, "mujoco", SPEC.width, SPEC.height) as r:
        poses = sample_near_queries(layout, SPEC, path, frames, r)
        again = sample_near_queries(layout, SPEC, path, frames, r)
    assert len(poses) == SPEC.n_query and geometry.is_rigid(poses) and np.array_equal(poses, again)
    for T in poses:  # a pose of the path, 30-70% of the way from one mapping frame to the next
        j = int(np.flatnonzero(np.all(np.isclose(path, T), axis=(1, 2)))[0])
        k = int(np.searchsorted(frames, j)) - 1
        assert frames[k] < j < frames[k + 1]
        assert 0.3 - 1e-9 <= (j - frames[k]) / (frames[k + 1] - frames[k]) <= 0.7 + 1e-9


@pytest.mark.parametrize("spec", [SPEC, replace(SPEC, n_query=40)], ids=["short", "long"])
def test_the_walk_is_a_smooth_sequence_on_another_route(scene, spec: SceneSpec) -> None:
    layout, _ = scene
    walk = sample_walk(layout, spec)
    assert len(walk) == spec.n_query and geometry.is_rigid(walk) and np.array_equal(walk, sample_walk(layout, spec))
    step = np.linalg.norm(np.diff(walk[:, :3, 3], axis=0), axis=1)
    turn = geometry.rotation_error(walk[:-1], walk[1:])
    assert step.max() <= spec.mapping_step_m + 0.03 and turn.max() <= spec.mapping_step_deg + 3  # as the mapping's
    assert step.min() > 0.02  # a walk, not a camera standing still
    occ = occupancy_grid(layout, 0)
    region = ndimage.binary_dilation(walkable_region(occ), np.ones((3, 3)))  # straight stretches cut corners
    assert region[occ.cell(walk[:, :2, 3])].all()
    assert np.abs(walk[:, 2, 0]).max() < 1e-6 and (walk[:, 2, 3] >= QUERY_HEIGHT[0]).all()  # upright, hand-held
    path, _ = mapping_path(layout, spec)
    gap = np.linalg.norm(walk[:, None, :3, 3] - path[None, :, :3, 3], axis=2)
    along = geometry.rotation_error(path[gap.argmin(axis=1)], walk)
    assert np.median(gap.min(axis=1)) > 0.1 and np.median(along) > 30  # not the mapping camera's path
    other = sample_walk(layout, replace(spec, seed=spec.seed + 1))
    assert not np.allclose(other[:2], walk[:2])  # the seed chooses where it starts
