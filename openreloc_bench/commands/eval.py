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
  openreloc-bench eval --suite scenes/smoke.yaml --methods hist-nn,nearest-frame --plugin ./hist_nn.py \
      --data data --out results
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from openreloc_bench import config
from openreloc_bench.commands.options import TRACK_HELP, add_plugin_argument, add_track_argument
from openreloc_bench.data import paths
from openreloc_bench.data.runs import load_map_records, load_run_queries
from openreloc_bench.data.scene import QUERY_SPLITS
from openreloc_bench.errors import ConfigError
from openreloc_bench.harness import runner, tables
from openreloc_bench.harness.ablations import ABLATED_METHOD, ROBUSTNESS_ROWS
from openreloc_bench.harness.executors import EXECUTORS
from openreloc_bench.harness.suites import ensure_suite_scenes
from openreloc_bench.methods import uses_masks

NAME = "eval"
HELP = "evaluate methods on a scene suite (maps, queries, metrics)"
ORDER = 40

MAX_TIMEOUT_S = 1e7
"""Upper bound of --timeout / --map-timeout (about four months; larger values overflow the OS's wait)."""


def add_arguments(p: argparse.ArgumentParser) -> None:
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--suite", type=Path, help="suite YAML (scenes/<suite>.yaml); missing scenes are generated")
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
    add_plugin_argument(p)


def _csv(s: str, flag: str) -> list[str]:
    """Comma-separated names, each once, in order; ConfigError when there is none."""
    names = list(dict.fromkeys(x.strip() for x in s.split(",") if x.strip()))
    if not names:
        raise ConfigError(f"{flag} names nothing: give comma-separated names")
    return names


def method_runs(names: list[str], config_files: list[str], ablations: bool) -> list[runner.MethodRun]:
    """Method variants: each named method with its overrides, plus the ablation rows if asked."""
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
    if not s.strip():
        return []
    try:
        seeds = [int(x) for x in _csv(s, "--seeds")]
    except ValueError:
        raise ConfigError(f"--seeds expects comma-separated integers, got '{s}'") from None
    wrong = [x for x in seeds if not 0 <= x < 2**63]
    if wrong:
        raise ConfigError(f"--seeds: {wrong[0]} is out of range (seeds are 64-bit integers >= 0)")
    return seeds


def run(args: argparse.Namespace) -> int:
    if args.workers < 1:
        raise ConfigError("--workers must be >= 1")
    for flag, value in (("--timeout", args.timeout), ("--map-timeout", args.map_timeout)):
        if not math.isfinite(value) or not 0 <= value <= MAX_TIMEOUT_S:
            raise ConfigError(f"{flag} must be a number of seconds in [0, {MAX_TIMEOUT_S:g}], got {value}")
    splits = _csv(args.splits, "--splits")
    if "mapping" in splits:
        raise ConfigError("--splits: 'mapping' builds the maps; localizing its own frames measures nothing")
    if args.robustness:
        splits += [r.key for r in ROBUSTNESS_ROWS if r.key not in splits]
    runs = method_runs(_csv(args.methods, "--methods"), args.method_config, args.ablations)
    seeds = _seeds(args.seeds)
    runner.seeded_runs(runs, seeds)  # unknown methods and bad settings fail here, before scenes are generated
    if args.scenes is not None:
        scenes = scene_names(_csv(args.scenes, "--scenes"), args.data)
    else:
        scenes = ensure_suite_scenes(args.suite, args.data)
    cfg = runner.EvalConfig(
        data=args.data, out=args.out, scenes=scenes, runs=runs, splits=splits, track=args.track,
        executor=args.executor, workers=args.workers, ray_address=args.ray_address, resume=args.resume,
        timeout_s=args.timeout, map_timeout_s=args.map_timeout, plugins=args.plugin, seeds=seeds,
    )  # fmt: skip
    report = runner.evaluate(cfg)
    queries = load_run_queries(args.out, uses_masks)
    if report.jobs_stale:
        print(f"resume: {report.jobs_stale} finished job(s) were run with other settings or scenes and were recomputed")
    if not queries.empty:
        _, suite, seeds = tables.write_tables(args.out / "tables", queries, load_map_records(args.out))
        print(tables.compact(suite))
        if not seeds.empty:
            print(tables.compact_seeds(seeds))
        print(f"tables: {args.out / 'tables'}")
    for err in report.errors:
        print(f"error: {err}")
    print(  # the summary last, where a user looks when the run ends
        f"maps: {report.maps_built} built, {report.maps_cached} cached; jobs: {report.jobs_run} run, "
        f"{report.jobs_skipped} resumed; queries: {report.queries_localized} of {report.queries} localized; "
        f"{len(report.errors)} errors; {report.wall_s:.1f} s"
    )
    return 1 if report.errors else 0
