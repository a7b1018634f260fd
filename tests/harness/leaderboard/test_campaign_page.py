"""The campaign's own page and the verdict table it writes into READMEs."""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from openreloc_bench.harness.campaign import CampaignPlan
from openreloc_bench.harness.leaderboard import campaign_page


def rows() -> pd.DataFrame:
    """Board rows of two suites; ``lighting`` ranks the methods the other way round from ``query``."""
    data = [
        ("s1", "a", "predicted", "query", 60.0, 50.0),
        ("s1", "b", "mask-free", "query", 40.0, 30.0),
        ("s1", "a", "predicted", "query_light1", 10.0, 5.0),
        ("s1", "b", "mask-free", "query_light1", 20.0, 15.0),
        ("s2", "a", "predicted", "query_light1", 11.0, 6.0),
    ]
    cols = ["suite", "method", "track", "split", "recall_50cm", "recall_25cm"]
    return pd.DataFrame(data, columns=cols).assign(map_mb=1.0)


def test_the_summary_reads_the_plans_headline_split_with_mask_free_methods_last() -> None:
    plan = CampaignPlan(suites=["s1", "s2"], methods=["a", "b"], tracks=["predicted"], splits=["query"])
    assert campaign_page.summary_table(rows(), plan)[2:] == [
        "| a | predicted | 60.0 / 50.0 |",
        "| b | mask-free | 40.0 / 30.0 |",
    ]
    plan.splits = ["query_light1"]
    assert campaign_page.summary_table(rows(), plan)[0] == "| Method | Track | s1 | s2 |"
    assert campaign_page.summary_table(rows(), plan)[2] == "| a | predicted | 10.0 / 5.0 | 11.0 / 6.0 |"


def test_the_verdict_block_weighs_the_headline_split(tmp_path: Path) -> None:
    plan = CampaignPlan(suites=["s1"], methods=["a", "b"], tracks=["predicted"], splits=["query_light1"])
    block = campaign_page.verdict_block(
        rows(), pd.DataFrame(), plan, tmp_path / "boards", tmp_path / "README.md", "c" * 40, 3
    )
    assert block.startswith(campaign_page.VERDICT_BEGIN) and block.endswith(campaign_page.VERDICT_END)
    assert "query_light1 split" in block and "3 step(s) of the plan still to run" in block
    assert "- **[s1](boards/s1/leaderboard.md)**: Predicted track: b leads at 50 cm (20.0 vs a 10.0)" in block


def test_the_page_counts_the_plans_steps_apart_from_data_generation() -> None:
    plan = CampaignPlan(suites=["s1"], methods=["a", "b"], tracks=["predicted"], splits=["query"])
    steps = {"generate/s1": {"wall_s": 360.0}, "headline/s1/predicted/a": {"wall_s": 3240.0}}
    record = {"commit": "c" * 40, "steps": steps}
    page = campaign_page.campaign_page(record, rows(), ["headline/s1/mask-free/b"], ["headline"], plan)
    assert "Wall time of the recorded steps: 1.00 h (1 of the plan's 2 steps and 1 data generation step(s)); " in page
    assert "1 step(s) of the plan still to run." in page
