"""Rigid transforms, quaternions, the pinhole camera and pose errors.

One source of truth for the project's conventions (see ARCHITECTURE.md):
poses are 4x4 float64 camera-to-world matrices ``T_wc`` in OpenCV camera axes (x right, y down,
z forward); quaternions are (w, x, y, z), unit, with w >= 0. scipy's ``Rotation`` uses (x, y, z, w),
so conversions happen here and nowhere else. Every function accepts a single item or a batch
(leading dimensions) so callers never loop in Python over poses or points.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

ArrayLike = np.ndarray

# OpenGL / pyrender / MuJoCo cameras look down -z with y up; OpenCV looks down +z with y down.
# Right-multiplying a camera-to-world pose by this flips between the two conventions.
GL_TO_CV = np.diag([1.0, -1.0, -1.0, 1.0])


class GeometryError(ValueError):
    """A pose, rotation or camera that violates the project's conventions."""


# --------------------------------------------------------------------------------------------
# SE(3)
# --------------------------------------------------------------------------------------------


def make_pose(R: ArrayLike, t: ArrayLike) -> np.ndarray:
    """Stack rotation(s) ``(...,3,3)`` and translation(s) ``(...,3)`` into ``(...,4,4)`` poses."""
    R = np.asarray(R, dtype=np.float64)
    t = np.asarray(t, dtype=np.float64)
    T = np.zeros(np.broadcast_shapes(R.shape[:-2], t.shape[:-1]) + (4, 4))
    T[..., :3, :3] = R
    T[..., :3, 3] = t
    T[..., 3, 3] = 1.0
    return T


def invert(T: ArrayLike) -> np.ndarray:
    """Inverse of rigid transform(s), using R^T rather than a general matrix inverse."""
    T = np.asarray(T, dtype=np.float64)
    Rt = np.swapaxes(T[..., :3, :3], -1, -2)
    return make_pose(Rt, -np.einsum("...ij,...j->...i", Rt, T[..., :3, 3]))


def compose(*transforms: ArrayLike) -> np.ndarray:
    """Left-to-right product ``T1 @ T2 @ ...`` of (batches of) 4x4 transforms."""
    out = np.asarray(transforms[0], dtype=np.float64)
    for T in transforms[1:]:
        out = out @ np.asarray(T, dtype=np.float64)
    return out


def transform_points(T: ArrayLike, points: ArrayLike) -> np.ndarray:
    """Apply a 4x4 transform to points ``(N,3)`` (or a batch of transforms to matching batches)."""
    T = np.asarray(T, dtype=np.float64)
    points = np.asarray(points, dtype=np.float64)
    return points @ np.swapaxes(T[..., :3, :3], -1, -2) + T[..., None, :3, 3]


def is_rigid(T: ArrayLike, tol: float = 1e-4) -> bool:
    """True if every matrix is a proper rigid transform (orthonormal R, det +1, last row 0 0 0 1)."""
    T = np.asarray(T, dtype=np.float64)
    if T.shape[-2:] != (4, 4) or not np.all(np.isfinite(T)):
        return False
    R = T[..., :3, :3]
    ortho = np.abs(R @ np.swapaxes(R, -1, -2) - np.eye(3)).max() < tol
    det = np.abs(np.linalg.det(R) - 1.0).max() < tol
    last = np.abs(T[..., 3, :] - np.array([0, 0, 0, 1.0])).max() < tol
    return bool(ortho and det and last)


def check_pose(T: ArrayLike, what: str = "pose") -> np.ndarray:
    """Return ``T`` as float64 (4,4) or raise :class:`GeometryError` saying what is wrong."""
    T = np.asarray(T, dtype=np.float64)
    if T.shape != (4, 4):
        raise GeometryError(f"{what}: expected a 4x4 matrix, got shape {T.shape}")
    if not np.all(np.isfinite(T)):
        raise GeometryError(f"{what}: contains NaN or inf")
    if not is_rigid(T):
        raise GeometryError(f"{what}: not a rigid transform (rotation not orthonormal or last row not 0 0 0 1)")
    return T


