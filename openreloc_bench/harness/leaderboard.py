"""The leaderboard: markdown, CSV, a sortable static HTML page and plots from a results directory.

Reads the per-query tables every ``eval`` / ``score`` run leaves (``tables/queries.csv`` under each
results directory given), so several runs, including outside submissions, merge into one board. Where
the queries carry their difficulty (generated scenes' ``difficulty.csv``), the board adds recall against
each difficulty axis, as plots and as numbers (``difficulty.csv``).
"""

from __future__ import annotations

import html
import logging
import math
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

import matplotlib
import matplotlib.artist
import matplotlib.lines
import matplotlib.ticker

matplotlib.use("Agg")  # headless: no display on benchmark machines
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from openreloc_bench.data import io, paths  # noqa: E402
from openreloc_bench.data.runs import QUERY_COLUMNS, backfill_difficulty, load_map_records, read_query_csv  # noqa: E402
from openreloc_bench.data.scene import Scene  # noqa: E402
from openreloc_bench.errors import DataError  # noqa: E402
from openreloc_bench.harness.ablations import ABLATION_ROWS, ROBUSTNESS_ROWS, ablation_label  # noqa: E402
from openreloc_bench.harness.metrics import cumulative_curve, summarize  # noqa: E402
from openreloc_bench.harness.tables import (  # noqa: E402
    SCENE_KEYS,
    build_tables,
    md_table,
    paper_table,
    pool_seeds,
)
from openreloc_bench.methods import uses_masks  # noqa: E402
from openreloc_bench.tracks import MASK_FREE  # noqa: E402

log = logging.getLogger(__name__)

BOARD_COLUMNS = {
    "method": "Method", "track": "Track", "split": "Split", "n_scenes": "Scenes", "n_seeds": "Seeds", "n_queries": "Queries",
    "recall_100cm": "R@100cm [%]", "recall_50cm": "R@50cm [%]", "recall_25cm": "R@25cm [%]",
    "recall_25cm_5deg": "R@25cm,5° [%]", "mte_50cm_m": "MTE@50 [m]", "mre_50cm_deg": "MRE@50 [°]",
    "mte_25cm_m": "MTE@25 [m]", "mre_25cm_deg": "MRE@25 [°]", "median_te_m": "Median TE [m]",
    "median_re_deg": "Median RE [°]", "map_mb": "Map [MB]", "mapping_time_s": "Mapping [s]",
    "latency_median_s": "Latency med [ms]", "latency_p90_s": "Latency p90 [ms]", "git_commit": "Commit",
}  # fmt: skip
FORMATS = {
    "recall": "{:.1f}",
    "mte": "{:.3f}",
    "mre": "{:.2f}",
    "median_te": "{:.3f}",
    "median_re": "{:.2f}",
    "map_mb": "{:.3g}",
    "mapping": "{:.1f}",
    "latency": "{:.1f}",
    "n_": "{:.0f}",
}


TRACK_TITLES = {
    "predicted": "Predicted track (headline): no instance image anywhere, each method segments for itself",
    "oracle-mask": "Oracle-mask track (upper bound): each query carries the dataset's instance masks",
}
"""The tracks in the order the board shows them, with the heading of each one's table."""


def _rank_of(track: str) -> int:
    order = list(TRACK_TITLES)
    return order.index(track) if track in order else len(order)


def _track_rank(track: pd.Series) -> pd.Series:
    return track.map(_rank_of)


BOARD_INPUT_COLUMNS = (*SCENE_KEYS, *QUERY_COLUMNS, "map_hash", "config_hash", "spec_hash", "git_commit")
"""What the board reads of each results directory's ``tables/queries.csv``."""


def load_queries(results: list[Path]) -> pd.DataFrame:
    """Concatenated per-query tables of the given results directories."""
    frames = []
    for r in results:
        path = r / "tables" / "queries.csv"
        if not path.is_file():
            raise DataError(r, "no tables/queries.csv (run 'openreloc-bench eval' or 'score' into it first)")
        frames.append(backfill_difficulty(read_query_csv(path, BOARD_INPUT_COLUMNS)))
    return _last_run_per_query(pd.concat(frames, ignore_index=True))


def _last_run_per_query(q: pd.DataFrame) -> pd.DataFrame:
    """One row per query of each run: the last (the seed, where runs over seeds are pooled, tells runs apart)."""
    return q.drop_duplicates(
        ["method", "track", "scene", "split", "query", *(["seed"] if "seed" in q else [])], keep="last"
    )


def load_maps(results: list[Path]) -> pd.DataFrame:
    return pd.concat([load_map_records(r) for r in results], ignore_index=True)


def _fmt(col: str, v: object) -> str:
    if isinstance(v, str):
        return v
    if v is None or (isinstance(v, float) and np.isnan(v)):
        return "-"
    for prefix, f in FORMATS.items():
        if col.startswith(prefix):
            return f.format(v) if np.isfinite(v) else "∞"
    return str(v)


def board(suite: pd.DataFrame) -> pd.DataFrame:
    """The leaderboard rows: the predicted track first, then the oracle-mask track; best Recall@25cm first
    within each (track, split)."""
    cols = [c for c in BOARD_COLUMNS if c in suite]
    b = suite.assign(_rank=_track_rank(suite["track"]))
    b = b.sort_values(["_rank", "split", "recall_25cm", "recall_50cm"], ascending=[True, True, False, False])
    b = b[cols].copy()
    b[["latency_median_s", "latency_p90_s"]] *= 1000.0  # shown in ms
    b["git_commit"] = b["git_commit"].astype(str).str.slice(0, 12)
    return b


