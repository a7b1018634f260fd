"""Where evaluation jobs run: inline, a local process pool, or a Ray cluster.

Every executor takes a picklable top-level function and a list of jobs and yields ``(job, result)``
as jobs finish; the function catches its own errors, so results are plain data either way and the
benchmark numbers do not depend on the executor. Local worker processes are started with
``forkserver`` (``spawn`` where unavailable), never ``fork``: a forked child of a process holding
GL contexts or torch thread pools can deadlock.
"""

from __future__ import annotations

import multiprocessing as mp
import os
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from typing import Any, Protocol, TypeVar

from openreloc_bench.errors import ConfigError
from openreloc_bench.processes import core_share, pool_worker, workers_stopped_on_interrupt

J = TypeVar("J")
EXECUTORS = ("local", "ray")


def mp_context() -> mp.context.BaseContext:
    """The start method for every process the harness creates (never fork).

    The fork server imports the harness (numpy, OpenCV, pandas), torch and transformers once
    (imported, never run: no thread pool, no GL context exists before a fork), so each worker or query
    server forked from it starts in milliseconds instead of re-importing: the text model's import alone
    took 5 s of every query job's map loading.
    """
    if "forkserver" not in mp.get_all_start_methods():
        return mp.get_context("spawn")
    ctx = mp.get_context("forkserver")
    ctx.set_forkserver_preload(
        ["openreloc_bench.harness.jobs", "torch", "transformers.models.auto.modeling_auto", "transformers.models.bert"]
    )
    return ctx


class Executor(Protocol):
    def map(self, fn: Callable[[J], Any], jobs: Sequence[J]) -> Iterator[tuple[J, Any]]: ...


class InlineExecutor:
    """Runs jobs one after the other in this process (``--workers 1``; easiest to debug)."""

    def map(self, fn: Callable[[J], Any], jobs: Sequence[J]) -> Iterator[tuple[J, Any]]:
        for job in jobs:
            yield job, fn(job)


class LocalExecutor:
    """A pool of ``workers`` fresh processes on this machine, each with its share of the cores' threads."""

    def __init__(self, workers: int):
        self.workers = workers

    def map(self, fn: Callable[[J], Any], jobs: Sequence[J]) -> Iterator[tuple[J, Any]]:
        if not jobs:
            return
        with (
            ProcessPoolExecutor(
                max_workers=min(self.workers, len(jobs)),
                mp_context=mp_context(),
                initializer=pool_worker,
                initargs=(os.getpid(), core_share(self.workers)),
            ) as pool,
            workers_stopped_on_interrupt(pool),
        ):
            futures = {pool.submit(fn, job): job for job in jobs}
            for fut in as_completed(futures):
                yield futures[fut], fut.result()


class RayExecutor:
    """Ray tasks, one CPU each, on a local instance or an existing cluster.

    ``address`` (or the ``RAY_ADDRESS`` environment variable, which ``ray.init`` reads) points at a
    running cluster, e.g. ``ray://head:10001`` or ``auto``; without one a local instance with
    ``workers`` CPUs is started. Data and results directories must be on storage all nodes share.
    """

    def __init__(self, workers: int, address: str | None = None):
        try:
            import ray
        except ImportError:
            raise ConfigError("the ray executor needs Ray: pip install 'openreloc-bench[ray]'") from None
        self._ray = ray
        if not ray.is_initialized():
            cluster = address or os.environ.get("RAY_ADDRESS")
            kwargs: dict[str, Any] = {"include_dashboard": False, "log_to_driver": False}
            if cluster:
                ray.init(address=cluster, **kwargs)
            else:
                ray.init(num_cpus=workers, **kwargs)

    def map(self, fn: Callable[[J], Any], jobs: Sequence[J]) -> Iterator[tuple[J, Any]]:
        ray = self._ray
        remote = ray.remote(num_cpus=1, max_retries=0)(fn)
        pending = {remote.remote(job): job for job in jobs}
        while pending:
            done, _ = ray.wait(list(pending), num_returns=1)
            yield pending.pop(done[0]), ray.get(done[0])


def make_executor(kind: str, workers: int, address: str | None = None) -> Executor:
    if kind == "ray":
        return RayExecutor(workers, address)
    if kind != "local":
        raise ConfigError(f"unknown executor '{kind}' (known: {', '.join(EXECUTORS)})")
    return InlineExecutor() if workers <= 1 else LocalExecutor(workers)
