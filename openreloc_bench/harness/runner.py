"""The evaluation runner: maps built once per (method config, scene), every query localized and scored.

Work is split into picklable jobs so any executor can run them: one :class:`MapJob` per (method
variant, scene), then one :class:`QueryJob` per (method variant, scene, split). A query job writes

    RESULTS/runs/<label>/<track>/<scene>/<split>.txt           T_cw pose file (estimates only)
                                         <split>.tum           TUM export (camera-to-world, for evo)
                                         <split>.queries.csv   per-query errors, runtime, failure reason, difficulty
                                         <split>.done.json     provenance + timings, written LAST

each atomically, the marker last: a job is finished exactly when its marker exists, so ``--resume``
skips it and a killed run never leaves a file that a resumed run would trust half-written. ``<track>``
is the one recorded for the method: ``mask-free`` for a method that declares it reads no masks, whose
results then stand for both tracks (:func:`openreloc_bench.methods.recorded_track`).

A query runs in a child "query server" process when a per-query timeout is set, so a method that
hangs can be abandoned (the child is killed and restarted for the next query); a method that raises
fails that query with the exception as reason. Either way the run goes on.
"""

from __future__ import annotations

import logging
import os
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from tqdm import tqdm

from openreloc_bench import bars, plugins
from openreloc_bench.data import io, paths
from openreloc_bench.data.results import write_results, write_tum
from openreloc_bench.data.scene import Scene
from openreloc_bench.data.types import SceneSequence
from openreloc_bench.errors import ConfigError, DataError
from openreloc_bench.harness import cache
from openreloc_bench.harness.ablations import ABLATED_METHOD, ABLATION_ROWS, ablation_label
from openreloc_bench.harness.executors import exit_with, make_executor, mp_context
from openreloc_bench.harness.score import (
    QUERY_COLUMNS,
    Outcome,
    score_split,
    with_difficulty,
)
from openreloc_bench.harness.tables import backfill_difficulty, read_query_csv
from openreloc_bench.methods import (
    QueryFrame,
    Relocalizer,
    create_method,
    localize_safely,
    method_config,
    recorded_track,
    uses_masks,
)
from openreloc_bench.tracks import DEFAULT_TRACK, MASK_FREE, ORACLE_MASK, TRACKS, RecordedTrack, Track

log = logging.getLogger(__name__)

MARKER_KEYS = ("git_commit", "spec_hash", "config_hash", "split", "scene", "track", "method")
"""What every finished job's marker records (the provenance columns of its per-query rows)."""
RESUME_KEYS = ("config_hash", "map_hash", "spec_hash", "track", "split")
"""What a finished job's marker must agree on with the job asked for, for ``--resume`` to reuse it."""
MAP_RECORD_KEYS = ("map_bytes", "mapping_time_s")
"""The numbers every finished map's record holds (its size and build time in the tables)."""


@dataclass
class MethodRun:
    """One method variant to evaluate (a registered method plus config overrides)."""

    label: str
    """Name in the results and the leaderboard, e.g. ``openreloc`` or ``openreloc+no_refine``."""
    method: str
    """Registry name."""
    overrides: dict[str, Any] = field(default_factory=dict)
    """Config overrides passed to the method's constructor."""
    seed: int | None = None
    """The method's ``seed`` setting in this run, when the evaluation repeats the variant over seeds."""
    variant: str = ""
    """The label without its seed: the tables pool every seed of a variant under it (empty: the label)."""

    def with_seed(self, seed: int) -> MethodRun:
        """This variant run with ``seed`` (labelled ``<label>@seed<N>``)."""
        return MethodRun(f"{self.label}@seed{seed}", self.method, {**self.overrides, "seed": seed}, seed, self.label)


@dataclass
class MapJob:
    run: MethodRun
    scene_dir: Path
    map_dir: Path
    spec_hash: str
    track: RecordedTrack
    """The mapping frames carry the dataset's instance masks only in the oracle-mask track (never in
    ``mask-free``)."""
    timeout_s: float
    """Limit on building the map, in seconds; 0 = none (built in the job's own process)."""
    provenance: dict[str, Any]
    plugins: list[str]
    n_frames: int = 0
    """Mapping frames (the progress bar counts them)."""


