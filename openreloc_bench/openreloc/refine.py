"""Fine stage: dual-path 2D ICP on the image plane (paper section 3.3, Eqs. 7-8).

For every matched landmark, its (subsampled) 3D points are projected at the current pose and
compared with the query mask of the object it was matched to:

- forward: each projected point inside the image -> nearest mask pixel,
- backward: each (subsampled) mask pixel -> nearest projected point,

each squared pixel distance robustified by a Huber kernel (threshold ``delta`` pixels), averaged
per object, and the per-object losses averaged over the matched objects. Adam optimises the pose.

Speed: the forward nearest mask pixel of every image pixel is precomputed once per object with a
distance transform that also returns the nearest pixel (``cv2.distanceTransformWithLabels``), so a
step only gathers coordinates (ICP-style: the correspondence is fixed within a step and the residual
``p - nearest(p)`` is differentiable in ``p``). All objects of all hypotheses are padded into one
batch (hypotheses may align different match sets: each group of hypotheses with the same set keeps its
own optimiser and stopping rules, and leaves the batch when it stops, :class:`.icp_batch.BatchProblem`),
whose losses and gradients one compiled pass computes (:func:`.icp_kernel.dual_path`, the chain rule
written out): as tensor operations, a step's cost was the operations' overhead more than their arithmetic.

Parametrisation: the pose is ``T_wc = T_init @ [R(q) | t]``, with ``q`` (w, x, y, z, normalised in
the forward pass) and ``t`` expressed in the *initial camera frame*. The rotation then turns the
camera about its own centre and ``t`` moves the centre, so neither depends on where the world
origin is (with ``T_cw`` parameters a rotation step swings the camera around the world origin by
``|c| * angle``, metres in a multi-room scene); points are transformed into the initial camera once.
Adam normalises each coordinate's gradient, so the quaternion/translation gradient-scale mismatch
(pixels per radian >> pixels per metre) does not matter, and lr 0.025 means steps of at most
~2.5 cm and ~3 degrees. The learning rates are halved on plateaus, which both sharpens the final
pose below the fixed-lr jitter and gives the early-stopping rule (stop after ``lr_reductions``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

import cv2
import numpy as np

from openreloc_bench import geometry
from openreloc_bench.config import check_ranges
from openreloc_bench.openreloc.icp_batch import BatchProblem, TargetTables
from openreloc_bench.openreloc.icp_kernel import BIG


@dataclass
class RefineConfig:
    """Settings of the dual-path 2D ICP refinement."""

    lr_rotation: float = 0.025
    """Adam learning rate of the quaternion (paper: 0.025)."""
    lr_translation: float = 0.025
    """Adam learning rate of the translation in metres (paper: 0.025)."""
    huber_delta: float = 10.0
    """Huber threshold in pixels (paper: 10): squared distances above delta^2 grow linearly in the distance."""
    max_iterations: int = 200
    """Hard cap on Adam steps."""
    plateau_patience: int = 6
    """Steps without a relative loss improvement of ``plateau_threshold`` before the learning rates halve."""
    plateau_threshold: float = 1e-3
    """Relative improvement that counts as progress for the plateau rule."""
    lr_reductions: int = 4
    """Early stopping: stop once the learning rates have been halved this many times."""
    stall_patience: int = 10
    """Beyond the paper (speed): also stop once the lowest loss of any hypothesis (the one that would be
    returned; among those aligning the same match set) has not improved by ``plateau_threshold``
    (relative) for this many steps. The learning-rate
    rule above watches the *summed* loss, which far-off hypotheses keep lowering long after the best one
    has settled; stopping then saves steps without changing the returned pose. 0 = off."""
    stall_min_iterations: int = 40
    """The stall rule applies only from this step on (after outlier masking has settled)."""
    max_points: int = 300
    """Landmark points per object used in the loss (random subset, fixed seed)."""
    max_mask_pixels: int = 300
    """Mask pixels per object used by the backward path (random subset, fixed seed)."""
    outlier_factor: float = 5.0
    """Per step, objects whose loss exceeds this multiple of the median object loss are masked out (moved objects)."""
    outlier_warmup: int = 20
    """Steps before outlier masking starts: early losses reflect the initial pose error, not moved objects."""
    outlier_min_loss: float = 4.0
    """Objects with a loss below this (squared pixels, i.e. ~2 px mean misfit) are never outliers."""
    backward_pixels: Literal["boundary", "all"] = "boundary"
    """Mask pixels of the backward path. "all" is the paper's literal form, but with subsampled points
    every interior pixel keeps a residual of about the point spacing, which rewards spreading the
    points (moving towards the object), a bias of a decimetre or more. "boundary" uses
    the mask's contour (minus the image border, where the mask is truncated, not the object): the
    extremal points are pulled onto the contour while the forward path keeps all points inside."""
    min_depth: float = 0.05
    """Points closer than this (metres, camera z) are ignored: behind or inside the camera."""
    max_side: int = 320
    """Beyond the paper (speed): masks are area-resampled so their longer side is at most this many
    pixels (the intrinsics scaled with them); ``huber_delta`` and reported losses stay in full-resolution
    pixels. 0 = full resolution (paper-literal). At 640x480, 320 leaves a quarter of the pixels to search."""
    occlusion_aware: bool = False
    """Beyond the paper (off by default): the forward path ignores projected points landing on pixels of
    *another* query segment (that segment hides them; pulling them onto the own mask drags the pose).
    Needs the ``occluders`` image. It fixes the drag of a box standing on a table, but off by default
    because it lowered recall on generated scenes: a wrong pose whose points fall on other segments pays
    nothing."""
    huber_delta_start: float = 0.0
    """Beyond the paper (coarse-to-fine): when larger than ``huber_delta``, the Huber threshold starts here
    and decays geometrically to ``huber_delta`` over ``anneal_steps`` (a wider quadratic basin first).
    0 = constant ``huber_delta`` (paper)."""
    correspondence_every: int = 3
    """Beyond the paper (speed): the backward path's nearest projected points (a brute-force search, the
    costliest part of a step) are recomputed every this many steps and held fixed in between, as classic ICP alternates correspondence
    and update steps. 1 = every step."""
    anneal_steps: int = 30
    """Steps of the Huber-threshold decay (used only with ``huber_delta_start``)."""
    restart_degrees: float = 6.0
    """Beyond the paper (basin hopping): the chosen refined pose is refined again from four starts orbiting
    its matched landmarks' centre by +-this many degrees (:func:`.hypotheses.orbit_starts`), and the lowest loss
    wins. Nearest-pixel correspondences make the loss landscape a chain of shallow basins: a sideways
    shift plus a turn that keeps the objects in view barely changes it. Many queries that end 0.5-1 m
    off have right matches that, refined from the *truth*, converge near it at a lower loss than the
    returned pose's: the refinement stopped in a neighbouring basin. 0 = off."""
    restart_margin: float = 0.1
    """A restart replaces the pose only when its loss, over the objects that count in the pose's own (not
    its outliers), is at least this share lower: the valley is flat enough that a pose 20 cm off can
    score slightly lower, and a restart that pushed one more object past ``outlier_factor`` would otherwise
    win by leaving it out of its mean."""
    restart_iterations: int = 60
    """Step cap of each restart's refinement: they start a few degrees from a settled pose, so a short run
    settles them (uncapped, the restarts take about twice as long)."""

    def __post_init__(self) -> None:
        check_ranges(
            self,
            positive=("lr_rotation", "lr_translation", "huber_delta", "outlier_factor", "min_depth"),
            at_least_one=(
                "plateau_patience",
                "max_points",
                "max_mask_pixels",
                "correspondence_every",
                "anneal_steps",
            ),
            non_negative=(
                "max_iterations",
                "restart_iterations",
                "plateau_threshold",
                "lr_reductions",
                "stall_patience",
                "stall_min_iterations",
                "outlier_warmup",
                "outlier_min_loss",
                "max_side",
                "huber_delta_start",
                "restart_degrees",
            ),
            share=("restart_margin",),
        )


