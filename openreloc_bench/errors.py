"""User-facing errors: the CLI prints these as one line and exits non-zero (no traceback)."""

from __future__ import annotations

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