@dataclass
class QueryJob:
    run: MethodRun
    scene_dir: Path
    split: str
    track: RecordedTrack
    """The recorded track: the queries carry the dataset's instance masks only in ``oracle-mask``."""
    map_dir: Path
    out_dir: Path
    timeout_s: float
    """Per-query limit in seconds; 0 = none (queries run in the job's own process)."""
    map_timeout_s: float
    """Limit on loading the map in the query worker, in seconds (used with ``timeout_s``)."""
    provenance: dict[str, Any]
    plugins: list[str]
    n_queries: int = 0
    """Queries of the split (the progress bar counts them)."""

    @property
    def marker(self) -> Path:
        return self.out_dir / f"{self.split}.done.json"


# --------------------------------------------------------------------------------------------
# One query
# --------------------------------------------------------------------------------------------


def localize_one(method: Relocalizer, query: QueryFrame) -> Outcome:
    """Call the method once (:func:`~openreloc_bench.methods.localize_safely`) as a row to score."""
    answer = localize_safely(method, query)
    return Outcome(answer.name, answer.T_wc, answer.seconds, answer.reason)


def _load_method(job: QueryJob) -> tuple[Relocalizer, SceneSequence, float]:
    plugins.load_plugins(job.plugins)
    method = create_method(job.run.method, **job.run.overrides)
    t0 = time.perf_counter()
    method.load_map(job.map_dir)
    seq = Scene(job.scene_dir).sequence(job.split)
    seq.load_instances = job.track == ORACLE_MASK
    return method, seq, time.perf_counter() - t0


def _serve(conn: Any, job: QueryJob) -> None:
    """Query-server child: load the map once, then answer query indices until told to stop."""
    try:
        method, seq, load_s = _load_method(job)
    except Exception as e:  # noqa: BLE001 -- reported by the parent as this job's one-line error
        conn.send(("error", f"{type(e).__name__}: {e}"))
        return
    conn.send(("ready", load_s))
    while (i := conn.recv()) is not None:
        conn.send(localize_one(method, QueryFrame.from_frame(seq[i], job.track)))


class QueryServer:
    """A child process running the method, so a hung query can be abandoned by killing it."""

    def __init__(self, job: QueryJob):
        self.job = job
        self.load_s = 0.0
        self.restarts = -1
        self._proc: Any = None
        self._conn: Any = None

    def _start(self) -> None:
        ctx = mp_context()
        self._conn, child = ctx.Pipe()
        self._proc = ctx.Process(target=_serve, args=(child, self.job), daemon=True)
        self._proc.start()
        child.close()
        self.restarts += 1
        if not self._conn.poll(self.job.map_timeout_s or None):
            self._stop()
            raise RuntimeError(f"loading the map timed out after {self.job.map_timeout_s:g} s")
        try:
            status, value = self._conn.recv()
        except EOFError:
            code = self._stop()
            raise RuntimeError(f"loading the map failed in the query worker (exit code {code})") from None
        if status == "error":
            self._stop()
            raise RuntimeError(f"loading the map failed: {value}")
        self.load_s += value

    def ask(self, i: int, name: str) -> Outcome:
        if self._proc is None:
            self._start()
        self._conn.send(i)
        if self._conn.poll(self.job.timeout_s):
            try:
                return self._conn.recv()
            except EOFError:
                pass
            code = self._stop()
            return Outcome(name, None, float("nan"), f"worker died (exit code {code})")
        self._stop()
        return Outcome(name, None, self.job.timeout_s, f"timeout after {self.job.timeout_s:g} s")

    def _stop(self) -> int | None:
        self._proc.kill()
        self._proc.join()
        code = self._proc.exitcode
        self._conn.close()
        self._proc = self._conn = None
        return code

    def close(self) -> None:
        if self._proc is not None:
            self._conn.send(None)
            self._proc.join(timeout=10)
            if self._proc.is_alive():
                self._stop()


_query_done: Callable[[], None] | None = None
"""Called after every query this process localizes: the inline executor's progress bar (see
:func:`_progress`); None in worker processes, whose jobs the bar counts when they finish."""


