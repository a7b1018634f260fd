"""The leaderboard: markdown, CSV, a sortable static HTML page and plots from results directories.

Reads the per-query tables every ``eval`` / ``score`` run leaves (``tables/queries.csv`` under each
results directory given), so several runs, including outside submissions, merge into one board. Where
the queries carry their difficulty (generated scenes' ``difficulty.csv``), the board adds recall against
each difficulty axis, as plots and as numbers (``difficulty.csv``). The rows (:mod:`.rows`), the verdict
(:mod:`.verdict`), the pages (:mod:`.pages`) and the plots (:mod:`.plots`) each have their module.
"""

from __future__ import annotations

import os
import shutil
from collections.abc import Callable
from pathlib import Path

from openreloc_bench.data import io, paths
from openreloc_bench.errors import ConfigError
from openreloc_bench.harness.leaderboard.pages import WHY_CAPTIONS, to_html, to_markdown
from openreloc_bench.harness.leaderboard.plots import (
    board_scene,
    method_colors,
    plot_cumulative,
    plot_headline_recall,
    plot_recall_vs_difficulty,
    plot_recall_vs_lighting,
    plot_recall_vs_map_size,
    plot_scene_recall,
    plot_topdown,
)
from openreloc_bench.harness.leaderboard.rows import (
    board,
    data_versions,
    difficulty_table,
    load_maps,
    load_queries,
    paired_differences,
    recorded_tracks,
    robustness_drops,
)
from openreloc_bench.harness.leaderboard.verdict import ABLATIONS
from openreloc_bench.harness.tables import build_tables, pool_seeds
from openreloc_bench.tracks import MASK_FREE

PAIRED_FILE = "paired.csv"
"""A board's comparisons of every two methods on the same queries of the headline split, which its verdict
weighs (and the campaign's README verdict reads)."""


def write_leaderboard(results: list[Path], out: Path, data: Path | None = None, card: Path | None = None) -> list[Path]:
    """Render everything into ``out`` (never inside or around a results directory); returns the files written.
    ``data``: the dataset directory, for each scene's floor plan under its top-down plot; ``card``: the
    data's dataset card (``openreloc-bench card``), which the pages link."""
    q = recorded_tracks(pool_seeds(load_queries(results)))  # pooled first: seeded runs carry the method's name
    for r in results:
        paths.check_output(out, [r], "--out", fills=True)
    _check_not_foreign_pages(out)
    scenes, suite = build_tables(q, load_maps(results))
    # The csv keeps every row; pages and plots compare methods, and a method's ablation variants, parts of
    # it, have their own table (``ablations_<track>.md``, written by ``eval --ablations``).
    q, scenes, shown = (t[~t["method"].isin(ABLATIONS)] for t in (q, scenes, suite))
    b = board(shown)
    out.mkdir(parents=True, exist_ok=True)
    plots_dir = out / "plots"
    plots_dir.mkdir(exist_ok=True)
    plots = [
        plots_dir / "cumulative_translation.png",
        plots_dir / "cumulative_rotation.png",
        plots_dir / "recall_per_scene.png",
    ]
    colors = method_colors(q["method"])  # a method looks the same in every plot of the board
    plot_cumulative(q, "t_err_m", 1.0, "translation error [m]", plots[0], colors)
    plot_cumulative(q, "r_err_deg", 20.0, "rotation error [°]", plots[1], colors)
    plot_scene_recall(scenes, plots[2], colors)
    plots.append(plots_dir / "recall_vs_map_size.png")
    plot_recall_vs_map_size(shown, plots[-1], colors)
    if plot_recall_vs_lighting(shown, plots_dir / "recall_vs_lighting.png", colors):
        plots.append(plots_dir / "recall_vs_lighting.png")
    if plot_headline_recall(b, plots_dir / "headline_recall.png", colors):
        plots.insert(0, plots_dir / "headline_recall.png")
    for scene in sorted(q.loc[q["split"] == "query", "scene"].unique()):
        plots.append(plots_dir / f"topdown_{scene}.png")
        specs = q.loc[q["scene"] == scene, "spec_hash"] if "spec_hash" in q else []
        plot_topdown(q, scene, plots[-1], board_scene(data, scene, list(specs)))
    binned = difficulty_table(q)
    difficulty_plots = []
    for track in [t for t in dict.fromkeys(b["track"]) if t != MASK_FREE] or [MASK_FREE]:
        path = plots_dir / f"difficulty_{track}.png"
        title = "methods that read no masks" if track == MASK_FREE else f"{track} track"
        if plot_recall_vs_difficulty(binned[binned["track"].isin([track, MASK_FREE])], title, path, colors):
            difficulty_plots.append(path)
    versions = data_versions(q)
    rel = [str(p.relative_to(out)) for p in difficulty_plots]
    card_link = os.path.relpath(card.resolve(), out.resolve()) if card else ""
    io.atomic_write_text(out / "leaderboard.csv", suite.to_csv(index=False))
    io.atomic_write_text(out / "difficulty.csv", binned.to_csv(index=False))
    drops = robustness_drops(q)
    ablations = copy_ablation_tables(results, out)
    abl = [p.name for p in ablations]
    pictures = [str(p.relative_to(out)) for p in plots]
    why = [p for p in pictures if Path(p).name in WHY_CAPTIONS]
    paired = paired_differences(q)
    io.atomic_write_text(out / PAIRED_FILE, paired.to_csv(index=False))
    io.atomic_write_text(
        out / "leaderboard.md", to_markdown(b, scenes, versions, rel, card_link, drops, abl, why, paired)
    )
    io.atomic_write_text(out / "index.html", to_html(b, pictures, versions, rel, card_link, drops, abl, why, paired))
    return [
        out / "leaderboard.md",
        out / "leaderboard.csv",
        out / "difficulty.csv",
        out / PAIRED_FILE,
        out / "index.html",
        *ablations,
        *plots,
        *difficulty_plots,
    ]


BOARD_PAGES = ("index.html", "leaderboard.md")


def _check_not_foreign_pages(out: Path) -> None:
    """Refuse to write a board over pages it did not write: a folder holding ``index.html`` or
    ``leaderboard.md`` but no ``leaderboard.csv`` (which every board writes) holds someone else's site."""
    if (out / "leaderboard.csv").is_file():
        return
    for page in BOARD_PAGES:
        if (out / page).exists():
            raise ConfigError(f"--out {out} holds a {page} no board wrote: choose another folder")


def copy_ablation_tables(results: list[Path], out: Path) -> list[Path]:
    """The ablation tables ``eval --ablations`` wrote (``tables/ablations_<track>.md``), copied beside the
    board, one per track: the first results folder's where several have one."""
    found: dict[str, Path] = {}
    for r in results:
        for table in sorted((r / "tables").glob("ablations_*.md")):
            found.setdefault(table.name, table)
    for name, table in found.items():
        shutil.copyfile(table, out / name)
    return [out / name for name in found]


def main(results: list[Path], out: Path, data: Path | None = None, say: Callable[[str], None] = print) -> list[Path]:
    """Render the board (:func:`write_leaderboard`), then say its verdict and per-track tables and how many
    files it wrote; returns them."""
    files = write_leaderboard(results, out, data)
    say((out / "leaderboard.md").read_text().split("\n## Per scene")[0].rstrip())  # one table per track
    say(f"wrote {len(files)} files to {out}")
    return files
