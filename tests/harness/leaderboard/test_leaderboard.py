"""Boards written whole: recall against each difficulty axis and the data version they score."""

from __future__ import annotations

import html
from pathlib import Path

import pandas as pd
import pytest

from openreloc_bench.data.runs import backfill_difficulty
from openreloc_bench.errors import ConfigError
from openreloc_bench.harness.leaderboard import write_leaderboard
from openreloc_bench.harness.leaderboard.plots import plot_recall_vs_difficulty
from openreloc_bench.harness.leaderboard.rows import data_versions
from tests.harness.leaderboard.boards import results_dir


def test_boards_plot_recall_against_each_difficulty_axis_with_values(tmp_path: Path) -> None:
    out = tmp_path / "board"
    files = write_leaderboard([results_dir(tmp_path / "r", "m")], out)
    png = out / "plots" / "difficulty_predicted.png"
    assert png in files and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    md = (out / "leaderboard.md").read_text()
    assert md.startswith("# openreloc-bench leaderboard (data v2)\n")
    assert "## Recall vs difficulty" in md and "![recall vs difficulty](plots/difficulty_predicted.png)" in md
    page = (out / "index.html").read_text()
    assert "<h1>openreloc-bench leaderboard (data v2)</h1>" in page and 'src="plots/difficulty_predicted.png"' in page
    numbers = pd.read_csv(out / "difficulty.csv").set_index(["axis", "bin"])
    # pooled over both splits: gap 0.1 m twice per split (errors 0.1, 0.1, 0.3, 0.6 m); light 1 and 0.5 vary
    assert numbers.loc[("gap_m", "0–0.25"), ["n", "recall_50cm", "recall_25cm"]].tolist() == [4, 75, 50]
    assert numbers.loc[("light_level", "0.5"), ["n", "recall_50cm", "recall_25cm"]].tolist() == [4, 50, 0]
    drawn = plot_recall_vs_difficulty(numbers.reset_index(), "predicted track", tmp_path / "p.png")
    assert drawn == ["gap_m", "light_level", "lookalikes_in_view"]  # all NaN or one value: no panel


def test_boards_name_the_data_version_they_score(tmp_path: Path) -> None:
    out = tmp_path / "board"
    write_leaderboard([results_dir(tmp_path / "old", "m", versioned=False)], out)
    md = (out / "leaderboard.md").read_text()
    assert md.startswith("# openreloc-bench leaderboard (data v1)\n")  # tables without the column: v1 data
    assert "Recall vs difficulty" not in md and not (out / "plots" / "difficulty_predicted.png").exists()
    q = pd.DataFrame({"spec_hash": ["a", "file:0f3e", "b"], "data_version": [2, 2, 2]})
    assert (
        data_versions(backfill_difficulty(q.drop(columns="data_version"))) == "data v1, scenes without a data version"
    )
    assert data_versions(q.assign(data_version=[1, 2, 2])) == "data v1 + v2"
    assert data_versions(q) == "data v2"


def test_boards_keep_ablation_variants_in_the_csv_and_link_their_table(tmp_path: Path) -> None:
    out = tmp_path / "board"
    ablated = results_dir(tmp_path / "abl", "openreloc+no_refine")
    (ablated / "tables" / "ablations_predicted.md").write_text("Ablations (predicted track; seed 0)\n")
    files = write_leaderboard([results_dir(tmp_path / "full", "openreloc"), ablated], out)
    assert set(pd.read_csv(out / "leaderboard.csv")["method"]) == {"openreloc", "openreloc+no_refine"}
    for page in ("leaderboard.md", "index.html"):
        text = (out / page).read_text()
        assert "openreloc+no_refine" not in text
        assert "Ablations of openreloc, predicted track:" in text and "ablations_predicted.md" in text
    assert set(pd.read_csv(out / "difficulty.csv")["method"]) == {"openreloc"}
    assert out / "ablations_predicted.md" in files
    assert (out / "ablations_predicted.md").read_text() == "Ablations (predicted track; seed 0)\n"


