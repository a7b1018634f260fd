"""Train the offline encoder's image tower end to end (``openreloc-bench train-encoder``): its training
scenes (:data:`~openreloc_bench.harness.training_data.ENCODER_DATA`), object crops cut from them (cached),
the tower (:mod:`openreloc_bench.vision.training`), its weights with their card and the held-out evaluation.
"""

from __future__ import annotations

import hashlib
import io as io_
import json
import platform
import time
import zipfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from openreloc_bench import config as cfgmod
from openreloc_bench.data import io, paths
from openreloc_bench.data.splits import LIGHT_SPLITS
from openreloc_bench.errors import ConfigError
from openreloc_bench.harness.training_data import ENCODER_DATA, held_out_seeds, training_scene_sets
from openreloc_bench.vision import create_segmenter, segmenter_fingerprint
from openreloc_bench.vision import vocabulary as voc
from openreloc_bench.vision.base import Segmenter
from openreloc_bench.vision.crops import CropSet, crops_from_scenes
from openreloc_bench.vision.offline import (
    MINILM_PACKAGE,
    ImageTower,
    OfflineEncoder,
    TextTower,
    TowerConfig,
    load_tower,
)
from openreloc_bench.vision.training import TrainConfig, evaluate, save_weights, train_tower, training_device

CROP_SPLITS = ("mapping", *LIGHT_SPLITS)
"""Crops come from the mapping, query and lighting splits (viewpoint and illumination diversity)."""
EVALUATION_KEYS = (
    "zero_shot_top1",
    "colour_top1_given_category",
    "instance_recall1_within_scene",
    "instance_recall1_pooled",
    "synonym_zero_shot_top1_mean",
    "synonym_ap_mean",
)
"""The held-out metrics said at the end."""


@dataclass
class EncoderTrainingConfig:
    """One training of the image tower (the command's defaults are the shipped weights' recipe)."""

    out: Path
    """Directory for ``image_tower.pt``, ``config.json``, ``evaluation.json`` and the crop cache ``crops/``
    (locked meanwhile)."""
    data: Path | None
    """Folder of ``train/`` and ``eval/`` scenes; None: ``out/scenes``. Scenes already in both are used as
    they are (never written to), else they are generated there."""
    scenes: int
    """Training scenes to generate."""
    eval_scenes: int
    """Held-out scenes to generate (seeds from a disjoint part of the training range)."""
    views: int
    """Views kept per object and split (random frames)."""
    width: int
    """Render width of generated scenes."""
    height: int
    """Render height of generated scenes."""
    workers: int
    """Parallel scene generation processes."""
    crop_segmenter: str
    """Cut crops by this segmenter's masks, each labelled with the object holding most of it; empty: the
    dataset's masks."""
    init: Path | None
    """Weights directory to start from (fine-tuning); None: random weights."""
    train: TrainConfig
    """The training's hyper-parameters; its ``seed`` also picks the scene seeds and the crops."""
    tower: TowerConfig
    """The tower's shape."""


def main(cfg: EncoderTrainingConfig, say: Callable[[str], None] = print) -> None:
    """Train, write the weights and their evaluation into ``cfg.out``, and say the held-out metrics."""
    device = training_device(cfg.train.device)  # refuse a missing GPU before generating scenes
    if cfg.data is not None:  # the user's scenes: weights and caches never go among them
        paths.check_output(cfg.out, [cfg.data / "train", cfg.data / "eval"], "--out")
    # a mistyped segmenter or missing starting weights fail here, not after the scenes are generated
    segmenter = create_segmenter(cfg.crop_segmenter) if cfg.crop_segmenter else None
    init, init_cfg, _ = load_tower(cfg.init) if cfg.init else (None, None, None)
    if init_cfg is not None and init_cfg != cfg.tower:
        raise ConfigError(f"--init {cfg.init}: its tower {init_cfg} differs from this run's {cfg.tower}")
    with paths.directory_lock(cfg.out, "openreloc-bench train-encoder"):
        _train(cfg, device, segmenter, init, say)