@dataclass
class RefineTarget:
    """One matched object: its landmark's world points and the query mask it was matched to."""

    landmark_id: int
    points_w: np.ndarray
    """(N, 3) world points of the landmark."""
    mask: np.ndarray
    """bool (H, W) query mask."""


@dataclass
class RefineResult:
    """Outcome of :func:`refine_pose`."""

    T_wc: np.ndarray
    """Refined camera-to-world pose (the initial pose when ``reason`` is set)."""
    loss: float
    """Final (best) total loss; ``inf`` when the optimisation diverged."""
    initial_loss: float
    object_losses: dict[int, float] = field(default_factory=dict)
    """Landmark id -> its dual-path loss at the returned pose."""
    outliers: list[int] = field(default_factory=list)
    """Landmark ids masked out (loss > outlier_factor x median) at the returned pose."""
    iterations: int = 0
    reason: str | None = None
    """Why the initial pose was returned instead (divergence), else None."""


def nearest_mask_pixels(mask: np.ndarray) -> np.ndarray:
    """(H, W, 2) float32 (x, y) of the nearest mask pixel for every pixel (itself inside the mask).

    ``cv2.distanceTransformWithLabels`` with pixel labels numbers the zero pixels of its input (here:
    the mask) in row-major order, so the label indexes the mask pixels returned by ``np.nonzero``.
    Its nearest pixel is exact for nearly all pixels (a few far pixels get a near-nearest one).
    """
    mask = np.asarray(mask, dtype=bool)
    ys, xs = np.nonzero(mask)
    if len(xs) == 0:
        raise ValueError("empty mask")
    _, labels = cv2.distanceTransformWithLabels(
        (~mask).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE, labelType=cv2.DIST_LABEL_PIXEL
    )
    table = np.zeros((len(xs) + 1, 2), dtype=np.float32)
    table[1:, 0], table[1:, 1] = xs, ys
    return table[labels]