def _localized(outcome: Outcome) -> Outcome:
    if _query_done is not None:
        _query_done()
    return outcome


def _localize_all(job: QueryJob) -> tuple[SceneSequence, dict[str, Outcome], float]:
    if job.timeout_s <= 0:
        method, seq, load_s = _load_method(job)
        outcomes = {
            n: _localized(localize_one(method, QueryFrame.from_frame(seq[i], job.track)))
            for i, n in enumerate(seq.names)
        }
        return seq, outcomes, load_s
    seq = Scene(job.scene_dir).sequence(job.split)
    server = QueryServer(job)
    try:
        outcomes = {n: _localized(server.ask(i, n)) for i, n in enumerate(seq.names)}
    finally:
        server.close()
    return seq, outcomes, server.load_s


# --------------------------------------------------------------------------------------------
# Jobs (top-level functions: executors pickle them)
# --------------------------------------------------------------------------------------------


def run_map_job(job: MapJob) -> dict[str, Any]:
    """Build (or reuse) one map; returns its record, or ``{"error": ...}``.

    With a time limit the map is built in a child process that is killed when the limit passes, so a
    method hanging in ``build_map`` fails its own map instead of hanging the evaluation.
    """
    if job.timeout_s <= 0:
        return _build_map(job)
    ctx = mp_context()
    recv, send = ctx.Pipe(duplex=False)
    proc = ctx.Process(target=_build_map_child, args=(send, job, os.getpid()))
    proc.start()
    send.close()
    try:
        if recv.poll(job.timeout_s):
            try:
                return recv.recv()
            except EOFError:
                proc.join()
                return {"error": f"the map worker died (exit code {proc.exitcode})"}
        proc.kill()
        return {"error": f"building the map timed out after {job.timeout_s:g} s"}
    finally:
        # a child that answered exits by itself; killing it on its way out would leave the semaphores
        # it made (torch, tqdm) to the resource tracker, which then warns about leaks at shutdown
        proc.join(timeout=30)
        if proc.is_alive():
            proc.kill()
            proc.join()
        recv.close()


def _build_map_child(conn: Any, job: MapJob, parent_pid: int) -> None:
    exit_with(parent_pid)
    conn.send(_build_map(job))
    conn.close()


def _build_map(job: MapJob) -> dict[str, Any]:
    try:
        plugins.load_plugins(job.plugins)
        method = create_method(job.run.method, **job.run.overrides)
        paths.check_output(job.map_dir, [job.scene_dir], "map directory")
        with bars.quiet():  # the evaluation's bar counts the frames
            return cache.cached_map(method, Scene(job.scene_dir), job.track, job.map_dir, job.provenance)
    except Exception as e:  # noqa: BLE001 -- reported per job; other jobs go on
        log.debug("map job failed", exc_info=True)
        return {"error": f"{type(e).__name__}: {e}"}


def run_query_job(job: QueryJob) -> dict[str, Any]:
    """Localize and score every query of one split; returns the done-marker content or ``{"error": ...}``."""
    try:
        return _run_query_job(job)
    except Exception as e:  # noqa: BLE001
        log.debug("query job failed", exc_info=True)
        return {"error": f"{type(e).__name__}: {e}"}