def track_groups(rows: pd.DataFrame) -> list[tuple[str, pd.DataFrame]]:
    """``rows`` (with a ``track`` column) per track, in the board's order (:data:`TRACK_TITLES`), each
    with the rows of the methods that read no masks, which stand in every track; those rows alone, under
    ``MASK_FREE``, when no method ran on a track."""
    free = rows[rows["track"] == MASK_FREE]
    tracks = sorted(set(rows["track"]) - {MASK_FREE}, key=lambda t: (_rank_of(t), t))
    groups = [(t, pd.concat([rows[rows["track"] == t], free])) for t in tracks]
    return groups if groups or free.empty else [(MASK_FREE, free)]


def _by_track(b: pd.DataFrame) -> list[tuple[str, pd.DataFrame]]:
    """The board's rows cut into one table per track (:func:`track_groups`), each with its heading."""
    free = "Methods that read no masks (the same on both tracks)"
    return [
        (
            TRACK_TITLES.get(track, free if track == MASK_FREE else f"{track} track"),
            t.sort_values(["split", "recall_25cm", "recall_50cm"], ascending=[True, False, False]),
        )
        for track, t in track_groups(b)
    ]


HEADLINE_SPLIT = "query"
"""The split a board's verdict reads (the other splits are the robustness variants of it)."""
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


def _at(rows: pd.DataFrame, col: str, cm: int) -> tuple[list[str], str, list[str]]:
    """The leaders on ``col``, 'at 50 cm (66.7 vs b 66.3)' (the best of the rest after 'vs', where there
    is one) and the methods that names, leaders first."""
    leaders, top, runner = _leaders(rows, col)
    vs = "" if runner is None else f" vs {runner.method} {_recall(runner[col])}"
    return leaders, f"at {cm} cm ({_recall(top)}{vs})", [*leaders, *([] if runner is None else [runner.method])]


def _map_size(row: pd.Series) -> str:
    v = row.get("map_mb", np.nan)
    return f"{_fmt('map_mb', v)} MB" if pd.notna(v) and v > 0 else "not recorded"


def track_verdict(rows: pd.DataFrame) -> str:
    """Who leads one track's rows (one per method: ``method``, ``recall_50cm``, ``recall_25cm``,
    ``map_mb``) at 50 cm and at 25 cm, with the recall of the best of the rest, and the map size of every
    method it names."""
    rows = rows.drop_duplicates("method")
    sizes = {r.method: _map_size(r) for _, r in rows.iterrows()}
    if len(rows) == 1:
        r = rows.iloc[0]
        return (
            f"only {r.method} ran ({_recall(r.recall_50cm)} at 50 cm, {_recall(r.recall_25cm)} at 25 cm; "
            f"map size {sizes[r.method]})"
        )
    lead50, at50, named50 = _at(rows, "recall_50cm", 50)
    lead25, at25, named25 = _at(rows, "recall_25cm", 25)
    text = f"{_names(lead50)} {'tie' if len(lead50) > 1 else 'leads'} {at50}"
    if lead25 == lead50:
        text += f" and {at25}"
    else:
        text += f", {_names(lead25)}{' tie' if len(lead25) > 1 else ''} {at25}"
    named = list(dict.fromkeys([*named50, *named25]))
    return f"{text}; map size: {', '.join(f'{m} {sizes[m]}' for m in named)}"


TRACK_NAMES = {
    "predicted": "Predicted track",
    "oracle-mask": "Oracle-mask track",
    MASK_FREE: "Both tracks (no method reads masks)",
}
"""What the verdict calls each track's comparison (:func:`track_groups`)."""


def verdict(b: pd.DataFrame, split: str = HEADLINE_SPLIT) -> str:
    """The board's verdict, one line made from its rows (columns ``method``, ``track``, ``split``,
    ``recall_50cm``, ``recall_25cm``, ``map_mb``): per track, in the board's order, who leads on ``split``
    at 50 cm and at 25 cm, by how much, and at what map size (:func:`track_verdict`). Methods that read
    no masks stand in every track's comparison. :data:`DIAGNOSTICS` and :data:`ABLATIONS` are not weighed
    (the line says so where the board has some), unless a track holds nothing else."""
    s = b[b["split"] == split]
    if s.empty:
        return f"No method ran the {split} split: no verdict."
    sentences, aside = [], set()
    for track, rows in track_groups(s):
        out = rows["method"].isin([*DIAGNOSTICS, *ABLATIONS]).to_numpy()
        if out.all():  # nothing else on the track: weigh what there is
            out = np.zeros(len(rows), dtype=bool)
        aside |= set(rows.loc[out, "method"])
        sentences.append(f"{TRACK_NAMES.get(track, f'{track} track')}: {track_verdict(rows[~out])}.")
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


def recorded_tracks(q: pd.DataFrame) -> pd.DataFrame:
    """The queries under the track their run recorded (``MASK_FREE`` for methods that declared they read
    no masks: their rows stand in both tracks' tables), one run per query. Tables written before the
    track was recorded that way (no ``uses_masks`` value) are read by the rule the board used then: a
    method registered here as reading no masks (``leaderboard --plugin`` registers a plugin's) is
    ``MASK_FREE``, any other keeps its track."""
    legacy = q["uses_masks"].isna() if "uses_masks" in q else pd.Series(True, index=q.index)
    free = {m for m in q.loc[legacy, "method"].unique() if not uses_masks(m)}
    return _last_run_per_query(q.assign(track=q["track"].mask(legacy & q["method"].isin(free), MASK_FREE)))