def backward_pixels(mask: np.ndarray, which: str) -> np.ndarray:
    """The mask pixels the backward path starts from (see :attr:`RefineConfig.backward_pixels`)."""
    mask = np.asarray(mask, dtype=bool)
    if which == "all":
        return mask
    contour = mask & ~cv2.erode(mask.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    contour[[0, -1], :] = False
    contour[:, [0, -1]] = False
    return contour if contour.any() else mask


def working_scale(height: int, width: int, max_side: int) -> float:
    """Factor masks are resized by so their longer side is at most ``max_side`` (1 = full size)."""
    return 1.0 if max_side <= 0 else min(1.0, max_side / max(height, width))


def scale_intrinsics(K: np.ndarray, s: float) -> np.ndarray:
    """Intrinsics of the image resized by ``s`` (pixel centres at integers: u' = s (u + 0.5) - 0.5)."""
    K2 = np.asarray(K, dtype=np.float64).copy()
    K2[:2, :2] *= s
    K2[:2, 2] = s * (K2[:2, 2] + 0.5) - 0.5
    return K2


def resize_mask(mask: np.ndarray, s: float) -> np.ndarray:
    """Area-resample a bool mask by ``s`` (a low-resolution pixel is set when half of it is covered)."""
    if s == 1.0:
        return np.asarray(mask, dtype=bool)
    h, w = mask.shape
    size = (max(1, round(w * s)), max(1, round(h * s)))
    return cv2.resize(np.asarray(mask, np.float32), size, interpolation=cv2.INTER_AREA) >= 0.5


def target_tables(
    targets: list[RefineTarget], K: np.ndarray, cfg: RefineConfig, seed: int, occluders: np.ndarray | None
) -> TargetTables:
    """The :class:`TargetTables` of ``targets`` (subsampled with ``seed``; ``occluders``: the union of
    all query segments, used when ``cfg.occlusion_aware``)."""
    rng = np.random.default_rng(seed)
    H0, W0 = targets[0].mask.shape
    s = working_scale(H0, W0, cfg.max_side)
    masks = [resize_mask(t.mask, s) for t in targets]
    H, W = masks[0].shape
    for m, t in zip(masks, targets):
        if not m.any() and t.mask.any():  # a sliver lost by resampling: keep its centroid pixel
            ys, xs = np.nonzero(t.mask)
            m[min(H - 1, int(s * ys.mean())), min(W - 1, int(s * xs.mean()))] = True
    occ = None if occluders is None or not cfg.occlusion_aware else resize_mask(occluders, s)
    n_tgt = len(targets)
    n_pts = max(min(cfg.max_points, len(t.points_w)) for t in targets)
    edges = [backward_pixels(m, cfg.backward_pixels) for m in masks]
    n_pix = max(max(1, min(cfg.max_mask_pixels, int(e.sum()))) for e in edges)
    pts_w = np.zeros((n_tgt, n_pts, 3), np.float64)
    pts_valid = np.zeros((n_tgt, n_pts), bool)
    pix = np.full((n_tgt, n_pix, 2), -BIG, np.float32)
    pix_valid = np.zeros((n_tgt, n_pix), bool)
    table = np.zeros((n_tgt, H * W, 4), np.float32)
    table[..., 2:] = 1.0  # outside the mask, counted: until a mask says otherwise
    for i, (t, m, e) in enumerate(zip(targets, masks, edges)):
        p = np.asarray(t.points_w, dtype=np.float64)
        if len(p) > cfg.max_points:
            p = p[np.sort(rng.choice(len(p), cfg.max_points, replace=False))]
        pts_w[i, : len(p)] = p
        pts_valid[i, : len(p)] = True
        ys, xs = np.nonzero(e)
        if len(xs) > cfg.max_mask_pixels:
            keep = np.sort(rng.choice(len(xs), cfg.max_mask_pixels, replace=False))
            ys, xs = ys[keep], xs[keep]
        pix[i, : len(xs)] = np.stack([xs, ys], axis=1)
        pix_valid[i, : len(xs)] = True
        if m.any():
            table[i, :, :2] = nearest_mask_pixels(m).reshape(-1, 2)
            table[i, :, 2] = ~m.reshape(-1)
        if occ is not None:
            table[i, :, 3] = ~(occ & ~m).reshape(-1)  # pixels of *another* segment hide what is behind them
    Kw = scale_intrinsics(K, s)
    return TargetTables(
        [t.landmark_id for t in targets],
        pts_w,
        pts_valid,
        pix,
        pix_valid,
        table.reshape(-1, 4),
        np.array([Kw[0, 0], Kw[1, 1], Kw[0, 2], Kw[1, 2]], np.float32),
        H,
        W,
        s,
    )


def _weights(obj_losses: np.ndarray, real: np.ndarray, cfg: RefineConfig, active: bool, unit: float) -> np.ndarray:
    """(B, n_obj): 1 for objects within ``outlier_factor`` x their hypothesis' median loss (or below
    ``outlier_min_loss``), 0 for outliers (moved objects) and padding (``real`` false); while masking
    is not ``active``, 1 for every real object."""
    if not active:
        return real.astype(np.float32)
    # the median of the real objects (padding sorts last), interpolated between the middle two
    ordered = np.sort(np.where(real, np.nan_to_num(obj_losses, nan=BIG), np.float32(np.inf)), axis=-1)
    n = real.sum(-1, keepdims=True)
    median = 0.5 * (np.take_along_axis(ordered, (n - 1) // 2, -1) + np.take_along_axis(ordered, n // 2, -1))
    limit = np.maximum(cfg.outlier_factor * median, np.float32(cfg.outlier_min_loss * unit))
    return ((obj_losses <= limit) & real).astype(np.float32)


def _stalled(lowest: list[float], cfg: RefineConfig, it: int) -> bool:
    """Whether the lowest loss (``lowest[k]`` after step k + 1) improved by less than ``plateau_threshold``
    over the last ``stall_patience`` steps (see :attr:`RefineConfig.stall_patience`)."""
    p = cfg.stall_patience
    if p <= 0 or it < max(cfg.stall_min_iterations, p + 1):
        return False
    before, now = lowest[-1 - p], lowest[-1]
    return bool(np.isfinite(before)) and now > (1.0 - cfg.plateau_threshold) * before


def _delta_at(cfg: RefineConfig, it: int) -> float:
    """Huber threshold of step ``it`` (1-based): geometric decay from ``huber_delta_start`` to ``huber_delta``."""
    if cfg.huber_delta_start <= cfg.huber_delta or cfg.anneal_steps <= 0:
        return cfg.huber_delta
    f = min(1.0, (it - 1) / cfg.anneal_steps)
    return cfg.huber_delta_start * (cfg.huber_delta / cfg.huber_delta_start) ** f


def refine_poses(
    T_inits: list[np.ndarray],
    K: np.ndarray,
    targets: list[RefineTarget],
    config: RefineConfig | None = None,
    seed: int = 0,
    occluders: np.ndarray | None = None,
    target_sets: list[list[int]] | None = None,
    tables: TargetTables | None = None,
) -> list[RefineResult]:
    """Refine every pose of ``T_inits`` (camera-to-world hypotheses) by minimising the dual-path 2D
    ICP loss over ``targets``, all hypotheses in one batch (each has its own parameters; Adam is
    per-coordinate, so they do not interact). ``occluders``: bool (H, W) union of all query segments
    (matched or not) for the occlusion-aware forward path.

    ``target_sets[b]``: the indices of the targets hypothesis ``b`` aligns (default: all), so that
    hypotheses with different matches share one batch. A step has a fixed cost larger than each
    hypothesis adds, so one batch is cheaper than a batch per match set.
    Object losses are keyed by landmark id, so a set may hold each landmark once.

    ``tables``: :func:`target_tables` of the same ``targets``, ``K``, ``seed`` and ``occluders`` (and a
    config that differs at most in its schedule), where the caller refines them again.

    Never raises on numerical trouble: a hypothesis whose loss or pose turns non-finite returns its
    initial pose with a reason.
    """
    cfg = config or RefineConfig()
    if not targets:
        raise ValueError("refine_poses needs at least one target")
    if not T_inits:
        raise ValueError("refine_poses needs at least one initial pose")
    T_inits = [geometry.check_pose(T, "initial pose") for T in T_inits]
    if target_sets is not None:
        _check_target_sets(target_sets, targets, len(T_inits))
    if tables is None:
        tables = target_tables(targets, K, cfg, seed, occluders)
    elif tables.landmark_ids != [t.landmark_id for t in targets]:
        raise ValueError("refine_poses: the tables were made for other targets")
    return _optimise(T_inits, tables, cfg, target_sets or [list(range(len(targets)))] * len(T_inits))


def _check_target_sets(target_sets: list[list[int]], targets: list[RefineTarget], n_hyp: int) -> None:
    """Raise ValueError unless there is one set per hypothesis, of valid indices and distinct landmarks."""
    if len(target_sets) != n_hyp:
        raise ValueError(f"{len(target_sets)} target sets for {n_hyp} initial poses")
    for b, ts in enumerate(target_sets):
        if not ts or not all(0 <= i < len(targets) for i in ts):
            raise ValueError(f"target set {b} must hold indices of the {len(targets)} targets, at least one: {ts}")
        if len({targets[i].landmark_id for i in ts}) != len(ts):
            raise ValueError(f"target set {b} aligns a landmark twice: {[targets[i].landmark_id for i in ts]}")


def refine_pose(
    T_init: np.ndarray,
    K: np.ndarray,
    targets: list[RefineTarget],
    config: RefineConfig | None = None,
    seed: int = 0,
    occluders: np.ndarray | None = None,
) -> RefineResult:
    """Refine one pose ``T_init`` (camera-to-world); see :func:`refine_poses`."""
    return refine_poses([T_init], K, targets, config, seed, occluders)[0]


class _Adam:
    """Adam on a group's (q, t) with the learning rates halved on plateaus of its summed loss: the
    arithmetic of ``torch.optim.Adam`` (default betas and eps) and the rule of ``ReduceLROnPlateau``
    (mode min, relative threshold, no cooldown), written out because their per-call machinery cost a
    third of a refinement step on these few-element tensors."""

    def __init__(self, params: list[np.ndarray], lrs: list[float], cfg: RefineConfig):
        self.params, self.lrs = params, list(lrs)
        self.avg = [np.zeros_like(p) for p in params]
        self.avg_sq = [np.zeros_like(p) for p in params]
        self.steps = 0
        self.patience, self.threshold = cfg.plateau_patience, cfg.plateau_threshold
        self.best, self.bad_steps, self.reductions = math.inf, 0, 0

    def step(self, grads: list[np.ndarray]) -> None:
        """One Adam step of the parameters, in place."""
        self.steps += 1
        bias1, bias2 = 1.0 - 0.9**self.steps, 1.0 - 0.999**self.steps
        for p, g, avg, avg_sq, lr in zip(self.params, grads, self.avg, self.avg_sq, self.lrs):
            avg += 0.1 * (g - avg)
            avg_sq *= 0.999
            avg_sq += 0.001 * g * g
            p += -lr / bias1 * (avg / (np.sqrt(avg_sq) / math.sqrt(bias2) + 1e-8))

    def plateau(self, loss: float) -> None:
        """Count a step without a relative improvement of ``threshold``; after more than ``patience`` of
        them in a row, halve the learning rates."""
        if loss < self.best * (1.0 - self.threshold):
            self.best, self.bad_steps = loss, 0
        else:
            self.bad_steps += 1
        if self.bad_steps > self.patience:
            self.lrs = [lr * 0.5 for lr in self.lrs]
            self.reductions += 1
            self.bad_steps = 0


@dataclass
class _Group:
    """Hypotheses that align the same targets, with their own Adam, learning-rate schedule and stopping
    rules: they run as they would in a batch of their own (losses over different targets are not
    comparable, so one set's settled loss must not stop another's refinement)."""

    rows: slice
    """Their rows in the problem (a group's hypotheses are contiguous)."""
    q: np.ndarray
    t: np.ndarray
    opt: _Adam
    lowest: list[float] = field(default_factory=list)
    """Lowest best loss of its hypotheses, per step (stall rule)."""
    stopped: int = 0
    """The step it stopped after; 0 while it runs."""

    @classmethod
    def start(cls, rows: slice, cfg: RefineConfig) -> _Group:
        n = rows.stop - rows.start
        q, t = np.tile(np.array([1.0, 0.0, 0.0, 0.0], np.float32), (n, 1)), np.zeros((n, 3), np.float32)
        return cls(rows, q, t, _Adam([q, t], [cfg.lr_rotation, cfg.lr_translation], cfg))


def _grouped(target_sets: list[list[int]]) -> tuple[list[int], list[slice]]:
    """Hypotheses reordered so that those with the same target set are contiguous, and each set's rows."""
    n_hyp = len(target_sets)
    keys = [tuple(ts) for ts in target_sets]
    rank = {k: i for i, k in enumerate(dict.fromkeys(keys))}
    order = sorted(range(n_hyp), key=lambda b: rank[keys[b]])
    ends = np.cumsum(np.bincount([rank[k] for k in keys])).tolist()
    return order, [slice(a, e) for a, e in zip([0, *ends[:-1]], ends)]


def _optimise(
    T_inits: list[np.ndarray], tables: TargetTables, cfg: RefineConfig, target_sets: list[list[int]]
) -> list[RefineResult]:
    order, slices = _grouped(target_sets)
    T_inits = [T_inits[b] for b in order]
    problem = BatchProblem(T_inits, tables, [target_sets[b] for b in order], cfg.min_depth)
    B, unit = len(T_inits), problem.unit
    groups = [_Group.start(rows, cfg) for rows in slices]
    # state of the live batch (the running groups' hypotheses, in order); a group that stops leaves it
    live, running, live_rows = problem, groups, list(range(B))
    best_loss = np.full(B, np.inf, np.float32)
    best_q, best_t = np.concatenate([g.q for g in groups]), np.concatenate([g.t for g in groups])
    alive = np.ones(B, bool)
    done_q, done_t = best_q.copy(), best_t.copy()  # every hypothesis' best, once its group has stopped
    initial = np.full(B, np.nan, np.float32)
    why: list[str | None] = [None] * B
    it = 0
    for it in range(1, cfg.max_iterations + 1):
        q, t = np.concatenate([g.q for g in running]), np.concatenate([g.t for g in running])
        delta = _delta_at(cfg, it)
        obj, terms = live.evaluate(q, t, delta, refresh=(it - 1) % max(1, cfg.correspondence_every) == 0)
        w = _weights(obj, live.real, cfg, it > cfg.outlier_warmup, unit)
        coef = w / np.maximum(w.sum(-1, keepdims=True), 1.0)
        value = (obj * coef).sum(-1)  # (live rows,)
        if it == 1:
            initial = value.copy()
        for k in np.flatnonzero(alive & ~np.isfinite(value)).tolist():
            alive[k], why[live_rows[k]] = False, "loss became non-finite"
        annealed = it > cfg.anneal_steps or cfg.huber_delta_start <= cfg.huber_delta
        improved = alive & (value < best_loss) if annealed else alive  # best only counts at the final delta
        best_loss = np.where(improved, value, best_loss)
        best_q = np.where(improved[:, None], q, best_q)
        best_t = np.where(improved[:, None], t, best_t)
        g_q, g_t = live.gradient(q, t, terms, np.where(alive[:, None], coef, np.float32(0.0)))
        for k in np.flatnonzero(alive & ~(np.isfinite(g_q).all(-1) & np.isfinite(g_t).all(-1))).tolist():
            alive[k], why[live_rows[k]] = False, "non-finite gradient"
        g_q = np.where(alive[:, None], g_q, np.float32(0.0))
        g_t = np.where(alive[:, None], g_t, np.float32(0.0))
        keep: list[int] = []  # live rows of the groups that go on
        start = 0
        for g in running:
            mine = slice(start, start + g.rows.stop - g.rows.start)
            start = mine.stop
            g.opt.step([g_q[mine], g_t[mine]])
            on = alive[mine]
            if annealed:
                g.opt.plateau(float(value[mine][on].sum()) if on.any() else 0.0)
            g.lowest.append(float(best_loss[mine].min()))
            if not on.any() or _stalled(g.lowest, cfg, it) or g.opt.reductions >= cfg.lr_reductions:
                g.stopped = it
                done_q[g.rows], done_t[g.rows] = best_q[mine], best_t[mine]
            else:
                keep += range(mine.start, mine.stop)
        if len(keep) < len(live_rows):
            running = [g for g in running if not g.stopped]
            if not running:
                break
            live, live_rows = live.subset(keep), [live_rows[k] for k in keep]
            best_loss, best_q, best_t, alive = best_loss[keep], best_q[keep], best_t[keep], alive[keep]
    done_q[live_rows], done_t[live_rows] = best_q, best_t  # the live batch's (the step cap stopped it)
    iterations = [0] * B
    for g in groups:
        iterations[g.rows] = [g.stopped or it] * (g.rows.stop - g.rows.start)
    results = _results(problem, cfg, T_inits, tables.landmark_ids, done_q, done_t, initial, why, iterations)
    return [results[order.index(b)] for b in range(B)]


def _results(
    problem: BatchProblem,
    cfg: RefineConfig,
    T_inits: list[np.ndarray],
    landmark_ids: list[int],
    best_q: np.ndarray,
    best_t: np.ndarray,
    initial: np.ndarray,
    why: list[str | None],
    iterations: list[int],
) -> list[RefineResult]:
    """Score the final local poses with the (shared) loss and express them as camera-to-world poses."""
    unit = problem.unit
    obj = problem.losses(best_q, best_t, cfg.huber_delta)
    w = _weights(obj, problem.real, cfg, True, unit)
    final = (obj * w).sum(-1) / np.maximum(w.sum(-1), 1.0)
    out = []
    for b, T_init in enumerate(T_inits):
        n = int(problem.real[b].sum())  # real slots come first
        ids = [landmark_ids[i] for i in problem.slots[b, :n]]
        qn = best_q[b].astype(np.float64)
        tn = best_t[b].astype(np.float64)
        if why[b] is None and not (
            np.all(np.isfinite(qn))
            and np.linalg.norm(qn) > 1e-8
            and np.all(np.isfinite(tn))
            and np.isfinite(float(final[b]))
        ):
            why[b] = "pose became non-finite"
        if why[b] is not None:
            out.append(
                RefineResult(
                    T_init.copy(),
                    float("inf"),
                    float(initial[b]) / unit,
                    iterations=iterations[b],
                    reason=f"refinement diverged: {why[b]}",
                )
            )
            continue
        delta_T = geometry.qt_to_pose(qn / np.linalg.norm(qn), tn)
        out.append(
            RefineResult(
                T_wc=geometry.compose(T_init, delta_T),
                loss=float(final[b]) / unit,
                initial_loss=float(initial[b]) / unit,
                object_losses={i: float(v) / unit for i, v in zip(ids, obj[b, :n].tolist())},
                outliers=[i for i, keep in zip(ids, w[b, :n].tolist()) if keep == 0.0],
                iterations=iterations[b],
            )
        )
    return out
