"""Paths a user gives, made safe: names stay names, outputs never overlap inputs, one writer per folder.

Every command that writes resolves its paths through these checks before it writes anything, so a
mistyped argument can fail with one line but can never make a command delete or overwrite a
dataset (``eval --scenes /abs/scene`` once joined an absolute name into the map cache, which then
removed the scene).
"""

from __future__ import annotations

import fcntl
import os
import shutil
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path

from openreloc_bench.data import io
from openreloc_bench.errors import ConfigError

CACHE_ENV = "OPENRELOC_BENCH_CACHE"
LOCK_NAME = ".openreloc-bench.lock"
OWNED_FOLDERS = {"scene.json": "scene", "manifest.json": "map"}
"""Files that mark a folder as a scene or a map: no output is written inside one, whichever scene or
map a command reads (a preview of one scene once overwrote another scene's frame)."""


def cache_root(cache_dir: str | Path | None = None) -> Path:
    """The user cache (environment scenes and maps, the describers' tables and answers): ``cache_dir``,
    else ``$OPENRELOC_BENCH_CACHE``, else the XDG user cache."""
    if cache_dir:
        return Path(cache_dir).expanduser()
    if os.environ.get(CACHE_ENV):
        return Path(os.environ[CACHE_ENV]).expanduser()
    xdg = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(xdg) / "openreloc-bench"


def plain_name(name: str, what: str) -> str:
    """``name`` if it is one plain path component (no separator, not ``.``/``..``), else ConfigError."""
    if not name or name in (".", "..") or Path(name).name != name or "/" in name or "\\" in name:
        raise ConfigError(f"{what} '{name}' must be a plain name, not a path")
    return name


def overlaps(a: Path, b: Path) -> bool:
    """True when ``a`` and ``b`` are the same directory or one lies inside the other."""
    a, b = Path(a).resolve(), Path(b).resolve()
    return a == b or a.is_relative_to(b) or b.is_relative_to(a)


def check_output(output: Path, inputs: Iterable[Path], what: str, fills: bool = False) -> Path:
    """Resolve ``output`` and refuse it when it equals, contains or lies inside any of ``inputs``, or
    lies inside any scene or map (:data:`OWNED_FOLDERS`); with ``fills`` (a folder the command writes
    its files into, not one it replaces whole), also when it is one."""
    out = Path(output).resolve()
    for src in inputs:
        if overlaps(out, src):
            raise ConfigError(f"{what} {output} overlaps the input {src}: choose a path outside it")
    for folder in (out, *out.parents) if fills else out.parents:
        for marker, kind in OWNED_FOLDERS.items():
            if (folder / marker).is_file():
                where = "is" if folder == out else "lies inside"
                raise ConfigError(f"{what} {output} {where} the {kind} {folder}: choose a path outside it")
    return out


def confined(path: Path, root: Path, what: str) -> Path:
    """Resolve ``path`` and require it strictly inside ``root`` (a derived path the program deletes or replaces)."""
    p, r = Path(path).resolve(), Path(root).resolve()
    if p == r or not p.is_relative_to(r):
        raise ConfigError(f"{what} {path} is not inside {root}; refusing to write there")
    return p


def check_output_file(output: Path, inputs: Iterable[Path], what: str, suffix: str = "") -> Path:
    """:func:`check_output` for a file to write: also refused when it is an existing directory, when it
    cannot be written (:func:`check_writable_file`) or, with ``suffix`` (``".png"``), when its name ends
    otherwise (the writer picks its format by it)."""
    if Path(output).is_dir():
        raise ConfigError(f"{what} {output} is a directory; give a file path")
    if suffix and Path(output).suffix.lower() != suffix:
        raise ConfigError(f"{what} {output} must end in {suffix}")
    out = check_output(output, inputs, what)
    check_writable_file(output, what)
    return out


def check_output_folder(output: Path, inputs: Iterable[Path], what: str) -> Path:
    """:func:`check_output` for a folder a command writes its files into (``fills``): also refused when it
    cannot be written (:func:`check_writable_folder`)."""
    out = check_output(output, inputs, what, fills=True)
    check_writable_folder(output, what)
    return out


