"""Metric tables (pandas) from per-query rows: per scene, per suite, and the paper's layouts.

The per-suite table pools all queries of all scenes (each query weighs the same), the way a
recall over a dataset is read; ``n_scenes`` says how many scenes a row covers, so rows of methods
run on different scene sets are not mistaken for comparable.

A variant run over several seeds (``eval --seeds``) has one row per seed (``<variant>@seed<N>``) in
these tables, a ``seeds`` table with each metric's spread over the seeds, and one pooled row in the
paper's tables and the leaderboard (:func:`pool_seeds`).
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from openreloc_bench.data import io
from openreloc_bench.harness.ablations import ABLATION_ROWS, FULL_ROW, ROBUSTNESS_ROWS, ablation_label
from openreloc_bench.harness.metrics import INTERVAL_COLUMNS, METRIC_COLUMNS, RECALLS, hits, recall_intervals, summarize

SCENE_KEYS = ["method", "track", "scene", "split"]
SUITE_KEYS = ["method", "track", "split"]
EXTRA_COLUMNS = ("n_scenes", "n_seeds", "map_mb", "mapping_time_s", "latency_median_s", "latency_p90_s")
COMPACT_COLUMNS = {
    "recall_50cm": "R@50cm% [95% CI]", "recall_25cm": "R@25cm% [95% CI]", "recall_25cm_5deg": "R@25cm,5°%",
    "recall_5cm_5deg": "R@5cm,5°%", "recall_vcre": "VCRE<90px%", "median_te_m": "med TE[m]",
    "median_re_deg": "med RE[°]", "auc_25cm_5deg": "AUC%", "map_mb": "map MB", "latency_median_ms": "lat[ms]",
}  # fmt: skip
WITH_INTERVAL = ("recall_50cm", "recall_25cm")
"""The recalls ``eval``'s summary prints with their intervals (the tables hold every recall's)."""


def metric_table(queries: pd.DataFrame, keys: list[str], maps: pd.DataFrame) -> pd.DataFrame:
    """One row per group of ``keys``: the paper's metrics, map size/time and query latency."""
    rows = []
    for key, g in queries.groupby(keys, sort=True):
        row: dict[str, Any] = dict(zip(keys, key))
        t, r, reproj = g["t_err_m"].to_numpy(), g["r_err_deg"].to_numpy(), _optional(g, "reproj_err_px")
        row.update(summarize(t, r, reproj, _optional(g, "confidence")))
        row["n_queries"], row["n_failed"] = int(row["n_queries"]), int(row["n_failed"])
        intervals = recall_intervals(hits(t, r, reproj), g["scene"].to_numpy())
        row.update({f"{k}_{end}": intervals[j, e] for j, k in enumerate(RECALLS) for e, end in enumerate(("lo", "hi"))})
        if reproj is None:
            row["recall_vcre_lo"] = row["recall_vcre_hi"] = math.nan
        scene_maps = maps.merge(g[["map_hash", "scene"]].drop_duplicates(), on=["map_hash", "scene"])
        row["n_scenes"] = int(g["scene"].nunique())
        row["n_seeds"] = max(1, int(g["seed"].nunique())) if "seed" in g else 1
        row["map_mb"] = float(scene_maps["map_mb"].mean()) if len(scene_maps) else math.nan
        row["mapping_time_s"] = float(scene_maps["mapping_time_s"].mean()) if len(scene_maps) else math.nan
        lat = g["runtime_s"].to_numpy(dtype=float)
        lat = lat[np.isfinite(lat)]
        row["latency_median_s"] = float(np.median(lat)) if lat.size else math.nan
        row["latency_p90_s"] = float(np.percentile(lat, 90)) if lat.size else math.nan
        for col in ("config_hash", "spec_hash", "git_commit"):
            row[col] = ",".join(sorted(set(map(str, g[col]))))
        versions = g["data_version"].dropna().unique() if "data_version" in g else []
        row["data_version"] = ",".join(f"{v:g}" for v in sorted(versions))  # empty: scenes that name none
        rows.append(row)
    cols = [
        *keys, *METRIC_COLUMNS, *INTERVAL_COLUMNS, *EXTRA_COLUMNS, "config_hash", "spec_hash", "data_version", "git_commit",
    ]  # fmt: skip
    return pd.DataFrame(rows, columns=cols)


def _optional(g: pd.DataFrame, column: str) -> np.ndarray | None:
    """A per-query column that older tables lack (None there, or where no row of ``g`` has a value)."""
    if column not in g or not g[column].notna().any():
        return None
    return g[column].to_numpy(dtype=np.float64)


