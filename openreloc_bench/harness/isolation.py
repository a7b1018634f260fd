"""Process isolation: a method's map build, or its queries, in a child process with a time limit.

A method that hangs is abandoned when its limit passes (its child is killed), and one that crashes
its process (a native library) fails the map or query it was at; the evaluation goes on either way.
The jobs (:mod:`openreloc_bench.harness.jobs`) give the work as picklable top-level functions.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from typing import Any, TypeVar

from openreloc_bench.errors import OpenRelocError
from openreloc_bench.harness.executors import mp_context
from openreloc_bench.harness.score import Outcome
from openreloc_bench.processes import exit_quietly_on_interrupt, exit_with, limit_threads, thread_limit

Job = TypeVar("Job")


def build_map_in_child(build: Callable[[Job], dict[str, Any]], job: Job, timeout_s: float) -> dict[str, Any]:
    """``build(job)`` (a map's record, or ``{"error": ...}``) in a child process killed after ``timeout_s``
    seconds, so a method hanging in ``build_map`` fails its own map instead of hanging the evaluation."""
    ctx = mp_context()
    recv, send = ctx.Pipe(duplex=False)
    proc = ctx.Process(target=_build_in_child, args=(send, build, job, os.getpid(), thread_limit()))
    proc.start()
    send.close()
    try:
        if recv.poll(timeout_s):
            try:
                return recv.recv()
            except EOFError:
                proc.join()
                return {"error": f"the map worker died (exit code {proc.exitcode})"}
        proc.kill()
        return {"error": f"building the map timed out after {timeout_s:g} s"}
    finally:
        # a child that answered exits by itself; killing it on its way out would leave the semaphores
        # it made (torch, tqdm) to the resource tracker, which then warns about leaks at shutdown
        proc.join(timeout=30)
        if proc.is_alive():
            proc.kill()
            proc.join()
        recv.close()


def _build_in_child(
    conn: Any, build: Callable[[Job], dict[str, Any]], job: Job, parent_pid: int, threads: int | None
) -> None:
    exit_quietly_on_interrupt()
    exit_with(parent_pid)
    limit_threads(threads)
    conn.send(build(job))
    conn.close()


Opener = Callable[[Job], tuple[Callable[[int], Outcome], float]]
"""Loads a job's method and map: returns the function answering the job's i-th query, and the seconds
loading took."""


def _serve(conn: Any, open_queries: Opener, job: Any, parent_pid: int, threads: int | None) -> None:
    """Query-server child: load the map once, then answer query indices until told to stop.

    It ends with its parent (a pool worker its run stopped): silently, also when the parent went while
    the map was loading and the pipe is broken by the time it answers."""
    exit_quietly_on_interrupt()
    exit_with(parent_pid)
    limit_threads(threads)
    try:
        _answer_queries(conn, open_queries, job)
    except (BrokenPipeError, ConnectionResetError, EOFError):
        os._exit(1)


def _answer_queries(conn: Any, open_queries: Opener, job: Any) -> None:
    try:
        answer, load_s = open_queries(job)
    except Exception as e:  # noqa: BLE001 -- reported by the parent as this job's one-line error
        conn.send(("error", f"{type(e).__name__}: {e}"))
        return
    conn.send(("ready", load_s))
    while (i := conn.recv()) is not None:
        try:
            conn.send(answer(i))
        except OpenRelocError as e:  # the query's input cannot be read: the run's error, not the method's
            conn.send(e)


class QueryServer:
    """A child process running the method, so a hung query can be abandoned by killing it (the next
    query starts a new child, which loads the map again)."""

    def __init__(self, open_queries: Opener, job: Any, timeout_s: float, map_timeout_s: float):
        self.open_queries, self.job = open_queries, job
        self.timeout_s = timeout_s
        """Per-query limit in seconds."""
        self.map_timeout_s = map_timeout_s
        """Limit on loading the map, in seconds (0: none)."""
        self.load_s = 0.0
        self.restarts = -1
        self._proc: Any = None
        self._conn: Any = None

    def _start(self) -> None:
        ctx = mp_context()
        self._conn, child = ctx.Pipe()
        self._proc = ctx.Process(
            target=_serve, args=(child, self.open_queries, self.job, os.getpid(), thread_limit()), daemon=True
        )
        self._proc.start()
        child.close()
        self.restarts += 1
        if not self._conn.poll(self.map_timeout_s or None):
            self._stop()
            raise RuntimeError(f"loading the map timed out after {self.map_timeout_s:g} s")
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
        """The outcome of query ``i`` (named ``name``): the method's, or a failure when it hung or died.
        A query whose input cannot be read raises the child's DataError (an error of the run)."""
        if self._proc is None:
            self._start()
        self._conn.send(i)
        if self._conn.poll(self.timeout_s):
            try:
                got = self._conn.recv()
            except EOFError:
                pass
            else:
                if isinstance(got, OpenRelocError):
                    raise got
                return got
            code = self._stop()
            return Outcome(name, None, float("nan"), f"worker died (exit code {code})")
        self._stop()
        return Outcome(name, None, self.timeout_s, f"timeout after {self.timeout_s:g} s")

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