def _train(
    cfg: EncoderTrainingConfig,
    device: torch.device,
    segmenter: Segmenter | None,
    init: ImageTower | None,
    say: Callable[[str], None],
) -> None:
    seed = cfg.train.seed
    torch.set_num_threads(cfg.train.threads)
    t0 = time.time()
    train_dirs, eval_dirs, generated = training_scene_sets(
        cfg.data or cfg.out / "scenes",
        ENCODER_DATA,
        seed,
        cfg.scenes,
        cfg.eval_scenes,
        cfg.width,
        cfg.height,
        cfg.workers,
    )
    if generated:
        say(f"generated {len(train_dirs) + len(eval_dirs)} scenes in {time.time() - t0:.0f} s")
    train_seeds, eval_seeds = held_out_seeds(train_dirs, eval_dirs)
    train = cached_crops(cfg, "train", train_dirs, seed, segmenter)
    held = cached_crops(cfg, "eval", eval_dirs, seed + 1, segmenter)
    if len(train) < 2 or len(held) < 1:
        raise ConfigError(
            f"too few object crops (train {len(train)}, eval {len(held)}): are the scenes' objects visible?"
        )
    say(f"{len(train)} training crops of {len(set(train.instance_keys))} objects; {len(held)} eval crops")
    text = TextTower(MINILM_PACKAGE)
    tower, info = train_tower(train, text, cfg.train, cfg.tower, log=say, init=init)
    meta = {
        "text_model": MINILM_PACKAGE,
        "text_model_hub_id": "sentence-transformers/all-MiniLM-L6-v2",
        "train": cfgmod.to_dict(cfg.train),
        "data": {
            "train_scenes": [p.name for p in train_dirs],
            "eval_scenes": [p.name for p in eval_dirs],
            "train_seeds": train_seeds,
            "eval_seeds": eval_seeds,
            "splits": list(CROP_SPLITS),
            "views_per_object_and_split": cfg.views,
            "crops_cut_by": cfg.crop_segmenter or "dataset masks",
            "init": str(cfg.init) if cfg.init else None,
            "render_size": [cfg.width, cfg.height],
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
            "threads": cfg.train.threads,
            **({"gpu": torch.cuda.get_device_name(device)} if device.type == "cuda" else {}),
        },
    }
    save_weights(cfg.out, tower, cfg.tower, meta)
    enc = OfflineEncoder(cfg.out)
    categories = sorted(set(train.category))
    result = evaluate(enc.encode_images, enc.encode_texts, held, categories=categories)
    if cfg.init:  # the same held-out crops, before fine-tuning
        before = OfflineEncoder(cfg.init)
        result["init"] = evaluate(before.encode_images, before.encode_texts, held, categories=categories)
    io.write_json(cfg.out / "evaluation.json", result)
    say("evaluation: " + ", ".join(f"{k} {result[k]:.3f}" for k in EVALUATION_KEYS if k in result))
    say(f"wrote {cfg.out}/image_tower.pt, config.json, evaluation.json")


def cached_crops(
    cfg: EncoderTrainingConfig, name: str, dirs: list[Path], seed: int, segmenter: Segmenter | None
) -> CropSet:
    """The crops of ``dirs`` sampled with ``seed`` (cut by ``segmenter``'s masks, if any), cached in ``cfg.out/crops`` under a key of the scenes
    (names and spec hashes: a regenerated scene is cut again) and the sampling, so re-training is cheap;
    a damaged cache is cut again too."""
    scenes = [[d.name, io.read_json(d / "scene.json").get("spec_hash")] for d in dirs]
    cut_by = [cfg.crop_segmenter, segmenter_fingerprint(cfg.crop_segmenter, {})] if cfg.crop_segmenter else []
    key = hashlib.sha1(json.dumps([scenes, cfg.views, seed, list(CROP_SPLITS), *cut_by]).encode()).hexdigest()[:12]
    cache = cfg.out / "crops" / f"{name}-{key}.npz"
    try:
        return CropSet.load(cache)
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile):
        pass
    crops = crops_from_scenes(
        dirs, splits=CROP_SPLITS, max_views_per_object=cfg.views, rng=np.random.default_rng(seed), segmenter=segmenter
    )
    buf = io_.BytesIO()
    crops.save(buf)
    io.atomic_write_bytes(cache, buf.getvalue())
    return crops