def pool_seeds(queries: pd.DataFrame) -> pd.DataFrame:
    """Every seed's rows under its variant's name. Each seed answers the same queries, so the pooled
    recall is the seeds' mean recall. A single run of a variant that was also run over seeds (an
    earlier eval into the same results) is left out rather than counted as one more seed."""
    if "seed" not in queries:
        return queries
    seeded = queries["seed"].notna()
    pooled = queries.assign(method=queries["method"].where(~seeded, queries["variant"]))
    runs_over_seeds = pd.MultiIndex.from_frame(pooled.loc[seeded, SCENE_KEYS].drop_duplicates())
    superseded = ~seeded & pd.MultiIndex.from_frame(pooled[SCENE_KEYS]).isin(runs_over_seeds)
    return pooled[~superseded]


SEED_METRICS = ("recall_50cm", "recall_25cm", "mte_25cm_m", "mre_25cm_deg")
SEED_KEYS = ["variant", "track", "split"]


def seed_table(queries: pd.DataFrame, maps: pd.DataFrame) -> pd.DataFrame:
    """Per variant run over seeds: each of :data:`SEED_METRICS`' mean, std, min and max over the seeds."""
    seeded = queries[queries["seed"].notna()] if "seed" in queries else queries.iloc[:0]
    stats = ("mean", "std", "min", "max")
    cols = [*SEED_KEYS, "n_seeds", "n_queries", *(f"{m}_{s}" for m in SEED_METRICS for s in stats)]
    if seeded.empty:
        return pd.DataFrame(columns=cols)
    per_seed = metric_table(seeded.astype({"seed": int}), [*SEED_KEYS, "seed"], maps)
    agg = per_seed.groupby(SEED_KEYS, sort=True).agg(
        n_seeds=("seed", "nunique"),
        n_queries=("n_queries", "first"),
        **{f"{m}_{s}": (m, s) for m in SEED_METRICS for s in stats},
    )
    return agg.reset_index()[cols]


def compact_seeds(seeds: pd.DataFrame) -> str:
    """Mean ± std [min, max] over seeds of the recalls, one line per variant."""
    lines = []
    for _, r in seeds.iterrows():
        cells = [
            f"{label} {r[f'{m}_mean']:.1f} ± {r[f'{m}_std']:.1f} [{r[f'{m}_min']:.1f}, {r[f'{m}_max']:.1f}]"
            for m, label in (("recall_50cm", "R@50cm%"), ("recall_25cm", "R@25cm%"))
        ]
        lines.append(f"{r['variant']} {r['track']} {r['split']}, {r['n_seeds']} seeds: " + "  ".join(cells))
    return "\n".join(lines)


def write_frame(df: pd.DataFrame, path_stem: Path) -> None:
    """CSV + JSON (records; infinities as strings so the JSON stays standard)."""
    io.atomic_write_text(path_stem.with_suffix(".csv"), df.to_csv(index=False))
    records = json.loads(df.replace([np.inf, -np.inf], ["inf", "-inf"]).to_json(orient="records"))
    io.write_json(path_stem.with_suffix(".json"), records)


def build_tables(queries: pd.DataFrame, maps: pd.DataFrame) -> tuple[pd.DataFrame, pd.DataFrame]:
    return metric_table(queries, SCENE_KEYS, maps), metric_table(queries, SUITE_KEYS, maps)


def write_tables(
    tables_dir: Path, queries: pd.DataFrame, maps: pd.DataFrame
) -> tuple[pd.DataFrame, pd.DataFrame, pd.DataFrame]:
    """queries / scenes / suite tables (CSV + JSON), the seeds table where variants ran over seeds and,
    where the runs exist, the paper's tables (markdown, seeds pooled); returns scenes, suite, seeds."""
    scenes, suite = build_tables(queries, maps)
    seeds = seed_table(queries, maps)
    write_frame(queries, tables_dir / "queries")
    write_frame(scenes, tables_dir / "scenes")
    write_frame(suite, tables_dir / "suite")
    if not seeds.empty:
        write_frame(seeds, tables_dir / "seeds")
    for name, text in paper_tables(pool_seeds(queries), maps).items():
        io.atomic_write_text(tables_dir / f"{name}.md", text)
    return scenes, suite, seeds


def compact(suite: pd.DataFrame) -> str:
    """The short table ``eval`` prints at the end."""
    suite = suite.assign(latency_median_ms=1000.0 * suite["latency_median_s"])
    for k in WITH_INTERVAL:
        suite[k] = [f"{v:.1f} [{lo:.1f}, {hi:.1f}]" for v, lo, hi in zip(suite[k], suite[f"{k}_lo"], suite[f"{k}_hi"])]
    cols = [c for c in COMPACT_COLUMNS if c in suite]
    view = suite[[*SUITE_KEYS, *cols]].rename(columns=COMPACT_COLUMNS)
    return view.to_string(index=False, float_format=lambda v: f"{v:.2f}", na_rep="-")


