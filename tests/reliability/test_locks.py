"""Long jobs hold a lock on their output directory: a second job on it fails at once with one line,
instead of both writing the same files (generate, eval's scene generation, map, train-encoder)."""

from __future__ import annotations

import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

from openreloc_bench.data import paths
from tests.reliability.conftest import World, checksums, one_line_error, run

SUITE = (
    "scenes:\n  - {name: s1, seed: 3, width: 32, height: 24, n_query: 2, max_mapping_frames: 2, displaced_share: 0.0}\n"
)


@contextmanager
def held(directory: Path, what: str, in_directory: bool) -> Iterator[None]:
    """``directory`` locked by another holder (a thread: flock locks belong to open files, not processes)."""
    locked, release = threading.Event(), threading.Event()

    def hold() -> None:
        with paths.directory_lock(directory, what, in_directory=in_directory):
            locked.set()
            release.wait(30)

    t = threading.Thread(target=hold)
    t.start()
    try:
        assert locked.wait(10)
        yield
    finally:
        release.set()
        t.join()


@pytest.mark.parametrize(
    "command, argv, out, in_directory",
    [
        ("generate", lambda w: ["generate", str(w.inputs / "suite.yaml"), "--out", str(w.tmp / "gen")], "gen", False),
        (
            "eval",
            lambda w: ["eval", "--suite", str(w.inputs / "suite.yaml"), "--methods", "nearest-frame", "--data", str(w.tmp / "gen"), "--out", str(w.tmp / "res")],
            "gen",
            False,
        ),
        ("map", lambda w: ["map", "--method", "nearest-frame", "--scene", str(w.scene), "--out", str(w.tmp / "m")], "m", False),
        ("train-encoder", lambda w: ["train-encoder", "--out", str(w.tmp / "enc")], "enc", True),
    ],
    ids=["generate", "eval-generating-scenes", "map", "train-encoder"],
)  # fmt: skip
def test_a_second_job_on_a_locked_output_fails_at_once(world: World, capsys, command, argv, out, in_directory) -> None:
    (world.inputs / "suite.yaml").write_text(SUITE)
    before = checksums(world.tmp)
    with held(world.tmp / out, f"openreloc-bench {command}", in_directory):
        code, _, err = run(argv(world), capsys)
    one_line_error(code, err, command, "is writing here; wait for it or choose another directory")
    after = checksums(world.tmp)
    assert {k: v for k, v in after.items() if not k.endswith(paths.LOCK_NAME)} == before


def test_a_dataset_folder_keeps_no_lock_file(world: World, capsys) -> None:
    """generate locks its --out (often the user's dataset folder) without leaving a file in it."""
    (world.inputs / "suite.yaml").write_text(SUITE.replace("s1", "sA"))  # refused: sA is of another spec
    before = checksums(world.data)
    code, _, err = run(["generate", str(world.inputs / "suite.yaml"), "--out", str(world.data)], capsys)
    one_line_error(code, err, "generate", "was generated from another spec")
    assert checksums(world.data) == before
