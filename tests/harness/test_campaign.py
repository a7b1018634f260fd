"""The leaderboard campaign: steps in priority order, one commit, resumable, boards rendered."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest

from openreloc_bench.errors import ConfigError, DataError
from openreloc_bench.harness import cache, campaign, runner
from openreloc_bench.harness.ablations import ABLATION_ROWS
from openreloc_bench.harness.leaderboard import campaign_page

SUITE = "name: tiny\nscenes:\n  - {name: t1, seed: 3, width: 32, height: 24, n_query: 2, max_mapping_frames: 2, displaced_share: 0.0}\n"


@pytest.fixture
def plan(tmp_path: Path) -> campaign.CampaignPlan:
    (tmp_path / "suites").mkdir()
    (tmp_path / "suites" / "tiny.yaml").write_text(SUITE)
    return campaign.CampaignPlan(
        suites=["tiny"], suite_dir=str(tmp_path / "suites"), methods=["test-oracle", "nearest-frame"],
        tracks=["predicted", "oracle-mask"], splits=["query", "query_light1"], seeds=[0, 1], ablation_suites=[],
        plugins=["harness_test_methods"],
    )  # fmt: skip


def config(plan: campaign.CampaignPlan, tmp_path: Path, **kw) -> campaign.CampaignConfig:
    return campaign.CampaignConfig(
        plan=plan, data=tmp_path / "data", work=tmp_path / "work", out=tmp_path / "board", workers=1, screenshot=False,
        **kw,
    )  # fmt: skip


@pytest.fixture
def commit(monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """The commit the campaign sees (mutable: a test moves the checkout by changing it)."""
    head = ["a" * 40]
    monkeypatch.setattr(cache, "git_commit", lambda: head[0])
    return head


def test_steps_run_headline_first_and_mask_free_methods_once(plan: campaign.CampaignPlan) -> None:
    steps = campaign.plan_steps(plan)
    assert [s.key for s in steps] == [
        "headline/tiny/predicted/test-oracle", "headline/tiny/predicted/nearest-frame",
        "headline/tiny/oracle-mask/test-oracle",
        "robustness/tiny/predicted/test-oracle", "robustness/tiny/predicted/nearest-frame",
        "robustness/tiny/oracle-mask/test-oracle",
        "seeds/tiny/predicted/test-oracle", "seeds/tiny/oracle-mask/test-oracle",  # nearest-frame has no seed
    ]  # fmt: skip
    assert steps[0].splits == ("query",) and steps[0].seeds == (0,)
    assert steps[3].splits == ("query_light1",) and steps[-1].seeds == (0, 1)
    assert {s.splits for s in steps if s.stage == "seeds"} == {("query",)}  # further seeds: the headline split only


def test_oracle_only_diagnostics_skip_the_predicted_track(plan: campaign.CampaignPlan) -> None:
    plan.methods, plan.oracle_only, plan.splits, plan.seeds = ["test-oracle"], ["test-oracle"], ["query"], [0]
    assert [s.key for s in campaign.plan_steps(plan)] == ["headline/tiny/oracle-mask/test-oracle"]


def test_ablations_run_last_on_their_suites(plan: campaign.CampaignPlan) -> None:
    plan.ablation_suites = ["tiny"]
    last = campaign.plan_steps(plan)[-1]
    assert (last.key, last.ablations, last.splits) == ("ablations/tiny/oracle-mask/openreloc", True, ("query",))
    labels = [r.label for r in runner.variant_runs([last.method], {}, True)]
    assert (
        labels[0] == "openreloc"
        and len(labels) == 1 + len(ABLATION_ROWS)
        and all(x.startswith("openreloc+") for x in labels[1:])
    )


def test_each_step_counts_only_the_runs_no_earlier_step_made(plan: campaign.CampaignPlan) -> None:
    plan.ablation_suites = ["tiny"]
    # the seeds stage repeats seed 0 (already run); the ablation step adds every ablation row
    assert campaign.new_jobs(campaign.plan_steps(plan)) == [1, 1, 1, 1, 1, 1, 1, 1, 1 + len(ABLATION_ROWS)]


def test_further_seeds_build_maps_only_where_the_map_depends_on_the_seed(plan: campaign.CampaignPlan) -> None:
    plan.methods, plan.tracks, plan.splits = ["test-oracle", "test-oracle-seeded-map"], ["predicted"], ["query"]
    steps = campaign.plan_steps(plan)
    assert [s.key for s in steps][2:] == [
        "seeds/tiny/predicted/test-oracle",
        "seeds/tiny/predicted/test-oracle-seeded-map",
    ]
    assert campaign.new_maps(steps) == [1, 1, 0, 1]  # seed 1's map of the seeded-map method; seed 0's is built


def test_time_left_comes_from_the_pace_of_like_steps(plan: campaign.CampaignPlan, tmp_path: Path) -> None:
    steps = campaign.plan_steps(plan)
    ledger = campaign.Ledger(tmp_path, "a" * 40)
    assert campaign.remaining_s(steps, ledger) is None and campaign.left_text(None) == ""
    for step, wall, maps in [(steps[0], 100.0, 60.0), (steps[1], 30.0, 10.0)]:
        ledger.add(step.key, {"step": step.record(), "errors": [], "wall_s": wall, "maps_s": maps, "maps_built": 1})
    # test-oracle: 40 s a run + 60 s of maps in the headline; nearest-frame: 20 s a run
    headline, robustness, seeds = 40 + 60, 40 + 20 + 40, 40 + 40
    assert campaign.remaining_s(steps, ledger) == pytest.approx(headline + robustness + seeds)
    assert campaign.left_text(360.0) == " (about 0.1 h left at the pace so far)"


def test_time_left_ignores_records_without_map_time(plan: campaign.CampaignPlan, tmp_path: Path) -> None:
    steps = campaign.plan_steps(plan)
    ledger = campaign.Ledger(tmp_path, "a" * 40)
    ledger.add(steps[0].key, {"step": steps[0].record(), "errors": [], "wall_s": 100.0, "maps_built": 1})
    assert ledger.done(steps[0]) and campaign.remaining_s(steps, ledger) is None


def test_campaign_renders_one_board_per_suite_and_resumes(
    plan: campaign.CampaignPlan, tmp_path: Path, commit: list[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    cfg = config(plan, tmp_path)
    said: list[str] = []
    assert campaign.run_campaign(cfg, said.append) == 0
    board = pd.read_csv(tmp_path / "board" / "tiny" / "leaderboard.csv")
    rows = {(r.method, r.track, r.split): r for r in board.itertuples()}
    assert set(rows) == {
        (m, t, s) for m, t in [("test-oracle", "predicted"), ("test-oracle", "oracle-mask"), ("nearest-frame", "mask-free")]
        for s in ("query", "query_light1")
    }  # fmt: skip
    assert rows["test-oracle", "predicted", "query"].n_seeds == 2 and set(board["git_commit"]) == {commit[0]}
    assert rows["test-oracle", "predicted", "query"].n_queries == 4  # 2 queries x 2 seeds
    page = (tmp_path / "board" / "campaign.md").read_text()
    assert f"commit `{commit[0]}`" in page and "0 step(s) of the plan still to run." in page
    assert "| test-oracle | predicted |" in page and "| nearest-frame | mask-free |" in page
    md = (tmp_path / "board" / "tiny" / "leaderboard.md").read_text()
    assert "Robustness" in md and f"Every row comes from commit {commit[0][:12]}." in md

    def no_eval(cfg: runner.EvalConfig) -> runner.EvalReport:
        raise AssertionError("a finished step ran again")

    monkeypatch.setattr(runner, "evaluate", no_eval)
    (tmp_path / "board" / "tiny" / "leaderboard.md").unlink()
    assert campaign.run_campaign(cfg, said.append) == 0
    assert (tmp_path / "board" / "tiny" / "leaderboard.md").is_file()  # rendered again, nothing run


def test_a_step_with_errors_runs_again(
    plan: campaign.CampaignPlan, tmp_path: Path, commit: list[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    plan.splits, plan.seeds, plan.methods = ["query"], [0], ["nearest-frame"]
    calls = []

    def failing(cfg: runner.EvalConfig) -> runner.EvalReport:
        calls.append(cfg.track)
        return runner.EvalReport(errors=["t1/nearest-frame: boom"])

    monkeypatch.setattr(runner, "evaluate", failing)
    assert campaign.run_campaign(config(plan, tmp_path), lambda s: None) == 1
    assert campaign.run_campaign(config(plan, tmp_path), lambda s: None) == 1
    assert calls == ["predicted", "predicted"]


def test_another_commit_or_a_dirty_tree_is_refused(
    plan: campaign.CampaignPlan, tmp_path: Path, commit: list[str]
) -> None:
    plan.splits, plan.seeds, plan.methods, plan.tracks = ["query"], [0], ["nearest-frame"], ["predicted"]
    campaign.run_campaign(config(plan, tmp_path), lambda s: None)
    commit[0] = "b" * 40
    with pytest.raises(ConfigError, match="at commit a+, this checkout's code is at b+"):
        campaign.run_campaign(config(plan, tmp_path), lambda s: None)
    commit[0] = "a" * 40 + "-dirty"
    with pytest.raises(ConfigError, match="commit first"):
        campaign.run_campaign(config(plan, tmp_path / "other"), lambda s: None)


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"methods": ["no-such-method"]}, "no-such-method"),
        ({"methods": []}, "'methods' must name at least one entry"),  # no default list: the plan names them
        ({"splits": ["query", "mapping"]}, "unknown split 'mapping'"),
        ({"tracks": ["predicted", "predicted"]}, "each once"),
        ({"ablation_suites": ["elsewhere"]}, "not one of the plan's suites"),
        ({"suites": ["missing"]}, "no suite file"),
        ({"estimate_h": {"headline": float("nan")}}, "estimate_h"),
        ({"estimate_h": {"warm-up": 1.0}}, "estimate_h"),
    ],
)
def test_bad_plans_fail_in_one_line(plan: campaign.CampaignPlan, change: dict, message: str) -> None:
    for k, v in change.items():
        setattr(plan, k, v)
    with pytest.raises(ConfigError, match=message):
        campaign.check_plan(plan)


def test_validation_suites_are_never_reported(plan: campaign.CampaignPlan) -> None:
    path = Path(plan.suite_dir) / "tiny.yaml"
    path.write_text("purpose: validation\n" + SUITE.replace("seed: 3", "seed: 10000003"))
    with pytest.raises(ConfigError, match="validation suite"):
        campaign.check_plan(plan)


def test_the_committed_plan_loads(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(Path(__file__).parents[2])  # its suites are named relative to the repository
    plan = campaign.load_plan(Path("leaderboard") / "plan.yaml")
    assert plan.tracks[0] == "predicted" and plan.seeds == [0, 1, 2]


def test_a_seeded_mask_free_method_stands_once_with_every_seed(
    plan: campaign.CampaignPlan, tmp_path: Path, commit: list[str]
) -> None:
    plan.methods, plan.splits = ["test-oracle-mask-free"], ["query"]
    assert [s.key for s in campaign.plan_steps(plan)] == [
        "headline/tiny/predicted/test-oracle-mask-free", "seeds/tiny/predicted/test-oracle-mask-free"
    ]  # fmt: skip
    assert campaign.run_campaign(config(plan, tmp_path), lambda s: None) == 0
    board = pd.read_csv(tmp_path / "board" / "tiny" / "leaderboard.csv")
    assert board[["method", "track", "n_seeds", "n_queries"]].values.tolist() == [
        ["test-oracle-mask-free", "mask-free", 2, 4]
    ]


def test_a_damaged_record_is_one_line(plan: campaign.CampaignPlan, tmp_path: Path, commit: list[str]) -> None:
    (tmp_path / "work").mkdir()
    (tmp_path / "work" / "campaign.json").write_text('["not", "a", "record"]')
    with pytest.raises(DataError, match="not a campaign record"):
        campaign.run_campaign(config(plan, tmp_path), lambda s: None)


def test_the_page_the_readmes_and_the_boards_carry_verdict_estimate_and_card(
    plan: campaign.CampaignPlan, tmp_path: Path, commit: list[str]
) -> None:
    plan.splits, plan.seeds, plan.estimate_h = ["query"], [0], {"headline": 1.5, "seeds": 0.5}
    plan.card_dir = str(tmp_path / "cards")
    (tmp_path / "cards").mkdir()
    (tmp_path / "cards" / "tiny.md").write_text("# Dataset card: tiny\n")
    readme = tmp_path / "README.md"
    readme.write_text(f"# Title\n\n{campaign_page.VERDICT_BEGIN}\nold text\n{campaign_page.VERDICT_END}\n\n## More\n")
    assert campaign.run_campaign(config(plan, tmp_path, verdict_into=[readme]), lambda s: None) == 0
    page = (tmp_path / "board" / "campaign.md").read_text()
    assert "| headline |" in page and "| 1.5 |" in page and "| all |" in page and "| 2.0 |" in page
    text = readme.read_text()
    assert text.startswith("# Title\n\n") and text.endswith(f"{campaign_page.VERDICT_END}\n\n## More\n")
    assert "old text" not in text and f"code version `{commit[0][:12]}`" in text
    assert "- **[tiny](board/tiny/leaderboard.md)**: Predicted track:" in text
    assert "| test-oracle | predicted |" in text
    for page in ("leaderboard.md", "index.html"):  # each board links its data's card
        assert "../../cards/tiny.md" in (tmp_path / "board" / "tiny" / page).read_text()


@pytest.mark.parametrize("content", ["no markers\n", f"{campaign_page.VERDICT_END}\n{campaign_page.VERDICT_BEGIN}\n"])
def test_a_readme_without_its_verdict_markers_is_refused_before_any_work(
    plan: campaign.CampaignPlan, tmp_path: Path, commit: list[str], content: str
) -> None:
    readme = tmp_path / "README.md"
    readme.write_text(content)
    with pytest.raises(ConfigError, match="verdict-into"):
        campaign.run_campaign(config(plan, tmp_path, verdict_into=[readme]), lambda s: None)
    assert not (tmp_path / "work").exists() and readme.read_text() == content


def test_a_step_a_sitting_ended_counts_its_earlier_time(
    plan: campaign.CampaignPlan, tmp_path: Path, commit: list[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    plan.splits, plan.seeds, plan.methods, plan.tracks = ["query"], [0], ["nearest-frame"], ["predicted"]
    key = "headline/tiny/predicted/nearest-frame"

    def ended_by_the_sitting(cfg: runner.EvalConfig) -> runner.EvalReport:
        raise KeyboardInterrupt

    monkeypatch.setattr(runner, "evaluate", ended_by_the_sitting)
    with pytest.raises(KeyboardInterrupt):
        campaign.run_campaign(config(plan, tmp_path), lambda s: None)
    earlier = campaign.Ledger(tmp_path / "work", commit[0]).data["interrupted_s"][key]
    assert earlier > 0
    monkeypatch.setattr(runner, "evaluate", lambda cfg: runner.EvalReport(wall_s=30.0))
    assert campaign.run_campaign(config(plan, tmp_path), lambda s: None) == 0
    ledger = campaign.Ledger(tmp_path / "work", commit[0])
    assert ledger.data["steps"][key]["earlier_s"] == earlier and not ledger.data["interrupted_s"]
    assert campaign_page.timings(ledger.data["steps"]).set_index("step").loc[key, "wall_s"] == 30.0 + earlier
