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
from pathlib import Path

from openreloc_bench.data import paths
from openreloc_bench.errors import ConfigError

NAME = "train-segmenter"
HELP = "train the learned class-agnostic segmenter on generated training scenes"
ORDER = 61


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
    from openreloc_bench import config as cfgmod
    from openreloc_bench.harness import train_segmenter
    from openreloc_bench.vision.learned_segment import NetConfig, load_weights
    from openreloc_bench.vision.segmenter_training import SegTrainConfig
    from openreloc_bench.vision.training import training_device

    for flag, value in (
        ("--scenes", args.scenes),
        ("--eval-scenes", args.eval_scenes),
        ("--per-split", args.per_split),
    ):
        if value < 1:
            raise ConfigError(f"{flag} must be >= 1, got {value}")
    train = cfgmod.from_dict(
        SegTrainConfig,
        {"seed": args.seed, "steps": args.steps, "batch": args.batch, "crop": args.crop, "lr": args.lr,
         "threads": args.threads, "device": args.device, "loader_workers": args.loader_workers,
         "max_seconds": 60.0 * args.max_minutes},
        "train-segmenter",
    )  # fmt: skip
    paths.check_output(args.out, [], "--out", fills=True)  # neither in nor a scene or map
    training_device(args.device)  # refuse a missing GPU before reading weights or generating anything
    net = load_weights(args.init)[1] if args.init else NetConfig()
    try:
        widths = tuple(int(w) for w in args.widths.split(",")) if args.widths else net.widths
        net = NetConfig(widths=widths, work_width=net.work_width if args.work_width is None else args.work_width)
    except ValueError as e:
        given = [
            f"--widths {args.widths!r}" if args.widths else "",
            f"--work-width {args.work_width}" if args.work_width is not None else "",
        ]
        raise ConfigError(f"{' '.join(g for g in given if g)}: {e}") from None
    cfg = train_segmenter.SegmenterTrainingConfig(
        out=args.out, data=args.data, scenes=args.scenes, eval_scenes=args.eval_scenes, per_split=args.per_split,
        width=args.width, height=args.height, workers=args.workers, init=args.init, net=net, train=train,
    )  # fmt: skip
    train_segmenter.main(cfg, say=lambda m: print(m, flush=True))
    return 0
