"""Executors: pool/inline/Ray produce the same results; bad executor names are user errors."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest

from openreloc_bench.data.runs import load_run_queries
from openreloc_bench.errors import ConfigError
from openreloc_bench.harness import runner
from openreloc_bench.harness.executors import InlineExecutor, LocalExecutor, make_executor
from openreloc_bench.harness.runner import EvalConfig, MethodRun
from openreloc_bench.methods import uses_masks
from openreloc_bench.processes import available_cores, core_share


def _square(x: int) -> int:
    return x * x


@pytest.mark.parametrize("executor", [InlineExecutor(), LocalExecutor(2)])
def test_map_yields_every_job_with_its_result(executor) -> None:
    assert sorted(executor.map(_square, [1, 2, 3])) == [(1, 1), (2, 4), (3, 9)]


def _threads(_: int) -> tuple[int, int, str | None, int]:
    """A worker's torch and OpenCV threads, OpenMP setting, and a map builder's torch threads."""
    import cv2
    import torch

    from openreloc_bench.harness.isolation import build_map_in_child

    child = build_map_in_child(_torch_threads, None, timeout_s=60)["threads"]
    return torch.get_num_threads(), cv2.getNumThreads(), os.environ.get("OMP_NUM_THREADS"), child


def _torch_threads(_: None) -> dict[str, int]:
    import torch

    return {"threads": torch.get_num_threads()}


def test_pool_workers_and_their_children_share_the_cores() -> None:
    workers = available_cores() + 1  # more workers than cores: one thread each
    (_, (torch_n, cv_n, omp, child_n)), *_ = LocalExecutor(workers).map(_threads, [0])
    assert (torch_n, cv_n, omp, child_n) == (1, 1, "1", 1)


def test_core_share_is_at_least_one_thread() -> None:
    cores = available_cores()
    assert (core_share(1), core_share(cores), core_share(10 * cores)) == (cores, 1, 1)


def _running(pid: int) -> bool:
    try:
        return "\tZ" not in Path(f"/proc/{pid}/status").read_text().split("State:")[1].splitlines()[0]
    except (FileNotFoundError, IndexError):
        return False


@pytest.mark.skipif(not Path("/proc").is_dir(), reason="reads /proc")
@pytest.mark.parametrize("reaped", [True, False])
def test_pool_workers_exit_when_the_eval_is_killed(reaped: bool) -> None:
    """SIGKILL the process running a pool: its worker, busy with a long job, exits within seconds
    instead of finishing the job (and writing results) for a run that was stopped; also while the killed
    process is a zombie its parent has not reaped yet."""
    script = (
        "from openreloc_bench.harness.executors import LocalExecutor\n"
        "from harness_test_methods import nap\n"
        "for _, pid in LocalExecutor(1).map(nap, [0, 120]):\n"
        "    print(pid, flush=True)\n"
    )
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(Path(__file__).parent), os.environ.get("PYTHONPATH", "")])}
    proc = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, text=True, env=env)
    try:
        worker = int(proc.stdout.readline())  # the first job is done; the worker is now in the 120 s one
        assert _running(worker)
        proc.kill()
        if reaped:
            proc.wait()
        deadline = time.monotonic() + 15
        while _running(worker) and time.monotonic() < deadline:
            time.sleep(0.2)
        assert not _running(worker)
    finally:
        proc.kill()


def test_ctrl_c_ends_the_pool_in_one_line() -> None:
    """SIGINT to the process group (what Ctrl-C sends) while a worker is busy: the workers end silently,
    the parent reports it once; no worker prints its KeyboardInterrupt traceback."""
    script = (
        "import sys\n"
        "from openreloc_bench.harness.executors import LocalExecutor\n"
        "from harness_test_methods import nap\n"
        "try:\n"
        "    for _, pid in LocalExecutor(1).map(nap, [0, 120]):\n"
        "        print(pid, flush=True)\n"
        "except KeyboardInterrupt:\n"
        "    sys.exit('interrupted')\n"
    )
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(Path(__file__).parent), os.environ.get("PYTHONPATH", "")])}
    proc = subprocess.Popen(
        [sys.executable, "-c", script],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
        start_new_session=True,  # its own process group, so the signal reaches this test's processes only
    )
    try:
        proc.stdout.readline()  # the first job is done; the worker is in the 120 s one
        os.killpg(proc.pid, signal.SIGINT)
        _, err = proc.communicate(timeout=30)
    finally:
        proc.kill()
    assert proc.returncode == 1 and err == "interrupted\n", err


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
            cfg = EvalConfig(
                data=data_dir,
                out=tmp_path / name,
                scenes=["sA", "sB"],
                runs=runs,
                executor=executor,
                workers=2,
                timeout_s=0.0,
                plugins=["harness_test_methods"],
            )
            if name == "inline":
                cfg.workers = 1
            assert runner.evaluate(cfg).errors == []
            frames.append(load_run_queries(tmp_path / name, uses_masks).drop(columns="runtime_s"))
    finally:
        ray.shutdown()
    pd.testing.assert_frame_equal(frames[0], frames[1])
    print(f"ray test took {time.perf_counter() - t0:.1f} s")
