"""The campaign's own page."""

from __future__ import annotations

import pandas as pd

from openreloc_bench.harness.leaderboard import campaign_page


def test_the_page_counts_the_plans_steps_apart_from_data_generation() -> None:
    rows = pd.DataFrame(
        [("s1", "a", "predicted", "query", 60.0, 50.0)],
        columns=["suite", "method", "track", "split", "recall_50cm", "recall_25cm"],
    )
    steps = {"generate/s1": {"wall_s": 360.0}, "headline/s1/predicted/a": {"wall_s": 3240.0}}
    record = {"commit": "c" * 40, "steps": steps}
    plan = {"suites": ["s1"], "tracks": ["predicted"], "methods": ["a", "b"]}
    page = campaign_page.campaign_page(record, rows, ["headline/s1/mask-free/b"], ["headline"], {}, plan)
    assert "Wall time of the recorded steps: 1.00 h (1 of the plan's 2 steps and 1 data generation step(s)); " in page
    assert "1 step(s) of the plan still to run." in page
