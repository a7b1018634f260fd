"""The dual-path 2D ICP loss of every (hypothesis, object) pair and its gradient, in one compiled pass.

A refinement step evaluates a few thousand projected points against their masks; as ~80 small tensor
operations the step cost mostly the operations' overhead and their temporaries, so the loss is written
as loops and compiled with numba (:func:`dual_path`). It returns each object's loss and the object's
gradient with respect to the hypothesis' rotation matrix and translation; :mod:`.icp_batch` sums them
with the weights :mod:`.refine` gives the objects (they depend on the losses: outliers) and takes the
quaternion's share. The arithmetic is float32, as the refinement's state is, with the sums over points
in float64.
"""

from __future__ import annotations

import numba
import numpy as np

BIG = np.float32(1e6)
"""Pixel coordinate of absent points (behind the camera, padding): never the nearest of anything real."""


@numba.njit(cache=True, nogil=True)
def _huber(sq: np.float32, delta: np.float32) -> tuple[np.float32, np.float32]:
    """Huber kernel on a squared distance (the Ceres convention) and its slope d huber / d sq."""
    d2 = delta * delta
    if sq <= d2:
        return sq, np.float32(1.0)
    root = np.sqrt(sq)
    return np.float32(2.0) * delta * root - d2, delta / root


@numba.njit(cache=True, nogil=True)
def dual_path(
    R: np.ndarray,
    t: np.ndarray,
    pts: np.ndarray,
    pts_valid: np.ndarray,
    table: np.ndarray,
    offset: np.ndarray,
    pix: np.ndarray,
    pix_valid: np.ndarray,
    nn_idx: np.ndarray,
    camera: np.ndarray,
    height: int,
    width: int,
    min_depth: float,
    delta: float,
    refresh: bool,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per (hypothesis b, object o): the dual-path loss at the local pose (R[b], t[b]) and its gradient.

    Shapes (B hypotheses, O objects, P points, M mask pixels): ``R`` (B, 3, 3), ``t`` (B, 3); ``pts``
    (B, O, P, 3) points in the initial camera frame, ``pts_valid`` (B, O, P); ``table`` (targets * H * W,
    4): per pixel of each target's image the nearest mask pixel (x, y), whether the pixel is outside the
    mask, whether it counts (not hidden by another segment); ``offset`` (B, O) where each object's image
    starts in it; ``pix`` (B, O, M, 2) backward-path mask pixels, ``pix_valid`` (B, O, M); ``nn_idx``
    (B, O, M) each pixel's nearest projected point, recomputed when ``refresh``, else read (held
    correspondences); ``camera`` (fx, fy, cx, cy). ``delta``: Huber threshold in pixels.

    A point counts when it is in front of the camera (beyond ``min_depth``); the forward path takes
    those inside the image whose pixel counts, and pulls them onto their nearest mask pixel; the backward
    path pulls each mask pixel's nearest point onto it. An object with no point in front gets the worst
    loss (4 delta max(H, W)) and no gradient; one with a non-finite point, a NaN loss.

    Returns the losses (B, O), d loss / d R (B, O, 3, 3) and d loss / d (points in the current camera)
    summed over points (B, O, 3), from which d loss / d t = -R times it.
    """
    n_hyp, n_obj, P = pts_valid.shape
    M = pix_valid.shape[2]
    fx, fy, cx, cy = camera[0], camera[1], camera[2], camera[3]
    delta32, depth32 = np.float32(delta), np.float32(min_depth)
    worst = np.float32(4.0 * delta * max(height, width))
    losses = np.zeros((n_hyp, n_obj), np.float32)
    g_R = np.zeros((n_hyp, n_obj, 3, 3))  # sums of thousands of float32 terms: float64, as the losses' sums
    g_sum = np.zeros((n_hyp, n_obj, 3))
    pc = np.empty((P, 3), np.float32)
    uv = np.empty((P, 2), np.float32)
    front = np.empty(P, np.bool_)
    g_uv = np.empty((P, 2), np.float32)
    us, vs = np.empty(P, np.float32), np.empty(P, np.float32)  # projections, contiguous for the search
    for b in range(n_hyp):
        for o in range(n_obj):
            n_front = 0
            corrupt = False  # a non-finite point makes the object's loss non-finite (the refinement gives up)
            for p in range(P):
                x = pts[b, o, p, 0] - t[b, 0]
                y = pts[b, o, p, 1] - t[b, 1]
                z = pts[b, o, p, 2] - t[b, 2]
                for j in range(3):  # R^T (p - t)
                    pc[p, j] = x * R[b, 0, j] + y * R[b, 1, j] + z * R[b, 2, j]
                if pts_valid[b, o, p] and not (
                    np.isfinite(pc[p, 0]) and np.isfinite(pc[p, 1]) and np.isfinite(pc[p, 2])
                ):
                    corrupt = True
                front[p] = pts_valid[b, o, p] and pc[p, 2] > depth32
                if front[p]:
                    n_front += 1
                    uv[p, 0] = fx * pc[p, 0] / pc[p, 2] + cx
                    uv[p, 1] = fy * pc[p, 1] / pc[p, 2] + cy
                else:
                    uv[p, 0] = BIG
                    uv[p, 1] = BIG
                g_uv[p, 0] = 0.0
                g_uv[p, 1] = 0.0
            # forward: projected points inside the image -> nearest mask pixel
            fwd = 0.0
            n_use = 0
            for p in range(P):
                if not front[p]:
                    continue
                ui, vi = np.rint(uv[p, 0]), np.rint(uv[p, 1])
                if ui < 0 or ui >= width or vi < 0 or vi >= height:
                    continue
                row = table[offset[b, o] + int(vi) * width + int(ui)]
                if row[3] <= 0:
                    continue
                n_use += 1
                rx = (uv[p, 0] - row[0]) * row[2]
                ry = (uv[p, 1] - row[1]) * row[2]
                value, slope = _huber(rx * rx + ry * ry, delta32)
                fwd += value
                g_uv[p, 0] = np.float32(2.0) * slope * rx
                g_uv[p, 1] = np.float32(2.0) * slope * ry
            scale_fwd = np.float32(1.0) / np.float32(max(n_use, 1))
            for p in range(P):
                g_uv[p, 0] *= scale_fwd
                g_uv[p, 1] *= scale_fwd
            # backward: mask pixels -> nearest projected point (absent points are parked at BIG)
            bwd = 0.0
            n_pix = 0
            for m in range(M):
                if pix_valid[b, o, m]:
                    n_pix += 1
            scale_bwd = np.float32(1.0) / np.float32(max(n_pix, 1))
            if refresh:
                us[:] = uv[:, 0]
                vs[:] = uv[:, 1]
            for m in range(M):
                if not pix_valid[b, o, m]:
                    continue
                px, py = pix[b, o, m, 0], pix[b, o, m, 1]
                if refresh:  # brute force over a few hundred points
                    best, best_p = np.float32(np.inf), 0
                    for p in range(P):
                        d = (us[p] - px) * (us[p] - px) + (vs[p] - py) * (vs[p] - py)
                        if d < best:
                            best, best_p = d, p
                    nn_idx[b, o, m] = best_p
                p = nn_idx[b, o, m]
                dx, dy = uv[p, 0] - px, uv[p, 1] - py
                value, slope = _huber(dx * dx + dy * dy, delta32)
                bwd += value
                if front[p]:  # absent points carry no gradient
                    g_uv[p, 0] += np.float32(2.0) * slope * scale_bwd * dx
                    g_uv[p, 1] += np.float32(2.0) * slope * scale_bwd * dy
            if corrupt:
                losses[b, o] = np.nan
                continue
            if n_front == 0:
                losses[b, o] = worst
                continue
            losses[b, o] = fwd / max(n_use, 1) + bwd / max(n_pix, 1)
            # chain rule: u = fx x / z + cx, v = fy y / z + cy; pc = R^T (p - t)
            for p in range(P):
                if not front[p] or (g_uv[p, 0] == 0.0 and g_uv[p, 1] == 0.0):
                    continue
                iz = np.float32(1.0) / pc[p, 2]
                gx, gy = g_uv[p, 0] * fx * iz, g_uv[p, 1] * fy * iz
                gz = -(gx * pc[p, 0] + gy * pc[p, 1]) * iz
                d = (pts[b, o, p, 0] - t[b, 0], pts[b, o, p, 1] - t[b, 1], pts[b, o, p, 2] - t[b, 2])
                for k in range(3):
                    g_R[b, o, k, 0] += d[k] * gx
                    g_R[b, o, k, 1] += d[k] * gy
                    g_R[b, o, k, 2] += d[k] * gz
                g_sum[b, o, 0] += gx
                g_sum[b, o, 1] += gy
                g_sum[b, o, 2] += gz
    return losses, g_R, g_sum
