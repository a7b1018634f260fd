"""The environment benchmark and the PPO example run end to end on the tiny room."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def run(script: str, *args: str, timeout: int = 300) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(ROOT / script), *args], capture_output=True, text=True, timeout=timeout)


def test_bench_envs_prints_rates_and_memory(env_options) -> None:
    opts = env_options["openreloc/ActiveReloc-v0"]
    res = run(
        "benchmarks/bench_envs.py",
        *("--scene", opts["scene"], "--cache-dir", opts["cache_dir"], "--method", "nearest-frame"),
        *("--sizes", "48x40", "--steps", "20", "--reloc-steps", "4", "--random-steps", "60"),
    )
    assert res.returncode == 0, res.stderr[-2000:]
    assert res.stdout.count("nearest-frame") >= 2 and "48x40" in res.stdout
    assert "60 random steps" in res.stdout and "RSS" in res.stdout


@pytest.mark.slow
def test_ppo_example_trains_and_evaluates(env_options, tmp_path: Path) -> None:
    pytest.importorskip("stable_baselines3")
    opts = env_options["openreloc/ActiveReloc-v0"]
    res = run(
        "examples/ppo_active_reloc.py",
        *("--scene", opts["scene"], "--cache-dir", opts["cache_dir"], "--method", "nearest-frame"),
        *("--timesteps", "128", "--n-steps", "32", "--size", "40", "--eval-episodes", "2", "--out", str(tmp_path)),
        timeout=600,
    )
    assert res.returncode == 0, res.stderr[-2000:]
    assert "PPO after 128 steps: success" in res.stdout and (tmp_path / "ppo_active_reloc.zip").is_file()
