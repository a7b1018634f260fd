"""Executors: pool/inline/Ray produce the same results; bad executor names are user errors."""

from __future__ import annotations

import os
import time
from pathlib import Path

import pandas as pd
import pytest

from openreloc_bench.errors import ConfigError
from openreloc_bench.harness import runner
from openreloc_bench.harness.executors import InlineExecutor, LocalExecutor, make_executor
from openreloc_bench.harness.runner import EvalConfig, MethodRun


def _square(x: int) -> int:
    return x * x


@pytest.mark.parametrize("executor", [InlineExecutor(), LocalExecutor(2)])
def test_map_yields_every_job_with_its_result(executor) -> None:
    assert sorted(executor.map(_square, [1, 2, 3])) == [(1, 1), (2, 4), (3, 9)]


def test_unknown_executor() -> None:
    with pytest.raises(ConfigError, match="unknown executor"):
        make_executor("slurm", 2)


@pytest.mark.slow
def test_ray_gives_the_same_results_as_inline(data_dir: Path, tmp_path: Path) -> None:
    ray = pytest.importorskip("ray")
    here = str(Path(__file__).parent)
    os.environ["PYTHONPATH"] = os.pathsep.join([here, os.environ.get("PYTHONPATH", "")])  # workers import the plugin
    runs = [MethodRun("test-oracle", "test-oracle"), MethodRun("nearest-frame", "nearest-frame")]
    frames = []
    t0 = time.perf_counter()
    try:
        ray.init(num_cpus=2, include_dashboard=False)
        for name, executor in [("inline", "local"), ("ray", "ray")]:
            cfg = EvalConfig(data=data_dir, out=tmp_path / name, scenes=["sA", "sB"], runs=runs, executor=executor,
                             workers=2, timeout_s=0.0, plugins=["harness_test_methods"])
            if name == "inline":
                cfg.workers = 1
            assert runner.evaluate(cfg).errors == []
            frames.append(runner.load_run_queries(tmp_path / name).drop(columns="runtime_s"))
    finally:
        ray.shutdown()
    pd.testing.assert_frame_equal(frames[0], frames[1])
    print(f"ray test took {time.perf_counter() - t0:.1f} s")
