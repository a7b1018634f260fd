"""Train the learned segmenter end to end (``openreloc-bench train-segmenter``): its training scenes
(:data:`~openreloc_bench.harness.training_data.SEGMENTER_DATA`), the boundary network
(:mod:`openreloc_bench.vision.segmenter_training`), the boundary threshold chosen on the held-out scenes,
and the weights with their card.
"""

from __future__ import annotations

import platform
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch

from openreloc_bench import config as cfgmod
from openreloc_bench.data import paths
from openreloc_bench.harness.training_data import SEGMENTER_DATA, held_out_seeds, training_scene_sets
from openreloc_bench.vision.learned_segment import NetConfig, save_weights
from openreloc_bench.vision.segmenter_training import (
    SegTrainConfig,
    check_crop,
    evaluate_thresholds,
    load_frames,
    train_boundary_net,
)
from openreloc_bench.vision.training import training_device

THRESHOLDS = (0.05, 0.1, 0.2, 0.3, 0.4, 0.5)
"""Boundary thresholds scored on the held-out scenes; the card records the best."""


@dataclass
class SegmenterTrainingConfig:
    """One training of the learned segmenter."""

    out: Path
    """Weights directory to write (``model.pt``, ``card.json``, ``manifest.json``, and ``checkpoint.pt``
    while it trains); locked meanwhile."""
    data: Path | None
    """Folder of ``train/`` and ``eval/`` scenes; None: ``out/scenes``. Scenes already in both are used as
    they are, else they are generated there."""
    scenes: int
    """Training scenes to generate."""
    eval_scenes: int
    """Held-out scenes to generate (threshold choice, card metrics)."""
    per_split: int
    """Frames kept per split and training scene (a third of it, at least 2, per held-out scene)."""
    width: int
    """Render width of generated scenes."""
    height: int
    """Render height of generated scenes."""
    workers: int
    """Parallel scene generation processes."""
    init: Path | None
    """Weights directory to start from (fine-tuning); None: random weights."""
    net: NetConfig
    """The network's shape."""
    train: SegTrainConfig
    """The training's hyper-parameters; its ``seed`` also picks the scene seeds and the frames."""


def main(cfg: SegmenterTrainingConfig, say: Callable[[str], None] = print) -> dict[str, Any]:
    """Train, write the weights with their card into ``cfg.out`` and say the held-out scores; returns the card."""
    device = training_device(cfg.train.device)  # refuse a missing GPU before generating anything
    check_crop(cfg.train, cfg.net)  # and a crop the network cannot take
    seed, threads = cfg.train.seed, cfg.train.threads
    with paths.directory_lock(cfg.out, "openreloc-bench train-segmenter"):
        train_dirs, eval_dirs, _ = training_scene_sets(
            cfg.data or cfg.out / "scenes", SEGMENTER_DATA, seed, cfg.scenes, cfg.eval_scenes, cfg.width,
            cfg.height, cfg.workers,
        )  # fmt: skip
        train_seeds, eval_seeds = held_out_seeds(train_dirs, eval_dirs)
        loaders = max(threads, cfg.train.loader_workers)
        train = load_frames(train_dirs, cfg.net, cfg.per_split, np.random.default_rng(seed), threads=loaders)
        held = load_frames(
            eval_dirs, cfg.net, max(2, cfg.per_split // 3), np.random.default_rng(seed + 1), threads=loaders
        )
        say(f"{len(train)} training frames from {len(train_dirs)} scenes; {len(held)} held-out frames")
        t0 = time.time()
        net, info = train_boundary_net(train, cfg.net, cfg.train, cfg.out / "checkpoint.pt", log=say, init=cfg.init)
        torch.set_num_threads(threads)
        scores = evaluate_thresholds(net, held, THRESHOLDS)
        best = max(THRESHOLDS, key=lambda t: scores[t]["mean_best_iou"] + scores[t]["ap50"])
        card = {
            "id": info["recipe"],
            **({"init": info["init"]} if "init" in info else {}),
            "threshold": best,
            "held_out": {"threshold": best, **scores[best]},
            "thresholds": {str(t): s for t, s in scores.items()},
            "train": cfgmod.to_dict(cfg.train),
            "data": {
                "train_seeds": train_seeds,
                "eval_seeds": eval_seeds,
                "render_size": [cfg.width, cfg.height],
                "frames_per_split": cfg.per_split,
                "train_frames": len(train),
                "eval_frames": len(held),
            },
            "history": info["history"],
            "steps_run": info["steps_run"],
            "train_seconds": info["train_seconds"],
            "wall_seconds": round(time.time() - t0, 1),
            "environment": {
                "torch": torch.__version__,
                "python": platform.python_version(),
                "device": torch.cuda.get_device_name(device) if device.type == "cuda" else "cpu",
                "threads": threads,
            },
        }
        save_weights(cfg.out, net, cfg.net, card)
    if info["steps_run"] < cfg.train.steps:
        minutes = cfg.train.max_seconds / 60.0
        say(f"note: training stopped at step {info['steps_run']} of {cfg.train.steps} (--max-minutes {minutes:g})")
    h = card["held_out"]
    say(
        f"held-out (threshold {best}): mean best IoU {h['mean_best_iou']:.3f}, AP50 {h['ap50']:.3f}, "
        f"over-seg {h['over_segmentation']:.3f}, under-seg {h['under_segmentation']:.3f} ({h['objects']} objects)"
    )
    say(f"wrote {cfg.out} (use segmenter_options: {{weights: {cfg.out}}})")
    return card
