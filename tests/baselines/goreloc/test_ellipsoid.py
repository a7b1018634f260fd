import cv2
import numpy as np
import pytest
from scipy.linalg import sqrtm

from baselines.goreloc.ellipsoid import (
    dual_quadrics,
    ellipse_boxes,
    ellipses_from_boxes,
    fit_ellipsoid,
    ngwd,
    project_quadrics,
    projection_matrix,
)
from openreloc_bench import geometry


def _rot_z(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])


def test_projected_dual_quadric_is_the_ellipse_fitted_to_its_projected_surface_points():
    K = geometry.intrinsics(500.0, 500.0, 320.0, 240.0)
    T_wc = geometry.look_at([3.0, -2.0, 1.8], [0.2, 0.1, 0.7])
    centre, R, axes = (
        np.array([0.3, 0.0, 0.8]),
        _rot_z(0.7) @ geometry.quat_to_rotmat([0.96, 0.2, 0.1, 0.0]),
        np.array([0.5, 0.3, 0.2]),
    )
    mu, S, valid = project_quadrics(dual_quadrics(centre[None], R[None], axes[None]), projection_matrix(K, T_wc))
    assert valid[0]
    th, ph = np.meshgrid(np.linspace(0, np.pi, 400), np.linspace(0, 2 * np.pi, 800))
    unit = np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], -1).reshape(-1, 3)
    uv, _ = geometry.project(K, T_wc, centre + (unit * axes) @ R.T)
    hull = cv2.convexHull(uv.astype(np.float32))
    (cx, cy), (w, h), angle = cv2.fitEllipse(hull)
    t = np.deg2rad(angle)
    R2 = np.array([[np.cos(t), -np.sin(t)], [np.sin(t), np.cos(t)]])
    S_fit = R2 @ np.diag([(w / 2) ** 2, (h / 2) ** 2]) @ R2.T
    assert np.allclose(mu[0], [cx, cy], atol=0.3)
    assert np.allclose(np.sqrt(np.linalg.eigvalsh(S[0])), np.sqrt(np.linalg.eigvalsh(S_fit)), rtol=0.01)
    assert np.allclose(S[0], S_fit, rtol=0.02, atol=0.02 * np.abs(S_fit).max())


def test_projection_is_invalid_behind_or_around_the_camera():
    K = geometry.intrinsics(500.0, 500.0, 320.0, 240.0)
    T_wc = np.eye(4)  # looking along +z
    Q = dual_quadrics(
        np.array([[0, 0, 4.0], [0, 0, -4.0], [0, 0, 0.2]]), np.repeat(np.eye(3)[None], 3, 0), np.full((3, 3), 0.5)
    )
    _, _, valid = project_quadrics(Q, projection_matrix(K, T_wc))
    assert valid.tolist() == [True, False, False]


def test_box_ellipses_are_inscribed():
    mu, S = ellipses_from_boxes(np.array([[10, 20, 50, 40]]))
    assert np.allclose(mu, [[30, 30]]) and np.allclose(S, [[[400, 0], [0, 100]]])
    assert np.allclose(ellipse_boxes(mu, S), [[10, 20, 50, 40]])


def test_ngwd_is_one_for_identical_ellipses_and_falls_with_distance():
    mu, S = ellipses_from_boxes(np.array([[100, 100, 180, 140]]))
    assert ngwd(mu, S, mu, S, 100.0)[0] == pytest.approx(1.0)
    shifts = np.array([0.0, 5.0, 20.0, 80.0, 300.0])
    values = ngwd(np.repeat(mu, 5, 0), np.repeat(S, 5, 0), mu + shifts[:, None], np.repeat(S, 5, 0), 100.0)
    assert np.all(np.diff(values) < 0) and values[-1] < 0.1
    bigger = ellipses_from_boxes(np.array([[90, 90, 190, 150]]))[1]
    assert ngwd(mu, S, mu, bigger, 100.0)[0] < 1.0


def test_ngwd_closed_form_matches_the_matrix_square_root():
    rng = np.random.default_rng(0)
    for _ in range(20):
        A, B = rng.normal(size=(2, 2, 2)) * 30
        S1, S2 = A @ A.T + np.eye(2), B @ B.T + np.eye(2)
        mu1, mu2 = rng.normal(size=(2, 2)) * 50
        r1 = np.real(sqrtm(S1))
        w2 = np.sum((mu1 - mu2) ** 2) + np.trace(S1 + S2 - 2 * np.real(sqrtm(r1 @ S2 @ r1)))
        assert ngwd(mu1, S1, mu2, S2, 100.0) == pytest.approx(np.exp(-np.sqrt(w2) / 100.0), rel=1e-6)


def test_fit_recovers_an_upright_ellipsoid_inscribed_in_the_points_box():
    rng = np.random.default_rng(1)
    R, half = _rot_z(0.4), np.array([0.6, 0.3, 0.4])
    pts = rng.uniform(-1, 1, (5000, 3)) * half @ R.T + [1.0, 2.0, 0.4]
    centre, R_fit, axes = fit_ellipsoid(pts, trim=0.0)
    assert np.allclose(centre, [1.0, 2.0, 0.4], atol=0.01)
    assert np.allclose(axes, half, atol=0.01)
    assert abs(abs(R_fit[:, 0] @ R[:, 0]) - 1) < 1e-3 and np.isclose(np.linalg.det(R_fit), 1.0)


def test_fit_stands_the_ellipsoid_along_the_worlds_up():
    rng = np.random.default_rng(2)
    R, half = _rot_z(0.4), np.array([0.6, 0.3, 0.4])
    z_up = rng.uniform(-1, 1, (5000, 3)) * half @ R.T + [1.0, 2.0, 0.4]
    to_y_down = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])  # a 7-Scenes-like world
    centre, R_fit, axes = fit_ellipsoid(z_up @ to_y_down.T, trim=0.0, up=to_y_down @ [0.0, 0.0, 1.0])
    assert np.allclose(centre, to_y_down @ [1.0, 2.0, 0.4], atol=0.01)
    assert np.allclose(axes, half, atol=0.01)
    assert np.allclose(R_fit[:, 2], [0.0, -1.0, 0.0], atol=1e-9)  # the vertical semi-axis is up