def robustness_drops(b: pd.DataFrame) -> pd.DataFrame:
    """Per (method, track): recall on the plain query split and its change on every robustness split
    (points of R@50cm / R@25cm; negative = lost), for the methods run on the query split and another.
    A change measured over another number of seeds than the query split's says so."""
    rows = []
    for (method, track), g in b.groupby(["method", "track"], sort=False):
        g = g.set_index("split")
        if "query" not in g.index or len(g) < 2:
            continue
        base = g.loc["query"]
        row = {"Method": method, "Track": track, "query": f"{base.recall_50cm:.1f} / {base.recall_25cm:.1f}"}
        for r in ROBUSTNESS_ROWS[1:]:
            if r.key in g.index:
                d50, d25 = (g.loc[r.key, c] - base[c] for c in ("recall_50cm", "recall_25cm"))
                other_seeds = "n_seeds" in g and g.loc[r.key, "n_seeds"] != base["n_seeds"]
                row[r.key] = f"{d50:+.1f} / {d25:+.1f}" + (
                    f" (over {g.loc[r.key, 'n_seeds']:.0f} seed(s))" if other_seeds else ""
                )
        rows.append(row)
    cols = ["Method", "Track", "query", *(r.key for r in ROBUSTNESS_ROWS[1:])]
    return pd.DataFrame(rows, columns=cols).dropna(axis=1, how="all").fillna("-")


ROBUSTNESS_TITLE = "Robustness: R@50cm / R@25cm on the query split, and their change on each variant [points]"


def provenance(b: pd.DataFrame) -> str:
    """The line naming the commit every row comes from (or, for a board merged from several runs, each)."""
    commits = sorted(set(b["git_commit"])) if "git_commit" in b else []
    if not commits:
        return "No commit recorded with these rows."
    if len(commits) == 1:
        return f"Every row comes from commit {commits[0]}."
    return f"Rows from {len(commits)} commits (see the Commit column): {', '.join(commits)}."


def data_versions(q: pd.DataFrame) -> str:
    """The data the per-query rows score, for the board's title: 'data v2', 'data v1 + v2', and 'scenes without a
    data version' where some scene names none (imported data); empty for no rows."""
    versions = q["data_version"].dropna()
    parts = ["data " + " + ".join(f"v{v:.0f}" for v in sorted(versions.unique()))] if len(versions) else []
    if q["data_version"].isna().any():
        parts.append("scenes without a data version")
    return ", ".join(parts)


def _title(versions: str) -> str:
    return f"openreloc-bench leaderboard ({versions})" if versions else "openreloc-bench leaderboard"


DIFFICULTY_TEXT = (
    "R@50cm (solid) and R@25cm (dashed) per bin of each query's difficulty (from its scene's difficulty.csv), "
    "pooled over every scene and query split each method ran; n = queries in the bin. The numbers are in "
    "difficulty.csv."
)


def to_markdown(b: pd.DataFrame, scenes: pd.DataFrame, versions: str = "", difficulty_plots: Sequence[str] = ()) -> str:
    """The board: its verdict (:func:`verdict`), one table per track (the predicted track's first), the
    robustness table, per-scene tables, map sizes and the recall-vs-difficulty plots (``difficulty_plots``,
    paths relative to the board)."""
    head = [BOARD_COLUMNS[c] for c in b.columns]
    lines = [
        f"# {_title(versions)}",
        "",
        f"**{verdict_lead()}:** {verdict(b)}",
        "",
        "Recall = share of all queries (failures count); MTE/MRE = mean error of the queries within the threshold.",
        "",
        provenance(b),
    ]
    for title, t in _by_track(b):
        lines += [
            "",
            f"## {title}",
            "",
            *md_table(head, [[_fmt(c, r[c]) for c in b.columns] for _, r in t.iterrows()]),
        ]
    drops = robustness_drops(b)
    if not drops.empty:
        lines += ["", f"## {ROBUSTNESS_TITLE}", "", *md_table(list(drops.columns), drops.values.tolist())]
    scenes = scenes.assign(_rank=_track_rank(scenes["track"])).sort_values(["_rank", "split"], kind="stable")
    for (track, split), t in scenes.groupby(["track", "split"], sort=False):
        rows = [(m, {"method": m}) for m in b[(b.track == track) & (b.split == split)]["method"]]
        lines += [
            "",
            f"## Per scene: {split} ({track} track), each cell @50cm / @25cm",
            "",
            paper_table(t, rows, sorted(t["scene"].unique())).rstrip(),
        ]
    # map size per (method, track) and scene, from the per-scene rows (runs without maps have none)
    sizes = scenes.pivot_table(index=["method", "track"], columns="scene", values="map_mb", aggfunc="mean")
    if not sizes.empty:
        rows = [[method, track, *(_fmt("map_mb", v) for v in row)] for (method, track), row in sizes.iterrows()]
        lines += ["", "## Map size per scene [MB]", "", *md_table(["Method", "Track", *sizes.columns], rows)]
    if difficulty_plots:
        lines += ["", "## Recall vs difficulty", "", DIFFICULTY_TEXT, ""]
        lines += [f"![recall vs difficulty]({p})" for p in difficulty_plots]
    return "\n".join(lines) + "\n"


