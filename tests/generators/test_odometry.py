"""RGB-D odometry and pose graph: the alignment and drift measures, and the path recovered from a
synthetic sequence (a textured box room ray-cast with numpy, with Kinect-like depth noise and holes)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from generators.odometry import OdometryConfig, align_to, drift, estimate_trajectory, loop_candidates
from openreloc_bench import geometry

W, H = 160, 120
K = geometry.intrinsics_from_fov(W, H, 60.0)
ROOM = np.array([[0.0, 0.0, 0.0], [6.0, 6.0, 3.0]])
BOXES = np.array(
    [[[0.5, 4.5, 0.0], [1.3, 5.5, 0.9]], [[4.6, 0.6, 0.0], [5.5, 1.4, 1.2]], [[4.8, 4.0, 0.8], [6.0, 4.8, 1.6]]]
)
PLANES = np.concatenate([ROOM[None], BOXES]).reshape(-1, 3)  # each row: a corner, giving 3 planes


def circle(n: int = 24, step_m: float = 0.2, step_deg: float = 15.0) -> np.ndarray:
    """A hand-held loop in the room: camera centres on a circle (step_m apart, a full turn for 24
    frames), each view turned step_deg from the last, looking outwards and a little down."""
    radius = step_m / np.radians(step_deg)
    poses = []
    for k in range(n):
        a = np.radians(step_deg) * k
        eye = np.array([3 + radius * np.cos(a), 3 + radius * np.sin(a), 1.4 + 0.1 * np.sin(2 * a)])
        yaw = a + np.radians(60)
        poses.append(geometry.look_at(eye, eye + [2 * np.cos(yaw), 2 * np.sin(yaw), -0.35]))
    return np.array(poses)


def texture() -> np.ndarray:
    """Blurred random noise at two scales: blobs SIFT finds on every surface."""
    rng = np.random.default_rng(0)
    t = sum(cv2.GaussianBlur(rng.normal(size=(512, 512, 3)).astype(np.float32), (0, 0), s) * s for s in (1.5, 4.0))
    return ((t - t.min()) / np.ptp(t) * 255).astype(np.float32)


def render(T: np.ndarray, tex: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Colour and depth of the room from T_wc: each ray's nearest box face, textured by its position on
    that face and shaded by its orientation; depth with 0.3 % noise and 2 % holes."""
    u, v = np.meshgrid(np.arange(W), np.arange(H))
    rays = (
        np.stack([(u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1], np.ones((H, W))], -1).reshape(-1, 3) @ T[:3, :3].T
    )
    o = T[:3, 3]
    with np.errstate(divide="ignore", invalid="ignore"):
        depth = np.max((ROOM - o)[:, None] / rays, axis=0).min(axis=1)  # where the ray leaves the room
        for box in BOXES:
            t = (box - o)[:, None] / rays
            near, far = t.min(axis=0).max(axis=1), t.max(axis=0).min(axis=1)
            depth = np.where((near <= far) & (near > 0) & (near < depth), near, depth)  # z = 1 on the rays
    p = o + rays * depth[:, None]
    plane = np.abs(p[:, None] - PLANES[None]).reshape(len(p), -1).argmin(axis=1)
    axis = plane % 3
    a = np.take_along_axis(p, ((axis + 1) % 3)[:, None], 1)[:, 0]
    b = np.take_along_axis(p, ((axis + 2) % 3)[:, None], 1)[:, 0]
    mx, my = ((c * 40 + plane * 37).astype(np.float32).reshape(H, W) for c in (a, b))
    rgb = cv2.remap(tex, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_WRAP) * (0.6 + 0.2 * axis.reshape(H, W, 1))
    depth = depth.reshape(H, W) * (1 + rng.normal(0, 0.003, (H, W)))
    depth[rng.random((H, W)) < 0.02] = 0
    return np.clip(rgb, 0, 255).astype(np.uint8), depth.astype(np.float32)


@pytest.fixture(scope="module")
def sequence() -> tuple[list[np.ndarray], list[np.ndarray], np.ndarray]:
    truth, tex, rng = circle(), texture(), np.random.default_rng(1)
    frames = [render(T, tex, rng) for T in truth]
    return [f[0] for f in frames], [f[1] for f in frames], truth


