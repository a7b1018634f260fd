"""A board's pages: the markdown board and the static HTML page with sortable tables and the plots."""

from __future__ import annotations

import html
import re
from collections.abc import Sequence
from pathlib import Path

import pandas as pd

from openreloc_bench.harness.ablations import ABLATED_METHOD
from openreloc_bench.harness.leaderboard.rows import (
    BOARD_COLUMNS,
    HEADLINE_SPLIT,
    ROBUSTNESS_TITLE,
    TRACK_TITLES,
    board_cell,
    format_cell,
    provenance,
    shown_columns,
    track_groups,
    track_rank,
)
from openreloc_bench.harness.leaderboard.verdict import verdict, verdict_lead
from openreloc_bench.harness.tables import md_table, paper_table
from openreloc_bench.methods import method_reference
from openreloc_bench.tracks import MASK_FREE


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


def _title(versions: str) -> str:
    return f"openreloc-bench leaderboard ({versions})" if versions else "openreloc-bench leaderboard"


DIFFICULTY_TEXT = (
    "R@50cm (solid) and R@25cm (dashed) per bin of each query's difficulty (from its scene's difficulty.csv), "
    "pooled over every scene and query split each method ran; n = queries in the bin. The numbers are in "
    "difficulty.csv."
)


def _ablation_links(ablations: Sequence[str]) -> list[tuple[str, str]]:
    """(track, path) of each ablation table (``ablations_<track>.md``, a path relative to the board)."""
    return [(Path(p).stem.removeprefix("ablations_"), p) for p in ablations]


WHY_CAPTIONS = {
    "headline_recall.png": "The verdict's numbers with their 95% intervals. The verdict weighs a lead on the "
    "same queries (paired.csv), which is sharper than comparing these whiskers: scenes differ more than methods.",
    "cumulative_translation.png": "Where the methods part: the share of queries within each translation "
    "error. A curve that rises late is coarse; one that levels off low fails often.",
    "recall_vs_lighting.png": "What the light takes: recall as the query splits darken.",
}
"""The plots that explain a verdict, shown first ("Why", in the board's order of its plots), with what to
read off each."""


def _why_markdown(why: Sequence[str]) -> list[str]:
    lines = ["", "## Why", ""]
    for p in why:
        lines += [f"![{Path(p).stem}]({p})", "", WHY_CAPTIONS.get(Path(p).name, ""), ""]
    return lines[:-1]


def to_markdown(
    b: pd.DataFrame,
    scenes: pd.DataFrame,
    versions: str = "",
    difficulty_plots: Sequence[str] = (),
    card: str = "",
    drops: pd.DataFrame | None = None,
    ablations: Sequence[str] = (),
    why: Sequence[str] = (),
    paired: pd.DataFrame | None = None,
) -> str:
    """The board: its verdict (:func:`verdict`, weighed on the same queries with ``paired``), the plots that explain it (``why``, :data:`WHY_CAPTIONS`),
    links to the data's ``card`` and to the ``ablations``
    tables (paths relative to the board, where there are some), one table per track (the predicted
    track's first), the robustness table (``drops``: :func:`~.rows.robustness_drops`), per-scene tables,
    map sizes and the recall-vs-difficulty plots (``difficulty_plots``, paths relative to the board)."""
    shown = shown_columns(b)
    head = [BOARD_COLUMNS[c] for c in shown]
    lines = [
        f"# {_title(versions)}",
        "",
        f"**{verdict_lead()}:** {verdict(b, paired=paired)}",
        "",
        "Recall = share of all queries (failures count), with its 95% interval (bootstrap over scenes, then queries); "
        "MTE/MRE = mean error of the queries within the threshold.",
        "",
        provenance(b)
        + (f" The data: [its dataset card]({card})." if card else "")
        + "".join(f" Ablations of {ABLATED_METHOD}, {t} track: [{p}]({p})." for t, p in _ablation_links(ablations)),
    ]
    if why:
        lines += _why_markdown(why)
    for title, t in _by_track(b):
        lines += [
            "",
            f"## {title}",
            "",
            *md_table(head, [[board_cell(r, c) for c in shown] for _, r in t.iterrows()]),
        ]
    if drops is not None and not drops.empty:
        lines += ["", f"## {ROBUSTNESS_TITLE}", "", *md_table(list(drops.columns), drops.values.tolist())]
    scenes = scenes.assign(_rank=scenes["track"].map(track_rank)).sort_values(["_rank", "split"], kind="stable")
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
        rows = [[method, track, *(format_cell("map_mb", v) for v in row)] for (method, track), row in sizes.iterrows()]
        lines += ["", "## Map size per scene [MB]", "", *md_table(["Method", "Track", *sizes.columns], rows)]
    if difficulty_plots:
        lines += ["", "## Recall vs difficulty", "", DIFFICULTY_TEXT, ""]
        lines += [f"![recall vs difficulty]({p})" for p in difficulty_plots]
    lines += ["", "## Methods", "", *md_table(["Method", "Paper and code"], method_references(b))]
    return "\n".join(lines) + "\n"


def method_references(b: pd.DataFrame) -> list[list[str]]:
    """``[method, the paper and code it follows]`` for each method of the board (:func:`method_reference`)."""
    return [[m, method_reference(m) or "-"] for m in sorted(set(b["method"]))]