_SORT_JS = """
document.querySelectorAll('table.sortable th').forEach((th, i) => th.addEventListener('click', () => {
  const body = th.closest('table').tBodies[0], asc = th.dataset.dir !== 'asc';
  th.closest('tr').querySelectorAll('th').forEach(h => delete h.dataset.dir); th.dataset.dir = asc ? 'asc' : 'desc';
  const key = td => { const t = td.textContent.trim(), n = t === '∞' ? Infinity : parseFloat(t);
                      return t === '-' ? NaN : (isNaN(n) ? t : n); };
  [...body.rows].sort((a, b) => { const x = key(a.cells[i]), y = key(b.cells[i]);
      if (Number.isNaN(x)) return 1; if (Number.isNaN(y)) return -1;
      return (x > y ? 1 : x < y ? -1 : 0) * (asc ? 1 : -1); }).forEach(r => body.appendChild(r));
}));
"""


def _html_table(title: str, head: list[str], rows: list[list[str]]) -> str:
    """A titled, sortable, horizontally scrolling table."""
    cells = "".join("<tr>" + "".join(f"<td>{html.escape(str(v))}</td>" for v in r) + "</tr>" for r in rows)
    heads = "".join(f"<th>{html.escape(h)}</th>" for h in head)
    return (
        f"<h2>{html.escape(title)}</h2>\n"
        f'<div class="scroll"><table class="sortable"><thead><tr>{heads}</tr></thead><tbody>{cells}</tbody></table></div>\n'
    )


def to_html(b: pd.DataFrame, plots: list[str], versions: str = "", difficulty_plots: Sequence[str] = ()) -> str:
    """The sortable page: the board's verdict, its tables, the robustness table, ``plots`` side by side
    and the recall-vs-difficulty plots full width."""
    head = [BOARD_COLUMNS[c] for c in b.columns]
    tables = "".join(
        _html_table(title, head, [[_fmt(c, r[c]) for c in b.columns] for _, r in t.iterrows()])
        for title, t in _by_track(b)
    )
    drops = robustness_drops(b)
    if not drops.empty:
        tables += _html_table(ROBUSTNESS_TITLE, list(drops.columns), drops.values.tolist())
    imgs = "".join(f'<figure><img src="{html.escape(p)}" alt="{html.escape(p)}"></figure>' for p in plots)
    if difficulty_plots:
        imgs += f'<h2 class="clear">Recall vs difficulty</h2>\n<p>{html.escape(DIFFICULTY_TEXT)}</p>\n'
        imgs += "".join(
            f'<figure><img class="wide" src="{html.escape(p)}" alt="{html.escape(p)}"></figure>'
            for p in difficulty_plots
        )
    return f"""<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>{html.escape(_title(versions))}</title>
<style>
body {{ font-family: system-ui, sans-serif; margin: 2em; color: #222; }}
table {{ border-collapse: collapse; font-size: 14px; }}
.scroll {{ overflow-x: auto; }}
th, td {{ border: 1px solid #ccc; padding: 4px 8px; text-align: right; }}
th {{ background: #f0f0f0; cursor: pointer; user-select: none; }}
th[data-dir=asc]::after {{ content: " ▲"; }} th[data-dir=desc]::after {{ content: " ▼"; }}
td {{ white-space: nowrap; }} td:first-child, td:nth-child(2), td:nth-child(3) {{ text-align: left; }}
tr:nth-child(even) {{ background: #fafafa; }}
img {{ max-width: 48%; float: left; margin: 1%; }}
img.wide {{ max-width: 98%; float: none; }} .clear {{ clear: both; }}
.verdict {{ font-size: 16px; background: #eef4fb; border-left: 4px solid #2a6ebb; padding: 8px 12px; }}
</style></head><body>
<h1>{html.escape(_title(versions))}</h1>
<p class="verdict"><strong>{html.escape(verdict_lead())}:</strong> {html.escape(verdict(b))}</p>
<p>Recall = share of all queries (failed queries count). MTE/MRE = mean error of the queries within the
threshold. Click a column header to sort. {html.escape(provenance(b))}</p>
{tables}{imgs}
<script>{_SORT_JS}</script>
</body></html>
"""


# --------------------------------------------------------------------------------------------
# Plots
# --------------------------------------------------------------------------------------------


def _save(fig: plt.Figure, path: Path) -> None:
    if fig.get_layout_engine() is None:  # a figure made with layout="constrained" keeps it
        fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


TRACK_MARKERS = {"predicted": "o", "oracle-mask": "s", MASK_FREE: "^"}
TRACK_LINES = {"predicted": "-", "oracle-mask": "--", MASK_FREE: "-."}
TRACK_HATCHES = {"predicted": "", "oracle-mask": "///", MASK_FREE: ".."}
"""How the plots tell the tracks apart: the colour is the method's (:func:`method_colors`)."""


def method_colors(methods: Iterable[str]) -> dict[str, tuple[float, ...]]:
    """One colour per method (by name), the same in each plot of a board: tab10's, then tab20b's, so that
    a board of the whole plan (nine methods and openreloc's ablation variants) repeats none."""
    palette = [*plt.get_cmap("tab10").colors, *plt.get_cmap("tab20b").colors]
    return {m: palette[k % len(palette)] for k, m in enumerate(sorted(set(methods)))}


def _style(track: str) -> dict[str, str]:
    return {"marker": TRACK_MARKERS.get(track, "D"), "ls": TRACK_LINES.get(track, ":")}


