import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from openreloc_bench import geometry as g


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(0)


def random_poses(rng: np.random.Generator, n: int) -> np.ndarray:
    return g.make_pose(Rotation.random(n, random_state=rng.integers(1 << 31)).as_matrix(), rng.normal(size=(n, 3)))


def test_quaternion_matches_scipy(rng):
    R = Rotation.random(200, random_state=1)
    q = g.rotmat_to_quat(R.as_matrix())
    xyzw = R.as_quat()
    expected = np.where(xyzw[:, 3:] < 0, -xyzw, xyzw)[:, [3, 0, 1, 2]]
    np.testing.assert_allclose(q, expected, atol=1e-12)
    assert np.all(q[:, 0] >= 0)
    np.testing.assert_allclose(g.quat_to_rotmat(q), R.as_matrix(), atol=1e-12)


@pytest.mark.parametrize("axis", [[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 0]])
def test_180_degree_rotations_round_trip(axis):
    R = Rotation.from_rotvec(np.pi * np.array(axis, float) / np.linalg.norm(axis)).as_matrix()
    q = g.rotmat_to_quat(R)
    assert abs(q[0]) < 1e-12 and np.isclose(np.linalg.norm(q), 1)
    np.testing.assert_allclose(g.quat_to_rotmat(q), R, atol=1e-12)


def test_negative_w_quaternion_is_same_rotation():
    q = np.array([-0.5, 0.5, -0.5, 0.5])
    np.testing.assert_allclose(g.quat_to_rotmat(q), g.quat_to_rotmat(-q), atol=1e-12)
    assert g.quat_canonical(q)[0] > 0


def test_zero_quaternion_rejected():
    with pytest.raises(g.GeometryError):
        g.quat_to_rotmat([0, 0, 0, 0])


def test_invert_and_compose(rng):
    T = random_poses(rng, 50)
    np.testing.assert_allclose(g.compose(T, g.invert(T)), np.broadcast_to(np.eye(4), T.shape), atol=1e-12)
    np.testing.assert_allclose(g.invert(T), np.linalg.inv(T), atol=1e-10)
    q, t = g.pose_to_qt(T)
    np.testing.assert_allclose(g.qt_to_pose(q, t), T, atol=1e-12)


def test_transform_points_matches_homogeneous(rng):
    T = random_poses(rng, 1)[0]
    P = rng.normal(size=(20, 3))
    homo = (T @ np.c_[P, np.ones(20)].T).T[:, :3]
    np.testing.assert_allclose(g.transform_points(T, P), homo, atol=1e-12)


def test_project_unproject_round_trip(rng):
    K = g.intrinsics_from_fov(640, 480, 60)
    T_wc = random_poses(rng, 1)[0]
    uv = rng.uniform([0, 0], [640, 480], size=(100, 2))
    depth = rng.uniform(0.5, 8, 100)
    P_w = g.transform_points(T_wc, g.unproject(K, uv, depth))
    uv2, z = g.project(K, T_wc, P_w)
    np.testing.assert_allclose(uv2, uv, atol=1e-8)
    np.testing.assert_allclose(z, depth, atol=1e-10)


def test_depth_to_points_skips_invalid():
    K = g.intrinsics_from_fov(4, 3, 60)
    depth = np.full((3, 4), 2.0)
    depth[0, 0], depth[1, 1], depth[2, 2] = 0, np.nan, np.inf
    assert g.depth_to_points(depth, K).shape == (9, 3)


def test_reproject_depth_shifts_by_the_disparity_and_keeps_the_nearest_surface():
    """Seen from 0.1 m to the right (f = 100 px), a point at depth d moves 10 / d px to the left."""
    K = g.intrinsics(100.0, 100.0, 20.0, 10.0)
    depth = np.zeros((20, 40))
    depth[10, 30] = 2.0  # -> column 25
    depth[5, 30], depth[5, 25] = 1.0, 2.0  # both -> column 20: the nearer one hides the other
    depth[15, 2] = 1.0  # -> column -8: out of view
    depth[0, 0] = np.nan  # no reading
    out = g.reproject_depth(depth, K, K, g.make_pose(np.eye(3), [-0.1, 0.0, 0.0]), (20, 40))
    assert out.dtype == np.float32 and out.shape == (20, 40)
    assert {(int(v), int(u)): float(out[v, u]) for v, u in zip(*np.nonzero(out))} == {(10, 25): 2.0, (5, 20): 1.0}


def test_principal_point_at_pixel_centre():
    K = g.intrinsics_from_fov(640, 480, 60)
    uv, _ = g.project(K, np.eye(4), np.array([[0.0, 0.0, 2.0]]))
    np.testing.assert_allclose(uv[0], [319.5, 239.5])


def test_look_at_faces_target():
    T = g.look_at([1.0, 2.0, 1.5], [4.0, 2.0, 1.5])
    np.testing.assert_allclose(T[:3, 2], [1, 0, 0], atol=1e-12)  # camera z (forward)
    np.testing.assert_allclose(T[:3, 1], [0, 0, -1], atol=1e-12)  # camera y (down) is world -z
    assert g.is_rigid(T)


def test_pose_errors_known_values():
    T_gt = np.eye(4)
    T_est = g.make_pose(Rotation.from_euler("z", 30, degrees=True).as_matrix(), [0.3, 0.4, 0.0])
    te, re = g.pose_errors(T_gt, T_est)
    assert np.isclose(te, 0.5) and np.isclose(re, 30.0)
    # 180 degrees: arccos argument clipped to exactly -1
    T_flip = g.make_pose(np.diag([1.0, -1.0, -1.0]), [0, 0, 0])
    assert np.isclose(g.rotation_error(T_gt, T_flip), 180.0)


def test_rotation_error_matches_scipy(rng):
    A, B = random_poses(rng, 100), random_poses(rng, 100)
    expected = np.degrees((Rotation.from_matrix(A[:, :3, :3]).inv() * Rotation.from_matrix(B[:, :3, :3])).magnitude())
    np.testing.assert_allclose(g.rotation_error(A, B), expected, atol=1e-6)


@pytest.mark.parametrize(
    "bad",
    [np.full((4, 4), np.nan), np.diag([2.0, 1, 1, 1]), np.diag([1.0, 1, -1, 1]), np.eye(3)],
    ids=["nan", "scaled", "reflection", "shape"],
)
def test_check_pose_rejects(bad):
    with pytest.raises(g.GeometryError):
        g.check_pose(bad)