# --------------------------------------------------------------------------------------------
# The paper's layout: rows = settings, "@50cm / @25cm" cells, scenes as columns
# --------------------------------------------------------------------------------------------

_PAPER_METRICS = (
    ("Recall[%]", "recall_{}", "{:.0f}"),
    ("MTE[m]", "mte_{}_m", "{:.2f}"),
    ("MRE[°]", "mre_{}_deg", "{:.1f}"),
)


def _cell(row: pd.Series | None, col: str, fmt: str) -> str:
    vals = []
    for thr in ("50cm", "25cm"):
        v = row[col.format(thr)] if row is not None else math.nan
        vals.append("-" if v is None or not np.isfinite(v) else fmt.format(v))
    return " / ".join(vals)


def md_table(head: list[str], rows: list[list[Any]]) -> list[str]:
    """The lines of a markdown table."""
    return ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)] + [
        "| " + " | ".join(map(str, r)) + " |" for r in rows
    ]


def paper_table(scenes: pd.DataFrame, rows: list[tuple[str, dict[str, str]]], scene_names: list[str]) -> str:
    """Markdown table: one line per (title, column filter), cells '@50cm / @25cm' per metric and scene."""
    header = ["Setting"] + [f"{m} {s}" for m, _, _ in _PAPER_METRICS for s in scene_names]
    body = []
    for title, where in rows:
        sel = scenes
        for k, v in where.items():
            sel = sel[sel[k] == v]
        by_scene = {r["scene"]: r for _, r in sel.iterrows()}
        body.append([title, *(_cell(by_scene.get(s), col, fmt) for _, col, fmt in _PAPER_METRICS for s in scene_names)])
    return "\n".join(md_table(header, body)) + "\n"


def on_shared_seeds(queries: pd.DataFrame) -> tuple[pd.DataFrame, str]:
    """The queries of a table's rows (pooled, :func:`pool_seeds`) on the seeds every seeded row ran, and
    those seeds as 'seeds 0, 1' ('' where no row is seeded): a row pooled over three seeds set against
    one of a single seed would compare seed noise with the change."""
    seeded = queries.dropna(subset=["seed"]) if "seed" in queries else queries.iloc[:0]
    if seeded.empty:
        return queries, ""
    shared = sorted(set.intersection(*seeded.groupby(["method", "split"])["seed"].agg(set)))
    if not shared:  # no seed in common: every row on its own seeds, as the leaderboard pools them
        return queries, "seeds pooled per row"
    kept = queries[queries["seed"].isna() | queries["seed"].isin(shared)]
    return kept, f"seed{'s' if len(shared) > 1 else ''} {', '.join(f'{v:g}' for v in shared)}"


def paper_tables(queries: pd.DataFrame, maps: pd.DataFrame) -> dict[str, str]:
    """The ablation table and one robustness table per (method, track), where their runs exist, each over
    the seeds all of its rows ran (:func:`on_shared_seeds`; ``queries`` pooled, :func:`pool_seeds`)."""
    out: dict[str, str] = {}

    def table(name: str, what: str, q: pd.DataFrame, rows: list[tuple[str, dict[str, str]]]) -> None:
        kept, seeds = on_shared_seeds(q)
        track = q["track"].iloc[0]
        head = f"{what} ({track} track{f'; {seeds}' if seeds else ''}), each cell @50cm / @25cm"
        out[name] = f"{head}\n\n" + paper_table(metric_table(kept, SCENE_KEYS, maps), rows, sorted(q["scene"].unique()))

    for track, t in queries.groupby("track"):
        labels = {ablation_label(r): r for r in (*ABLATION_ROWS, FULL_ROW) if ablation_label(r) in set(t["method"])}
        if len(labels) > 1:
            abl = t[t["method"].isin(list(labels)) & (t["split"] == "query")]
            rows = [(r.title, {"method": label, "split": "query"}) for label, r in labels.items()]
            table(f"ablations_{track}", "Ablations", abl, rows)
        for method, m in t.groupby("method"):
            rob = [(r.title, {"split": r.key}) for r in ROBUSTNESS_ROWS if r.key in set(m["split"])]
            if len(rob) > 1:
                splits = [where["split"] for _, where in rob]
                table(f"robustness_{method}_{track}", f"Robustness of {method}", m[m["split"].isin(splits)], rob)
    return out