def plot_cumulative(
    q: pd.DataFrame, col: str, xmax: float, xlabel: str, path: Path, colors: dict[str, Any] | None = None
) -> plt.Axes:
    """Share of queries under each error, one curve per (method, track) on the plain query split: the
    method's colour, the track's line style. Returns the plot."""
    grid = np.linspace(0, xmax, 400)
    s = q[q["split"] == HEADLINE_SPLIT]
    colors = colors or method_colors(s["method"])
    fig, ax = plt.subplots(figsize=(6, 4))
    for (method, track), g in s.groupby(["method", "track"]):
        curve = cumulative_curve(g[col].to_numpy(), grid)
        ax.plot(grid, curve, TRACK_LINES.get(track, ":"), color=colors[method], label=f"{method} ({track})")
    ax.set(xlabel=xlabel, ylabel="queries [%]", ylim=(0, 100), xlim=(0, xmax), title=f"Cumulative {xlabel}")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7 if s.groupby(["method", "track"]).ngroups > 6 else 8)
    _save(fig, path)
    return ax


def plot_scene_recall(scenes: pd.DataFrame, path: Path, colors: dict[str, Any] | None = None) -> plt.Axes:
    """Recall@50cm (light) and @25cm (dark) per scene and (method, track) on the plain query split: the
    method's colour, the track's hatch. Returns the plot."""
    s = scenes[scenes["split"] == HEADLINE_SPLIT]
    runs = sorted({(m, t) for m, t in zip(s["method"], s["track"])}, key=lambda r: (_rank_of(r[1]), r))
    colors = colors or method_colors(s["method"])
    names = sorted(s["scene"].unique())
    x, width = np.arange(len(names)), 0.8 / max(len(runs), 1)
    fig, ax = plt.subplots(figsize=(max(6, 1.2 * len(names) * max(1, len(runs) / 2)), 4))
    for k, (method, track) in enumerate(runs):
        g = s[(s["method"] == method) & (s["track"] == track)].set_index("scene").reindex(names)
        look = {"color": colors[method], "hatch": TRACK_HATCHES.get(track, "xx"), "edgecolor": "white", "lw": 0}
        bars = ax.bar(x + k * width, g["recall_50cm"], width, alpha=0.45, **look)
        ax.bar_label(bars, fmt="%.0f", fontsize=7)
        ax.bar(x + k * width, g["recall_25cm"], width, label=f"{method} ({track})", **look)
    ax.set_xticks(x + width * (len(runs) - 1) / 2, names, rotation=30, ha="right")
    ax.set(ylabel="recall [%]  (light @50cm, dark @25cm)", ylim=(0, 100), title="Recall per scene")
    ax.legend(fontsize=8)
    _save(fig, path)
    return ax


def plot_recall_vs_map_size(suite: pd.DataFrame, path: Path, colors: dict[str, Any] | None = None) -> list[plt.Axes]:
    """The paper's trade-off on the query split, one panel per track (:func:`track_groups`: the methods
    that read no masks in each): every method's R@25cm (filled) and R@50cm (hollow) at its map size per
    scene, joined by a line. A method without a recorded map size (a result scored by ``score``) is drawn
    on the panel's left edge at its recall. Returns the panels (none when no method ran the query split)."""
    s = suite[suite["split"] == HEADLINE_SPLIT]
    groups = track_groups(s)
    colors = colors or method_colors(s["method"])
    fig, grid = plt.subplots(
        1, max(len(groups), 1), figsize=(4.5 * max(len(groups), 1) + 2.5, 4.5), squeeze=False, sharey=True
    )
    sizes = s.loc[s["map_mb"] > 0, "map_mb"]
    xlim = (sizes.min() / 2, sizes.max() * 2) if len(sizes) else (0.1, 10.0)
    for ax, (track, rows) in zip(grid.flat, groups):
        for r in rows.sort_values("method").itertuples():
            label = r.method if r.track == track else f"{r.method} ({r.track})"
            mapped = bool(r.map_mb > 0)  # NaN: no map recorded
            where = {} if mapped else {"transform": ax.get_yaxis_transform(), "clip_on": False}
            x = r.map_mb if mapped else 0.0
            look = {"marker": TRACK_MARKERS.get(r.track, "D"), "color": colors[r.method]}
            ax.plot([x, x], [r.recall_25cm, r.recall_50cm], color=look["color"], lw=1, alpha=0.6, **where)
            ax.scatter(x, r.recall_50cm, marker=look["marker"], facecolors="none", edgecolors=look["color"], **where)
            ax.scatter(
                x, r.recall_25cm, **look, label=label if mapped else f"{label}: no map size, on the axis", **where
            )
        ax.set_xscale("log")
        ax.set_xlim(*xlim)
        ax.xaxis.set_major_formatter(matplotlib.ticker.FuncFormatter(lambda v, _: f"{v:g}"))
        ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        ax.set(xlabel="map size per scene [MB]", ylim=(-3, 103))
        ax.set_title(TRACK_NAMES.get(track, f"{track} track"), fontsize=10)
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.16), ncol=2, frameon=False)
    grid[0][0].set_ylabel("recall [%]  (filled @25cm, hollow @50cm)")
    if not groups:
        grid[0][0].text(
            0.5, 0.5, f"no method ran the {HEADLINE_SPLIT} split", ha="center", transform=grid[0][0].transAxes
        )
    fig.suptitle(f"Recall vs map size ({HEADLINE_SPLIT} split)")
    _save(fig, path)
    return list(grid.flat[: len(groups)])


