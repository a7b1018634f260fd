"""Training and evaluation of the learned segmenter's boundary network on generated scenes.

The target of a frame is its instance boundary map: pixels whose instance id differs from a
4-neighbour's (both sides, so a boundary is two pixels wide at the working resolution). The loss is
class-balanced binary cross-entropy plus a soft Dice term (boundaries are a few percent of the pixels).
Augmentation covers what separates scenes and splits: flips, scale, colour gain, gamma, and darkening
down to the lighting-decay splits' levels with 8-bit re-quantisation, then sensor-like noise.

Every step's crops follow from (seed, step) alone, so they are the same whether the training process
cuts them itself or ``loader_workers`` processes cut them ahead (a GPU trains faster than one core
augments), and a resumed run needs no random state. Training is resumable: a checkpoint (network,
optimiser, step) is written atomically every ``checkpoint_every`` steps and picked up when the same
recipe is run again.
"""

from __future__ import annotations

import hashlib
import io as _io
import json
import math
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import torch
import torch.nn.functional as F
from scipy.special import ndtri
from tqdm import tqdm

from openreloc_bench.data import io
from openreloc_bench.data.scene import Scene
from openreloc_bench.data.splits import DISPLACED_SPLIT, LIGHT_SPLITS, MAPPING_SPLIT
from openreloc_bench.errors import ConfigError
from openreloc_bench.vision.learned_segment import (
    BoundaryNet,
    NetConfig,
    load_weights,
    segment_scores,
    segments_from_boundaries,
    standardize,
    work_size,
)
from openreloc_bench.vision.training import training_device

FRAME_SPLITS = (MAPPING_SPLIT, *LIGHT_SPLITS, DISPLACED_SPLIT)


@dataclass
class SegTrainConfig:
    """Hyper-parameters of one training run (saved in the weights' card)."""

    seed: int = 0
    """Seeds numpy and torch (initialisation, batches, crops, augmentation)."""
    steps: int = 6000
    """Optimiser steps."""
    batch: int = 8
    """Crops per step."""
    crop: int = 192
    """Side of the square training crops, in working-resolution pixels (multiple of the net's stride)."""
    lr: float = 3e-3
    """Peak AdamW learning rate (linear warm-up, cosine decay to 2% of it)."""
    weight_decay: float = 1e-4
    """AdamW weight decay."""
    warmup_steps: int = 200
    """Steps of linear learning-rate warm-up."""
    dice_weight: float = 1.0
    """Weight of the soft Dice term next to the class-balanced cross-entropy."""
    max_pos_weight: float = 10.0
    """Cap of the cross-entropy's positive-class weight (negatives / positives of the batch)."""
    dark_prob: float = 0.35
    """Share of crops darkened to 12-60% brightness and re-quantised (the lighting-decay splits)."""
    threads: int = 2
    """torch CPU threads."""
    device: str = "cpu"
    """torch device of the steps ("cpu", "cuda", "cuda:1"); augmentation stays on the CPU."""
    mixed_precision: bool = True
    """On a CUDA device, run the network in bfloat16 autocast (the CPU always trains in float32)."""
    loader_workers: int = 0
    """Processes that cut and augment the next batches while the device trains (0: the training process
    cuts them itself); the batches, and so the weights, do not depend on it."""
    max_seconds: float = 0.0
    """Stop after this many seconds of training even if the schedule is unfinished (0: never); for
    time-boxed machines. The card records the steps actually run."""
    checkpoint_every: int = 250
    """Steps between checkpoints (a killed run resumes from the last one)."""

    def __post_init__(self) -> None:
        for key in ("steps", "batch", "crop", "threads", "checkpoint_every"):
            if getattr(self, key) < 1:
                raise ValueError(f"'{key}' must be >= 1, got {getattr(self, key)}")
        if self.loader_workers < 0:
            raise ValueError(f"'loader_workers' must be >= 0, got {self.loader_workers}")
        if not (math.isfinite(self.max_seconds) and self.max_seconds >= 0):
            raise ValueError(f"'max_seconds' must be >= 0, got {self.max_seconds}")
        for key in ("lr", "dice_weight", "max_pos_weight"):
            v = getattr(self, key)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"'{key}' must be a positive number, got {v}")
        if not 0.0 <= self.dark_prob <= 1.0:
            raise ValueError(f"'dark_prob' must be in [0, 1], got {self.dark_prob}")


