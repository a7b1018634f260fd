"""Train the learned segmenter (``segmenter: learned``) on generated training scenes.

Generates its own scenes from the seeds reserved for training (never a benchmark or validation
scene): ``--scenes`` to train on and ``--eval-scenes`` more, from a disjoint part of the range, on
which the boundary threshold is chosen and the card's held-out metrics are measured. Writes a
weights directory (``model.pt``, ``card.json``, ``manifest.json``) to use as
``segmenter_options: {weights: DIR}``. Everything follows from ``--seed``; a killed run resumes from
its last checkpoint when started again with the same arguments. ``--init DIR`` fine-tunes existing
weights (e.g. on scenes of a new data version) instead of starting from random ones.

  openreloc-bench train-segmenter --out weights/segmenter --device cuda
  openreloc-bench train-segmenter --out weights/tuned --init weights/segmenter --lr 1e-3 --steps 3000
"""

from __future__ import annotations

import argparse
import platform
import time
from pathlib import Path

from openreloc_bench.errors import ConfigError

NAME = "train-segmenter"
HELP = "train the learned class-agnostic segmenter on generated training scenes"
ORDER = 61

TRAIN_SEED_OFFSET = 200_000
EVAL_SEED_OFFSET = 700_000
"""Training scenes use seeds TRAINING_SEED_MIN + TRAIN_SEED_OFFSET + 1000 * seed + i, evaluation scenes
TRAINING_SEED_MIN + EVAL_SEED_OFFSET + ...: disjoint from each other and from the encoder's scenes."""
SCENE_SPEC = dict(with_floors=True, max_mapping_frames=30, n_query=10, n_displaced=3)
"""Training scenes: a few frames of every split per scene (frames are sampled per split)."""
THRESHOLDS = (0.05, 0.1, 0.2, 0.3, 0.4, 0.5)


def add_arguments(p: argparse.ArgumentParser) -> None:
    # the defaults are a CPU recipe; the shipped weights (vision/weights/segmenter/card.json) are a GPU
    # run: --device cuda --scenes 90 --widths 24,36,72,144,192 --batch 32 --steps 5600, then --init (those
    # weights) --seed 1 --scenes 40 --lr 1e-3 --steps 7600, held out on seed 0's scenes (docs/experiments.md)
    p.add_argument("--out", type=Path, required=True, help="weights directory to write")
    p.add_argument("--seed", type=int, default=0, help="training seed (also picks the scene seeds)")
    p.add_argument("--device", default="cpu", help="torch device of the training steps: cpu, cuda, cuda:N")
    p.add_argument("--scenes", type=int, default=60, help="training scenes to generate")
    p.add_argument("--eval-scenes", type=int, default=6, help="held-out scenes (threshold choice, card metrics)")
    p.add_argument("--data", type=Path, default=None, help="scene folder (train/, eval/) (default: OUT/scenes)")
    p.add_argument("--steps", type=int, default=6000, help="optimiser steps")
    p.add_argument("--batch", type=int, default=8, help="crops per step")
    p.add_argument("--crop", type=int, default=192, help="crop side at the working resolution")
    p.add_argument("--lr", type=float, default=3e-3, help="peak learning rate")
    p.add_argument(
        "--init", type=Path, default=None, help="weights directory to start from, fine-tuning (default: random weights)"
    )
    p.add_argument(
        "--widths",
        default=None,
        help="channels of the network's stem and stages, comma-separated (default: 16,24,48,96,128; "
        "with --init: the starting weights')",
    )
    p.add_argument(
        "--work-width",
        type=int,
        default=None,
        help="width the network sees, frames downscaled to it (default: 320; with --init: the starting weights')",
    )
    p.add_argument("--per-split", type=int, default=12, help="frames kept per split and scene")
    p.add_argument("--width", type=int, default=640, help="render width of the generated scenes")
    p.add_argument("--height", type=int, default=480, help="render height of the generated scenes")
    p.add_argument("--workers", type=int, default=2, help="parallel scene generation processes")
    p.add_argument(
        "--loader-workers",
        type=int,
        default=0,
        help="processes cutting training crops ahead of the steps (0: the training process; same weights "
        "for any number; on a GPU, give it most of the CPU cores)",
    )
    p.add_argument("--threads", type=int, default=2, help="torch CPU threads")
    p.add_argument(
        "--max-minutes",
        type=float,
        default=0.0,
        help="stop training after this many minutes even if --steps are not done (0: never; the card "
        "records the steps run)",
    )


