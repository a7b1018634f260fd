"""What a campaign says of itself: ``campaign.md`` (code version, wall time by stage beside the plan's
estimate, the longest steps, what is left, the summary table) and the verdict table it writes into the
READMEs that carry its markers."""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any, Protocol

import pandas as pd

from openreloc_bench.data import io
from openreloc_bench.errors import ConfigError
from openreloc_bench.harness.leaderboard.verdict import verdict, verdict_lead
from openreloc_bench.harness.tables import md_table
from openreloc_bench.tracks import MASK_FREE


class PagePlan(Protocol):
    """What the page reads of a plan (``harness.campaign.CampaignPlan``, which imports this module)."""

    suites: list[str]
    methods: list[str]
    tracks: list[str]
    splits: list[str]
    estimate_h: dict[str, float]


VERDICT_BEGIN = "<!-- verdict: written by `openreloc-bench campaign`; edits between these markers are replaced -->"
VERDICT_END = "<!-- /verdict -->"


def timings(steps: dict[str, dict[str, Any]]) -> pd.DataFrame:
    """Wall time of every recorded step (``campaign.json``'s ``steps``), with the sittings that ended it
    mid-way, longest first."""
    rows = [
        {"step": key, "stage": key.split("/")[0], "wall_s": rec["wall_s"] + rec.get("earlier_s", 0.0)}
        for key, rec in steps.items()
    ]
    return pd.DataFrame(rows, columns=["step", "stage", "wall_s"]).sort_values("wall_s", ascending=False)


def summary_table(suite_rows: pd.DataFrame, plan: PagePlan) -> list[str]:
    """R@50cm / R@25cm on the plan's headline split of every method (rows) on every suite (columns), per
    track in the plan's order (mask-free methods last): markdown lines."""
    head = suite_rows[(suite_rows["split"] == plan.splits[0]) & suite_rows["method"].isin(plan.methods)]
    shown = [s for s in plan.suites if s in set(head["suite"])]
    order = {t: k for k, t in enumerate([*plan.tracks, MASK_FREE])}
    head = head.assign(_rank=head["track"].map(lambda x: order.get(x, len(order))))
    rows = []
    for (method, track), g in head.sort_values(["_rank", "method"]).groupby(["method", "track"], sort=False):
        cells = {r.suite: f"{r.recall_50cm:.1f} / {r.recall_25cm:.1f}" for r in g.itertuples()}
        rows.append([method, track, *(cells.get(s, "-") for s in shown)])
    return md_table(["Method", "Track", *shown], rows)


def campaign_page(
    record: dict[str, Any],
    suite_rows: pd.DataFrame,
    pending: list[str],
    stages: Sequence[str],
    plan: PagePlan,
    left: str = "",
) -> str:
    """``campaign.md`` from the campaign's record (``campaign.json``: its code version and finished steps),
    the boards' rows (``suite`` column added), the steps still to run (``left``: about how long they take)
    and the plan (its ``estimate_h`` per stage, its suites, tracks, methods and headline split)."""
    estimate_h = plan.estimate_h
    t = timings(record["steps"])
    total = t["wall_s"].sum()
    generated = int((t["stage"] == "generate").sum())  # one per suite, outside the plan's numbered steps
    done = len(t) - generated
    lines = [
        "# Leaderboard campaign",
        "",
        f"Every row of the boards comes from the code at commit `{record['commit']}` (the last commit that "
        "changed the code: commits of results since keep it).",
        f"Wall time of the recorded steps: {total / 3600:.2f} h ({done} of the plan's {done + len(pending)} "
        f"steps and {generated} data generation step(s)); "
        f"{len(pending)} step(s) of the plan still to run{left if pending else ''}.",
        "",
    ]
    by_stage = t.groupby("stage")["wall_s"].sum()
    shares = [
        [s, f"{by_stage.get(s, 0.0) / 3600:.2f}", f"{estimate_h[s]:.1f}" if s in estimate_h else "-",
         f"{100 * by_stage.get(s, 0.0) / max(total, 1e-9):.0f}"]
        for s in ["generate", *stages] if s in by_stage or s in estimate_h
    ]  # fmt: skip
    if estimate_h:
        shares.append(["all", f"{total / 3600:.2f}", f"{sum(estimate_h.values()):.1f}", "100"])
    lines += md_table(["Stage", "Wall [h]", "Plan's estimate [h]", "Share [%]"], shares)
    lines += ["", "Longest steps:", ""] + [f"- `{r.step}`: {r.wall_s / 60:.1f} min" for r in t.head(8).itertuples()]
    if pending:
        lines += ["", "Still to run:", ""] + [f"- `{p}`" for p in pending]
    if not suite_rows.empty:
        lines += ["", f"## Summary: R@50cm / R@25cm [%] on the {plan.splits[0]} split", ""]
        lines += summary_table(suite_rows, plan)
    return "\n".join(lines) + "\n"


def verdict_block(
    suite_rows: pd.DataFrame, paired: pd.DataFrame, plan: PagePlan, boards: Path, into: Path, commit: str, pending: int
) -> str:
    """The verdict table for the README ``into``: each suite's verdict line (weighed on the same queries
    with the boards' ``paired`` comparisons, a ``suite`` column telling them apart), linked to its board
    (under ``boards``), and the summary table; the code version and, for an unfinished campaign, how many
    steps are left."""
    state = f"; {pending} step(s) of the plan still to run" if pending else ""
    split = plan.splits[0]
    lines = [VERDICT_BEGIN, f"**{verdict_lead(split)}**, code version `{commit[:12]}`{state}:", ""]
    for suite in plan.suites:
        rows = suite_rows[suite_rows["suite"] == suite]
        if not rows.empty:
            link = os.path.relpath(boards / suite / "leaderboard.md", into.resolve().parent)
            same = paired[paired["suite"] == suite] if "suite" in paired else None
            lines.append(f"- **[{suite}]({link})**: {verdict(rows, split, same)}")
    lines += ["", "R@50cm / R@25cm [%]:", ""]
    lines += summary_table(suite_rows, plan)
    return "\n".join([*lines, VERDICT_END])


def check_verdict_files(files: Sequence[Path]) -> None:
    """One-line errors, before any work, for a file to write the verdict into that cannot take it."""
    for f in files:
        if not f.is_file():
            raise ConfigError(f"--verdict-into {f}: no such file")
        text = f.read_text(encoding="utf-8")
        if (
            text.count(VERDICT_BEGIN) != 1
            or text.count(VERDICT_END) != 1
            or text.index(VERDICT_BEGIN) > text.index(VERDICT_END)
        ):
            raise ConfigError(
                f"--verdict-into {f}: it must hold the lines '{VERDICT_BEGIN}' and '{VERDICT_END}' once, in that order"
            )


def write_verdict(path: Path, block: str) -> None:
    """Replace the marked block of ``path`` (checked by :func:`check_verdict_files`) with ``block``."""
    text = path.read_text(encoding="utf-8")
    head, rest = text.split(VERDICT_BEGIN, 1)
    tail = rest.split(VERDICT_END, 1)[1]
    io.atomic_write_text(path, head + block + tail)
