"""Atomic file writes."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from openreloc_bench.data import io


def test_an_array_is_written_whole_and_reads_back_exactly(tmp_path: Path) -> None:
    a = np.random.default_rng(0).random((4, 3)).astype(np.float32)
    path = tmp_path / "deep" / "a.npy"
    io.atomic_write_npy(path, a)
    back = np.load(path, allow_pickle=False)
    assert back.dtype == np.float32 and np.array_equal(back, a)
    assert [p.name for p in path.parent.iterdir()] == ["a.npy"]  # no temp file left beside it