def _run_query_job(job: QueryJob) -> dict[str, Any]:
    job.marker.unlink(missing_ok=True)  # a recomputed job is unfinished until its new marker exists
    started = datetime.now(timezone.utc).isoformat(timespec="seconds")
    t0 = time.perf_counter()
    seq, outcomes, load_s = _localize_all(job)
    table = with_difficulty(score_split(seq, outcomes), Scene(job.scene_dir), job.split)
    poses = {n: o.T_wc for n, o in outcomes.items() if o.T_wc is not None}
    prov = job.provenance
    comments = [
        f"method {job.run.label} ({prov['config_hash']}), track {job.track}, scene {prov['scene']}, "
        f"spec {prov['spec_hash']}, commit {prov['git_commit']}"
    ]
    job.out_dir.mkdir(parents=True, exist_ok=True)
    write_results(job.out_dir / f"{job.split}.txt", poses, comments)
    stamps = {n: float(i) for i, n in enumerate(seq.names)}  # the query's index in the split, for evo
    write_tum(job.out_dir / f"{job.split}.tum", poses, stamps)
    write_tum(job.out_dir / f"{job.split}.gt.tum", dict(zip(seq.names, seq.poses)), stamps)
    io.atomic_write_text(job.out_dir / f"{job.split}.queries.csv", table.to_csv(index=False))
    runtime = table["runtime_s"].to_numpy()
    record = {
        **prov,
        "split": job.split,
        "track": job.track,
        "n_queries": len(table),
        "n_success": int(table["success"].sum()),
        "load_map_s": load_s,
        "localize_s": float(np.nansum(runtime)),
        "job_wall_s": time.perf_counter() - t0,
        "timeout_s": job.timeout_s,
        "started": started,
        "finished": datetime.now(timezone.utc).isoformat(timespec="seconds"),
    }
    io.write_json(job.marker, record)
    return record


# --------------------------------------------------------------------------------------------
# Planning and running an evaluation
# --------------------------------------------------------------------------------------------


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


