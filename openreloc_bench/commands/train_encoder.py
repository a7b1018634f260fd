"""Train the offline encoder's image tower on object crops from generated training scenes.

Scenes are generated with seeds reserved for training (>= generators.spec.TRAINING_SEED_MIN, never in
a benchmark suite): ``--scenes`` for training and ``--eval-scenes`` more, from a disjoint seed range,
for held-out evaluation. Crops come from the mapping, query and lighting splits (viewpoint and
illumination diversity). Writes ``image_tower.pt`` (fp16), ``config.json`` (shapes, hyper-parameters,
data seeds) and ``evaluation.json`` into ``--out``. With ``--data DIR`` holding ``train/`` and
``eval/`` scene folders already, those scenes are used as they are and nothing is generated.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import platform
import time
from pathlib import Path

from openreloc_bench.errors import ConfigError

NAME = "train-encoder"
HELP = "train the offline image encoder (aligned to frozen MiniLM) on generated training scenes"
ORDER = 60

CROP_SPLITS = ("mapping", "query", "query_light1", "query_light2", "query_light3", "query_light4")
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
    parser.add_argument("--data", type=Path, default=None, help="scene folder (train/, eval/); default OUT/scenes")
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
        "--repeat-threshold",
        type=float,
        default=0.0,
        help="category-balanced sampling: categories under this share of the crops repeat (0: off)",
    )


def _scene_dirs(root: Path) -> list[Path]:
    return sorted(p for p in root.iterdir() if (p / "scene.json").is_file()) if root.is_dir() else []


def _generate(root: Path, prefix: str, seeds: list[int], args: argparse.Namespace) -> list[Path]:
    """Generate (or finish) one scene per reserved seed, in spawned processes."""
    try:
        from generators.generate import generate_scenes, training_specs
    except ImportError as e:
        raise ConfigError(
            f"the scene generator is not available ({e}); pass --data with train/ and eval/ scenes"
        ) from None
    specs = training_specs(prefix, seeds, args.width, args.height, max_mapping_frames=24, n_query=8, n_displaced=0)
    root.mkdir(parents=True, exist_ok=True)
    return generate_scenes(specs, root, resume=True, workers=args.workers, desc=f"{prefix} scenes")


def run(args: argparse.Namespace) -> int:
    # heavy imports here, not at module level: the CLI imports every command module at start-up
    import numpy as np
    import torch

    from openreloc_bench import config as cfgmod
    from openreloc_bench.data import io
    from openreloc_bench.vision import vocabulary as voc
    from openreloc_bench.vision.crops import CropSet, crops_from_scenes
    from openreloc_bench.vision.offline import MINILM_PACKAGE, OfflineEncoder, TextTower, TowerConfig
    from openreloc_bench.vision.training import TrainConfig, evaluate, save_weights, train_tower, training_device

    if args.scenes < 1 or args.eval_scenes < 1 or args.epochs < 1 or args.views < 1:
        raise ConfigError("--scenes, --eval-scenes, --epochs and --views must be >= 1")
    if not 0.0 <= args.repeat_threshold <= 1.0:
        raise ConfigError("--repeat-threshold must be in [0, 1]")
    device = training_device(args.device)  # refuse a missing GPU before generating scenes
    torch.set_num_threads(args.threads)
    data = args.data or args.out / "scenes"
    train_dirs, eval_dirs = _scene_dirs(data / "train"), _scene_dirs(data / "eval")
    generated = not (train_dirs and eval_dirs)
    if generated:
        from generators.spec import TRAINING_SEED_MIN

        base = TRAINING_SEED_MIN + 1000 * args.seed
        train_seeds = [base + i for i in range(args.scenes)]
        eval_seeds = [TRAINING_SEED_MIN + EVAL_SEED_OFFSET + 1000 * args.seed + i for i in range(args.eval_scenes)]
        t0 = time.time()
        train_dirs = _generate(data / "train", "train", train_seeds, args)
        eval_dirs = _generate(data / "eval", "eval", eval_seeds, args)
        print(f"generated {len(train_dirs) + len(eval_dirs)} scenes in {time.time() - t0:.0f} s", flush=True)
    train_seeds = [io.read_json(d / "scene.json").get("seed") for d in train_dirs]
    eval_seeds = [io.read_json(d / "scene.json").get("seed") for d in eval_dirs]
    if set(train_seeds) & set(eval_seeds):
        raise ConfigError("training and evaluation scenes share seeds; evaluation must be on held-out scenes")
    sets = []
    for name, dirs, seed in (("train", train_dirs, args.seed), ("eval", eval_dirs, args.seed + 1)):
        # crops are cached beside the scenes, keyed by the scene list and sampling, so re-training is cheap
        key = hashlib.sha1(
            json.dumps([[d.name for d in dirs], args.views, seed, list(CROP_SPLITS)]).encode()
        ).hexdigest()[:12]
        cache = data / f"crops-{name}-{key}.npz"
        if cache.is_file():
            sets.append(CropSet.load(cache))
        else:
            sets.append(
                crops_from_scenes(
                    dirs, splits=CROP_SPLITS, max_views_per_object=args.views, rng=np.random.default_rng(seed)
                )
            )
            sets[-1].save(cache)
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
    tower, info = train_tower(train, text, cfg, tower_cfg, log=lambda m: print(m, flush=True))
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
    result = evaluate(enc.encode_images, enc.encode_texts, held, categories=sorted(set(train.category)))
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
