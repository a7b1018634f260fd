"""The benchmark scripts run end to end on tiny inputs and print their tables.

The numbers they print are the leaderboard's evidence, so a script that no longer runs (a renamed
import, a changed signature) must fail the suite, not the next person who wants a number. Timings are
not checked: these are smoke runs, the targets live in the printed numbers.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from openreloc_bench import geometry
from openreloc_bench.cli import main
from openreloc_bench.data.results import read_results
from openreloc_bench.data.scene import Scene
from tests.conftest import write_tiny_scene

BENCHMARKS = Path(__file__).resolve().parents[2] / "benchmarks"


def run_benchmark(script: str, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, str(BENCHMARKS / script), *args], capture_output=True, text=True, timeout=300
    )


def test_bench_localize_pools_the_queries_of_map_scene_pairs(tmp_path: Path) -> None:
    """Pooled over two scenes whose query names coincide, the errors are those of each scene's own run."""
    pairs, errors = [], []
    for seed, n_query in ((0, 3), (1, 4)):
        scene = write_tiny_scene(tmp_path / f"tiny{seed}", n_query=n_query, seed=seed)
        map_dir, poses = tmp_path / f"m{seed}", tmp_path / f"poses{seed}.txt"
        assert (
            main(
                [
                    "map",
                    "--method",
                    "nearest-frame",
                    "--scene",
                    str(scene),
                    "--out",
                    str(map_dir),
                    "--set",
                    "thumb_size=8",
                ]
            )
            == 0
        )
        assert (
            main(
                [
                    "localize",
                    "--method",
                    "nearest-frame",
                    "--set",
                    "thumb_size=8",
                    "--map",
                    str(map_dir),
                    "--scene",
                    str(scene),
                    "--out",
                    str(poses),
                ]
            )
            == 0
        )
        seq = Scene(scene).sequence("query")
        estimates = read_results(poses)
        errors += [geometry.translation_error(T, estimates[name]) for name, T in zip(seq.names, seq.poses)]
        pairs += ["--map", str(map_dir), "--scene", str(scene)]
    done = run_benchmark("bench_localize.py", *pairs, "--method", "nearest-frame", "--set", "thumb_size=8")
    assert done.returncode == 0, done.stderr
    assert "nearest-frame on tiny0, tiny1 / query (predicted, 7 queries, one at a time)" in done.stdout  # the default
    assert "localized 7/7" in done.stdout
    assert f"median error {np.median(errors) * 100:.1f} cm" in done.stdout


def test_bench_localize_rejects_unpaired_maps(tmp_path: Path) -> None:
    done = run_benchmark("bench_localize.py", "--map", "a", "--map", "b", "--scene", "s", "--method", "nearest-frame")
    assert done.returncode == 2
    assert "--map and --scene come in pairs: got 2 maps and 1 scenes" in done.stderr


def test_bench_harness_reports_overhead_in_both_modes() -> None:
    done = run_benchmark("bench_harness.py", "--scenes", "1", "--queries", "3", "--size", "32x24")
    assert done.returncode == 0, done.stderr
    rows = [line.split() for line in done.stdout.splitlines() if line.startswith(("in-process", "query server"))]
    assert len(rows) == 2
    for row in rows:
        wall, method_s, overhead = (float(v) for v in row[-4:-1])
        assert abs(wall - method_s - overhead) < 0.02


def test_periodic_shifts_counts_wrong_poses_whole_periods_away(tmp_path: Path) -> None:
    sys.path.insert(0, str(BENCHMARKS))
    try:
        from periodic_shifts import shift_table, whole_period_shift
    finally:
        sys.path.remove(str(BENCHMARKS))
    offsets = np.array([[1.0, 0.0, 0.0], [0.52, -0.49, 0.0], [0.3, 0.0, 0.0], [0.01, 0.0, 0.0]])
    assert whole_period_shift(offsets, 0.5, 0.05).tolist() == [True, True, False, False]
    queries = pd.DataFrame(
        {
            "variant": "m",
            "track": "mask-free",
            "split": "query",
            "gt_x": 0.0,
            "gt_y": 0.0,
            "gt_z": 0.0,
            "est_x": [0.0, 1.0, 1.0, 0.8, np.nan],
            "est_y": 0.0,
            "est_z": 0.0,
            "t_err_m": [0.0, 1.0, 1.0, 0.8, np.nan],
            "r_err_deg": [0.1, 0.2, 5.0, 0.1, np.nan],
        }
    )
    row = shift_table(queries, 0.5, 0.05, 0.5, 1.0).iloc[0]
    # three wrong estimates (one missing is a failure, not a wrong pose); one keeps its rotation at 2 periods
    assert (row["queries"], row["wrong"], row["at_periods"], row["share_at_periods"]) == (5, 3, 1, 33.3)
    assert row["recall_50cm"] == 20.0
    result = run_benchmark("periodic_shifts.py", str(tmp_path))
    assert result.returncode == 2 and "no finished query jobs" in result.stderr