# ------------------------------------------------------------------------------------------------ data


def boundary_map(ids: np.ndarray) -> np.ndarray:
    """uint8 (H, W): 1 where a 4-neighbour has another instance id (both sides of every edge)."""
    b = np.zeros(ids.shape, bool)
    dx = ids[:, 1:] != ids[:, :-1]
    dy = ids[1:, :] != ids[:-1, :]
    b[:, 1:] |= dx
    b[:, :-1] |= dx
    b[1:, :] |= dy
    b[:-1, :] |= dy
    return b.astype(np.uint8)


@dataclass
class FrameSet:
    """Frames at the working resolution: RGB and instance ids, and the scene each came from."""

    rgb: np.ndarray
    """(N, h, w, 3) uint8."""
    ids: np.ndarray
    """(N, h, w) int32 instance ids."""
    scene: list[str]

    def __len__(self) -> int:
        return len(self.rgb)


def load_frames(
    scene_dirs: Sequence[Path],
    net_cfg: NetConfig,
    per_split: int,
    rng: np.random.Generator,
    splits: Sequence[str] = FRAME_SPLITS,
    progress: bool = True,
    threads: int = 4,
) -> FrameSet:
    """Up to ``per_split`` random frames of each split of each scene, resized to the working resolution
    (RGB by area averaging, as the segmenter does at run time; ids by nearest neighbour). The frames are
    picked first, in order, then decoded by ``threads`` threads (the same frames for any number)."""
    picks = []
    for d in scene_dirs:
        scene = Scene(d)
        for split in splits:
            if split not in scene.splits():
                continue
            seq = scene.sequence(split)
            for i in np.sort(rng.choice(len(seq), min(per_split, len(seq)), replace=False)):
                picks.append((scene.name, f"{d}/{split}", seq, int(i)))
    if not picks:
        raise ConfigError("no training frames found (scenes without the expected splits?)")

    def read(pick: tuple[str, str, Any, int]) -> tuple[np.ndarray, np.ndarray]:
        _, where, seq, i = pick
        f = seq[i]
        if f.instance is None:
            raise ConfigError(f"{where}: frames without instance masks cannot train the segmenter")
        w, h = work_size(seq.width, seq.height, net_cfg.work_width, net_cfg.stride)
        return (
            cv2.resize(f.color, (w, h), interpolation=cv2.INTER_AREA),
            cv2.resize(f.instance, (w, h), interpolation=cv2.INTER_NEAREST),
        )

    with ThreadPoolExecutor(max(1, threads)) as pool:  # decoding and resizing release the GIL
        frames = pool.map(read, picks)
        pairs = list(tqdm(frames, total=len(picks), desc="frames", unit="frame", disable=not progress, leave=False))
    sizes = {p[0].shape for p in pairs}
    if len(sizes) > 1:
        raise ConfigError(f"training scenes differ in aspect ratio ({sorted(sizes)}): use one frame shape")
    return FrameSet(
        np.stack([p[0] for p in pairs]), np.stack([p[1] for p in pairs]).astype(np.int32), [p[0] for p in picks]
    )


_NORMAL_QUANTILES = ndtri((np.arange(2**16) + 0.5) / 2**16).astype(np.float32)
"""Standard normal samples by inverse transform of 16-bit uniforms: several times faster than numpy's
float normals on a crop, and the sensor noise needs no finer tails."""


