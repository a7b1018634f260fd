"""Generate the scenes of a suite YAML (``scenes/*.yaml``) into ``OUT/<scene name>/``.

Each scene gets the mapping split and every query split of ``openreloc_bench/data/splits.py`` in the
ScanNet-export layout, and a ``difficulty.csv`` measuring every query frame. ``--resume`` keeps finished
frames of an interrupted run; ``--workers N`` renders N scenes in parallel processes. A scene folder
generated from another spec (or holding other files) is never replaced, and OUT is locked while
generation runs.
"""

from __future__ import annotations

import argparse
from pathlib import Path

NAME = "generate"
HELP = "generate synthetic scenes from a suite YAML"
ORDER = 10


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "suite", metavar="SUITE", help="suite YAML (e.g. scenes/smoke.yaml) or a bundled suite's name (smoke)"
    )
    parser.add_argument("--out", type=Path, required=True, help="output directory (scenes go to OUT/<name>/)")
    parser.add_argument(
        "--resume",
        action="store_true",
        help="reuse finished frames of an interrupted run (without it, existing scenes of the same spec are regenerated)",
    )
    parser.add_argument("--workers", type=int, default=1, help="scenes generated in parallel")
    parser.add_argument("--scenes", type=str, default=None, help="comma-separated scene names (default: all)")


def run(args: argparse.Namespace) -> int:
    from generators.generate import generate_suite
    from generators.spec import load_suite
    from openreloc_bench.data import paths
    from openreloc_bench.errors import ConfigError
    from openreloc_bench.harness.suites import suite_file

    if args.workers < 1:
        raise ConfigError(f"--workers must be >= 1, got {args.workers}")
    suite_path = suite_file(args.suite)
    suite = load_suite(suite_path)
    for spec in suite.scene_specs():  # a scene directory is replaced when regenerated: never over the suite file
        paths.check_output(args.out / spec.name, [suite_path], "scene directory")
    only = [s.strip() for s in args.scenes.split(",") if s.strip()] if args.scenes is not None else None
    for path in generate_suite(suite, args.out, resume=args.resume, workers=args.workers, only=only):
        print(path)
    return 0
