"""User-facing errors: the CLI prints these as one line and exits non-zero (no traceback)."""

from __future__ import annotations

import os
import signal
from pathlib import Path


class OpenRelocError(Exception):
    """Base for errors caused by user input (files, specs, configs, method names)."""


class DataError(OpenRelocError):
    """A dataset file is missing, unreadable or malformed; the message names the file."""

    def __init__(self, path: Path | str, problem: str):
        self.path = Path(path)
        self.problem = problem
        super().__init__(f"{path}: {problem}")

    def __reduce__(self) -> tuple[type, tuple[Path, str]]:
        # raised in a worker process (scene generation, executors), it is pickled back to the caller
        return type(self), (self.path, self.problem)


class ConfigError(OpenRelocError):
    """A config or spec value is unknown or out of range; the message names the key."""


def exit_quietly_on_interrupt() -> None:
    """In a child process: end silently on Ctrl-C, which reaches the whole process group.

    The parent reports the interruption in one line; without this every worker, map builder and query
    server printed its own ``KeyboardInterrupt`` traceback (~40 lines) under it. What a child left
    half-written is a temp file that the next (resumed) run removes.
    """
    signal.signal(signal.SIGINT, lambda signum, frame: os._exit(128 + signum))
