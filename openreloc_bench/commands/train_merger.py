"""Train the instance merge classifier of the predicted track's maps on generated training scenes.

Generates scenes from the seeds reserved for training (never a benchmark or validation scene),
builds each one's instances from the segmenter's masks as mapping does (fusion, observation,
grouping, fill when on; ``--config`` and ``--set`` take openreloc's settings), labels every pair of
touching instances from the scene's object boxes, and fits the logistic regression of
``reconstruction/instance_repair.py``. ``--eval-scenes`` more, from a disjoint part of the range, give the
card's held-out pair accuracy. The merge threshold is a
mapping setting, chosen on the validation suite with ``openreloc-bench diagnose``. Writes a directory
to use as ``--set mapping.instances.repair.merger=DIR``.

  openreloc-bench train-merger --out weights/merger
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from openreloc_bench.commands.options import add_method_config_arguments, method_overrides
from openreloc_bench.errors import ConfigError

NAME = "train-merger"
HELP = "train the predicted track's instance merge classifier on generated training scenes"
ORDER = 62


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", type=Path, required=True, help="directory to write (merger.json, manifest.json)")
    p.add_argument("--seed", type=int, default=0, help="picks the scene seeds")
    p.add_argument("--scenes", type=int, default=12, help="training scenes to generate")
    p.add_argument("--eval-scenes", type=int, default=3, help="held-out scenes for the card's pair accuracy")
    p.add_argument(
        "--data",
        type=Path,
        default=None,
        help="scene folder (train/, eval/; generated when empty) (default: OUT/scenes)",
    )
    p.add_argument(
        "--segmenter", default=None, help="segmenter whose masks the instances come from; default: the method config's"
    )
    p.add_argument("--workers", type=int, default=2, help="parallel scene generation processes")
    add_method_config_arguments(p)  # openreloc's settings: its mapping section and segmenter options apply


def run(args: argparse.Namespace) -> int:
    from openreloc_bench import config as cfgmod
    from openreloc_bench.data import paths
    from openreloc_bench.harness.merger_training import collect_examples, pair_accuracy
    from openreloc_bench.harness.training_data import MERGER_DATA, scene_seeds, training_scene_sets
    from openreloc_bench.openreloc.method import OpenReLocConfig
    from openreloc_bench.reconstruction.instance_repair import FEATURES, fit_merger
    from openreloc_bench.vision import create_segmenter

    for flag, value in (("--scenes", args.scenes), ("--eval-scenes", args.eval_scenes)):
        if value < 1:
            raise ConfigError(f"{flag} must be >= 1, got {value}")
    method_cfg = cfgmod.from_dict(OpenReLocConfig, method_overrides(args), "openreloc")
    if args.segmenter:
        method_cfg.segmenter, method_cfg.segmenter_options = args.segmenter, {}
    # an unknown name or missing weights fail before generating anything
    segmenter = create_segmenter(method_cfg.segmenter, **method_cfg.segmenter_options)
    data = args.data or args.out / "scenes"
    config = method_cfg.mapping
    paths.check_output(args.out, [], "--out", fills=True)  # neither in nor a scene or map
    with paths.directory_lock(args.out, "openreloc-bench train-merger"):
        train_dirs, eval_dirs, _ = training_scene_sets(
            data, MERGER_DATA, args.seed, args.scenes, args.eval_scenes, 640, 480, args.workers
        )
        t0 = time.time()
        train = collect_examples(train_dirs, segmenter, config)
        held = collect_examples(eval_dirs, segmenter, config)
        if train.same.all() or not train.same.any():
            raise ConfigError(f"the {len(train.same)} training pairs are all of one kind: generate more --scenes")
        classifier = fit_merger(train.features, train.same)
        threshold = config.instances.repair.merge_threshold
        classifier.card = {
            "segmenter": segmenter.config() if hasattr(segmenter, "config") else {"name": method_cfg.segmenter},
            "grouping": config.instances.grouping,
            "train_seeds": scene_seeds(train_dirs),
            "eval_seeds": scene_seeds(eval_dirs),
            "train_pairs": int(len(train.same)),
            "train_one_object": int(train.same.sum()),
            "held_out": {"threshold": threshold, **pair_accuracy(classifier, held, threshold)},
            "weights": {f: round(float(w), 4) for f, w in zip(FEATURES, classifier.weights)},
            "seconds": round(time.time() - t0, 1),
        }
        classifier.save(args.out)
    h = classifier.card["held_out"]
    print(
        f"{len(train.same)} training pairs ({int(train.same.sum())} one object); held-out at {threshold}: "
        f"accuracy {h['accuracy']:.3f}, precision {h['precision']:.3f}, recall {h['recall']:.3f} "
        f"({h['pairs']} pairs)"
    )
    print(f"wrote {args.out} (use --set mapping.instances.repair.merger={args.out})")
    return 0