def run(args: argparse.Namespace) -> int:
    # heavy imports here: the CLI imports every command module at start-up
    import numpy as np
    import torch

    from openreloc_bench import config as cfgmod
    from openreloc_bench.data import io, paths
    from openreloc_bench.harness.suites import scene_dirs, training_scenes
    from openreloc_bench.vision.learned_segment import NetConfig, load_weights, save_weights
    from openreloc_bench.vision.segmenter_training import (
        SegTrainConfig,
        evaluate_thresholds,
        load_frames,
        train_boundary_net,
    )
    from openreloc_bench.vision.training import training_device

    for flag, value in (
        ("--scenes", args.scenes),
        ("--eval-scenes", args.eval_scenes),
        ("--per-split", args.per_split),
    ):
        if value < 1:
            raise ConfigError(f"{flag} must be >= 1, got {value}")
    cfg = cfgmod.from_dict(
        SegTrainConfig,
        {"seed": args.seed, "steps": args.steps, "batch": args.batch, "crop": args.crop, "lr": args.lr,
         "threads": args.threads, "device": args.device, "loader_workers": args.loader_workers,
         "max_seconds": 60.0 * args.max_minutes},
        "train-segmenter",
    )  # fmt: skip
    device = training_device(args.device)  # refuse a missing GPU before generating anything
    net_cfg = load_weights(args.init)[1] if args.init else NetConfig()
    try:
        widths = tuple(int(w) for w in args.widths.split(",")) if args.widths else net_cfg.widths
        net_cfg = NetConfig(
            widths=widths, work_width=net_cfg.work_width if args.work_width is None else args.work_width
        )
    except ValueError as e:
        given = [
            f"--widths {args.widths!r}" if args.widths else "",
            f"--work-width {args.work_width}" if args.work_width is not None else "",
        ]
        raise ConfigError(f"{' '.join(g for g in given if g)}: {e}") from None
    data = args.data or args.out / "scenes"
    with paths.directory_lock(args.out, "openreloc-bench train-segmenter"):
        train_dirs, eval_dirs = scene_dirs(data / "train"), scene_dirs(data / "eval")
        if not (train_dirs and eval_dirs):
            from generators.spec import TRAINING_SEED_MIN

            base = TRAINING_SEED_MIN + 1000 * args.seed
            seeds = [base + TRAIN_SEED_OFFSET + i for i in range(args.scenes)]
            train_dirs = training_scenes(
                data / "train", "train", seeds, args.width, args.height, args.workers, **SCENE_SPEC
            )
            seeds = [base + EVAL_SEED_OFFSET + i for i in range(args.eval_scenes)]
            eval_dirs = training_scenes(
                data / "eval", "eval", seeds, args.width, args.height, args.workers, **SCENE_SPEC
            )
        seeds = {
            name: [io.read_json(d / "scene.json").get("seed") for d in dirs]
            for name, dirs in (("train", train_dirs), ("eval", eval_dirs))
        }
        if set(seeds["train"]) & set(seeds["eval"]):
            raise ConfigError("training and evaluation scenes share seeds; evaluation must be on held-out scenes")
        threads = max(args.threads, args.loader_workers)
        train = load_frames(train_dirs, net_cfg, args.per_split, np.random.default_rng(args.seed), threads=threads)
        held = load_frames(
            eval_dirs, net_cfg, max(2, args.per_split // 3), np.random.default_rng(args.seed + 1), threads=threads
        )
        print(f"{len(train)} training frames from {len(train_dirs)} scenes; {len(held)} held-out frames", flush=True)
        t0 = time.time()
        net, info = train_boundary_net(
            train, net_cfg, cfg, args.out / "checkpoint.pt", log=lambda m: print(m, flush=True), init=args.init
        )
        torch.set_num_threads(args.threads)
        scores = evaluate_thresholds(net, held, THRESHOLDS)
        best = max(THRESHOLDS, key=lambda t: scores[t]["mean_best_iou"] + scores[t]["ap50"])
        card = {
            "id": info["recipe"],
            **({"init": info["init"]} if "init" in info else {}),
            "threshold": best,
            "held_out": {"threshold": best, **scores[best]},
            "thresholds": {str(t): s for t, s in scores.items()},
            "train": cfgmod.to_dict(cfg),
            "data": {
                "train_seeds": seeds["train"],
                "eval_seeds": seeds["eval"],
                "render_size": [args.width, args.height],
                "frames_per_split": args.per_split,
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
                "threads": args.threads,
            },
        }
        save_weights(args.out, net, net_cfg, card)
    if info["steps_run"] < cfg.steps:
        print(f"note: training stopped at step {info['steps_run']} of {cfg.steps} (--max-minutes {args.max_minutes:g})")
    h = card["held_out"]
    print(
        f"held-out (threshold {best}): mean best IoU {h['mean_best_iou']:.3f}, AP50 {h['ap50']:.3f}, "
        f"over-seg {h['over_segmentation']:.3f}, under-seg {h['under_segmentation']:.3f} ({h['objects']} objects)"
    )
    print(f"wrote {args.out} (use segmenter_options: {{weights: {args.out}}})")
    return 0
