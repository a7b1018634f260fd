"""User-facing errors: the CLI prints these as one line and exits non-zero (no traceback)."""

from __future__ import annotations

import traceback
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


class PluginError(OpenRelocError):
    """A method from outside this project raised while building or loading its map; the message names
    the method and the file and line that raised (``-v`` shows the traceback)."""


def raised_at(e: BaseException, file: Path | None = None) -> str:
    """``<file> line <n>: <Error>: <message>`` on one line, at the innermost frame in ``file`` (a plugin's
    source, where the bug most likely is) or else the innermost frame: what a test runner would show first."""
    frames = traceback.extract_tb(e.__traceback__)
    in_file = [f for f in frames if file is not None and Path(f.filename).resolve() == file]
    return described(e, (in_file or frames or [None])[-1])


def described(e: BaseException, frame: traceback.FrameSummary | None) -> str:
    """``<file> line <n>: <Error>: <message>`` on one line (the message's whitespace folded, cut at 300
    characters), at ``frame`` (none: no place)."""
    message = " ".join(str(e).split())[:300]
    where = f"{Path(frame.filename).name} line {frame.lineno}: " if frame is not None else ""
    return f"{where}{type(e).__name__}: {message}" if message else f"{where}{type(e).__name__}"
