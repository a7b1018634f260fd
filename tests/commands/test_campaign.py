"""``openreloc-bench campaign``: the plan's steps listed, bad plans in one line, a trial run end to end."""

from __future__ import annotations

from pathlib import Path

import pytest

from openreloc_bench.cli import main
from openreloc_bench.data import io
from openreloc_bench.harness import campaign

SUITE = "name: tiny\nscenes:\n  - {name: t1, seed: 3, width: 32, height: 24, n_query: 2, max_mapping_frames: 2, displaced_share: 0.0}\n"


@pytest.fixture
def plan(tmp_path: Path) -> Path:
    (tmp_path / "tiny.yaml").write_text(SUITE)
    path = tmp_path / "plan.yaml"
    path.write_text(
        f"suites: [tiny]\nsuite_dir: {tmp_path}\nmethods: [nearest-frame]\ntracks: [predicted, oracle-mask]\n"
        "splits: [query]\nseeds: [0]\nablation_suites: []\n"
    )
    return path


def test_list_prints_every_step_and_runs_nothing(plan: Path, tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    assert main(["campaign", str(plan), "--data", str(tmp_path / "d"), "--work", str(tmp_path / "w"), "--list"]) == 0
    out = capsys.readouterr().out
    assert "1/1 to run headline/tiny/predicted/nearest-frame: query; seeds [0]" in out
    assert out.endswith("0 of 1 steps done\n")
    assert not (tmp_path / "w").exists() and not (tmp_path / "d").exists()


def test_trial_run_writes_the_board_and_the_campaign_page(
    plan: Path, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    args = ["campaign", str(plan), "--data", str(tmp_path / "d"), "--work", str(tmp_path / "w")]
    args += ["--out", str(tmp_path / "board"), "--workers", "1", "--no-screenshot", "--allow-dirty"]
    assert main(args) == 0
    out = capsys.readouterr().out
    assert "Wall time of the recorded steps" in out and "0 step(s) of the plan still to run" in out
    assert (tmp_path / "board" / "tiny" / "index.html").is_file()
    assert "| nearest-frame | mask-free |" in (tmp_path / "board" / "campaign.md").read_text()
    assert main([*args[:6], "--list"]) == 0
    assert capsys.readouterr().out.endswith(
        "1/1 done   headline/tiny/predicted/nearest-frame: query; seeds [0]\n1 of 1 steps done\n"
    )


def test_list_reads_a_campaign_begun_at_another_commit(
    plan: Path, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    step = campaign.plan_steps(campaign.load_plan(plan))[0]
    record = {"step": step.record(), "errors": [], "wall_s": 5.0, "maps_s": 1.0, "maps_built": 1}
    io.write_json(tmp_path / "w" / "campaign.json", {"commit": "f" * 40, "steps": {step.key: record}})
    assert main(["campaign", str(plan), "--data", str(tmp_path / "d"), "--work", str(tmp_path / "w"), "--list"]) == 0
    out = capsys.readouterr().out
    assert out.startswith(f"{tmp_path / 'w'} holds a campaign run at commit {'f' * 40}, not this checkout's\n")
    assert out.endswith(f"  1/1 done   {step.key}: query; seeds [0]\n1 of 1 steps done\n")


@pytest.mark.parametrize(
    ("text", "message"),
    [("methods: [nope]\n", "nope"), ("colour: red\n", "unknown key 'plan.colour'"), ("- a\n", "mapping")],
)
def test_bad_plan_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture, text: str, message: str) -> None:
    (tmp_path / "plan.yaml").write_text(text)
    assert main(["campaign", str(tmp_path / "plan.yaml"), "--data", "d", "--work", "w", "--list"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and message in err
