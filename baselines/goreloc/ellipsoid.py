"""Objects as ellipsoids (dual quadrics), their projection to ellipses (dual conics), and the
normalised Gaussian Wasserstein distance (NGWD) GOReloc scores ellipse pairs with.

Conventions: an ellipsoid is a centre ``c`` (3,), a rotation ``R`` (3, 3) whose columns are its axes
and semi-axis lengths ``axes`` (3,); its dual quadric is ``Q* = T diag(a^2, b^2, c^2, -1) T^T`` with
``T = [[R, c], [0, 1]]``. An ellipse is a centre ``mu`` (2,) and its shape matrix
``S = R2 diag(a^2, b^2) R2^T`` (the points x with ``(x - mu)^T S^-1 (x - mu) = 1``), which is also
the covariance GOReloc gives the ellipse when it compares two of them as Gaussians. Every function
is vectorised over a leading axis of ellipsoids or ellipse pairs.
"""

from __future__ import annotations

import numpy as np

from openreloc_bench.reconstruction.gravity import levelling

Z_UP = np.array([0.0, 0.0, 1.0])
MIN_SEMI_AXIS_M = 0.01
"""Semi-axes are at least this long (m), so flat objects (rugs, paintings) keep a proper quadric."""


def fit_ellipsoid(
    points: np.ndarray, trim: float = 0.01, scale: float = 1.0, up: np.ndarray = Z_UP
) -> tuple[np.ndarray, ...]:
    """(centre (3,), R (3, 3), semi-axes (3,)) of the upright ellipsoid inscribed in the points' box.

    The box is gravity-aligned (indoor objects stand upright along the world's ``up``, which the map
    builder establishes: :func:`openreloc_bench.reconstruction.gravity.estimate_up`): its yaw is the principal
    direction of the points' xy spread, its extent along each axis spans the ``trim`` and ``1 - trim``
    quantiles (robust to stray points of noisy masks). The semi-axes are half the extents times
    ``scale``. GOReloc's own ellipsoids come from multi-view detection boxes (OA-SLAM); with RGB-D
    mapping frames, the object's fused points give them directly.
    """
    level = levelling(up)  # world -> a frame whose z is up
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3) @ level.T
    if len(pts) < 3:
        raise ValueError(f"an ellipsoid needs at least 3 points, got {len(pts)}")
    xy = pts[:, :2] - pts[:, :2].mean(axis=0)
    _, vecs = np.linalg.eigh(np.cov(xy.T))
    e1 = vecs[:, 1]  # major horizontal direction
    R = np.array([[e1[0], -e1[1], 0.0], [e1[1], e1[0], 0.0], [0.0, 0.0, 1.0]])  # right-handed, z up
    local = pts @ R
    lo, hi = np.quantile(local, [trim, 1.0 - trim], axis=0)
    centre = R @ ((lo + hi) / 2)
    axes = np.maximum((hi - lo) / 2 * scale, MIN_SEMI_AXIS_M)
    return level.T @ centre, level.T @ R, axes


def dual_quadrics(centres: np.ndarray, rotations: np.ndarray, axes: np.ndarray) -> np.ndarray:
    """(N, 4, 4) dual quadrics ``Q*`` of N ellipsoids."""
    n = len(centres)
    T = np.zeros((n, 4, 4))
    T[:, :3, :3] = rotations
    T[:, :3, 3] = centres
    T[:, 3, 3] = 1.0
    D = np.zeros((n, 4, 4))
    D[:, [0, 1, 2], [0, 1, 2]] = np.asarray(axes, dtype=np.float64) ** 2
    D[:, 3, 3] = -1.0
    return T @ D @ T.transpose(0, 2, 1)


def projection_matrix(K: np.ndarray, T_wc: np.ndarray) -> np.ndarray:
    """(3, 4) ``P = K [R_cw | t_cw]`` of a camera-to-world pose."""
    R, t = T_wc[:3, :3], T_wc[:3, 3]
    return np.asarray(K, dtype=np.float64) @ np.hstack([R.T, (-R.T @ t)[:, None]])


def project_quadrics(Q: np.ndarray, P: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Ellipses (mu (N, 2), S (N, 2, 2), valid (N,)) of dual quadrics ``Q`` seen through ``P``.

    ``C* = P Q* P^T`` normalised so that ``C*33 = -1``, as GOReloc does. A projection is valid when
    the ellipsoid's centre is in front of the camera and the ellipsoid does not cross the camera's
    principal plane (``C*33 < 0`` before normalising; otherwise its outline is not an ellipse); the
    ellipses of invalid ones are meaningless and the NGWD treats them as infinitely far.
    """
    C = np.einsum("ij,njk,lk->nil", P, Q, P)
    c33 = C[:, 2, 2]
    depth = -Q[:, 3, :] @ P[2]  # the last row of Q* is -[c, 1]: the centres' depths
    valid = (c33 < 0) & (depth > 0)
    scale = np.where(valid, -c33, 1.0)
    Cn = C / scale[:, None, None]
    mu = -Cn[:, :2, 2]
    S = Cn[:, :2, :2] + mu[:, :, None] * mu[:, None, :]
    return mu, S, valid


def ellipses_from_boxes(boxes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The axis-aligned ellipses inscribed in [x0, y0, x1, y1] boxes: (mu (N, 2), S (N, 2, 2))."""
    b = np.asarray(boxes, dtype=np.float64).reshape(-1, 4)
    mu = (b[:, :2] + b[:, 2:]) / 2
    S = np.zeros((len(b), 2, 2))
    S[:, 0, 0] = ((b[:, 2] - b[:, 0]) / 2) ** 2
    S[:, 1, 1] = ((b[:, 3] - b[:, 1]) / 2) ** 2
    return mu, S


def ellipse_boxes(mu: np.ndarray, S: np.ndarray) -> np.ndarray:
    """(N, 4) tight [x0, y0, x1, y1] boxes of ellipses: half-widths are sqrt(S11) and sqrt(S22)."""
    half = np.sqrt(np.maximum(np.stack([S[:, 0, 0], S[:, 1, 1]], axis=1), 0.0))
    return np.hstack([mu - half, mu + half])


def ngwd(mu1: np.ndarray, S1: np.ndarray, mu2: np.ndarray, S2: np.ndarray, scale: float) -> np.ndarray:
    """Normalised Gaussian Wasserstein distance ``exp(-W2 / scale)`` of ellipse pairs, in (0, 1].

    ``W2^2 = |mu1 - mu2|^2 + tr(S1 + S2 - 2 (S1^1/2 S2 S1^1/2)^1/2)``. For 2x2 SPD matrices the trace
    of that square root is ``sqrt(tr(S1 S2) + 2 sqrt(det S1 det S2))`` (the square root of a matrix
    similar to S1 S2: the sum of the square roots of its eigenvalues), which vectorises over
    thousands of pairs per query where ``scipy.linalg.sqrtm`` would loop; the tests compare both.
    """
    d_mu = np.sum((mu1 - mu2) ** 2, axis=-1)
    tr12 = np.einsum("...ij,...ji->...", S1, S2)
    det = np.maximum(np.linalg.det(S1) * np.linalg.det(S2), 0.0)
    cross = np.sqrt(np.maximum(tr12 + 2.0 * np.sqrt(det), 0.0))
    w2 = d_mu + np.trace(S1, axis1=-2, axis2=-1) + np.trace(S2, axis1=-2, axis2=-1) - 2.0 * cross
    return np.exp(-np.sqrt(np.maximum(w2, 0.0)) / scale)
