"""The evaluation runner: lists an evaluation's jobs and runs them, maps built once per (map key,
scene) and every query localized and scored.

:func:`list_jobs` checks everything up front (methods, configs, scenes, splits, track) and lists the jobs
(:mod:`~openreloc_bench.harness.jobs`); :func:`evaluate` runs the map jobs, then the query jobs, on an
executor (:mod:`~openreloc_bench.harness.executors`), with one progress bar for each. What the jobs
wrote is read back by :mod:`openreloc_bench.data.runs`.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from contextlib import contextmanager, nullcontext
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from tqdm import tqdm

from openreloc_bench import plugins
from openreloc_bench.data import io, paths
from openreloc_bench.data.scene import Scene
from openreloc_bench.errors import ConfigError, DataError
from openreloc_bench.harness import cache
from openreloc_bench.harness.ablations import ABLATED_METHOD, ABLATION_ROWS, ablation_label
from openreloc_bench.harness.executors import make_executor
from openreloc_bench.harness.jobs import (
    MapJob,
    MethodRun,
    QueryJob,
    counting_queries,
    finished,
    run_map_job,
    run_query_job,
)
from openreloc_bench.methods import Relocalizer, create_method, method_config, recorded_track, uses_masks
from openreloc_bench.tracks import DEFAULT_TRACK, MASK_FREE, ORACLE_MASK, TRACKS, Track


@dataclass
class EvalConfig:
    """One ``openreloc-bench eval`` invocation."""

    data: Path
    """Directory holding one sub-directory per scene."""
    out: Path
    """Results directory (maps cache, runs, tables)."""
    scenes: list[str]
    """Scene names (directories under ``data``)."""
    runs: list[MethodRun]
    """Method variants to evaluate."""
    splits: list[str] = field(default_factory=lambda: ["query"])
    """Query splits to localize."""
    track: Track = DEFAULT_TRACK
    """``oracle-mask`` (queries carry the dataset's instance masks) or ``predicted`` (RGB only)."""
    executor: str = "local"
    """``local`` (process pool; inline with one worker) or ``ray``."""
    workers: int = 1
    """Parallel jobs."""
    ray_address: str | None = None
    """Existing Ray cluster (default: ``RAY_ADDRESS`` or a local instance)."""
    resume: bool = False
    """Skip jobs whose completion marker exists and records the same method config, map, scene spec,
    track and split (otherwise every query job is recomputed)."""
    timeout_s: float = 300.0
    """Per-query limit in seconds (0 = no limit, queries run in the job's process)."""
    map_timeout_s: float = 3600.0
    """Limit on building one map, and on loading it in a query worker, in seconds (0 = no limit)."""
    plugins: list[str] = field(default_factory=list)
    """Plugins to import first, in this process and every worker: module names or ``.py`` files
    (:mod:`openreloc_bench.plugins`)."""
    seeds: list[int] = field(default_factory=list)
    """Run every variant whose method has a ``seed`` setting once per seed (one seed's recall moves by
    points on a few hundred queries); deterministic methods run once. Empty: each run's own config."""


@dataclass
class EvalReport:
    """What an evaluation did (for the CLI's summary and the tests)."""

    maps_built: int = 0
    maps_cached: int = 0
    jobs_run: int = 0
    jobs_skipped: int = 0
    jobs_stale: int = 0
    """Finished jobs ``--resume`` found but recomputed: they were run with other settings or scenes."""
    queries: int = 0
    """Queries localized by the jobs run (not those resumed)."""
    queries_localized: int = 0
    """Of these, the ones with an estimate."""
    errors: list[str] = field(default_factory=list)
    wall_s: float = 0.0
    maps_s: float = 0.0
    """Of ``wall_s``, the time spent building maps."""


def list_jobs(cfg: EvalConfig) -> tuple[list[MapJob], list[QueryJob]]:
    """Validate everything up front (methods, configs, scenes, splits, track) and list the jobs."""
    if cfg.track not in TRACKS:
        raise ConfigError(f"unknown track '{cfg.track}' (known: {', '.join(TRACKS)})")
    plugin_specs = plugins.load_plugins(cfg.plugins)  # as the workers import them
    commit = cache.git_commit()
    scenes, sizes = {}, {}
    masked = ORACLE_MASK if cfg.track == ORACLE_MASK and any(uses_masks(r.method) for r in cfg.runs) else None
    for name in cfg.scenes:
        scene = Scene(cfg.data / paths.plain_name(name, "scene"))
        avail = scene.splits()
        for split in ["mapping", *cfg.splits]:
            if split not in avail:
                raise DataError(scene.root, f"scene has no split '{split}' (available: {', '.join(avail)})")
            # an incomplete or inconsistent scene (or one without the masks the track gives) fails here
            sizes[name, split] = len(scene.sequence(split, masked))
        scene.difficulty()  # so does a broken difficulty table (the query tables join it)
        scenes[name] = scene
    # the results folder (what the run creates, replaces, cleans of stray temps) holds no scene, nor is in one
    paths.check_output(cfg.out, [s.root for s in scenes.values()], "results folder")
    map_jobs, query_jobs = [], []
    for run, method in seeded_runs(cfg.runs, cfg.seeds):
        mcfg = method_config(method)
        chash = cache.config_hash(mcfg)
        track = recorded_track(method, cfg.track)  # also which masks the map is built from
        map_hash = cache.map_key(method, track)
        source = cache.method_source(method)
        for name, scene in scenes.items():
            spec = scene.spec_hash
            map_dir = cache.map_folder(cfg.out, run.method, map_hash, name)  # rebuilt (removed first) when stale
            prov = {
                "method": run.label,
                "variant": run.variant or run.label,
                "seed": run.seed,
                "registry_name": run.method,
                "method_source": source,
                "method_config": mcfg,
                "config_hash": chash,
                "map_hash": map_hash,
                "scene": name,
                "spec_hash": spec,
                "git_commit": commit,
                "uses_masks": track != MASK_FREE,
            }
            map_jobs.append(
                MapJob(
                    run, scene.root, map_dir, spec, track, cfg.map_timeout_s, prov, plugin_specs, sizes[name, "mapping"]
                )
            )
            for split in cfg.splits:
                out_dir = paths.confined(cfg.out / "runs" / run.label / track / name, cfg.out / "runs", "run folder")
                query_jobs.append(
                    QueryJob(
                        run,
                        scene.root,
                        split,
                        track,
                        map_dir,
                        out_dir,
                        cfg.timeout_s,
                        cfg.map_timeout_s,
                        prov,
                        plugin_specs,
                        sizes[name, split],
                    )
                )
    return map_jobs, query_jobs


def variant_runs(names: list[str], overrides: dict[str, dict[str, Any]], ablations: bool) -> list[MethodRun]:
    """Each named method with its config overrides, plus the paper's ablation rows of
    ``ABLATED_METHOD`` (and the full method they are compared with) if ``ablations``."""
    runs = [MethodRun(n, n, overrides.get(n, {})) for n in names]
    if ablations:
        base = overrides.get(ABLATED_METHOD, {})
        runs += [MethodRun(ablation_label(r), ABLATED_METHOD, {**base, **r.overrides}) for r in ABLATION_ROWS]
        if ABLATED_METHOD not in names:
            runs.append(MethodRun(ABLATED_METHOD, ABLATED_METHOD, base))
    return runs


def seeded_runs(runs: list[MethodRun], seeds: list[int]) -> list[tuple[MethodRun, Relocalizer]]:
    """Every run with its method instance, repeated once per seed where the method has a ``seed`` setting."""
    if len(set(seeds)) != len(seeds):
        raise ConfigError(f"seeds repeat: {seeds}")
    out = []
    for run in runs:
        method = create_method(run.method, **run.overrides)
        if not seeds or "seed" not in method_config(method)["config"]:
            out.append((run, method))
            continue
        if "seed" in run.overrides:
            raise ConfigError(
                f"method '{run.label}': its config sets seed {run.overrides['seed']} and seeds "
                f"{seeds} are given too; use one of them"
            )
        out += [(r, create_method(r.method, **r.overrides)) for r in map(run.with_seed, seeds)]
    return out


def evaluate(cfg: EvalConfig) -> EvalReport:
    """Run an evaluation; per-job errors are collected in the report, the run goes on.

    The results folder is locked for the whole run: a second evaluation on it fails at once.
    """
    map_jobs, query_jobs = list_jobs(cfg)
    with paths.directory_lock(cfg.out, "openreloc-bench eval"):
        refuse_pooling(cfg.out, query_jobs)
        return _evaluate(cfg, map_jobs, query_jobs)


def refuse_pooling(out: Path, query_jobs: list[QueryJob]) -> None:
    """ConfigError when ``out`` holds finished runs of a method variant and track that this run does not
    redo (another scene or split) but made with other settings: the tables would pool both into one row,
    with one config hash shown for them."""
    planned = {j.marker.resolve() for j in query_jobs}  # one file however --out is spelled
    wanted = {(j.run.label, j.track): j.provenance["config_hash"] for j in query_jobs}
    for (label, track), config_hash in wanted.items():
        for marker in sorted((out / "runs" / label / track).glob("*/*.done.json")):
            if marker.resolve() in planned:
                continue  # redone (or resumed) by this run
            try:
                done = io.read_json(marker)
            except DataError:
                continue  # a damaged marker: the job does not count
            other = done.get("config_hash") if isinstance(done, dict) else None
            if other is not None and other != config_hash:
                split = marker.name.removesuffix(".done.json")
                raise ConfigError(
                    f"{out} holds a run of '{label}' ({track}) on {marker.parent.name}/{split} made with other "
                    f"settings (config {other}, this run's {config_hash}); its tables would pool them: "
                    "choose another --out, or include that scene and split to redo it"
                )


def _evaluate(cfg: EvalConfig, map_jobs: list[MapJob], query_jobs: list[QueryJob]) -> EvalReport:
    t0 = time.perf_counter()
    report = EvalReport()
    io.remove_stray_temps(cfg.out)
    # several variants may share a map (same method config): build each distinct map dir once
    unique: dict[Path, MapJob] = {}
    for j in map_jobs:
        unique.setdefault(j.map_dir, j)
    todo_maps = [j for j in unique.values() if cache.read_map_record(j.map_dir, j.spec_hash) is None]
    report.maps_cached = len(unique) - len(todo_maps)
    executor = make_executor(cfg.executor, cfg.workers, cfg.ray_address)
    failed_maps: dict[Path, str] = {}
    with _progress("maps", "frame", sum(j.n_frames for j in todo_maps)) as bar:
        for job, rec in executor.map(run_map_job, todo_maps):
            bar.update(job.n_frames)
            if "error" in rec:
                failed_maps[job.map_dir] = rec["error"]
                report.errors.append(f"map {job.run.label}/{job.scene_dir.name}: {rec['error']}")
                bar.set_postfix(errors=len(report.errors))
            else:
                report.maps_built += 1
    report.maps_s = time.perf_counter() - t0
    todo = []
    for j in query_jobs:
        if j.map_dir in failed_maps:
            continue
        if cfg.resume and finished(j):
            report.jobs_skipped += 1
            continue
        if cfg.resume and j.marker.is_file():
            report.jobs_stale += 1
        todo.append(j)
    with _progress("queries", "query", sum(j.n_queries for j in todo), per_item=True) as bar:
        for job, rec in executor.map(run_query_job, todo):
            bar.update(job.n_queries - bar.ticked)  # the queries of a job run in another process, at once
            bar.ticked = 0
            if "error" in rec:
                report.errors.append(f"{job.run.label}/{job.scene_dir.name}/{job.split}: {rec['error']}")
                bar.set_postfix(errors=len(report.errors))
            else:
                report.jobs_run += 1
                report.queries += rec["n_queries"]
                report.queries_localized += rec["n_success"]
    report.wall_s = time.perf_counter() - t0
    return report


class _Bar(tqdm):
    ticked = 0
    """Queries of the current job counted already, one by one, in this process."""


@contextmanager
def _progress(desc: str, unit: str, total: int, per_item: bool = False) -> Iterator[_Bar]:
    """One bar counting ``total`` frames or queries, with rate and ETA (none when there is nothing to do).

    With ``per_item`` the queries a job localizes in this process (inline executor) tick the bar one by
    one; jobs run elsewhere advance it by their size when they finish.
    """
    with _Bar(total=total, desc=desc, unit=unit, disable=not total, dynamic_ncols=True) as bar:

        def tick() -> None:
            bar.ticked += 1
            bar.update()

        with counting_queries(tick) if per_item else nullcontext():
            yield bar
