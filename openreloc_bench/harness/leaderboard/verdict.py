"""A board's verdict line: per track, who leads on the headline split at 50 and at 25 cm, by how much,
and at what map size. A lead must hold on the same queries: where the board compared the two methods
query by query (:func:`~.rows.paired_differences`), the best is ahead only when the interval of the
difference lies above zero; without that comparison, where the rows carry 95% intervals
(``recall_50cm_lo`` / ``_hi``), a best recall whose interval overlaps the next method's is no lead. Either
way a difference the intervals do not carry calls the two level."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd

from openreloc_bench.harness.ablations import ABLATION_ROWS, ablation_label
from openreloc_bench.harness.leaderboard.rows import HEADLINE_SPLIT, TRACK_NAMES, format_cell, track_groups

DIAGNOSTICS = ("openreloc-oracle-association",)
"""Rows a board shows that are no method: ``openreloc`` given the true landmark association, which bounds
what follows the association."""
ABLATIONS = tuple(ablation_label(r) for r in ABLATION_ROWS)
"""The labels of ``openreloc``'s ablation variants (``openreloc+<row>``), parts of one method."""


def _recall(v: float) -> str:
    return f"{v:.1f}"


def _names(methods: Sequence[str]) -> str:
    """'a', 'a and b', 'a, b and c'."""
    return methods[0] if len(methods) == 1 else f"{', '.join(methods[:-1])} and {methods[-1]}"


def _leaders(rows: pd.DataFrame, col: str) -> tuple[list[str], float, pd.Series | None]:
    """The methods with the best ``col`` (equal as the board prints them, to 0.1), that value, and the
    best of the rest (None when every method ties)."""
    shown = rows[col].round(1)
    top = shown.max()
    rest = rows.assign(_shown=shown)[shown < top].sort_values(["_shown", "method"], ascending=[False, True])
    return sorted(rows.loc[shown == top, "method"]), top, (rest.iloc[0] if len(rest) else None)


def _interval(row: pd.Series, col: str) -> tuple[float, float] | None:
    """``col``'s 95% interval in ``row``, None where the row has none."""
    lo, hi = row.get(f"{col}_lo", np.nan), row.get(f"{col}_hi", np.nan)
    return None if pd.isna(lo) or pd.isna(hi) else (float(lo), float(hi))


def _value(row: pd.Series, col: str) -> str:
    """'66.7' or, with its interval, '66.7 [61.2, 72.1]'."""
    ci = _interval(row, col)
    return _recall(row[col]) + ("" if ci is None else f" [{_recall(ci[0])}, {_recall(ci[1])}]")


def _paired(paired: pd.DataFrame | None, a: str, b: str, col: str) -> tuple[float, float, float] | None:
    """``a`` minus ``b`` on ``col`` over the queries both answered, with its interval; None if not compared."""
    if paired is None or paired.empty:
        return None
    hit = paired[(paired["method"] == a) & (paired["other"] == b) & (paired["column"] == col)]
    return None if hit.empty else (float(hit["diff"].iloc[0]), float(hit["lo"].iloc[0]), float(hit["hi"].iloc[0]))


def _at(
    rows: pd.DataFrame, col: str, cm: int, paired: pd.DataFrame | None = None
) -> tuple[list[str], str, str, list[str]]:
    """Who comes first on ``col``, how ('leads', 'tie', or 'are level' where the difference to the best of
    the rest is not carried by its interval: paired on the same queries where ``paired`` has the two, else
    where the two recalls' intervals overlap), 'at 50 cm (66.7 vs b 66.3)' and the methods that names,
    leaders first."""
    leaders, top, runner = _leaders(rows, col)
    first = rows[rows["method"] == leaders[0]].iloc[0]
    if runner is None:
        return leaders, "tie", f"at {cm} cm ({_value(first, col)})", leaders
    named = [*leaders, runner.method]
    same = _paired(paired, leaders[0], runner.method, col)
    if same is not None:
        d, lo, hi = same
        gap = f"{d:+.1f} [{lo:+.1f}, {hi:+.1f}] on the same queries"
        if lo <= 0:
            return named, "are level", f"at {cm} cm ({_recall(first[col])} vs {_recall(runner[col])}, {gap})", named
        verb = "tie" if len(leaders) > 1 else "leads"
        return (
            leaders,
            verb,
            f"at {cm} cm ({_recall(first[col])} vs {runner.method} {_recall(runner[col])}, {gap})",
            named,
        )
    a, b = _interval(first, col), _interval(runner, col)
    if a is not None and b is not None and a[0] <= b[1]:
        return named, "are level", f"at {cm} cm ({_value(first, col)} vs {_value(runner, col)})", named
    verb = "tie" if len(leaders) > 1 else "leads"
    return leaders, verb, f"at {cm} cm ({_value(first, col)} vs {runner.method} {_value(runner, col)})", named


