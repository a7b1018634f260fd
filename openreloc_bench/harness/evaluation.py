"""One evaluation from its config to its tables: what ``openreloc-bench eval`` (and ``demo``) runs.

The methods are checked first, then a suite's missing scenes are generated, every job runs
(:func:`~openreloc_bench.harness.runner.evaluate`), and the results folder's tables are written from
every finished job in it (:func:`tabulate`, which the campaign uses too).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import pandas as pd

from openreloc_bench.data import paths, runs
from openreloc_bench.harness import runner, tables
from openreloc_bench.harness.metrics import THRESHOLDS_M
from openreloc_bench.harness.suites import ensure_suite_scenes, suite_scene_names
from openreloc_bench.methods import uses_masks


def tabulate(results: Path) -> tuple[pd.DataFrame, pd.DataFrame, pd.DataFrame] | None:
    """Write ``results/tables`` from every finished job under ``results`` (:func:`tables.write_tables`);
    returns the per-query rows and the suite and seeds tables, or None (and writes nothing) when no job
    has finished."""
    queries = runs.load_run_queries(results, uses_masks)
    if queries.empty:
        return None
    _, suite, seeds = tables.write_tables(results / "tables", queries, runs.load_map_records(results))
    return queries, suite, seeds


TOP_REASONS = 3
"""Failure reasons the summary names per method (the rest are in ``tables/queries.csv``)."""


def failure_lines(queries: pd.DataFrame, per_query: Path) -> list[str]:
    """Per method and track with failed queries, how many failed and the commonest reasons (numbers
    folded, so '3 matches' and '5 matches' count as one reason); a warning for a method that placed no
    query within 50 cm, which is a bug in its output far more often than a hard scene."""
    lines = []
    for (method, track), q in queries.groupby(["method", "track"], sort=True):
        failed = q[~q["success"].astype(bool)]
        if len(failed):
            reasons = (
                failed["reason"].fillna("no reason given").astype(str).str.replace(r"\d+(\.\d+)?", "N", regex=True)
            )
            counts = sorted(reasons.value_counts().items(), key=lambda kv: (-kv[1], kv[0]))
            top = ", ".join(f"{n} x '{r}'" for r, n in counts[:TOP_REASONS])
            lines.append(
                f"failed: {method} ({track}): {len(failed)} of {len(q)} queries: {top} (every query: {per_query})"
            )
        if len(q) and not (q["t_err_m"] < THRESHOLDS_M["50cm"]).any():
            lines.append(
                f"warning: {method} ({track}) placed none of its {len(q)} queries within 50 cm; check that it "
                "returns camera-to-world poses in the map's frame (OpenCV axes)"
            )
    return lines


def main(cfg: runner.EvalConfig, suite: Path | None = None, say: Callable[[str], None] = print) -> runner.EvalReport:
    """Evaluate ``cfg``, write the tables and say them, the errors and a summary (last, where a user looks
    when the run ends). ``suite``: a suite YAML whose scenes to evaluate instead of ``cfg.scenes``, its
    missing ones generated under ``cfg.data`` once the methods and their settings are known to be good."""
    runner.seeded_runs(cfg.runs, cfg.seeds)  # unknown methods and bad settings fail here, before scenes are generated
    if suite is not None:  # the results folder must not hold the scenes about to be generated
        paths.check_output(cfg.out, [cfg.data / name for name in suite_scene_names(suite)], "results folder")
        cfg = replace(cfg, scenes=ensure_suite_scenes(suite, cfg.data))
    report = runner.evaluate(cfg)
    if report.jobs_stale:
        say(f"resume: {report.jobs_stale} finished job(s) were run with other settings or scenes and were recomputed")
    tabulated = tabulate(cfg.out)
    if tabulated is not None:
        queries, suite_table, seeds = tabulated
        say(tables.compact(suite_table))
        if not seeds.empty:
            say(tables.compact_seeds(seeds))
        say(f"tables: {cfg.out / 'tables'}")
        for line in failure_lines(queries, cfg.out / "tables" / "queries.csv"):
            say(line)
    for err in report.errors:
        say(f"error: {err}")
    say(
        f"maps: {report.maps_built} built, {report.maps_cached} cached; jobs: {report.jobs_run} run, "
        f"{report.jobs_skipped} resumed; queries: {report.queries_localized} of {report.queries} localized; "
        f"{len(report.errors)} errors; {report.wall_s:.1f} s"
    )
    return report
