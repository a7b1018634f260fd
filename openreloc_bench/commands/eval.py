"""Evaluate relocalization methods on a scene suite: generate missing scenes, build each method's map
once per scene (cached by method config + scene spec hash), localize every query of the requested
splits, score them and write pose files, TUM exports and metric tables under RESULTS.

Results are resumable (--resume skips finished (scene, method, split) jobs) and record the method's
full config, the track, the scene spec hashes and the git commit. The track recorded is --track, or
mask-free for a method that declares it reads no masks (``uses_masks = False``): it is given none, and
its results stand for both tracks. --seeds repeats every seeded method
once per seed (the maps are shared) and reports each metric's spread over the seeds. Jobs run inline,
on a local process pool (--workers N) or on Ray (--executor ray; RAY_ADDRESS or --ray-address selects
a cluster).

Example (hist_nn.py registering a method, as in the README's "Adding a method"):
  openreloc-bench eval --suite scenes/smoke.yaml --methods nearest-frame --data data --out results
  openreloc-bench eval --suite demo --methods hist-nn,nearest-frame --plugin ./hist_nn.py \
      --data data --out results
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Sequence
from pathlib import Path

from openreloc_bench import config
from openreloc_bench.commands.options import TRACK_HELP, add_plugin_argument, add_track_argument, comma_list
from openreloc_bench.data import paths
from openreloc_bench.data.splits import QUERY_SPLITS
from openreloc_bench.errors import ConfigError
from openreloc_bench.harness import evaluation, runner
from openreloc_bench.harness.ablations import ABLATED_METHOD, ROBUSTNESS_ROWS
from openreloc_bench.harness.executors import EXECUTORS
from openreloc_bench.harness.suites import suite_file

NAME = "eval"
HELP = "evaluate methods on a scene suite (maps, queries, metrics)"
ORDER = 40

MAX_TIMEOUT_S = 1e7
"""Upper bound of --timeout / --map-timeout (about four months; larger values overflow the OS's wait)."""


def add_arguments(p: argparse.ArgumentParser) -> None:
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument(
        "--suite", help="suite YAML, or a bundled suite's name (smoke, demo, ...); missing scenes are generated"
    )
    src.add_argument("--scenes", help="comma-separated scene directories already under --data (e.g. converted ScanNet)")
    p.add_argument("--methods", required=True, help="comma-separated registered method names")
    p.add_argument("--data", type=Path, required=True, help="dataset directory (one sub-directory per scene)")
    p.add_argument("--out", type=Path, required=True, help="results directory")
    p.add_argument("--splits", default="query", help=f"comma-separated query splits (of {', '.join(QUERY_SPLITS)})")
    add_track_argument(p, TRACK_HELP)
    p.add_argument("--executor", default="local", choices=EXECUTORS, help="where jobs run")
    p.add_argument("--workers", type=int, default=1, help="parallel jobs (local: 1 = inline, N = process pool)")
    p.add_argument("--ray-address", help="existing Ray cluster (default: $RAY_ADDRESS, else a local instance)")
    p.add_argument("--resume", action="store_true", help="skip (scene, method, split) jobs that already finished")
    p.add_argument("--timeout", type=float, default=300.0, help="per-query limit in seconds (0 = none, in-process)")
    p.add_argument(
        "--map-timeout",
        type=float,
        default=3600.0,
        help="limit on building one map, and on loading it, in seconds (0 = none, in-process)",
    )
    p.add_argument("--ablations", action="store_true", help=f"also run the paper's ablation rows of {ABLATED_METHOD}")
    p.add_argument("--robustness", action="store_true", help="also localize the lighting 1-4 and displaced splits")
    p.add_argument(
        "--seeds",
        default="",
        help="comma-separated seeds: run every method that has a 'seed' setting once per seed and "
        "report the spread (tables/seeds.csv); deterministic methods run once",
    )
    p.add_argument(
        "--method-config",
        action="append",
        default=[],
        metavar="NAME=YAML",
        help="config overrides for one method from a YAML mapping (repeatable)",
    )
    p.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="NAME:KEY=VALUE",
        help="one setting of one method, over its --method-config (YAML value; nested keys with dots, "
        "e.g. openreloc:anchors.enabled=false); repeatable",
    )
    add_plugin_argument(p)