def _map_size(row: pd.Series) -> str:
    v = row.get("map_mb", np.nan)
    return f"{format_cell('map_mb', v)} MB" if pd.notna(v) and v > 0 else "not recorded"


def track_verdict(rows: pd.DataFrame, paired: pd.DataFrame | None = None) -> str:
    """Who leads one track's rows (one per method: ``method``, ``recall_50cm``, ``recall_25cm``,
    ``map_mb``) at 50 cm and at 25 cm, with the recall of the best of the rest, and the map size of every
    method it names; ``paired``: the track's :func:`~.rows.paired_differences` rows, where there are."""
    rows = rows.drop_duplicates("method")
    sizes = {r.method: _map_size(r) for _, r in rows.iterrows()}
    if len(rows) == 1:
        r = rows.iloc[0]
        return (
            f"only {r.method} ran ({_recall(r.recall_50cm)} at 50 cm, {_recall(r.recall_25cm)} at 25 cm; "
            f"map size {sizes[r.method]})"
        )
    lead50, verb50, at50, named50 = _at(rows, "recall_50cm", 50, paired)
    lead25, verb25, at25, named25 = _at(rows, "recall_25cm", 25, paired)
    text = f"{_names(lead50)} {verb50} {at50}"
    if (lead25, verb25) == (lead50, verb50):
        text += f" and {at25}"
    else:
        text += f", {_names(lead25)}{'' if verb25 == 'leads' else ' ' + verb25} {at25}"
    named = list(dict.fromkeys([*named50, *named25]))
    return f"{text}; map size: {', '.join(f'{m} {sizes[m]}' for m in named)}"


def verdict(b: pd.DataFrame, split: str = HEADLINE_SPLIT, paired: pd.DataFrame | None = None) -> str:
    """The board's verdict, one line made from its rows (columns ``method``, ``track``, ``split``,
    ``recall_50cm``, ``recall_25cm``, ``map_mb``): per track, in the board's order, who leads on ``split``
    at 50 cm and at 25 cm, by how much, and at what map size (:func:`track_verdict`), weighed on the same
    queries where ``paired`` (:func:`~.rows.paired_differences` of ``split``) compares the two. Methods that
    read no masks stand in every track's comparison. :data:`DIAGNOSTICS` and :data:`ABLATIONS` are not
    weighed (the line says so where the board has some), unless a track holds nothing else."""
    s = b[b["split"] == split]
    if s.empty:
        return f"No method ran the {split} split: no verdict."
    sentences, aside = [], set()
    for track, rows in track_groups(s):
        out = rows["method"].isin([*DIAGNOSTICS, *ABLATIONS]).to_numpy()
        if out.all():  # nothing else on the track: weigh what there is
            out = np.zeros(len(rows), dtype=bool)
        aside |= set(rows.loc[out, "method"])
        same = None if paired is None or paired.empty else paired[paired["track"] == track]
        sentences.append(f"{TRACK_NAMES.get(track, f'{track} track')}: {track_verdict(rows[~out], same)}.")
    skipped = [f"the diagnostic {m}" for m in sorted(aside & set(DIAGNOSTICS))]
    if aside & set(ABLATIONS):
        n = len(aside & set(ABLATIONS))
        skipped.append(f"{n} ablation variant{'s' if n > 1 else ''} of openreloc")
    if skipped:
        sentences.append(f"Not weighed: {_names(skipped)}.")
    return " ".join(sentences)


def verdict_lead(split: str = HEADLINE_SPLIT) -> str:
    """What a board's verdict line is headed with."""
    return f"Verdict ({split} split, recall [%])"