LIGHT_SPLITS = ("query", "query_light1", "query_light2", "query_light3", "query_light4")
"""The lighting levels in order: the original lighting, then the four decayed variants."""
LIGHT_NAMES = ("original", "light 1", "light 2", "light 3", "light 4")


def plot_recall_vs_lighting(suite: pd.DataFrame, path: Path, colors: dict[str, Any] | None = None) -> list[plt.Axes]:
    """R@50cm (solid) and R@25cm (dashed) per lighting level, for every (method, track) run on any of
    them: the method's colour, the track's marker; a run of one level alone is its points (the legend says
    which). Returns the plot, or nothing (and no file) when no method ran a decayed level."""
    s = suite[suite["split"].isin(LIGHT_SPLITS)]
    if not s["split"].isin(LIGHT_SPLITS[1:]).any():
        return []
    colors = colors or method_colors(s["method"])
    fig, ax = plt.subplots(figsize=(7, 4.5))
    x = np.arange(len(LIGHT_SPLITS))
    runs = sorted(s.groupby(["method", "track"]), key=lambda r: (_rank_of(r[0][1]), r[0]))
    for (method, track), g in runs:
        g = g.set_index("split").reindex(LIGHT_SPLITS)
        ran = g["recall_50cm"].notna().to_numpy()  # a line joins the levels run, skipping the others
        alone = "" if ran.sum() > 1 else f", {LIGHT_NAMES[int(ran.argmax())]} only"
        look = {"marker": TRACK_MARKERS.get(track, "D"), "color": colors[method]}
        ax.plot(x[ran], g["recall_50cm"][ran], "-", **look, label=f"{method} ({track}){alone}")
        ax.plot(x[ran], g["recall_25cm"][ran], "--", **look, mfc="none", alpha=0.7)
    ax.set_xticks(x, LIGHT_NAMES)
    ax.set(xlabel="lighting decay level", ylabel="recall [%]  (solid @50cm, dashed @25cm)", ylim=(-3, 103))
    ax.set_title("Recall vs lighting")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="center left", bbox_to_anchor=(1.0, 0.5))
    _save(fig, path)
    return [ax]


DIFFICULTY_BINS: dict[str, tuple[str, tuple[float, ...] | None]] = {
    "gap_m": ("distance to the nearest mapping camera [m]", (0, 0.25, 0.5, 1, 2, math.inf)),
    "gap_deg": ("rotation to mapping views within 1 m [°]", (0, 10, 20, 45, 90, math.inf)),
    "visible_objects": ("objects in view", (0, 2, 4, 6, 8, 12, math.inf)),
    "light_level": ("light level (1 = mapping lighting)", None),
    "displaced_in_view": ("moved objects in view", (0, 1, 2, 3, math.inf)),
    "lookalikes_in_view": ("objects in view with a look-alike", (0, 1, 2, 3, math.inf)),
    "object_area": ("image share of the objects", (0, 0.1, 0.2, 0.3, 0.5, math.inf)),
}
"""Per difficulty axis: its plot title and bin edges, fixed so boards of different suites and runs bin alike
(the gap bins meet the recall thresholds; None: one bin per value, for the few light levels)."""
BINNED_COLUMNS = ("track", "method", "axis", "bin", "lo", "hi", "n", "recall_50cm", "recall_25cm")


def _bin_labels(edges: np.ndarray, integral: bool) -> list[str]:
    """'lo–hi' per bin [lo, hi) and '≥lo' for an open last one; for integer values the values a bin holds
    ('1', '2–3', '8+')."""
    if integral:
        return [
            f"{a:g}+" if math.isinf(b) else f"{a:g}" if b - a == 1 else f"{a:g}–{b - 1:g}"
            for a, b in zip(edges, edges[1:])
        ]
    return [f"≥{a:g}" if math.isinf(b) else f"{a:g}–{b:g}" for a, b in zip(edges, edges[1:])]


def binned_recall(queries: pd.DataFrame, axis: str, bins: Sequence[float] | None) -> pd.DataFrame:
    """R@50cm and R@25cm of each (track, method) per bin of the difficulty column ``axis`` (columns
    :data:`BINNED_COLUMNS`), over every scene and split the rows hold: which queries a method loses as they
    get harder. ``bins``: increasing edges of the bins [lo, hi), or None for one bin per value (lo = hi).
    ``n`` counts a bin's queries (a run over seeds scores each once per seed, and its recall is their mean);
    rows without a value (scenes without ``difficulty.csv``) and empty bins are left out."""
    if axis not in queries:
        raise ValueError(f"the per-query rows have no column '{axis}'")
    values = queries[axis].astype(float).to_numpy()
    known = ~np.isnan(values)
    if bins is None:
        lo = hi = np.unique(values[known])
        index = np.searchsorted(lo, values)
        labels = [f"{v:g}" for v in lo]
    else:
        edges = np.asarray(bins, dtype=float)
        if edges.ndim != 1 or len(edges) < 2 or np.any(np.isnan(edges)) or np.any(np.diff(edges) <= 0):
            raise ValueError(f"bins of '{axis}' must be two or more increasing edges, got {list(bins)}")
        lo, hi = edges[:-1], edges[1:]
        index = np.searchsorted(edges, values, side="right") - 1
        known &= (index >= 0) & (index < len(lo))
        finite = np.r_[values[known], edges[np.isfinite(edges)]]
        labels = _bin_labels(edges, integral=bool(np.all(finite % 1 == 0)))
    rows = []
    picked = queries[known].assign(_bin=index[known])
    for (track, method, k), g in picked.groupby(["track", "method", "_bin"]):
        m = summarize(g["t_err_m"].to_numpy(), g["r_err_deg"].to_numpy())
        n = len(g[["scene", "split", "query"]].drop_duplicates())
        rows.append((track, method, axis, labels[k], lo[k], hi[k], n, m["recall_50cm"], m["recall_25cm"]))
    return pd.DataFrame(rows, columns=list(BINNED_COLUMNS))


