"""Per-stage timing of one OpenReLoc query: ``with stage("associate"):`` adds the block's time to the
query's ``timings`` (kept in the query's diagnostics)."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from contextlib import AbstractContextManager, contextmanager

import numpy as np

from openreloc_bench.openreloc.consistency import Compare

Stage = Callable[[str], AbstractContextManager[None]]
"""``with stage(name):`` adds the block's time to the query's timing of stage ``name``."""


def stage_timer(timings: dict[str, float]) -> Stage:
    @contextmanager
    def stage(name: str) -> Iterator[None]:
        t = time.perf_counter()
        try:
            yield
        finally:
            timings[name] = round(timings.get(name, 0.0) + time.perf_counter() - t, 4)  # a stage may run twice

    return stage


def timed(stage: Stage, name: str, compare: Compare) -> Compare:
    """``compare`` with the time of every call added to stage ``name``."""

    def timed(poses: list[np.ndarray]) -> list[float]:
        with stage(name):
            return compare(poses)

    return timed