# --------------------------------------------------------------------------------------------
# Quaternions (w, x, y, z)
# --------------------------------------------------------------------------------------------


def quat_canonical(q: ArrayLike) -> np.ndarray:
    """Normalise quaternion(s) and flip the sign so that w >= 0 (q and -q are the same rotation)."""
    q = np.asarray(q, dtype=np.float64)
    norm = np.linalg.norm(q, axis=-1, keepdims=True)
    if np.any(norm < 1e-12) or not np.all(np.isfinite(q)):
        raise GeometryError("quaternion with zero norm or non-finite entries")
    q = q / norm
    return np.where(q[..., :1] < 0, -q, q)


def quat_to_rotmat(q: ArrayLike) -> np.ndarray:
    """(w, x, y, z) quaternion(s) -> rotation matrices ``(...,3,3)``."""
    q = quat_canonical(q)
    shape = q.shape[:-1]
    R = Rotation.from_quat(q.reshape(-1, 4)[:, [1, 2, 3, 0]]).as_matrix()
    return R.reshape(shape + (3, 3))


def rotmat_to_quat(R: ArrayLike) -> np.ndarray:
    """Rotation matrices ``(...,3,3)`` -> canonical (w, x, y, z) quaternion(s)."""
    R = np.asarray(R, dtype=np.float64)
    shape = R.shape[:-2]
    xyzw = Rotation.from_matrix(R.reshape(-1, 3, 3)).as_quat()
    return quat_canonical(xyzw[:, [3, 0, 1, 2]]).reshape(shape + (4,))


def pose_to_qt(T: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """4x4 pose(s) -> ((w,x,y,z), t)."""
    T = np.asarray(T, dtype=np.float64)
    return rotmat_to_quat(T[..., :3, :3]), T[..., :3, 3].copy()


def qt_to_pose(q: ArrayLike, t: ArrayLike) -> np.ndarray:
    """((w,x,y,z), t) -> 4x4 pose(s)."""
    return make_pose(quat_to_rotmat(q), t)


def look_at(eye: ArrayLike, target: ArrayLike, up: ArrayLike = (0.0, 0.0, 1.0)) -> np.ndarray:
    """Camera-to-world pose (OpenCV axes) at ``eye`` looking at ``target`` with world ``up``."""
    eye = np.asarray(eye, dtype=np.float64)
    forward = np.asarray(target, dtype=np.float64) - eye
    forward /= np.linalg.norm(forward)
    up = np.asarray(up, dtype=np.float64)
    right = np.cross(forward, up)
    if np.linalg.norm(right) < 1e-9:  # looking straight up/down: any horizontal right vector
        right = np.cross(forward, np.array([1.0, 0.0, 0.0]))
    right /= np.linalg.norm(right)
    down = np.cross(forward, right)
    return make_pose(np.stack([right, down, forward], axis=1), eye)


# --------------------------------------------------------------------------------------------
# Pinhole camera
# --------------------------------------------------------------------------------------------


def intrinsics(fx: float, fy: float, cx: float, cy: float) -> np.ndarray:
    """3x3 intrinsic matrix K."""
    return np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])


def intrinsics_from_fov(width: int, height: int, fov_y_deg: float) -> np.ndarray:
    """K for a centred pinhole camera with square pixels and the given vertical field of view.

    Pixel centres sit at integer coordinates, so the principal point of a W x H image is
    ((W-1)/2, (H-1)/2).
    """
    fy = 0.5 * height / np.tan(np.radians(fov_y_deg) / 2)
    return intrinsics(fy, fy, (width - 1) / 2.0, (height - 1) / 2.0)