def difficulty_table(q: pd.DataFrame) -> pd.DataFrame:
    """:func:`binned_recall` on every axis of :data:`DIFFICULTY_BINS`, one after the other."""
    return pd.concat([binned_recall(q, axis, bins) for axis, (_, bins) in DIFFICULTY_BINS.items()], ignore_index=True)


def plot_recall_vs_difficulty(
    binned: pd.DataFrame, title: str, path: Path, colors: dict[str, Any] | None = None
) -> list[str]:
    """One panel per difficulty axis of ``binned`` (:func:`binned_recall` rows) with more than one bin:
    R@50cm (solid) and R@25cm (dashed) per bin, one colour per method, each bin's query count under its
    label. Returns the axes drawn; none (and no file) when no axis has two bins (all queries alike, or no
    difficulty known)."""
    axes = [a for a in DIFFICULTY_BINS if binned.loc[binned["axis"] == a, "bin"].nunique() > 1]
    if not axes:
        return []
    ncols = min(len(axes), 4)
    fig, grid = plt.subplots(
        math.ceil(len(axes) / ncols), ncols, figsize=(3.6 * ncols, 3.3 * math.ceil(len(axes) / ncols)), squeeze=False
    )
    methods = sorted(binned["method"].unique())
    colors = colors or method_colors(methods)
    for ax, axis in zip(grid.flat, axes):
        a = binned[binned["axis"] == axis]
        bins = a.groupby("bin").agg(lo=("lo", "first"), n=("n", "max")).sort_values("lo")
        x = np.arange(len(bins))
        for method in methods:
            g = a[a["method"] == method].set_index("bin").reindex(bins.index)
            ax.plot(x, g["recall_50cm"], "-", marker="o", ms=3, color=colors[method])
            ax.plot(x, g["recall_25cm"], "--", marker="o", ms=3, mfc="none", color=colors[method], alpha=0.7)
        ax.set_xticks(x, [f"{b}\nn={n}" for b, n in zip(bins.index, bins["n"])], fontsize=7)
        ax.set(ylim=(-3, 103), title=DIFFICULTY_BINS[axis][0])  # lines at 0 and 100 stay visible
        ax.title.set_fontsize(9)
        ax.grid(alpha=0.3)
    for row in grid:
        row[0].set_ylabel("recall [%]")
    for ax in grid.flat[len(axes) :]:
        ax.axis("off")
    Line2D = matplotlib.lines.Line2D
    handles = [Line2D([], [], color=colors[m], marker="o", ms=3, label=m) for m in methods]
    handles += [Line2D([], [], color="0.4", ls=ls, label=f"R@{t}") for ls, t in (("-", "50cm"), ("--", "25cm"))]
    grid[0][-1].legend(handles=handles, fontsize=7, loc="upper left", bbox_to_anchor=(1.02, 1.0))
    fig.suptitle(f"Recall vs difficulty, {title}: all query splits pooled")
    _save(fig, path)
    return axes


TOPDOWN_MARGIN_M = 0.5
"""How far a top-down plot reaches beyond the building; an estimate farther out is drawn at the plot's
edge and counted as outside."""
TOPDOWN_VIEW_MARGIN_M = 2.0
"""The same beyond the true cameras, for a scene whose plan is unknown."""
RECALL_RADIUS_M = 0.5


def topdown_extent(gt_xy: np.ndarray, scene: Scene | None = None) -> tuple[np.ndarray, np.ndarray, str]:
    """(min xy, max xy, what it is) of a top-down plot: the building's plan and the true cameras with
    :data:`TOPDOWN_MARGIN_M` around when the scene is known ("building"), else the true cameras with
    :data:`TOPDOWN_VIEW_MARGIN_M` ("view")."""
    pts = np.asarray(gt_xy, dtype=np.float64).reshape(-1, 2)
    pts = pts[np.isfinite(pts).all(axis=1)]
    what, margin = "view", TOPDOWN_VIEW_MARGIN_M
    if scene is not None:
        from generators.preview import plan_extent  # the generator only where a board draws a scene

        extent = plan_extent(scene)
        if extent is not None:
            pts, what, margin = np.vstack([pts, *extent]), "building", TOPDOWN_MARGIN_M
    if not len(pts):
        return np.full(2, -margin), np.full(2, margin), what
    return pts.min(axis=0) - margin, pts.max(axis=0) + margin, what


