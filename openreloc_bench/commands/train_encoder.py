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
import hashlib
import io as io_
import json
import math
import platform
import time
import zipfile
from pathlib import Path
from typing import TYPE_CHECKING

from openreloc_bench.errors import ConfigError

if TYPE_CHECKING:
    import torch

NAME = "train-encoder"
HELP = "train the offline image encoder (aligned to frozen MiniLM) on generated training scenes"
ORDER = 60

CROP_SPLITS = ("mapping", "query", "query_light1", "query_light2", "query_light3", "query_light4")
SCENE_SPEC = dict(max_mapping_frames=24, n_query=8, n_displaced=0)
"""Training scenes: crops come from a few frames of each."""
EVAL_SEED_OFFSET = 500_000
"""Eval scenes use seeds TRAINING_SEED_MIN + EVAL_SEED_OFFSET + ..., disjoint from the training range."""


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
    from openreloc_bench.data import paths
    from openreloc_bench.vision.training import training_device

    _check_numbers(args)
    device = training_device(args.device)  # refuse a missing GPU before generating scenes
    if args.data is not None:  # the user's scenes: weights and caches never go among them
        paths.check_output(args.out, [args.data / "train", args.data / "eval"], "--out")
    with paths.directory_lock(args.out, "openreloc-bench train-encoder"):
        return _train(args, device)