def project(K: ArrayLike, T_wc: ArrayLike, points_w: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Project world points ``(N,3)`` into pixels.

    Returns ``(uv (N,2), depth (N,))``; points behind the camera get depth <= 0 and should be masked
    by the caller (their uv is still finite to keep the output vectorised).
    """
    p_c = transform_points(invert(T_wc), points_w)
    z = p_c[..., 2]
    z_safe = np.where(np.abs(z) < 1e-9, 1e-9, z)
    uv = (p_c[..., :2] / z_safe[..., None]) @ np.asarray(K)[:2, :2].T + np.asarray(K)[:2, 2]
    return uv, z


def unproject(K: ArrayLike, uv: ArrayLike, depth: ArrayLike) -> np.ndarray:
    """Pixels ``(N,2)`` with metric depths ``(N,)`` -> camera-frame points ``(N,3)``."""
    K = np.asarray(K, dtype=np.float64)
    uv = np.asarray(uv, dtype=np.float64)
    depth = np.asarray(depth, dtype=np.float64)
    x = (uv[..., 0] - K[0, 2]) / K[0, 0] * depth
    y = (uv[..., 1] - K[1, 2]) / K[1, 1] * depth
    return np.stack([x, y, depth], axis=-1)


def depth_to_points(
    depth: ArrayLike, K: ArrayLike, T_wc: ArrayLike | None = None, mask: ArrayLike | None = None
) -> np.ndarray:
    """Valid (finite, > 0) depth pixels -> points ``(N,3)``, in world frame if ``T_wc`` is given."""
    depth = np.asarray(depth, dtype=np.float64)
    valid = np.isfinite(depth) & (depth > 0)
    if mask is not None:
        valid &= np.asarray(mask, dtype=bool)
    v, u = np.nonzero(valid)
    pts = unproject(K, np.stack([u, v], axis=-1), depth[v, u])
    return pts if T_wc is None else transform_points(T_wc, pts)


def reproject_depth(
    depth: ArrayLike, K_from: ArrayLike, K_to: ArrayLike, T_to_from: ArrayLike, hw_to: tuple[int, int]
) -> np.ndarray:
    """A depth map as another pinhole camera sees it (``T_to_from`` maps the first camera's points
    into the second's): each valid pixel lands on its nearest pixel there, the nearest surface wins,
    and pixels no depth reaches are 0 (invalid). Float32 (H, W) at ``hw_to``."""
    h, w = hw_to
    pts = transform_points(T_to_from, depth_to_points(depth, K_from))
    pts = pts[pts[:, 2] > 0]
    uv = np.rint(pts[:, :2] / pts[:, 2:] @ np.asarray(K_to)[:2, :2].T + np.asarray(K_to)[:2, 2]).astype(np.int64)
    inside = (uv[:, 0] >= 0) & (uv[:, 0] < w) & (uv[:, 1] >= 0) & (uv[:, 1] < h)
    nearest = np.full(h * w, np.inf)
    np.minimum.at(nearest, uv[inside, 1] * w + uv[inside, 0], pts[inside, 2])
    return np.where(np.isfinite(nearest), nearest, 0.0).reshape(h, w).astype(np.float32)


# --------------------------------------------------------------------------------------------
# Pose errors
# --------------------------------------------------------------------------------------------


def translation_error(T_gt: ArrayLike, T_est: ArrayLike) -> np.ndarray:
    """Distance between camera centres (metres) of camera-to-world poses."""
    T_gt, T_est = np.asarray(T_gt, dtype=np.float64), np.asarray(T_est, dtype=np.float64)
    return np.linalg.norm(T_gt[..., :3, 3] - T_est[..., :3, 3], axis=-1)


def rotation_error(T_gt: ArrayLike, T_est: ArrayLike) -> np.ndarray:
    """Angle (degrees) of ``R_gt^T R_est``; accepts 4x4 poses or 3x3 rotations."""
    R_gt = np.asarray(T_gt, dtype=np.float64)[..., :3, :3]
    R_est = np.asarray(T_est, dtype=np.float64)[..., :3, :3]
    trace = np.einsum("...ji,...ji->...", R_gt, R_est)  # trace(R_gt^T R_est)
    return np.degrees(np.arccos(np.clip((trace - 1.0) / 2.0, -1.0, 1.0)))


def pose_errors(T_gt: ArrayLike, T_est: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """(translation error in metres, rotation error in degrees)."""
    return translation_error(T_gt, T_est), rotation_error(T_gt, T_est)
