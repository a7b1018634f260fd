"""Up established from the cameras and the cloud's horizontal surfaces, whatever the world frame."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from openreloc_bench import geometry
from openreloc_bench.reconstruction.gravity import estimate_up, levelling


def room(R: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Cameras walking a z-up room, held level but pitched down by 10-30 degrees, and the room's floor,
    table top and two walls (1 cm apart), all turned by ``R`` into another world frame."""
    g = np.arange(0.0, 3.0, 0.02)
    floor = np.stack(np.meshgrid(g, g, [0.0]), -1).reshape(-1, 3)
    table = np.stack(np.meshgrid(g[:40] + 1, g[:40] + 1, [0.75]), -1).reshape(-1, 3)
    wall_x = np.stack(np.meshgrid([0.0], g, g[:120]), -1).reshape(-1, 3)
    wall_y = np.stack(np.meshgrid(g, [3.0], g[:120]), -1).reshape(-1, 3)
    points = np.concatenate([floor, table, wall_x, wall_y]) + rng.normal(0, 0.002, (1, 3))
    poses = []
    for yaw in np.linspace(0, 300, 12):
        d = np.radians(yaw)
        eye = np.array([1.5 + np.cos(d), 1.5 + np.sin(d), 1.5])
        target = eye + np.array([np.cos(d), np.sin(d), -np.tan(np.radians(rng.uniform(10, 30)))])
        poses.append(geometry.look_at(eye, target))
    turn = geometry.make_pose(R, np.zeros(3))
    return np.stack([turn @ T for T in poses]), points @ R.T


@pytest.mark.parametrize("world", ["z up", "gravity along +y", "tilted"])
def test_up_is_found_in_any_world_frame(world: str) -> None:
    rng = np.random.default_rng(0)
    R = {
        "z up": np.eye(3),
        "gravity along +y": Rotation.from_euler("x", -90, degrees=True).as_matrix(),
        "tilted": Rotation.from_rotvec([0.3, -0.5, 0.2]).as_matrix(),
    }[world]
    poses, points = room(R, rng)
    up = estimate_up(poses, points, spacing=0.02)
    truth = R @ np.array([0.0, 0.0, 1.0])
    assert np.degrees(np.arccos(np.clip(up @ truth, -1, 1))) < 1.0  # the cameras alone are 10-30 deg off
    np.testing.assert_allclose(levelling(up) @ up, [0.0, 0.0, 1.0], atol=1e-9)
    assert geometry.is_rigid(geometry.make_pose(levelling(up), np.zeros(3)))


def test_without_horizontal_surfaces_the_cameras_decide() -> None:
    poses, _ = room(np.eye(3), np.random.default_rng(1))
    wall = np.stack(np.meshgrid([0.0], np.arange(0, 3, 0.02), np.arange(0, 2, 0.02)), -1).reshape(-1, 3)
    up = estimate_up(poses, wall, spacing=0.02)
    assert up[2] > 0.9  # roughly up: the pitched cameras' mean
