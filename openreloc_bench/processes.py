"""How the child processes of a run end: with their parent, and never with a traceback of their own.

Ctrl-C sends SIGINT to every process of the terminal's process group. The parent reports the
interruption in one line; without these, every worker, map builder and query server printed its own
``KeyboardInterrupt`` traceback (~40 lines) under it.
"""

from __future__ import annotations

import os
import signal
import threading
import time
from collections.abc import Iterator
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from contextlib import contextmanager

from tqdm import tqdm

from openreloc_bench.data import io


def exit_quietly_on_interrupt() -> None:
    """In a child whose parent waits on it alone (a map builder, a query server): end silently on Ctrl-C.
    What it left half-written is a temp file that the next (resumed) run removes."""
    signal.signal(signal.SIGINT, lambda signum, frame: os._exit(128 + signum))
    bars_on_a_thread_lock()


def pool_worker(parent_pid: int, threads: int | None = None) -> None:
    """Initializer of a process pool's workers: ignore Ctrl-C, which the parent handles by stopping them
    (:func:`workers_stopped_on_interrupt`), exit with the parent (:func:`exit_with`) and use at most
    ``threads`` compute threads (:func:`limit_threads`)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    bars_on_a_thread_lock()
    exit_with(parent_pid)
    limit_threads(threads)


_thread_limit: int | None = None


def available_cores() -> int:
    """The cores this process may run on (its CPU affinity where the system has one, as on Linux)."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


def core_share(workers: int) -> int:
    """Compute threads for each of ``workers`` processes sharing this machine's cores (at least 1)."""
    return max(1, available_cores() // workers)


def limit_threads(threads: int | None) -> None:
    """Cap this process's compute threads (torch, OpenCV, and OpenMP libraries loaded later, such as
    faiss) at ``threads``; None leaves the libraries' defaults (every core).

    A pool of N workers on C cores gives each C // N: two workers on two cores that each ran two torch
    threads took 105 s where one thread each took 85 s (an OpenReLoc query job of the demo). The cap is
    passed on to the map builders and query servers a worker starts (:func:`thread_limit`)."""
    global _thread_limit
    if threads is None:
        return
    import cv2
    import torch

    _thread_limit = threads
    os.environ["OMP_NUM_THREADS"] = str(threads)
    torch.set_num_threads(threads)
    cv2.setNumThreads(threads)


def thread_limit() -> int | None:
    """This process's cap set by :func:`limit_threads` (None: none)."""
    return _thread_limit


def bars_on_a_thread_lock() -> None:
    """In a child that may end by ``os._exit`` or be killed: its progress bars lock with a thread lock.

    tqdm's default is a multiprocessing lock, a named semaphore that such an end leaves to the resource
    tracker, which then warns of a leak under the run's "interrupted". The lock is not shared with other
    processes here anyway (children start by spawn or from the fork server), so a thread lock guards the
    same writes."""
    tqdm.set_lock(threading.RLock())


@contextmanager
def workers_stopped_on_interrupt(pool: ProcessPoolExecutor) -> Iterator[None]:
    """Around the wait on a pool of :func:`pool_worker` processes: Ctrl-C stops the workers in their jobs
    and is raised as ``KeyboardInterrupt`` once the pool has seen them go.

    The handler only kills (``ProcessPoolExecutor`` has no public way to stop a job before Python 3.14):
    an exception raised inside the pool's own waiting can leave a future's lock held, and the shutdown
    then hangs (seen as a flaky test); a worker dying of the signal itself broke the pool, at times
    before the parent's own interrupt was raised. Outside the main thread, signals are not ours to take.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    interrupted = False

    def stop(signum: int, frame: object) -> None:
        nonlocal interrupted
        interrupted = True
        for proc in list(getattr(pool, "_processes", {}).values()):
            proc.kill()

    previous = signal.signal(signal.SIGINT, stop)
    try:
        yield
    except BrokenProcessPool:
        if interrupted:
            raise KeyboardInterrupt from None
        raise
    finally:
        signal.signal(signal.SIGINT, previous)
    if interrupted:
        raise KeyboardInterrupt


def exit_with(parent_pid: int, poll_s: float = 1.0) -> None:
    """In a child process: exit as soon as process ``parent_pid`` (the one that started it) is gone.

    Killing an eval (SIGTERM, SIGKILL) ends only its main process; the workers are children of the
    fork server, not of it, so without this they finish their jobs and write results for a run that
    was stopped (orphans were seen still running long after, next to a new run on the same folder).
    """

    def watch() -> None:
        while True:
            time.sleep(poll_s)
            if not io.process_alive(parent_pid):
                os._exit(1)

    threading.Thread(target=watch, name="exit-with-parent", daemon=True).start()