def method_runs(
    names: list[str], config_files: list[str], ablations: bool, settings: Sequence[str] = ()
) -> list[runner.MethodRun]:
    """Method variants: each named method with its overrides (``--method-config`` files, then ``--set``
    settings over them), plus the ablation rows if asked."""
    overrides: dict[str, dict] = {}
    for item in config_files:
        name, sep, path = item.partition("=")
        if not sep or not name or not path:
            raise ConfigError(f"--method-config expects NAME=YAML, got '{item}'")
        if name not in names:
            raise ConfigError(f"--method-config names '{name}', which is not in --methods")
        if name in overrides:
            raise ConfigError(f"--method-config names '{name}' twice; merge the settings into one file")
        overrides[name] = config.load_mapping(path)
    for item in settings:
        name, sep, setting = item.partition(":")
        if not sep or not name or "=" not in setting:
            raise ConfigError(f"--set expects NAME:KEY=VALUE (e.g. openreloc:anchors.enabled=false), got '{item}'")
        if name not in names:
            raise ConfigError(f"--set names '{name}', which is not in --methods")
        overrides[name] = config.merge(overrides.get(name, {}), config.parse_overrides([setting]))
    return runner.variant_runs(names, overrides, ablations)


def scene_names(entries: list[str], data: Path) -> list[str]:
    """``--scenes`` entries as scene names under ``data``: a plain name, or a path to a directory directly
    inside ``data`` (a path elsewhere is refused: scenes are always read from, and named under, --data)."""
    names = []
    for entry in entries:
        if entry in (".", "..") or Path(entry).name != entry:
            p = Path(entry).resolve()
            if p.parent != Path(data).resolve():
                raise ConfigError(f"--scenes '{entry}' is not a scene directory directly under --data {data}")
            entry = p.name
        names.append(paths.plain_name(entry, "--scenes entry"))
    return list(dict.fromkeys(names))


def _seeds(s: str) -> list[int]:
    """``--seeds`` as 64-bit seeds >= 0 (none when empty)."""
    if not s.strip():
        return []
    try:
        seeds = [int(x) for x in comma_list(s, "--seeds")]
    except ValueError:
        raise ConfigError(f"--seeds expects comma-separated integers, got '{s}'") from None
    wrong = [x for x in seeds if not 0 <= x < 2**63]
    if wrong:
        raise ConfigError(f"--seeds: {wrong[0]} is out of range (seeds are 64-bit integers >= 0)")
    return seeds


def eval_config(args: argparse.Namespace) -> runner.EvalConfig:
    """The evaluation the arguments ask for, every flag checked (``--suite``'s scenes are left to
    :func:`~openreloc_bench.harness.evaluation.main`, which generates the missing ones)."""
    if args.workers < 1:
        raise ConfigError("--workers must be >= 1")
    for flag, value in (("--timeout", args.timeout), ("--map-timeout", args.map_timeout)):
        if not math.isfinite(value) or not 0 <= value <= MAX_TIMEOUT_S:
            raise ConfigError(f"{flag} must be a number of seconds in [0, {MAX_TIMEOUT_S:g}], got {value}")
    splits = comma_list(args.splits, "--splits")
    if "mapping" in splits:
        raise ConfigError("--splits: 'mapping' builds the maps; localizing its own frames measures nothing")
    if args.robustness:
        splits += [r.key for r in ROBUSTNESS_ROWS if r.key not in splits]
    runs = method_runs(comma_list(args.methods, "--methods"), args.method_config, args.ablations, args.overrides)
    seeds = _seeds(args.seeds)
    scenes = [] if args.scenes is None else scene_names(comma_list(args.scenes, "--scenes"), args.data)
    return runner.EvalConfig(
        data=args.data, out=args.out, scenes=scenes, runs=runs, splits=splits, track=args.track,
        executor=args.executor, workers=args.workers, ray_address=args.ray_address, resume=args.resume,
        timeout_s=args.timeout, map_timeout_s=args.map_timeout, plugins=args.plugin, seeds=seeds,
    )  # fmt: skip


def run(args: argparse.Namespace) -> int:
    suite = None if args.suite is None else suite_file(args.suite)
    return 1 if evaluation.main(eval_config(args), suite).errors else 0