def augment(
    rgb: np.ndarray, ids: np.ndarray, crop: int, dark_prob: float, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """One random training crop (RGB uint8, boundary uint8) of a frame."""
    h, w = ids.shape
    s = rng.uniform(0.75, 1.35)  # objects nearer or farther than in the frame
    sh, sw = max(crop, round(h * s)), max(crop, round(w * s))
    img = cv2.resize(rgb, (sw, sh), interpolation=cv2.INTER_AREA if s < 1 else cv2.INTER_LINEAR)
    lab = cv2.resize(ids, (sw, sh), interpolation=cv2.INTER_NEAREST)
    y, x = rng.integers(0, sh - crop + 1), rng.integers(0, sw - crop + 1)
    img, lab = img[y : y + crop, x : x + crop], lab[y : y + crop, x : x + crop]
    if rng.random() < 0.5:
        img, lab = img[:, ::-1], lab[:, ::-1]
    # colour as one lookup table per channel (gamma, gain, darkening): cheap, and 8-bit like a camera's
    lut = (np.arange(256) / 255.0)[:, None] ** rng.uniform(0.7, 1.4) * rng.uniform(0.85, 1.15, 3)
    if rng.random() < dark_prob:
        lut = np.round(np.clip(lut * rng.uniform(0.12, 0.6), 0, 1) * 255.0) / 255.0  # dark, and 8-bit again
    img = cv2.LUT(np.ascontiguousarray(img), np.clip(np.round(lut * 255.0), 0, 255).astype(np.uint8)[None])
    gauss = _NORMAL_QUANTILES[rng.integers(0, len(_NORMAL_QUANTILES), img.shape, dtype=np.uint16)]
    noisy = img + gauss * np.float32(rng.uniform(0.0, 0.02) * 255.0)
    out = np.clip(np.round(noisy), 0, 255).astype(np.uint8)
    return out, boundary_map(np.ascontiguousarray(lab))


class StepBatches(torch.utils.data.Dataset):
    """Step ``s``'s batch of augmented crops, drawn from a generator seeded by (seed, s) alone: the same
    batch in any process and after any resume."""

    def __init__(self, frames: FrameSet, cfg: SegTrainConfig):
        self.frames, self.cfg = frames, cfg

    def __len__(self) -> int:
        return self.cfg.steps

    def __getitem__(self, step: int) -> tuple[torch.Tensor, torch.Tensor]:
        rng = np.random.default_rng([self.cfg.seed, step])
        idx = rng.integers(0, len(self.frames), self.cfg.batch)
        pairs = [augment(self.frames.rgb[i], self.frames.ids[i], self.cfg.crop, self.cfg.dark_prob, rng) for i in idx]
        x = standardize(np.stack([p[0] for p in pairs]))
        return x, torch.from_numpy(np.stack([p[1] for p in pairs])).float()[:, None]


def batches_from(frames: FrameSet, cfg: SegTrainConfig, start: int, pin_memory: bool) -> torch.utils.data.DataLoader:
    """Steps ``start`` .. ``steps - 1`` in order, cut by ``cfg.loader_workers`` processes (or inline);
    ``pin_memory`` for a CUDA device."""
    workers = cfg.loader_workers
    return torch.utils.data.DataLoader(
        StepBatches(frames, cfg),
        batch_size=None,
        sampler=range(start, cfg.steps),
        num_workers=workers,
        prefetch_factor=4 if workers else None,
        pin_memory=pin_memory,
    )


def boundary_loss(logit: torch.Tensor, target: torch.Tensor, cfg: SegTrainConfig) -> torch.Tensor:
    """Class-balanced BCE + ``dice_weight`` x soft Dice on the boundary class."""
    pos = target.sum()
    pos_weight = ((target.numel() - pos) / pos.clamp_min(1.0)).clamp(max=cfg.max_pos_weight)
    bce = F.binary_cross_entropy_with_logits(logit, target, pos_weight=pos_weight)
    p = torch.sigmoid(logit)
    dice = 1.0 - (2.0 * (p * target).sum() + 1.0) / (p.sum() + target.sum() + 1.0)
    return bce + cfg.dice_weight * dice


# ------------------------------------------------------------------------------------------------ training


def recipe_id(cfg: SegTrainConfig, net_cfg: NetConfig, scenes: Sequence[str], init_id: str = "") -> str:
    """Hash of everything that determines the weights (a checkpoint resumes only the same recipe);
    ``init_id`` is the card id of the weights training started from ("" for a random start)."""
    same_weights = ("threads", "checkpoint_every", "loader_workers", "max_seconds")
    recipe = {k: v for k, v in asdict(cfg).items() if k not in same_weights}
    # "batches": crops drawn per (seed, step); weights of the earlier single-stream sampling have ids without it
    parts = {"train": recipe, "net": asdict(net_cfg), "scenes": list(scenes), "batches": "per-step"}
    if init_id:  # absent for a random start, so that ids of earlier weights stay what they were
        parts["init"] = init_id
    return hashlib.sha256(json.dumps(parts, sort_keys=True).encode()).hexdigest()[:16]


def check_crop(cfg: SegTrainConfig, net_cfg: NetConfig) -> None:
    """A crop side the network cannot take (not a multiple of its stride): a one-line error."""
    if cfg.crop % net_cfg.stride:
        raise ConfigError(f"crop {cfg.crop} must be a multiple of the network's stride {net_cfg.stride}")


def train_boundary_net(
    frames: FrameSet,
    net_cfg: NetConfig,
    cfg: SegTrainConfig,
    checkpoint: Path | None = None,
    log: Callable[[str], None] = print,
    init: Path | None = None,
) -> tuple[BoundaryNet, dict[str, Any]]:
    """Train on ``frames``, from random weights or from the weights directory ``init`` (fine-tuning,
    e.g. on scenes of a new data version); resumes from ``checkpoint`` when it holds the same recipe."""
    check_crop(cfg, net_cfg)
    if cfg.crop > min(frames.ids.shape[1:]):
        raise ConfigError(f"crop {cfg.crop} is larger than the frames ({frames.ids.shape[2]}x{frames.ids.shape[1]})")
    device = training_device(cfg.device)
    torch.set_num_threads(cfg.threads)
    torch.manual_seed(cfg.seed)
    net = BoundaryNet(net_cfg)
    init_id = ""
    if init is not None:
        start, start_cfg, start_card = load_weights(init)
        if start_cfg != net_cfg:
            raise ConfigError(f"{init}: its network ({start_cfg}) is not the one to train ({net_cfg})")
        net.load_state_dict(start.state_dict())
        init_id = start_card.get("id", "")
    cuda = device.type == "cuda"
    memory_format = torch.channels_last if cuda else torch.contiguous_format
    net = net.to(device, memory_format=memory_format)
    torch.backends.cudnn.benchmark = cuda
    opt = torch.optim.AdamW(net.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay)
    rid = recipe_id(cfg, net_cfg, sorted(set(frames.scene)), init_id)
    step, history, seconds = 0, [], 0.0
    if checkpoint is not None and checkpoint.is_file():
        state = torch.load(checkpoint, map_location=device, weights_only=False)
        if state.get("recipe") == rid:
            net.load_state_dict(state["net"])
            opt.load_state_dict(state["opt"])
            step, history, seconds = state["step"], state["history"], state["seconds"]
            log(f"resumed from step {step} of {cfg.steps}")
        else:
            log("checkpoint is from another recipe: starting over")

    def lr_at(s: int) -> float:
        if s < cfg.warmup_steps:
            return cfg.lr * (s + 1) / cfg.warmup_steps
        t = (s - cfg.warmup_steps) / max(1, cfg.steps - cfg.warmup_steps)
        return cfg.lr * (0.02 + 0.98 * 0.5 * (1 + math.cos(math.pi * min(1.0, t))))

    net.train()
    t0, window = time.perf_counter(), []
    autocast = torch.autocast("cuda", torch.bfloat16, enabled=cuda and cfg.mixed_precision)
    with tqdm(total=cfg.steps, initial=step, desc="train segmenter", unit="step") as bar:
        for x, y in batches_from(frames, cfg, step, pin_memory=cuda):
            x = x.to(device, non_blocking=True, memory_format=memory_format)
            y = y.to(device, non_blocking=True)
            for g in opt.param_groups:
                g["lr"] = lr_at(step)
            with autocast:
                logit = net(x)
            loss = boundary_loss(logit.float(), y, cfg)
            opt.zero_grad(set_to_none=True)
            loss.backward()
            opt.step()
            step += 1
            window.append(loss.detach())
            bar.update(1)
            out_of_time = cfg.max_seconds > 0 and seconds + time.perf_counter() - t0 > cfg.max_seconds
            if step % cfg.checkpoint_every == 0 or step == cfg.steps or out_of_time:
                history.append({"step": step, "loss": round(float(torch.stack(window).mean()), 5)})
                bar.set_postfix(loss=history[-1]["loss"])
                window = []
                if checkpoint is not None:
                    _save_checkpoint(checkpoint, net, opt, step, history, seconds + time.perf_counter() - t0, rid)
            if out_of_time:
                log(f"stopped at step {step} of {cfg.steps}: max_seconds {cfg.max_seconds:g} reached")
                break
    net.eval()
    info = {
        "history": history,
        "train_seconds": round(seconds + time.perf_counter() - t0, 1),
        "recipe": rid,
        "steps_run": step,
    }
    if init_id:
        info["init"] = init_id
    return net.cpu().to(memory_format=torch.contiguous_format), info


def _save_checkpoint(
    path: Path, net: BoundaryNet, opt: Any, step: int, history: list, seconds: float, rid: str
) -> None:
    buf = _io.BytesIO()
    torch.save(
        {
            "net": net.state_dict(),
            "opt": opt.state_dict(),
            "step": step,
            "history": history,
            "seconds": seconds,
            "recipe": rid,
        },
        buf,
    )
    io.atomic_write_bytes(path, buf.getvalue())


# ------------------------------------------------------------------------------------------------ evaluation


def match_segments(pred: np.ndarray, gt: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Overlaps of one frame: (intersection (n_gt, n_pred), gt areas, pred areas), over the ground-truth
    ids > 0 and the predicted labels in increasing order (label 0 of ``pred``, if any, excluded)."""
    g_ids, g_inv = np.unique(gt, return_inverse=True)
    p_ids, p_inv = np.unique(pred, return_inverse=True)
    g_inv, p_inv = g_inv.ravel(), p_inv.ravel()
    inter = np.bincount(g_inv * len(p_ids) + p_inv, minlength=len(g_ids) * len(p_ids)).reshape(len(g_ids), -1)
    gi, pi = g_ids > 0, p_ids > 0
    return inter[np.ix_(gi, pi)], np.bincount(g_inv)[gi], np.bincount(p_inv)[pi]


def frame_metrics(pred: np.ndarray, gt: np.ndarray, scores: np.ndarray | None, min_frac: float) -> dict[str, Any]:
    """Per-frame statistics over the objects covering >= ``min_frac`` of the image: best IoU per object,
    split (over-segmented) and swallowed (under-segmented) objects, and the AP50 inputs (per prediction:
    score, true positive, ignored). ``scores`` align with ``pred``'s labels > 0 in increasing order."""
    inter, g_area, p_area = match_segments(pred, gt)
    big = g_area >= min_frac * gt.size
    if inter.shape[1] == 0:
        n = int(big.sum())
        return {
            "best_iou": [0.0] * n,
            "split": [False] * n,
            "swallowed": [False] * n,
            "n_gt": n,
            "scores": [],
            "tp": [],
            "ignore": [],
        }
    iou = inter / np.maximum(g_area[:, None] + p_area[None, :] - inter, 1)
    share = inter / np.maximum(g_area[:, None], 1)  # of each object, per segment
    main = share.argmax(1)
    purity = inter[np.arange(len(g_area)), main] / np.maximum(p_area[main], 1)
    split = (share >= 0.2).sum(1) >= 2  # spread over >= 2 segments holding >= 20% each
    swallowed = (share.max(1) >= 0.5) & (purity < 0.5)  # its main segment is mostly something else
    scores = p_area.astype(float) if scores is None else np.asarray(scores, float)
    owner = iou.argmax(0)
    on_objects = inter.sum(0)
    tp, ignore, claimed = [], [], set()
    for j in np.argsort(-scores, kind="stable"):
        g = int(owner[j])
        hit = bool(iou[g, j] >= 0.5 and big[g] and g not in claimed)
        claimed |= {g} if hit else set()
        tp.append(hit)
        # a segment on a small object or mostly on unlabelled pixels is neither right nor wrong
        ignore.append(bool(not hit and ((iou[g, j] >= 0.5 and not big[g]) or on_objects[j] < 0.5 * p_area[j])))
    return {
        "best_iou": iou.max(1)[big].tolist(),
        "split": split[big].tolist(),
        "swallowed": swallowed[big].tolist(),
        "n_gt": int(big.sum()),
        "scores": np.sort(scores)[::-1].tolist(),
        "tp": tp,
        "ignore": ignore,
    }


def average_precision(frames: list[dict[str, Any]]) -> float:
    """COCO-style AP at IoU 0.5 (101-point interpolated) over every frame's predictions."""
    n_gt = sum(f["n_gt"] for f in frames)
    rows = [(s, t) for f in frames for s, t, ig in zip(f["scores"], f["tp"], f["ignore"]) if not ig]
    if n_gt == 0:
        return float("nan")
    if not rows:
        return 0.0
    rows.sort(key=lambda r: -r[0])
    tp = np.cumsum([t for _, t in rows])
    precision = tp / np.arange(1, len(rows) + 1)
    recall = tp / n_gt
    precision = np.maximum.accumulate(precision[::-1])[::-1]
    grid = np.linspace(0, 1, 101)
    idx = np.searchsorted(recall, grid, side="left")
    return float(np.mean([precision[i] if i < len(precision) else 0.0 for i in idx]))


def summarize(frames: list[dict[str, Any]]) -> dict[str, float]:
    """Mean best IoU, AP50, over- and under-segmentation rates over frames' statistics."""
    best = [v for f in frames for v in f["best_iou"]]
    split = [v for f in frames for v in f["split"]]
    swallowed = [v for f in frames for v in f["swallowed"]]
    return {
        "mean_best_iou": float(np.mean(best)) if best else float("nan"),
        "ap50": average_precision(frames),
        "over_segmentation": float(np.mean(split)) if split else float("nan"),
        "under_segmentation": float(np.mean(swallowed)) if swallowed else float("nan"),
        "objects": len(best),
    }


def evaluate_thresholds(
    net: BoundaryNet,
    frames: FrameSet,
    thresholds: Sequence[float],
    min_frac: float = 0.01,
    min_area_frac: float = 0.0005,
) -> dict[float, dict[str, float]]:
    """Held-out metrics at each boundary threshold (the network runs once per frame)."""
    stats: dict[float, list[dict[str, Any]]] = {t: [] for t in thresholds}
    with torch.inference_mode():
        for i in range(len(frames)):
            prob = torch.sigmoid(net(standardize(frames.rgb[i][None])))[0, 0].numpy()
            for t in thresholds:
                labels = segments_from_boundaries(prob, t, max(1, round(min_area_frac * prob.size)))
                stats[t].append(frame_metrics(labels, frames.ids[i], segment_scores(labels, prob), min_frac))
    return {t: summarize(s) for t, s in stats.items()}
