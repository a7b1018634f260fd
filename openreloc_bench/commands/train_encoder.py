"""Train the offline encoder's image tower on object crops from generated training scenes.

Scenes are generated with seeds reserved for training (>= generators.spec.TRAINING_SEED_MIN, never in
a benchmark suite): ``--scenes`` for training and ``--eval-scenes`` more, from a disjoint seed range,
for held-out evaluation. Crops come from the mapping, query and lighting splits (viewpoint and
illumination diversity). Writes ``image_tower.pt`` (fp16), ``config.json`` (shapes, hyper-parameters,
data seeds) and ``evaluation.json`` into ``--out`` (locked meanwhile), and caches the crops in
``--out/crops/``. With ``--data DIR`` holding ``train/`` and ``eval/`` scene folders already, those
scenes are used as they are (never written to) and nothing is generated.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from openreloc_bench.data import paths
from openreloc_bench.errors import ConfigError

NAME = "train-encoder"
HELP = "train the offline image encoder (aligned to frozen MiniLM) on generated training scenes"
ORDER = 60


def add_arguments(parser: argparse.ArgumentParser) -> None:
    # the defaults are the recipe of the shipped weights (openreloc_bench/vision/weights/config.json)
    parser.add_argument(
        "--out", type=Path, required=True, help="directory for image_tower.pt, config.json, evaluation.json"
    )
    parser.add_argument("--seed", type=int, default=0, help="training seed (also picks the scene seeds)")
    parser.add_argument("--scenes", type=int, default=210, help="training scenes to generate")
    parser.add_argument("--eval-scenes", type=int, default=10, help="held-out scenes for evaluation")
    parser.add_argument("--epochs", type=int, default=6, help="training epochs")
    parser.add_argument("--data", type=Path, default=None, help="scene folder (train/, eval/) (default: OUT/scenes)")
    parser.add_argument("--views", type=int, default=3, help="views kept per object and split (random frames)")
    parser.add_argument("--width", type=int, default=320, help="render width of generated training scenes")
    parser.add_argument("--height", type=int, default=240, help="render height of generated training scenes")
    parser.add_argument(
        "--threads", type=int, default=2, help="torch threads (the shipped weights: 2; 1 is faster on a loaded machine)"
    )
    parser.add_argument(
        "--pairs-per-batch", type=int, default=128, help="anchor crops per batch (each with a second view)"
    )
    parser.add_argument("--input-size", type=int, default=40, help="crop side fed to the image tower")
    parser.add_argument("--workers", type=int, default=2, help="parallel scene generation processes")
    parser.add_argument("--instance-weight", type=float, default=0.3, help="two-view image loss weight")
    parser.add_argument(
        "--scenes-per-batch",
        type=int,
        default=4,
        help="anchors of a batch come from this many scenes (0: all scenes at random)",
    )
    parser.add_argument(
        "--device", default="cpu", help="torch device of the training steps: cpu (the shipped weights), cuda, cuda:N"
    )
    parser.add_argument(
        "--crop-segmenter",
        default="",
        help="cut crops by this segmenter's masks (e.g. learned: noisy borders and parts, as in the predicted "
        "track) instead of the dataset's; each mask is labelled with the object holding most of it",
    )
    parser.add_argument("--init", type=Path, help="weights directory to start from (fine-tuning)")
    parser.add_argument(
        "--repeat-threshold",
        type=float,
        default=0.0,
        help="category-balanced sampling: categories under this share of the crops repeat (0: off)",
    )


def _check_numbers(args: argparse.Namespace) -> None:
    """One-line errors for flags out of range, before any scene is generated or crop cut."""
    at_least = {
        "--scenes": (args.scenes, 1), "--eval-scenes": (args.eval_scenes, 1), "--epochs": (args.epochs, 1),
        "--views": (args.views, 1), "--threads": (args.threads, 1), "--pairs-per-batch": (args.pairs_per_batch, 1),
        "--input-size": (args.input_size, 1), "--workers": (args.workers, 1), "--seed": (args.seed, 0),
        "--scenes-per-batch": (args.scenes_per_batch, 0), "--width": (args.width, 16), "--height": (args.height, 16),
    }  # fmt: skip
    for flag, (value, low) in at_least.items():
        if value < low:
            raise ConfigError(f"{flag} must be >= {low}, got {value}")
    if not math.isfinite(args.instance_weight) or args.instance_weight < 0:
        raise ConfigError(f"--instance-weight must be a finite number >= 0, got {args.instance_weight}")
    if not 0.0 <= args.repeat_threshold <= 1.0:
        raise ConfigError(f"--repeat-threshold must be in [0, 1], got {args.repeat_threshold}")


def run(args: argparse.Namespace) -> int:
    # heavy imports here, not at module level: the CLI imports every command module at start-up
    from openreloc_bench.harness import train_encoder
    from openreloc_bench.vision.offline import TowerConfig
    from openreloc_bench.vision.training import TrainConfig, training_device

    _check_numbers(args)
    paths.check_output(args.out, [], "--out", fills=True)  # neither in nor a scene or map
    training_device(args.device)  # refuse a missing GPU before generating scenes
    train = TrainConfig(
        seed=args.seed, epochs=args.epochs, threads=args.threads, instance_weight=args.instance_weight,
        pairs_per_batch=args.pairs_per_batch, scenes_per_batch=args.scenes_per_batch,
        repeat_threshold=args.repeat_threshold, device=args.device,
    )  # fmt: skip
    cfg = train_encoder.EncoderTrainingConfig(
        out=args.out, data=args.data, scenes=args.scenes, eval_scenes=args.eval_scenes, views=args.views,
        width=args.width, height=args.height, workers=args.workers, crop_segmenter=args.crop_segmenter,
        init=args.init, train=train, tower=TowerConfig(input_size=args.input_size),
    )  # fmt: skip
    train_encoder.main(cfg, say=lambda m: print(m, flush=True))
    return 0
