"""Evaluation jobs: one :class:`MapJob` per (method variant, scene), one :class:`QueryJob` per (method
variant, scene, split), picklable so that any executor runs them. A query job writes

    RESULTS/runs/<label>/<track>/<scene>/<split>.txt           T_cw pose file (estimates only)
                                         <split>.tum           TUM export (camera-to-world, for evo)
                                         <split>.queries.csv   per-query errors, runtime, failure reason, difficulty
                                         <split>.done.json     provenance + timings, written LAST

each atomically, the marker last: a job is finished exactly when its marker exists, so ``--resume``
skips it and a killed run never leaves a file that a resumed run would trust half-written. ``<track>``
is the one recorded for the method: ``mask-free`` for a method that declares it reads no masks, whose
results then stand for both tracks (:func:`openreloc_bench.methods.recorded_track`).

With a time limit, a job runs the method in a child process (:mod:`~openreloc_bench.harness.isolation`):
a query that hangs fails after its limit, and the next one is asked of a new child; a method that raises
fails that query with the exception as reason (:func:`~openreloc_bench.methods.localize_safely`).
Either way the run goes on.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import numpy as np

from openreloc_bench import bars, plugins
from openreloc_bench.data import io, paths
from openreloc_bench.data.results import write_results, write_tum
from openreloc_bench.data.scene import Scene
from openreloc_bench.data.types import SceneSequence
from openreloc_bench.errors import DataError
from openreloc_bench.harness import cache
from openreloc_bench.harness.isolation import QueryServer, build_map_in_child
from openreloc_bench.harness.score import Outcome, score_split, with_difficulty
from openreloc_bench.methods import QueryFrame, create_method, localize_safely
from openreloc_bench.tracks import RecordedTrack

log = logging.getLogger(__name__)

RESUME_KEYS = ("config_hash", "map_hash", "spec_hash", "track", "split")
"""What a finished job's marker must agree on with the job asked for, for ``--resume`` to reuse it."""


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


_query_done: Callable[[], None] | None = None
"""Called after every query this process localizes (:func:`counting_queries`); None in worker processes,
whose jobs the bar counts when they finish."""


@contextmanager
def counting_queries(tick: Callable[[], None]) -> Iterator[None]:
    """Call ``tick`` after every query that jobs localize in this process while the block runs (the inline
    executor's progress bar)."""
    global _query_done
    _query_done = tick
    try:
        yield
    finally:
        _query_done = None


def _localized(outcome: Outcome) -> Outcome:
    if _query_done is not None:
        _query_done()
    return outcome


def open_queries(job: QueryJob) -> tuple[Callable[[int], Outcome], float]:
    """Load the job's method and map once: the function answering the split's ``i``-th query (a row to
    score), and the seconds loading took."""
    plugins.load_plugins(job.plugins)
    method = create_method(job.run.method, **job.run.overrides)
    t0 = time.perf_counter()
    method.load_map(job.map_dir)
    seq = Scene(job.scene_dir).sequence(job.split, job.track)
    load_s = time.perf_counter() - t0

    def answer(i: int) -> Outcome:
        got = localize_safely(method, QueryFrame.from_frame(seq[i], job.track))
        return Outcome(got.name, got.T_wc, got.seconds, got.reason, got.confidence)

    return answer, load_s


def _localize_all(job: QueryJob) -> tuple[SceneSequence, dict[str, Outcome], float]:
    seq = Scene(job.scene_dir).sequence(job.split)
    if job.timeout_s <= 0:
        answer, load_s = open_queries(job)
        return seq, {n: _localized(answer(i)) for i, n in enumerate(seq.names)}, load_s
    server = QueryServer(open_queries, job, job.timeout_s, job.map_timeout_s)
    try:
        outcomes = {n: _localized(server.ask(i, n)) for i, n in enumerate(seq.names)}
    finally:
        server.close()
    return seq, outcomes, server.load_s


def run_map_job(job: MapJob) -> dict[str, Any]:
    """Build (or reuse) one map; returns its record, or ``{"error": ...}``.

    With a time limit the map is built in a child process that is killed when the limit passes, so a
    method hanging in ``build_map`` fails its own map instead of hanging the evaluation.
    """
    return _build_map(job) if job.timeout_s <= 0 else build_map_in_child(_build_map, job, job.timeout_s)


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
