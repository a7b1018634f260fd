"""The batched dual-path loss: its hand-written gradient against autograd, and its quaternions."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from scipy.spatial.transform import Rotation

from openreloc_bench.openreloc.icp_batch import QUAT_FORMS, BatchProblem, quat_to_rotmat
from openreloc_bench.openreloc.icp_kernel import BIG
from openreloc_bench.openreloc.refine import RefineConfig, target_tables
from tests.openreloc.boxworld import ROOM, render
from tests.openreloc.test_refine import HW, T_GT, K, perturbed, targets_at


@pytest.mark.parametrize(
    ("occlusion_aware", "refresh", "with_outlier", "padded"),
    [(False, True, False, False), (True, True, False, False), (False, False, True, False), (False, True, False, True)],
)
def test_hand_written_gradient_equals_autograd(
    occlusion_aware: bool, refresh: bool, with_outlier: bool, padded: bool
) -> None:
    """The compiled loss and its chain-rule gradient against autograd through a torch form of the same
    loss, at poses where points fall outside masks, outside the image and (for the far start) behind the
    camera; ``padded``: the hypotheses align target sets of different lengths."""
    _, _, inst = render(ROOM, K, T_GT, HW)
    targets = targets_at(T_GT)
    starts = [perturbed(0, 0.05, 0.2), perturbed(1, 0.1, 0.5), perturbed(2, 0.3, 2.5)]
    cfg = RefineConfig(occlusion_aware=occlusion_aware)
    n = len(targets)
    sets = [list(range(n)), list(range(n - 2)), list(range(1, n))] if padded else [list(range(n))] * 3
    problem = BatchProblem(starts, target_tables(targets, K, cfg, 0, inst > 0), sets, cfg.min_depth)
    rng = np.random.default_rng(3)
    q = (np.c_[np.ones(3), rng.normal(0, 0.05, (3, 3))] * [[1.3], [0.8], [1.0]]).astype(np.float32)
    t = rng.normal(0, 0.1, (3, 3)).astype(np.float32)
    problem.evaluate(q, t, cfg.huber_delta)  # correspondences of this pose
    t_moved = t + 0.02 if not refresh else t  # stale correspondences: held from the previous pose
    coef = rng.uniform(0.2, 1.0, (3, problem.n_obj)).astype(np.float32)
    if with_outlier:
        coef[:, 0] = 0.0
    obj, terms = problem.evaluate(q, t_moved, cfg.huber_delta, refresh=refresh)
    g_q, g_t = problem.gradient(q, t_moved, terms, coef)
    q_ref, t_ref = torch.tensor(q, requires_grad=True), torch.tensor(t_moved, requires_grad=True)
    expected = reference_losses(problem, q_ref, t_ref, cfg.huber_delta)
    (expected * torch.from_numpy(coef)).sum().backward()
    assert np.isfinite(obj).all() and float(np.abs(g_t).max()) > 1.0
    assert np.allclose(obj, expected.detach().numpy(), rtol=1e-4, atol=1e-3)
    assert np.allclose(g_q, q_ref.grad.numpy(), rtol=1e-3, atol=1e-2 * float(q_ref.grad.abs().max()))
    assert np.allclose(g_t, t_ref.grad.numpy(), rtol=1e-3, atol=1e-2 * float(t_ref.grad.abs().max()))


def reference_losses(problem, q: torch.Tensor, t: torch.Tensor, delta: float) -> torch.Tensor:
    """The dual-path loss of every (hypothesis, object) of ``problem`` as differentiable torch operations,
    with the backward path's correspondences the compiled pass left in ``problem.nn_idx``."""
    H, W, d = problem.H, problem.W, delta * problem.scale
    fx, fy, cx, cy = problem.camera.tolist()
    qn = q / q.norm(dim=-1, keepdim=True)
    R = torch.einsum("bk,ijkl,bl->bij", qn, torch.from_numpy(QUAT_FORMS), qn)
    pc = torch.einsum("bopk,bkj->bopj", torch.from_numpy(problem.pts) - t[:, None, None, :], R)
    front = torch.from_numpy(problem.pts_valid) & (pc[..., 2] > problem.min_depth)
    z = torch.where(front, pc[..., 2], torch.ones_like(pc[..., 2]))
    uv = torch.stack([fx * pc[..., 0] / z + cx, fy * pc[..., 1] / z + cy], dim=-1)
    ui, vi = torch.round(uv[..., 0].detach()).long(), torch.round(uv[..., 1].detach()).long()
    inside = front & (ui >= 0) & (ui < W) & (vi >= 0) & (vi < H)
    flat = vi.clamp(0, H - 1) * W + ui.clamp(0, W - 1) + torch.from_numpy(problem.offset)[..., None]
    row = torch.from_numpy(problem.pixel_table)[flat]
    use = inside & (row[..., 3] > 0)

    def huber(sq: torch.Tensor) -> torch.Tensor:
        return torch.where(sq <= d * d, sq, 2.0 * d * torch.sqrt(sq.clamp_min(d * d)) - d * d)

    fwd = (huber(((uv - row[..., :2]) * row[..., 2:3]).pow(2).sum(-1)) * use).sum(-1) / use.sum(-1).clamp_min(1)
    absent = torch.full_like(uv, float(BIG))
    nearest = torch.gather(
        torch.where(front[..., None], uv, absent), 2, torch.from_numpy(problem.nn_idx)[..., None].expand(-1, -1, -1, 2)
    )
    valid = torch.from_numpy(problem.pix_valid)
    bwd = (huber((nearest - torch.from_numpy(problem.pix)).pow(2).sum(-1)) * valid).sum(-1) / valid.sum(-1).clamp_min(1)
    return torch.where(front.sum(-1) == 0, torch.full_like(fwd, 4.0 * d * max(H, W)), fwd + bwd)


def test_quaternion_rotation_matches_scipy() -> None:
    q = np.random.default_rng(0).normal(size=(6, 4)).astype(np.float32)  # unnormalised on purpose
    expected = Rotation.from_quat(q[:, [1, 2, 3, 0]]).as_matrix()  # scipy: (x, y, z, w)
    assert np.allclose(quat_to_rotmat(q), expected, atol=1e-6)
