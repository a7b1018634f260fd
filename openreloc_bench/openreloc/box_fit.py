"""Camera poses fitted to object boxes: a landmark's image box is that of its extreme points
(:func:`extreme_points`), and :func:`fit_boxes_many` moves poses until those boxes fit the masks' boxes.

The verification (:mod:`.verify`) fits its sampled poses this way: P3P on mask centroids is biased,
because a mask's centroid is not where its landmark's centre projects, but a mask's box bounds where
the landmark's extreme points project (on every side the image border does not cut).
"""

from __future__ import annotations

import itertools

import numpy as np
from scipy.spatial.transform import Rotation

_DIRECTIONS = np.array(
    [d for d in itertools.product((-1, 0, 1), repeat=3) if sum(map(abs, d)) in (1, 3)], dtype=np.float64
)
"""The 6 axis and 8 diagonal directions: a landmark's extreme points along them bound its image box."""


def extreme_points(points: np.ndarray) -> np.ndarray:
    """(14, 3) points of ``points`` extreme along the axis and diagonal directions: their projected
    bounding box approximates the whole object's from any viewpoint at a fraction of the cost."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    return points[np.argmax(points @ _DIRECTIONS.T, axis=0)]


def fit_boxes_many(
    extremes: np.ndarray,
    boxes: np.ndarray,
    valid: np.ndarray,
    K: np.ndarray,
    size: tuple[int, int],
    R: np.ndarray,
    t: np.ndarray,
    scale: float,
    iterations: int = 20,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Box fits of S starts at once: for each start s, the pose (R[s], t[s] world to camera, started there)
    whose projected boxes of ``extremes[s]`` (n, E, 3) best fit ``boxes[s]`` (n, 4) [x0, y0, x1, y1] in an
    image of ``size`` (w, h); ``valid[s]`` (n,) marks the real boxes of a start padded to n. Huber
    (``scale`` pixels) on the edge offsets, by damped Gauss-Newton on a left perturbation of the pose, with
    each start's own damping and stopping. An edge is the projection of one extreme point (the arg-min or
    arg-max), so its Jacobian is the usual point-projection one. A box side on the image border only
    bounds (the mask is cut there; the object may go on). Returns (R (S, 3, 3), t (S, 3), ok (S,)), ok
    false where a fit diverged.

    Hand-written: ``scipy.optimize.least_squares`` with finite differences is several times slower per
    fit. Batched: the verification fits a hundred poses per query, each on a dozen box sides, so a loop
    over the fits cost Python overhead, not arithmetic."""
    w, h = size
    S, n = boxes.shape[:2]
    f, c = K[[0, 1], [0, 1]], K[:2, 2]
    bound = np.concatenate([boxes[..., :2] <= 0, boxes[..., 2:] >= (w, h)], axis=-1)  # (S, n, 4) one-sided sides
    sign = np.array([1.0, 1.0, -1.0, -1.0])  # a bound side is violated when (edge - border) * sign > 0
    axis = np.array([0, 1, 0, 1])  # the image axis of each side: x0, y0, x1, y1
    x_side, y_side = axis == 0, axis == 1
    fa = f[axis]
    padded = ~np.asarray(valid, bool)[..., None]

    def linearise(R: np.ndarray, t: np.ndarray, live: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Residuals (L, 4n) and Jacobians (L, 4n, 6) of the starts ``live`` at poses (R, t)."""
        Xc = extremes[live] @ np.swapaxes(R, 1, 2)[:, None] + t[:, None, None, :]  # (L, n, E, 3)
        z = np.maximum(Xc[..., 2], 0.05)
        uv = f * Xc[..., :2] / z[..., None] + c
        pick = np.concatenate([uv.argmin(2), uv.argmax(2)], axis=-1)  # (L, n, 4): x0, y0, x1, y1's extreme point
        at = (np.arange(len(live))[:, None, None], np.arange(n)[None, :, None], pick)
        P = Xc[at]  # (L, n, 4, 3): the point defining each edge
        zp = np.maximum(P[..., 2], 0.05)
        r = uv[(*at, axis)] - boxes[live]
        inactive = (bound[live] & (r * sign <= 0)) | padded[live]
        r = np.where(inactive, 0.0, r)
        # d edge / d P: f_a / z on the edge's axis, -f_a P_a / z^2 on depth
        along = fa / zp
        d0 = np.where(x_side, along, 0.0)
        d1 = np.where(y_side, along, 0.0)
        d2 = -fa * np.where(x_side, P[..., 0], P[..., 1]) / zp**2
        # left perturbation: dP/domega = -[P]_x, dP/dtau = I; P x dP written out (np.cross's own
        # arithmetic, without its axis shuffling)
        p0, p1, p2 = P[..., 0], P[..., 1], P[..., 2]
        J = np.stack([p1 * d2 - p2 * d1, p2 * d0 - p0 * d2, p0 * d1 - p1 * d0, d0, d1, d2], axis=-1)
        J = np.where(inactive[..., None], 0.0, J)  # (L, n, 4, 6): d edge / d (omega, tau)
        return r.reshape(len(live), -1), J.reshape(len(live), -1, 6)

    def huber(r: np.ndarray) -> np.ndarray:
        a = np.abs(r)
        return np.where(a <= scale, 0.5 * a**2, scale * (a - 0.5 * scale)).sum(-1)

    R, t = np.array(R, np.float64), np.array(t, np.float64)
    r, J = linearise(R, t, np.arange(S))
    cost, damping = huber(r), np.full(S, 1e-3)
    ok, running = np.ones(S, bool), np.ones(S, bool)
    for _ in range(iterations):
        live = np.flatnonzero(running)
        if not len(live):
            break
        wts = np.minimum(1.0, scale / np.maximum(np.abs(r[live]), 1e-12))  # IRLS weights of the Huber loss
        Jl = J[live]
        H = np.swapaxes(Jl, 1, 2) @ (wts[..., None] * Jl)
        g = (np.swapaxes(Jl, 1, 2) @ (wts * r[live])[..., None])[..., 0]
        diag = np.diagonal(H, axis1=1, axis2=2) + 1e-9
        damped = H + damping[live, None, None] * (np.eye(6) * diag[:, None, :])
        step, solved = _solve_each(damped, g)
        ok[live[~solved]] = running[live[~solved]] = False
        live, step = live[solved], step[solved]
        if not len(live):
            continue
        dR = Rotation.from_rotvec(step[:, :3]).as_matrix()
        R_new, t_new = dR @ R[live], (dR @ t[live, :, None])[..., 0] + step[:, 3:]
        r_new, J_new = linearise(R_new, t_new, live)
        cost_new = huber(r_new)
        better = cost_new < cost[live]
        up, down = live[better], live[~better]
        R[up], t[up], r[up], J[up], cost[up] = (
            R_new[better],
            t_new[better],
            r_new[better],
            J_new[better],
            cost_new[better],
        )
        damping[up] = np.maximum(damping[up] / 10, 1e-7)
        running[up[np.linalg.norm(step[better], axis=1) < 1e-6]] = False
        damping[down] *= 10
        running[down[damping[down] > 1e4]] = False
    ok &= np.isfinite(R).all((1, 2)) & np.isfinite(t).all(1)
    return R, t, ok


def _solve_each(A: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """-A[i]^-1 b[i] for a stack of systems, and which were solvable (one singular system fails numpy's
    batched solve: then each is solved alone)."""
    try:
        return -np.linalg.solve(A, b[..., None])[..., 0], np.ones(len(A), bool)
    except np.linalg.LinAlgError:
        out, solved = np.zeros_like(b), np.ones(len(A), bool)
        for i in range(len(A)):
            try:
                out[i] = -np.linalg.solve(A[i], b[i])
            except np.linalg.LinAlgError:
                solved[i] = False
        return out, solved