def clip_to_extent(xy: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``xy`` (N, 2) clipped into the box [lo, hi], and which points were outside it."""
    xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    drawn = np.clip(xy, lo, hi)
    return drawn, np.any(drawn != xy, axis=1)


def plot_topdown(q: pd.DataFrame, scene: str, path: Path, scene_data: Scene | None = None) -> list[plt.Axes]:
    """True vs estimated camera positions (x, y) on the plain query split, one panel per (method, track),
    a line from each truth to its estimate; over the scene's floor plan when ``scene_data`` is given.

    An estimate outside the building (or, without the scene, far from every true camera) is drawn at the
    panel's edge with its own marker and counted in the legend. Returns the panels."""
    s = q[(q["scene"] == scene) & (q["split"] == "query")]
    runs = sorted({(m, t) for m, t in zip(s["method"], s["track"])})
    ncols = min(len(runs), 4)
    nrows = math.ceil(len(runs) / ncols)
    fig, grid = plt.subplots(
        nrows, ncols, figsize=(4.4 * ncols, 5.4 * nrows + 0.8), squeeze=False, layout="constrained"
    )
    lo, hi, where = topdown_extent(s[["gt_x", "gt_y"]].to_numpy(), scene_data)
    plan: dict[str, matplotlib.artist.Artist] = {}
    panels = list(grid.flat[: len(runs)])
    for ax, (method, track) in zip(panels, runs):
        g = s[(s["method"] == method) & (s["track"] == track)]
        if scene_data is not None:
            from generators.preview import draw_floor, floor_index

            for f in sorted(set(floor_index(scene_data, g["gt_z"].to_numpy()).tolist())):
                for h in draw_floor(ax, scene_data, f, room_names=False, displaced=False):
                    plan.setdefault(h.get_label(), h)
        ok = g[g["success"]]
        drawn, outside = clip_to_extent(ok[["est_x", "est_y"]].to_numpy(), lo, hi)
        ax.plot(np.c_[ok["gt_x"], drawn[:, 0]].T, np.c_[ok["gt_y"], drawn[:, 1]].T, color="0.35", lw=0.7, zorder=8)
        ax.scatter(g["gt_x"], g["gt_y"], s=14, c="tab:green", zorder=9, label=f"true position ({len(g)})")
        inside = drawn[~outside]
        ax.scatter(
            inside[:, 0], inside[:, 1], s=14, c="tab:red", marker="x", zorder=10, label=f"estimate ({len(inside)})"
        )
        if outside.any():
            ax.scatter(
                drawn[outside, 0],
                drawn[outside, 1],
                s=45,
                c="darkred",
                marker="X",
                clip_on=False,
                zorder=11,
                label=f"estimate outside the {where} ({int(outside.sum())}), drawn at the edge",
            )
        failed = g[~g["success"]]
        ax.scatter(
            failed["gt_x"],
            failed["gt_y"],
            s=40,
            facecolors="none",
            edgecolors="k",
            zorder=9,
            label=f"no pose returned ({len(failed)})",
        )
        within = int((ok["t_err_m"] < RECALL_RADIUS_M).sum())
        ax.set_title(f"{method} ({track})\n{len(ok)}/{len(g)} returned a pose, {within} within 50 cm", fontsize=9)
        ax.set(xlabel="x [m]", ylabel="y [m]", xlim=(lo[0], hi[0]), ylim=(lo[1], hi[1]))
        ax.set_aspect("equal", adjustable="box")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=6, loc="upper center", bbox_to_anchor=(0.5, -0.13), ncol=2, frameon=False)
    for ax in grid.flat[len(runs) :]:
        ax.axis("off")
    if plan:
        fig.legend(handles=list(plan.values()), loc="outside lower center", ncol=min(len(plan), 5), fontsize=7)
    over = " over its floor plan" if plan else ""
    fig.suptitle(f"{scene}: camera positions, top-down{over}")
    _save(fig, path)
    return panels


def board_scene(data: Path | None, name: str, spec_hashes: Sequence[str] = ()) -> Scene | None:
    """Scene ``name`` under ``data``, whose floor plan a top-down plot draws; None (the plot goes without,
    with a warning where it was expected) when there is no ``data``, no such scene, an unreadable one, or
    one of another spec than the runs' (``spec_hashes``: its plan would not be theirs)."""
    if data is None:
        return None
    root = Path(data) / name
    if Path(name).name != name or not (root / "scene.json").is_file():
        log.warning("no scene %s under %s: its top-down plot has no floor plan", name, data)
        return None
    try:
        scene = Scene(root)
    except DataError as e:
        log.warning("%s: its top-down plot has no floor plan", e)
        return None
    others = sorted({h for h in spec_hashes if isinstance(h, str)} - {scene.spec_hash})
    if others:
        log.warning(
            "%s is spec %s, the runs' is %s: its top-down plot has no floor plan", root, scene.spec_hash, others[0]
        )
        return None
    return scene


def write_leaderboard(results: list[Path], out: Path, data: Path | None = None) -> list[Path]:
    """Render everything into ``out`` (never inside or around a results directory); returns the files written.
    ``data``: the dataset directory, for each scene's floor plan under its top-down plot."""
    q = recorded_tracks(pool_seeds(load_queries(results)))  # pooled first: seeded runs carry the method's name
    for r in results:
        paths.check_output(out, [r], "--out")
    scenes, suite = build_tables(q, load_maps(results))
    b = board(suite)
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
    plot_recall_vs_map_size(suite, plots[-1], colors)
    if plot_recall_vs_lighting(suite, plots_dir / "recall_vs_lighting.png", colors):
        plots.append(plots_dir / "recall_vs_lighting.png")
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
    io.atomic_write_text(out / "leaderboard.csv", suite.to_csv(index=False))
    io.atomic_write_text(out / "difficulty.csv", binned.to_csv(index=False))
    io.atomic_write_text(out / "leaderboard.md", to_markdown(b, scenes, versions, rel))
    io.atomic_write_text(out / "index.html", to_html(b, [str(p.relative_to(out)) for p in plots], versions, rel))
    return [
        out / "leaderboard.md",
        out / "leaderboard.csv",
        out / "difficulty.csv",
        out / "index.html",
        *plots,
        *difficulty_plots,
    ]