def test_boards_print_recalls_with_their_intervals_and_the_fields_thresholds(tmp_path: Path) -> None:
    out = tmp_path / "board"
    write_leaderboard([results_dir(tmp_path / "r", "m")], out)
    md = (out / "leaderboard.md").read_text()
    page = (out / "index.html").read_text()
    # every plot opens at full size; the per-scene bars are as wide as the page
    assert '<a href="plots/cumulative_translation.png"><img src=' in page
    assert '<a href="plots/recall_per_scene.png"><img class=wide src=' in page
    headline, folded = page.split("<details><summary>The other splits (", 1)  # the query split's rows first
    assert "<td>query</td>" in headline.split("<h2>")[-1] and "<td>query_light1</td>" not in headline
    assert "<td>query_light1</td>" in folded.split("</details>")[0]
    for column in ("R@50cm [%]", "R@5cm,5° [%]", "R@10cm,10° [%]", "VCRE<90px [%]"):
        assert column in md and html.escape(column) in page
    assert "recall_50cm_lo" not in md  # the bounds are printed in their recall's cell, not as columns
    suite = pd.read_csv(out / "leaderboard.csv").set_index("split")
    for recall in ("recall_50cm", "recall_25cm", "recall_5cm_5deg", "recall_10cm_10deg", "recall_25cm_5deg"):
        lo, value, hi = suite.loc["query", [f"{recall}_lo", recall, f"{recall}_hi"]]
        assert lo <= value <= hi
        assert f"{value:.1f} [{lo:.1f}, {hi:.1f}]" in md and f"{value:.1f} [{lo:.1f}, {hi:.1f}]" in page
    lo, hi = suite.loc["query", ["recall_50cm_lo", "recall_50cm_hi"]]
    assert lo < hi  # 3 of 4 queries within 50 cm: far from certain


def test_a_board_is_not_written_over_pages_no_board_wrote(tmp_path: Path) -> None:
    site = tmp_path / "site"
    site.mkdir()
    (site / "index.html").write_text("<p>my lab</p>")
    results = results_dir(tmp_path / "r", "m")
    with pytest.raises(ConfigError, match="holds a index.html no board wrote"):
        write_leaderboard([results], site)
    assert sorted(site.iterdir()) == [site / "index.html"] and (site / "index.html").read_text() == "<p>my lab</p>"
    board = tmp_path / "board"
    write_leaderboard([results], board)
    assert write_leaderboard([results], board)  # a board's own folder is rewritten


def test_boards_cite_each_methods_paper_and_code(tmp_path: Path) -> None:
    out = tmp_path / "board"
    write_leaderboard([results_dir(tmp_path / "r", "sift-pnp"), results_dir(tmp_path / "u", "unknown-method")], out)
    md, page = (out / "leaderboard.md").read_text(), (out / "index.html").read_text()
    assert "## Methods" in md and "| sift-pnp | Sarlin et al., From Coarse to Fine" in md
    assert "| unknown-method | - |" in md  # a name no method is registered under cites nothing
    url = "https://github.com/cvg/Hierarchical-Localization"
    assert f'<a href="{url}">{url}</a>' in page


def test_boards_open_with_the_plots_that_explain_the_verdict(tmp_path: Path) -> None:
    out = tmp_path / "board"
    files = write_leaderboard(
        [results_dir(tmp_path / "r", "sift-pnp"), results_dir(tmp_path / "u", "nearest-frame")], out
    )
    assert out / "plots" / "headline_recall.png" in files
    md, page = (out / "leaderboard.md").read_text(), (out / "index.html").read_text()
    why = md.index("## Why")
    assert why < md.index("## Methods that read no masks")
    shown = [line for line in md[why:].split("\n## ")[0].splitlines() if line.startswith("![")]
    assert shown == [
        "![headline_recall](plots/headline_recall.png)",
        "![cumulative_translation](plots/cumulative_translation.png)",
        "![recall_vs_lighting](plots/recall_vs_lighting.png)",
    ]
    assert "which is sharper than comparing these whiskers" in md
    paired = pd.read_csv(out / "paired.csv")  # what the verdict weighs: both methods on the same 4 queries
    assert out / "paired.csv" in files and set(paired.method) == {"sift-pnp", "nearest-frame"}
    assert (paired.n_queries == 4).all()
    assert page.index("<h2>Why</h2>") < page.index("<table")
    assert page.count('src="plots/headline_recall.png"') == 1  # not again among the other plots
