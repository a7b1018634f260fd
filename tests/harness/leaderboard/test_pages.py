"""The board's pages: the verdict first, then one table per track, the predicted track's first."""

from __future__ import annotations

import pandas as pd

from openreloc_bench.harness.leaderboard.pages import to_html, to_markdown
from openreloc_bench.harness.leaderboard.verdict import verdict
from tests.harness.leaderboard.boards import runs


def test_boards_open_with_the_verdict_then_the_predicted_table_then_the_oracle_mask_table() -> None:
    b = runs(("openreloc", "oracle-mask", 88.7, 82.7, 0.68), ("sift-pnp", "mask-free", 66.3, 66.0, 12.1),
             ("openreloc", "predicted", 32.7, 20.3, 0.74))  # fmt: skip
    scenes = pd.DataFrame(columns=["method", "track", "split", "scene", "map_mb"])
    md = to_markdown(b, scenes).splitlines()
    assert md[2] == f"**Verdict (query split, recall [%]):** {verdict(b)}" and md[2].count("\n") == 0
    headings = [ln for ln in md if ln.startswith("## ")]
    assert headings[0].startswith("## Predicted track (headline)") and headings[1].startswith("## Oracle-mask track")
    page = to_html(b, [])
    assert page.index("<h1>") < page.index('<p class="verdict"><strong>Verdict (query split, recall [%]):</strong>')
    assert page.index('class="verdict"') < page.index("<h2>Predicted track (headline)") < page.index("<h2>Oracle-mask")