def check_writable_file(output: Path, what: str) -> Path:
    """Refuse a file path that cannot be written (no such folder, not writable) before any work starts,
    so that a long run does not lose its results at the end."""
    out = Path(output)
    if out.is_dir():
        raise ConfigError(f"{what} {output} is a directory; give a file path")
    _check_creatable(out.resolve().parent, output, what)
    if out.exists() and not os.access(out, os.W_OK):
        raise ConfigError(f"{what} {output} is not writable")
    return out


def check_writable_folder(output: Path, what: str) -> Path:
    """:func:`check_writable_file` for a folder a command fills: it, or the folder it would be made in,
    must be a writable folder."""
    out = Path(output)
    if out.exists() and not out.is_dir():
        raise ConfigError(f"{what} {output} is a file; give a folder")
    _check_creatable(out.resolve(), output, what)
    return out


def _check_creatable(folder: Path, output: Path, what: str) -> None:
    """ConfigError unless ``folder``'s nearest existing ancestor (itself, if it exists) is a writable folder."""
    while not folder.exists():
        folder = folder.parent
    if not folder.is_dir() or not os.access(folder, os.W_OK | os.X_OK):
        raise ConfigError(f"{what} {output}: cannot write in {folder}")


@contextmanager
def directory_lock(directory: Path, what: str, in_directory: bool = True) -> Iterator[None]:
    """Hold an exclusive lock on ``directory`` (created if needed) for a long job writing into it.

    A second job on the same directory fails at once with a one-line error naming the holder's pid,
    instead of both computing everything and one removing the other's files in flight. The lock is an
    ``flock`` on a dot file: the kernel releases it when its holder dies, even by SIGKILL. With
    ``in_directory=False`` the directory itself is locked and nothing is written into it (a map
    directory, every byte of which counts as the map's size; a dataset folder, which stays as the
    user keeps it); the holder's pid is then unknown, and a directory the lock created is removed again
    if the job fails before writing into it.
    """
    directory = Path(directory)
    created = not directory.exists()
    directory.mkdir(parents=True, exist_ok=True)
    if in_directory:
        fd = os.open(directory / LOCK_NAME, os.O_RDWR | os.O_CREAT, 0o666)
    else:
        fd = os.open(directory, os.O_RDONLY | os.O_DIRECTORY)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = f"another {what}"
            if in_directory:
                holder += f" (pid {os.pread(fd, 32, 0).decode(errors='replace').strip() or 'unknown'})"
            raise ConfigError(
                f"{directory}: {holder} is writing here; wait for it or choose another directory"
            ) from None
        if in_directory:
            os.ftruncate(fd, 0)
            os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
        yield
    except BaseException:
        if created and not in_directory and directory.is_dir() and not any(directory.iterdir()):
            directory.rmdir()
        raise
    finally:
        os.close(fd)


@contextmanager
def staged(target: Path) -> Iterator[Path]:
    """A new hidden sibling folder of ``target`` to write into, removed if the block fails; one that a
    killed run left (its pid in the name is gone) is removed first."""
    target = Path(target)
    prefix = f".{target.name}.partial-"
    for old in target.parent.glob(prefix + "*"):
        pid = old.name[len(prefix) :]
        if pid.isdigit() and not io.process_alive(int(pid)):
            shutil.rmtree(old, ignore_errors=True)
    stage = target.parent / f"{prefix}{os.getpid()}"
    shutil.rmtree(stage, ignore_errors=True)
    stage.mkdir(parents=True)
    try:
        yield stage
    except BaseException:
        shutil.rmtree(stage, ignore_errors=True)
        raise


@contextmanager
def new_directory(out: Path, what: str, not_empty: str) -> Iterator[Path]:
    """Write the new directory ``out`` (absent or empty) through a hidden sibling (:func:`staged`), which
    takes its place only once complete: a failed or interrupted run leaves no partial ``out``. ``out``
    is locked meanwhile, so of two runs into it the second fails at once; ``not_empty`` is the one-line
    error for an ``out`` that holds files."""
    out = Path(out)
    with directory_lock(out, what, in_directory=False):
        if any(out.iterdir()):
            raise ConfigError(not_empty)
        with staged(out) as stage:
            yield stage
            os.rmdir(out)  # still empty: nobody else writes here while we hold the lock
            os.rename(stage, out)
