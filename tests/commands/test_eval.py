"""``openreloc-bench eval`` end to end: CLI output, method configs, bad input, kill + resume."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "harness"))
from harness_test_methods import make_scene  # noqa: E402

from openreloc_bench.cli import main  # noqa: E402
from openreloc_bench.data import io  # noqa: E402
from openreloc_bench.data.runs import load_run_queries  # noqa: E402
from openreloc_bench.methods import uses_masks  # noqa: E402

HARNESS_TESTS = str(Path(__file__).resolve().parents[1] / "harness")


@pytest.fixture(scope="module")
def data(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("data")
    for i, name in enumerate(["s1", "s2"]):
        make_scene(root, name, splits=("query", "query_light1"), seed=10 + i)
    return root


def eval_args(data: Path, out: Path, *extra: str) -> list[str]:
    return [
        "eval",
        "--scenes",
        "s1,s2",
        "--data",
        str(data),
        "--out",
        str(out),
        "--plugin",
        "harness_test_methods",
        *extra,
    ]


def test_eval_prints_a_metrics_table(data: Path, tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    cfg = tmp_path / "oracle.yaml"
    cfg.write_text("noise_m: 0.3\n")
    rc = main(
        eval_args(
            data,
            tmp_path / "r",
            "--methods",
            "test-oracle,nearest-frame",
            "--timeout",
            "0",
            "--method-config",
            f"test-oracle={cfg}",
        )
    )
    out = " ".join(capsys.readouterr().out.split())
    assert rc == 0
    assert "R@50cm%" in out and "test-oracle predicted query" in out  # the default track
    assert "nearest-frame mask-free query" in out  # declares it reads no masks
    q = load_run_queries(tmp_path / "r", uses_masks)
    assert (q[q.method == "test-oracle"]["t_err_m"].round(6) == 0.3).all()


def test_eval_prints_the_spread_over_seeds(data: Path, tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    rc = main(eval_args(data, tmp_path / "r", "--methods", "test-oracle", "--timeout", "0", "--seeds", "0,3"))
    out = capsys.readouterr().out
    assert rc == 0 and "test-oracle@seed3" in out
    assert "test-oracle predicted query, 2 seeds: R@50cm% 100.0 ± 0.0 [100.0, 100.0]  R@25cm% 50.0 ± 70.7" in out
    assert (tmp_path / "r" / "tables" / "seeds.csv").is_file()


@pytest.mark.parametrize(
    "extra", [["--workers", "1", "--map-timeout", "0"], ["--workers", "1"], ["--workers", "2"]]
)  # maps built in this process, in a child process (the map time limit), in pool workers
def test_progress_counts_queries_and_frames_and_the_summary_ends(
    data: Path, tmp_path: Path, capfd: pytest.CaptureFixture, extra: list[str]
) -> None:
    args = ["--methods", "test-oracle,nearest-frame", "--splits", "query,query_light1", "--timeout", "0", *extra]
    assert main(eval_args(data, tmp_path / "r", *args)) == 0
    out, err = capfd.readouterr()  # the workers' output too
    # one bar each: 2 methods x 2 scenes x 4 mapping frames, 2 methods x 2 scenes x 2 splits x 3 queries
    assert err.count("maps:   0%") == 1 and "| 16/16 [" in err and "frame/s]" in err
    assert err.count("queries:   0%") == 1 and "| 24/24 [" in err and "query/s]" in err and "<" in err
    assert "nearest-frame map" not in err  # the method's own bar over the same frames stays off
    last = out.strip().splitlines()[-1]
    assert last.startswith("maps: 4 built, 0 cached; jobs: 8 run, 0 resumed; queries: 24 of 24 localized; 0 errors")


@pytest.mark.parametrize(
    "extra, message",
    [
        (["--methods", "nope"], "unknown method 'nope'"),
        (["--methods", "test-oracle", "--method-config", "x=y.yaml"], "not in --methods"),
        (["--methods", "test-oracle", "--splits", "query_displaced"], "no split 'query_displaced'"),
        (["--methods", "test-oracle", "--workers", "0"], "--workers must be >= 1"),
        (["--methods", "test-oracle", "--seeds", "0,one"], "--seeds expects comma-separated integers"),
    ],
)
def test_bad_input_is_one_line(
    data: Path, tmp_path: Path, capsys: pytest.CaptureFixture, extra: list[str], message: str
) -> None:
    assert main(eval_args(data, tmp_path / "r", *extra)) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1


@pytest.mark.parametrize(
    "source, message",
    [
        (["--scenes", "s1,nowhere"], "scene directory not found"),
        (["--suite", "SUITE"], "unknown key 'scenes[0].colour'"),
    ],
)
def test_missing_scene_or_bad_suite_is_one_line(
    data: Path, tmp_path: Path, capsys, source: list[str], message: str
) -> None:
    suite = tmp_path / "s.yaml"
    suite.write_text("name: t\nscenes:\n  - {name: x, seed: 1, colour: red}\n")
    source = [str(suite) if a == "SUITE" else a for a in source]
    rc = main(["eval", *source, "--methods", "nearest-frame", "--data", str(data), "--out", str(tmp_path / "r")])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and message in err and len(err.splitlines()) == 1


def test_killed_run_resumes_without_recomputing_or_duplicating(data: Path, tmp_path: Path) -> None:
    out = tmp_path / "r"
    slow = tmp_path / "slow.yaml"
    slow.write_text("delay_s: 0.4\n")
    args = eval_args(
        data,
        out,
        "--methods",
        "test-oracle",
        "--splits",
        "query,query_light1",
        "--method-config",
        f"test-oracle={slow}",
    )
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([HARNESS_TESTS, os.environ.get("PYTHONPATH", "")])}
    proc = subprocess.Popen(
        [sys.executable, "-m", "openreloc_bench.cli", *args],
        env=env,
        start_new_session=True,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    deadline = time.time() + 120
    while not list(out.glob("runs/*/*/*/*.done.json")) and time.time() < deadline and proc.poll() is None:
        time.sleep(0.05)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    done_before = {p: p.read_text() for p in out.glob("runs/*/*/*/*.done.json")}
    assert 1 <= len(done_before) < 4, "kill should land mid-run"
    assert main(args + ["--resume"]) == 0
    done_after = {p: p.read_text() for p in out.glob("runs/*/*/*/*.done.json")}
    assert len(done_after) == 4
    assert all(done_after[p] == text for p, text in done_before.items())  # finished jobs not recomputed
    q = load_run_queries(out, uses_masks)
    assert len(q) == 2 * 2 * 3 and not q.duplicated(["scene", "split", "query"]).any() and q["success"].all()
    assert not list(out.rglob("*.tmp"))
    assert len(io.read_json(out / "tables" / "queries.json")) == 12


def test_ablation_flag_adds_one_variant_per_paper_row() -> None:
    from openreloc_bench.commands.eval import method_runs
    from openreloc_bench.harness.ablations import ABLATION_ROWS

    runs = method_runs(["nearest-frame"], [], ablations=True)
    assert [r.label for r in runs] == ["nearest-frame", *[f"openreloc+{r.key}" for r in ABLATION_ROWS], "openreloc"]
    assert runs[1].overrides == {"no_refine": True} and runs[5].overrides == {"retrieval": "visibility"}


def test_set_overrides_one_method_over_its_config_file(tmp_path: Path) -> None:
    from openreloc_bench.commands.eval import method_runs
    from openreloc_bench.errors import ConfigError

    path = tmp_path / "o.yaml"
    path.write_text("anchors: {enabled: false, min_inliers: 12}\nmin_objects: 2\n")
    names = ["openreloc", "nearest-frame"]
    runs = method_runs(
        names, [f"openreloc={path}"], False, ["openreloc:anchors.enabled=true", "nearest-frame:thumb_size=8"]
    )
    assert runs[0].overrides == {"anchors": {"enabled": True, "min_inliers": 12}, "min_objects": 2}
    assert runs[1].overrides == {"thumb_size": 8}
    for bad, message in (
        ("anchors.enabled=true", "expects NAME:KEY=VALUE"),
        ("openreloc:anchors", "expects NAME:KEY=VALUE"),
        ("sift-pnp:ratio=0.7", "names 'sift-pnp', which is not in --methods"),
    ):
        with pytest.raises(ConfigError, match=message):
            method_runs(names, [], False, [bad])