def plan(cfg: EvalConfig) -> tuple[list[MapJob], list[QueryJob]]:
    """Validate everything up front (methods, configs, scenes, splits, track) and list the jobs."""
    if cfg.track not in TRACKS:
        raise ConfigError(f"unknown track '{cfg.track}' (known: {', '.join(TRACKS)})")
    plugin_specs = plugins.load_plugins(cfg.plugins)  # as the workers import them
    commit = cache.git_commit()
    scenes, sizes = {}, {}
    for name in cfg.scenes:
        scene = Scene(cfg.data / paths.plain_name(name, "scene"))
        avail = scene.splits()
        for split in ["mapping", *cfg.splits]:
            if split not in avail:
                raise DataError(scene.root, f"scene has no split '{split}' (available: {', '.join(avail)})")
            # an incomplete or inconsistent scene fails here, before any work
            sizes[name, split] = len(scene.sequence(split))
        scene.difficulty()  # so does a broken difficulty table (the query tables join it)
        if cfg.track == ORACLE_MASK:
            for split in cfg.splits:
                if not (scene.root / split / "instance").is_dir():
                    raise DataError(scene.root / split, "no instance masks: use --track predicted")
        scenes[name] = scene
    # the results folder (what the run creates, replaces, cleans of stray temps) holds no scene, nor is in one
    paths.check_output(cfg.out, [s.root for s in scenes.values()], "results folder")
    map_jobs, query_jobs = [], []
    for run, method in seeded_runs(cfg.runs, cfg.seeds):
        mcfg = method_config(method)
        chash = cache.config_hash(mcfg)
        track = recorded_track(method, cfg.track)  # also which masks the map is built from
        map_hash = cache.map_key(method, track)
        for name, scene in scenes.items():
            spec = scene.spec_hash
            # rebuilt (removed first) when stale: confined to the cache, whatever a plugin names its method
            map_dir = paths.confined(cfg.out / "maps" / run.method / map_hash / name, cfg.out / "maps", "map cache")
            prov = {
                "method": run.label,
                "variant": run.variant or run.label,
                "seed": run.seed,
                "registry_name": run.method,
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


def _create(run: MethodRun) -> Relocalizer:
    try:
        return create_method(run.method, **run.overrides)
    except TypeError as e:  # plugins that take **kwargs loosely fail this way on a bad key
        raise ConfigError(f"method '{run.label}': invalid config ({e})") from None


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
        method = _create(run)
        if not seeds or "seed" not in method_config(method)["config"]:
            out.append((run, method))
            continue
        if "seed" in run.overrides:
            raise ConfigError(
                f"method '{run.label}': its config sets seed {run.overrides['seed']} and seeds "
                f"{seeds} are given too; use one of them"
            )
        out += [(r, _create(r)) for r in map(run.with_seed, seeds)]
    return out


def evaluate(cfg: EvalConfig) -> EvalReport:
    """Run an evaluation; per-job errors are collected in the report, the run goes on.

    The results folder is locked for the whole run: a second evaluation on it fails at once.
    """
    map_jobs, query_jobs = plan(cfg)
    with paths.directory_lock(cfg.out, "openreloc-bench eval"):
        return _evaluate(cfg, map_jobs, query_jobs)


def finished(job: QueryJob) -> bool:
    """Whether ``job``'s marker exists and records the config, map, scene spec, track and split asked for."""
    if not job.marker.is_file():
        return False
    try:
        done = io.read_json(job.marker)
    except DataError:  # a damaged marker: the job is recomputed
        return False
    want = {**job.provenance, "track": job.track, "split": job.split}
    return isinstance(done, dict) and all(done.get(k) == want[k] for k in RESUME_KEYS)


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
    global _query_done
    with _Bar(total=total, desc=desc, unit=unit, disable=not total, dynamic_ncols=True) as bar:

        def tick() -> None:
            bar.ticked += 1
            bar.update()

        _query_done = tick if per_item else None
        try:
            yield bar
        finally:
            _query_done = None


def load_run_queries(out: Path) -> pd.DataFrame:
    """Every finished job's per-query rows under ``out/runs``, with the job's provenance columns and
    ``uses_masks``; where two jobs answered the same query on the same recorded track, the later one."""
    frames = []
    for marker in sorted((out / "runs").glob("*/*/*/*.done.json")):
        rec = io.read_json(marker)
        missing = [k for k in MARKER_KEYS if not isinstance(rec, dict) or k not in rec]
        if missing:
            raise DataError(marker, f"no '{missing[0]}': not a finished job's marker (remove it to recompute the job)")
        df = read_query_csv(marker.with_name(f"{rec['split']}.queries.csv"), QUERY_COLUMNS)
        df.insert(0, "map_hash", rec.get("map_hash", rec["config_hash"]))  # older runs keyed maps by the full config
        rec = {**rec, **marker_track(rec)}
        for key in MARKER_KEYS:
            df.insert(0, key, rec[key])
        df["uses_masks"] = rec["uses_masks"]
        df["variant"] = rec.get("variant", rec["method"])  # runs from before seeds: their own variant
        df["seed"] = pd.array([rec.get("seed")] * len(df), dtype="Int64")
        df["_finished"] = rec.get("finished", "")
        frames.append(backfill_difficulty(df))
    if not frames:
        return pd.DataFrame()
    q = pd.concat(frames, ignore_index=True).sort_values("_finished", kind="stable")
    q = q.drop_duplicates(["method", "track", "scene", "split", "query"], keep="last").sort_index()
    return q.drop(columns="_finished").reset_index(drop=True)


def marker_track(rec: dict[str, Any]) -> dict[str, Any]:
    """A finished job's recorded ``track`` and ``uses_masks``. Markers written before the track was
    recorded from the method's declaration (no ``uses_masks``) name the track the run was asked for:
    a method registered here as reading no masks is read as ``mask-free`` (the rule the board applied
    when drawing them), any other keeps its track."""
    if "uses_masks" in rec:
        return {"track": rec["track"], "uses_masks": bool(rec["uses_masks"])}
    masks = uses_masks(rec.get("registry_name", rec["method"]))
    return {"track": rec["track"] if masks else MASK_FREE, "uses_masks": masks}


def load_map_records(out: Path) -> pd.DataFrame:
    """Mapping time and map size of every cached map, one row per (map hash, scene)."""
    rows = []
    for p in sorted((out / "maps").glob("*/*/*.done.json")):
        r = io.read_json(p)
        if not isinstance(r, dict) or not all(isinstance(r.get(k), (int, float)) for k in MAP_RECORD_KEYS):
            raise DataError(p, "not a finished map's record (remove it: the map is rebuilt by the next eval)")
        rows.append(
            {
                "map_hash": p.parent.name,
                "scene": p.name[: -len(".done.json")],
                "map_mb": r["map_bytes"] / 1e6,
                "mapping_time_s": r["mapping_time_s"],
            }
        )
    return pd.DataFrame(rows, columns=["map_hash", "scene", "map_mb", "mapping_time_s"])