def _train(args: argparse.Namespace, device: torch.device) -> int:
    # heavy imports here, not at module level: the CLI imports every command module at start-up
    import numpy as np
    import torch

    from openreloc_bench import config as cfgmod
    from openreloc_bench.data import io
    from openreloc_bench.data.scene import check_scene_info
    from openreloc_bench.harness.suites import scene_dirs, training_scenes
    from openreloc_bench.vision import create_segmenter, segmenter_fingerprint
    from openreloc_bench.vision import vocabulary as voc
    from openreloc_bench.vision.crops import CropSet, crops_from_scenes
    from openreloc_bench.vision.offline import MINILM_PACKAGE, OfflineEncoder, TextTower, TowerConfig, load_tower
    from openreloc_bench.vision.training import TrainConfig, evaluate, save_weights, train_tower

    torch.set_num_threads(args.threads)
    data = args.data or args.out / "scenes"
    train_dirs, eval_dirs = scene_dirs(data / "train"), scene_dirs(data / "eval")
    generated = not (train_dirs and eval_dirs)
    if generated:
        from generators.spec import TRAINING_SEED_MIN

        base = TRAINING_SEED_MIN + 1000 * args.seed
        train_seeds = [base + i for i in range(args.scenes)]
        eval_seeds = [TRAINING_SEED_MIN + EVAL_SEED_OFFSET + 1000 * args.seed + i for i in range(args.eval_scenes)]
        t0 = time.time()
        train_dirs = training_scenes(
            data / "train", "train", train_seeds, args.width, args.height, args.workers, **SCENE_SPEC
        )
        eval_dirs = training_scenes(
            data / "eval", "eval", eval_seeds, args.width, args.height, args.workers, **SCENE_SPEC
        )
        print(f"generated {len(train_dirs) + len(eval_dirs)} scenes in {time.time() - t0:.0f} s", flush=True)
    infos = {d: check_scene_info(io.read_json(d / "scene.json"), d / "scene.json") for d in train_dirs + eval_dirs}
    train_seeds = [infos[d].get("seed") for d in train_dirs]
    eval_seeds = [infos[d].get("seed") for d in eval_dirs]
    if set(train_seeds) & set(eval_seeds):
        raise ConfigError("training and evaluation scenes share seeds; evaluation must be on held-out scenes")
    segmenter = create_segmenter(args.crop_segmenter) if args.crop_segmenter else None
    init, init_cfg, _ = load_tower(args.init) if args.init else (None, None, None)
    sets = []
    for name, dirs, seed in (("train", train_dirs, args.seed), ("eval", eval_dirs, args.seed + 1)):
        # crops are cached in OUT, keyed by the scenes (names and spec hashes: a regenerated scene is cut
        # again) and the sampling, so re-training is cheap; a damaged cache is cut again too
        scenes = [[d.name, infos[d].get("spec_hash")] for d in dirs]
        cut_by = [args.crop_segmenter, segmenter_fingerprint(args.crop_segmenter, {})] if args.crop_segmenter else []
        key = hashlib.sha1(json.dumps([scenes, args.views, seed, list(CROP_SPLITS), *cut_by]).encode()).hexdigest()[:12]
        cache = args.out / "crops" / f"{name}-{key}.npz"
        try:
            sets.append(CropSet.load(cache))
        except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile):
            crops = crops_from_scenes(
                dirs,
                splits=CROP_SPLITS,
                max_views_per_object=args.views,
                rng=np.random.default_rng(seed),
                segmenter=segmenter,
            )
            buf = io_.BytesIO()
            crops.save(buf)
            io.atomic_write_bytes(cache, buf.getvalue())
            sets.append(crops)
    train, held = sets
    if len(train) < 2 or len(held) < 1:
        raise ConfigError(
            f"too few object crops (train {len(train)}, eval {len(held)}): are the scenes' objects visible?"
        )
    print(f"{len(train)} training crops of {len(set(train.instance_keys))} objects; {len(held)} eval crops", flush=True)
    text = TextTower(MINILM_PACKAGE)
    cfg = TrainConfig(
        seed=args.seed,
        epochs=args.epochs,
        threads=args.threads,
        instance_weight=args.instance_weight,
        pairs_per_batch=args.pairs_per_batch,
        scenes_per_batch=args.scenes_per_batch,
        repeat_threshold=args.repeat_threshold,
        device=args.device,
    )
    tower_cfg = TowerConfig(input_size=args.input_size)
    if init_cfg is not None and init_cfg != tower_cfg:
        raise ConfigError(f"--init {args.init}: its tower {init_cfg} differs from this run's {tower_cfg}")
    tower, info = train_tower(train, text, cfg, tower_cfg, log=lambda m: print(m, flush=True), init=init)
    meta = {
        "text_model": MINILM_PACKAGE,
        "text_model_hub_id": "sentence-transformers/all-MiniLM-L6-v2",
        "train": cfgmod.to_dict(cfg),
        "data": {
            "train_scenes": [p.name for p in train_dirs],
            "eval_scenes": [p.name for p in eval_dirs],
            "train_seeds": train_seeds,
            "eval_seeds": eval_seeds,
            "splits": list(CROP_SPLITS),
            "views_per_object_and_split": args.views,
            "crops_cut_by": args.crop_segmenter or "dataset masks",
            "init": str(args.init) if args.init else None,
            "render_size": [args.width, args.height],
            "train_crops": len(train),
            "train_objects": len(set(train.instance_keys)),
            "categories": sorted(set(train.category)),
        },
        "held_out_synonyms": {k: list(v) for k, v in voc.HELD_OUT_SYNONYMS.items()},
        "history": info["history"],
        "train_seconds": info["train_seconds"],
        "environment": {
            "torch": torch.__version__,
            "python": platform.python_version(),
            "threads": args.threads,
            **({"gpu": torch.cuda.get_device_name(device)} if device.type == "cuda" else {}),
        },
    }
    save_weights(args.out, tower, tower_cfg, meta)
    enc = OfflineEncoder(args.out)
    categories = sorted(set(train.category))
    result = evaluate(enc.encode_images, enc.encode_texts, held, categories=categories)
    if args.init:  # the same held-out crops, before fine-tuning
        before = OfflineEncoder(args.init)
        result["init"] = evaluate(before.encode_images, before.encode_texts, held, categories=categories)
    io.write_json(args.out / "evaluation.json", result)
    keys = (
        "zero_shot_top1",
        "colour_top1_given_category",
        "instance_recall1_within_scene",
        "instance_recall1_pooled",
        "synonym_zero_shot_top1_mean",
        "synonym_ap_mean",
    )
    print("evaluation: " + ", ".join(f"{k} {result[k]:.3f}" for k in keys if k in result))
    print(f"wrote {args.out}/image_tower.pt, config.json, evaluation.json")
    return 0
