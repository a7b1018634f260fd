"""The board's rows: the per-query rows of results folders under the tracks their runs recorded, the
suite rows in the board's order and cut per track, the robustness changes, the provenance line, and
recall per bin of each query difficulty (the numbers of ``difficulty.csv``)."""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from openreloc_bench.data.runs import QUERY_COLUMNS, backfill_difficulty, load_map_records, read_query_csv
from openreloc_bench.data.splits import DISPLACED_SPLIT, PLAIN_SPLIT
from openreloc_bench.errors import DataError
from openreloc_bench.harness.ablations import ROBUSTNESS_ROWS
from openreloc_bench.harness.metrics import RECALLS, hits, paired_difference, summarize
from openreloc_bench.harness.tables import SCENE_KEYS
from openreloc_bench.methods import uses_masks
from openreloc_bench.tracks import MASK_FREE

BOARD_COLUMNS = {
    "method": "Method", "track": "Track", "split": "Split", "n_scenes": "Scenes", "n_seeds": "Seeds", "n_queries": "Queries",
    "recall_100cm": "R@100cm [%]", "recall_50cm": "R@50cm [%]", "recall_25cm": "R@25cm [%]",
    "recall_25cm_5deg": "R@25cm,5° [%]",
    "recall_10cm_10deg": "R@10cm,10° [%]", "recall_5cm_5deg": "R@5cm,5° [%]", "recall_vcre": "VCRE<90px [%]",
    "auc_25cm_5deg": "AUC@25cm,5° [%]", "mte_50cm_m": "MTE@50 [m]", "mre_50cm_deg": "MRE@50 [°]",
    "mte_25cm_m": "MTE@25 [m]", "mre_25cm_deg": "MRE@25 [°]", "median_te_m": "Median TE [m]",
    "median_re_deg": "Median RE [°]", "map_mb": "Map [MB]", "mapping_time_s": "Mapping [s]",
    "latency_median_s": "Latency med [ms]", "latency_p90_s": "Latency p90 [ms]", "git_commit": "Commit",
}  # fmt: skip
FORMATS = {
    "recall": "{:.1f}",
    "auc": "{:.1f}",
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


def track_rank(track: str) -> int:
    """Where ``track`` stands in the board's order (:data:`TRACK_TITLES`); other tracks after them."""
    order = list(TRACK_TITLES)
    return order.index(track) if track in order else len(order)


TRACK_NAMES = {
    "predicted": "Predicted track",
    "oracle-mask": "Oracle-mask track",
    MASK_FREE: "Both tracks (no method reads masks)",
}
"""What the verdict calls each track's comparison (:func:`track_groups`)."""


HEADLINE_SPLIT = PLAIN_SPLIT
"""The split a board's verdict reads (the other splits are the robustness variants of it)."""


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
    """Size and build time of every map cached under the results directories."""
    return pd.concat([load_map_records(r) for r in results], ignore_index=True)


def format_cell(col: str, v: object) -> str:
    """A value of column ``col`` as the board prints it (:data:`FORMATS`; ``-`` for none, ``∞`` for infinite)."""
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
    within each (track, split). Every recall's 95% interval rides along (``_lo`` / ``_hi``), which the
    verdict reads and :func:`board_cell` prints beside its recall."""
    b = suite.assign(_rank=suite["track"].map(track_rank))
    b = b.sort_values(["_rank", "split", "recall_25cm", "recall_50cm"], ascending=[True, True, False, False])
    bounds = [
        f"{k}_{end}" for k in BOARD_COLUMNS if k.startswith("recall") for end in ("lo", "hi") if f"{k}_{end}" in b
    ]
    b = b[[c for c in BOARD_COLUMNS if c in b] + bounds].copy()
    b[["latency_median_s", "latency_p90_s"]] *= 1000.0  # shown in ms
    b["git_commit"] = b["git_commit"].astype(str).str.slice(0, 12)
    return b


def board_cell(row: pd.Series, col: str) -> str:
    """``row``'s value of ``col`` as a page prints it: :func:`format_cell`, and a recall with its 95%
    interval where the row has one (``66.7 [61.2, 72.1]``)."""
    cell = format_cell(col, row[col])
    lo, hi = row.get(f"{col}_lo", math.nan), row.get(f"{col}_hi", math.nan)
    return cell if pd.isna(lo) or pd.isna(hi) else f"{cell} [{lo:.1f}, {hi:.1f}]"


def shown_columns(b: pd.DataFrame) -> list[str]:
    """The columns of :func:`board` rows a page prints (the intervals' bounds are printed inside their
    recall's cell)."""
    return [c for c in b.columns if c in BOARD_COLUMNS]


def track_groups(rows: pd.DataFrame) -> list[tuple[str, pd.DataFrame]]:
    """``rows`` (with a ``track`` column) per track, in the board's order (:data:`TRACK_TITLES`), each
    with the rows of the methods that read no masks, which stand in every track; those rows alone, under
    ``MASK_FREE``, when no method ran on a track."""
    free = rows[rows["track"] == MASK_FREE]
    tracks = sorted(set(rows["track"]) - {MASK_FREE}, key=lambda t: (track_rank(t), t))
    groups = [(t, pd.concat([rows[rows["track"] == t], free])) for t in tracks]
    return groups if groups or free.empty else [(MASK_FREE, free)]


PAIRED_COLUMNS = ("recall_50cm", "recall_25cm")
"""The recalls the verdict weighs, and :func:`paired_differences` compares."""


def paired_differences(q: pd.DataFrame, split: str = HEADLINE_SPLIT) -> pd.DataFrame:
    """Every two methods of a track (those that read no masks stand in each) compared on the queries of
    ``split`` both answered: ``diff`` = ``method``'s recall minus ``other``'s in points (seeds averaged per
    query), with its 95% interval (:func:`~openreloc_bench.harness.metrics.paired_difference`). One row
    per (track, method, other, recall column), both orders: the second is the first negated."""
    rows = []
    s = q[q["split"] == split]
    for track, group in track_groups(s):
        inside = pd.DataFrame(
            hits(group["t_err_m"].to_numpy(), group["r_err_deg"].to_numpy()), columns=RECALLS, index=group.index
        )
        keyed = inside[list(PAIRED_COLUMNS)].assign(method=group["method"], scene=group["scene"], query=group["query"])
        shares = keyed.groupby(["method", "scene", "query"])[list(PAIRED_COLUMNS)].mean()  # seeds averaged
        for col in PAIRED_COLUMNS:
            table = shares[col].unstack(0)
            for a, b in itertools.combinations(sorted(table.columns), 2):
                both = table[[a, b]].dropna()
                if both.empty:
                    continue
                diff, lo, hi = paired_difference(
                    both[a].to_numpy(), both[b].to_numpy(), both.index.get_level_values("scene").to_numpy()
                )
                for m, other, sign in ((a, b, 1), (b, a, -1)):
                    low, high = sorted((sign * lo, sign * hi))
                    rows.append((track, m, other, col, sign * diff, low, high, len(both)))
    return pd.DataFrame(rows, columns=["track", "method", "other", "column", "diff", "lo", "hi", "n_queries"])


def recorded_tracks(q: pd.DataFrame) -> pd.DataFrame:
    """The queries under the track their run recorded (``MASK_FREE`` for methods that declared they read
    no masks: their rows stand in both tracks' tables), one run per query. Tables written before the
    track was recorded that way (no ``uses_masks`` value) are read by the rule the board used then: a
    method registered here as reading no masks (``leaderboard --plugin`` registers a plugin's) is
    ``MASK_FREE``, any other keeps its track."""
    legacy = q["uses_masks"].isna() if "uses_masks" in q else pd.Series(True, index=q.index)
    free = {m for m in q.loc[legacy, "method"].unique() if not uses_masks(m)}
    return _last_run_per_query(q.assign(track=q["track"].mask(legacy & q["method"].isin(free), MASK_FREE)))


def _recalls(q: pd.DataFrame) -> tuple[float, float]:
    """R@50cm and R@25cm [%] of the queries ``q``."""
    m = summarize(q["t_err_m"].to_numpy(), q["r_err_deg"].to_numpy())
    return m["recall_50cm"], m["recall_25cm"]


def _seeds(q: pd.DataFrame) -> set[int]:
    """The seeds the queries ``q`` ran with (none for runs that were not run over seeds)."""
    return set(q["seed"].dropna().astype(int)) if "seed" in q else set()


def robustness_drops(q: pd.DataFrame) -> pd.DataFrame:
    """Per (method, track) of the per-query rows ``q``: recall on the plain query split and its change on
    every robustness split (points of R@50cm / R@25cm; negative = lost), each against the query split over
    the seeds that variant ran, so a variant run on seed 0 is not set against a mean over three seeds (a
    change that cannot be, the query split lacking the variant's seeds, says over which). Methods run on
    the query split alone have no row."""
    rows = []
    for (method, track), g in q.groupby(["method", "track"], sort=False):
        splits = dict(tuple(g.groupby("split")))
        variants = [r.key for r in ROBUSTNESS_ROWS[1:] if r.key in splits]
        if HEADLINE_SPLIT not in splits or not variants:
            continue
        query = splits[HEADLINE_SPLIT]
        r50, r25 = _recalls(query)
        row = {"Method": method, "Track": track, HEADLINE_SPLIT: f"{r50:.1f} / {r25:.1f}"}
        for key in variants:
            variant = splits[key]
            seeds = _seeds(variant)
            same = query[query["seed"].isin(seeds)] if seeds else query
            base = same if len(same) else query
            seen = ""
            if key == DISPLACED_SPLIT:
                variant, base, seen = _seeing_a_change(variant, base)
            if variant.empty or base.empty:
                row[key] = "no query sees a change"
                continue
            (v50, v25), (b50, b25) = _recalls(variant), _recalls(base)
            other = "" if _seeds(base) == seeds else f" (query split over seed(s) {sorted(_seeds(base))})"
            row[key] = f"{v50 - b50:+.1f} / {v25 - b25:+.1f}{seen}{other}"
        rows.append(((track_rank(track), -r25, -r50), row))  # the board's order: by track, best first
    cols = ["Method", "Track", HEADLINE_SPLIT, *(r.key for r in ROBUSTNESS_ROWS[1:])]
    drops = pd.DataFrame([row for _, row in sorted(rows, key=lambda r: r[0])], columns=cols)
    return drops.dropna(axis=1, how="all").fillna("-")


def _frame(q: pd.DataFrame) -> pd.Series:
    """The frame id of each per-query row ('query_displaced/000007' -> '000007'): one view across splits."""
    return q["query"].str.rsplit("/", n=1).str[-1]


def _seeing_a_change(displaced: pd.DataFrame, query: pd.DataFrame) -> tuple[pd.DataFrame, pd.DataFrame, str]:
    """The displaced split's queries whose view holds a change (``displaced_in_view`` > 0), the query split's
    rows of the same views, and a note of how many views that is: a change no query sees cannot cost
    recall. Rows without the column (imported data) are kept whole, without a note."""
    if "displaced_in_view" not in displaced or displaced["displaced_in_view"].isna().all():
        return displaced, query, ""
    changed = displaced[displaced["displaced_in_view"] > 0]
    views = set(zip(changed["scene"], _frame(changed)))
    same = [(s, f) in views for s, f in zip(query["scene"], _frame(query))]
    return changed, query[same], f" ({len(views)} views see a change)"


ROBUSTNESS_TITLE = (
    "Robustness: R@50cm / R@25cm on the query split, and their change on each variant against the same seeds"
    " (query_displaced: on the views that see a change, against the same views of the query split) [points]"
)


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


DIFFICULTY_BINS: dict[str, tuple[str, tuple[float, ...] | None]] = {
    "gap_m": ("distance to the nearest mapping camera [m]", (0, 0.25, 0.5, 1, 2, math.inf)),
    "gap_deg": ("rotation to mapping views within 1 m [°]", (0, 10, 20, 45, 90, math.inf)),
    "visible_objects": ("objects in view", (0, 1, 2, 3, 4, 6, 8, 12, math.inf)),
    "light_level": ("light level (1 = mapping lighting)", None),
    "displaced_in_view": ("changes in view (moved, added, removed objects)", (0, 1, 2, 3, math.inf)),
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
        if np.isposinf(edges[-1]):  # an open last bin holds infinity too
            index[np.isposinf(values)] = len(lo) - 1
        known &= (index >= 0) & (index < len(lo))
        finite = np.r_[values[known & np.isfinite(values)], edges[np.isfinite(edges)]]
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