def random_motion(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    q = rng.normal(size=4)
    return geometry.make_pose(geometry.quat_to_rotmat(q / np.linalg.norm(q)), rng.normal(0, 3, 3))


def test_align_to_undoes_a_rigid_motion() -> None:
    truth = circle()
    moved = random_motion(0) @ truth
    assert np.allclose(align_to(moved, truth), truth, atol=1e-9)
    d = drift(moved, truth)
    assert d.ate_rmse_m < 1e-9 and d.ate_max_m < 1e-9 and d.rotation_max_deg < 1e-4


def test_drift_measures_a_known_perturbation() -> None:
    """Centres pushed 5 cm up and down in turn (their best rigid fit is the identity), views turned 2
    degrees about their optical axes and one view 6 degrees."""
    truth = circle()
    est = truth.copy()
    est[:, 2, 3] += 0.05 * (-1) ** np.arange(len(est))
    est[:, :3, :3] = est[:, :3, :3] @ geometry.quat_to_rotmat([np.cos(np.radians(1)), 0, 0, np.sin(np.radians(1))])
    est[5, :3, :3] = truth[5, :3, :3] @ geometry.quat_to_rotmat([np.cos(np.radians(3)), np.sin(np.radians(3)), 0, 0])
    d = drift(random_motion(1) @ est, truth)
    assert d.ate_rmse_m == pytest.approx(0.05, abs=1e-6) and d.ate_max_m == pytest.approx(0.05, abs=1e-6)
    assert d.rotation_median_deg == pytest.approx(2.0, abs=1e-4) and d.rotation_max_deg == pytest.approx(6.0, abs=1e-4)


def test_align_to_moves_segments_each_on_its_own() -> None:
    truth = circle()
    segments = np.repeat([0, 1], 12)
    moved = np.concatenate([random_motion(3) @ truth[:12], random_motion(4) @ truth[12:]])
    assert np.allclose(align_to(moved, truth, segments), truth, atol=1e-9)
    assert drift(moved, truth).ate_rmse_m > 0.1 and drift(moved, truth, segments).ate_max_m < 1e-9
    with pytest.raises(ValueError, match="segments must have shape"):
        align_to(moved, truth, segments[:5])


def test_align_to_one_centre_and_bad_shapes() -> None:
    truth = np.stack([geometry.look_at([1, 2, 1.5], [3, 2, 1]), geometry.look_at([1, 2, 1.5], [1, 4, 1])])
    moved = random_motion(2) @ truth
    assert np.allclose(align_to(moved, truth), truth, atol=1e-9)
    with pytest.raises(ValueError, match="N, 4, 4"):
        align_to(moved[:1], truth)


def test_loop_candidates_pick_one_frame_per_earlier_visit() -> None:
    truth = circle(30)  # frames 24-29 revisit frames 0-5
    cfg = OdometryConfig(max_loop_candidates=3)
    assert loop_candidates(truth, 25, cfg) == [1, 22]  # 23 and 24 are too recent, 22 is 0.4 m off
    assert loop_candidates(truth, 25, OdometryConfig(max_loop_candidates=1)) == [1]
    assert loop_candidates(truth, 2, cfg) == []


def test_estimate_recovers_the_path(sequence) -> None:
    rgbs, depths, truth = sequence
    first = estimate_trajectory(rgbs, depths, K, truth[0])
    assert np.allclose(first.poses[0], truth[0]) and geometry.is_rigid(first.poses)
    d = drift(first.poses, truth)
    assert d.ate_rmse_m < 0.03 and d.ate_max_m < 0.05 and d.rotation_max_deg < 1.5, d
    assert geometry.translation_error(truth, first.poses).max() < 0.1  # anchored at frame 0, not only aligned
    assert first.failed_pairs == 0 and first.loop_closures >= 1 and not first.segments.any()
    assert first.edges == len(truth) - 1 + first.loop_closures
    again = estimate_trajectory(rgbs, depths, K, truth[0])
    assert np.array_equal(again.poses, first.poses) and again.edges == first.edges


def test_a_black_frame_splits_the_trajectory_without_crashing(sequence) -> None:
    rgbs, depths, truth = (x[:7] for x in sequence)
    rgbs, depths = list(rgbs), list(depths)
    rgbs[3], depths[3] = np.zeros_like(rgbs[3]), np.zeros_like(depths[3])
    est = estimate_trajectory(rgbs, depths, K, truth[0], OdometryConfig(max_loop_candidates=0))
    assert est.failed_pairs == 2 and est.poses.shape == truth.shape and np.isfinite(est.poses).all()
    assert est.segments.tolist() == [0, 0, 0, 1, 2, 2, 2]
    assert geometry.translation_error(truth[:3], est.poses[:3]).max() < 0.03
    assert drift(est.poses, truth, est.segments).ate_max_m < 0.03


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("max_keypoints", 2, "max_keypoints must be >= 4"),
        ("min_inliers", 0, "min_inliers must be >= 4"),
        ("loop_radius_m", 0.0, "loop_radius_m must be > 0"),
        ("loop_angle_deg", 200.0, r"loop_angle_deg must be in \(0, 180\]"),
        ("max_loop_candidates", -1, "max_loop_candidates and seed must be >= 0"),
        ("min_fitness", 1.5, r"min_fitness must be in \[0, 1\]"),
        ("depth_trunc_m", -1.0, "depth_trunc_m must be > 0"),
    ],
)
def test_config_validation(field: str, value: float, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        OdometryConfig(**{field: value})


def test_input_validation(sequence) -> None:
    rgbs, depths, truth = sequence
    with pytest.raises(ValueError, match="as many colour as depth"):
        estimate_trajectory(rgbs[:3], depths[:2], K, truth[0])
    with pytest.raises(ValueError, match="all of one size"):
        estimate_trajectory([rgbs[0], rgbs[1][:60]], depths[:2], K, truth[0])