_URL = re.compile(r"https?://\S+")


def _linked(text: str) -> str:
    """``text`` escaped for HTML, its web addresses as links."""
    parts = _URL.split(text)
    links = [f'<a href="{html.escape(u)}">{html.escape(u)}</a>' for u in _URL.findall(text)]
    return "".join(html.escape(p) + (links[k] if k < len(links) else "") for k, p in enumerate(parts))


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
    return f"<h2>{html.escape(title)}</h2>\n{_sortable(head, rows)}"


def _sortable(head: list[str], rows: list[list[str]]) -> str:
    cells = "".join("<tr>" + "".join(f"<td>{html.escape(str(v))}</td>" for v in r) + "</tr>" for r in rows)
    heads = "".join(f"<th>{html.escape(h)}</th>" for h in head)
    return f'<div class="scroll"><table class="sortable"><thead><tr>{heads}</tr></thead><tbody>{cells}</tbody></table></div>\n'


def _track_table(title: str, head: list[str], t: pd.DataFrame, shown: list[str]) -> str:
    """A track's table: the headline split's rows, the other splits' folded under them."""
    rows = {
        headline: [[board_cell(r, c) for c in shown] for _, r in part.iterrows()]
        for headline, part in t.groupby(t["split"] == HEADLINE_SPLIT)
    }
    text = f"<h2>{html.escape(title)}</h2>\n"
    if True in rows:
        text += _sortable(head, rows[True])
    if False in rows:
        text += f"<details><summary>The other splits ({len(rows[False])} rows)</summary>\n{_sortable(head, rows[False])}</details>\n"
    return text


WIDE_PLOTS = ("recall_per_scene", "topdown_")
"""Plots as wide as the page: a bar group per scene, a panel per split."""


def _figure(path: str, wide: bool) -> str:
    """A plot that opens at full size when clicked."""
    p = html.escape(path)
    return f'<figure><a href="{p}"><img{" class=wide" if wide else ""} src="{p}" alt="{p}"></a></figure>'


def to_html(
    b: pd.DataFrame,
    plots: list[str],
    versions: str = "",
    difficulty_plots: Sequence[str] = (),
    card: str = "",
    drops: pd.DataFrame | None = None,
    ablations: Sequence[str] = (),
    why: Sequence[str] = (),
    paired: pd.DataFrame | None = None,
) -> str:
    """The sortable page: the board's verdict (weighed on the same queries with ``paired``), the plots that explain it (``why``), links to the data's
    ``card`` and the ``ablations`` tables, its tables (the headline split's rows first, the others folded),
    the robustness table (``drops``), the other ``plots`` side by side and the recall-vs-difficulty plots
    full width."""
    shown = shown_columns(b)
    head = [BOARD_COLUMNS[c] for c in shown]
    tables = "".join(_track_table(title, head, t, shown) for title, t in _by_track(b))
    if drops is not None and not drops.empty:
        tables += _html_table(ROBUSTNESS_TITLE, list(drops.columns), drops.values.tolist())
    imgs = "".join(_figure(p, wide=Path(p).name.startswith(WIDE_PLOTS)) for p in plots if p not in why)
    why_html = "".join(
        f"<div class=why>{_figure(p, wide=False)}<p>{html.escape(WHY_CAPTIONS.get(Path(p).name, ''))}</p></div>"
        for p in why
    )
    if why_html:
        why_html = f'<h2>Why</h2>\n<div class="whys">{why_html}</div>\n'
    if difficulty_plots:
        imgs += f'<h2 class="clear">Recall vs difficulty</h2>\n<p>{html.escape(DIFFICULTY_TEXT)}</p>\n'
        imgs += "".join(_figure(p, wide=True) for p in difficulty_plots)
    cited = "".join(f"<li><b>{html.escape(m)}</b>: {_linked(ref)}</li>" for m, ref in method_references(b))
    imgs += f'<h2 class="clear">Methods</h2>\n<ul>{cited}</ul>\n'
    card_link = f' The data: <a href="{html.escape(card)}">its dataset card</a>.' if card else ""
    card_link += "".join(
        f' Ablations of {ABLATED_METHOD}, {html.escape(t)} track: <a href="{html.escape(p)}">{html.escape(p)}</a>.'
        for t, p in _ablation_links(ablations)
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
.whys {{ display: flex; flex-wrap: wrap; gap: 1em; }} .why {{ flex: 1 1 30%; min-width: 320px; }}
.why img {{ max-width: 100%; float: none; margin: 0; }} .why p {{ margin: 0.2em 0; font-size: 14px; }}
</style></head><body>
<h1>{html.escape(_title(versions))}</h1>
<p class="verdict"><strong>{html.escape(verdict_lead())}:</strong> {html.escape(verdict(b, paired=paired))}</p>
<p>Recall = share of all queries (failed queries count), with its 95% interval (bootstrap over scenes, then
queries). MTE/MRE = mean error of the queries within the threshold. Click a column header to sort. {html.escape(provenance(b))}{card_link}</p>
{why_html}{tables}{imgs}
<script>{_SORT_JS}</script>
</body></html>
"""
