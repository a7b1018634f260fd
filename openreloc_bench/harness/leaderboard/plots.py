"""A board's plots: cumulative errors, recall per scene, recall against map size, lighting and each
difficulty axis, and the top-down camera positions over a scene's floor plan. A method has one colour in
every plot of a board (:func:`method_colors`), a track its own marker, line and hatch."""

from __future__ import annotations

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

from openreloc_bench.data.scene import Scene  # noqa: E402
from openreloc_bench.data.splits import LIGHT_SPLITS, QUERY_SPLIT_BY_NAME  # noqa: E402
from openreloc_bench.errors import DataError  # noqa: E402
from openreloc_bench.harness.leaderboard.rows import (  # noqa: E402
    DIFFICULTY_BINS,
    HEADLINE_SPLIT,
    TRACK_NAMES,
    track_groups,
    track_rank,
)
from openreloc_bench.harness.metrics import cumulative_curve  # noqa: E402
from openreloc_bench.methods import available_methods  # noqa: E402
from openreloc_bench.tracks import MASK_FREE  # noqa: E402

log = logging.getLogger(__name__)


def _save(fig: plt.Figure, path: Path) -> None:
    if fig.get_layout_engine() is None:  # a figure made with layout="constrained" keeps it
        fig.tight_layout()
    fig.savefig(path, dpi=110, bbox_inches="tight")  # legends placed beside the axes stay in the picture
    plt.close(fig)


TRACK_MARKERS = {"predicted": "o", "oracle-mask": "s", MASK_FREE: "^"}
TRACK_LINES = {"predicted": "-", "oracle-mask": "--", MASK_FREE: "-."}
TRACK_HATCHES = {"predicted": "", "oracle-mask": "///", MASK_FREE: ".."}
"""How the plots tell the tracks apart: the colour is the method's (:func:`method_colors`)."""


def method_colors(methods: Iterable[str]) -> dict[str, tuple[float, ...]]:
    """One colour per method (by name), the same in every plot of every board: tab10's, then tab20b's, in
    the order of the registered methods' names (those of ``methods`` no method is registered under after
    them), so that a method keeps its colour whichever others a board shows."""
    palette = [*plt.get_cmap("tab10").colors, *plt.get_cmap("tab20b").colors]
    registered = sorted(available_methods())
    order = registered + sorted(set(methods) - set(registered))
    return {m: palette[order.index(m) % len(palette)] for m in set(methods)}


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
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))  # beside the curves, never on them
    _save(fig, path)
    return ax


HEADLINE_RECALLS = {"recall_50cm": "50 cm", "recall_25cm": "25 cm", "recall_5cm_5deg": "5 cm, 5°"}
"""The recalls the headline plot shows: the paper's two thresholds and the field's precise one."""


def plot_headline_recall(b: pd.DataFrame, path: Path, colors: dict[str, Any] | None = None) -> plt.Axes | None:
    """The verdict in a picture: recall on the headline split at each of :data:`HEADLINE_RECALLS` per
    (method, track), bars with their 95% intervals (bars whose whiskers overlap are level). None when no
    method ran the headline split."""
    s = b[b["split"] == HEADLINE_SPLIT]
    if s.empty:
        return None
    s = s.assign(_rank=s["track"].map(track_rank)).sort_values(["_rank", "method"], kind="stable")
    cols = [c for c in HEADLINE_RECALLS if c in s]
    colors = colors or method_colors(s["method"])
    y, height = np.arange(len(cols)), 0.8 / len(s)
    fig, ax = plt.subplots(figsize=(8, 1.2 + 0.35 * len(s) * len(cols)))
    for k, (_, r) in enumerate(s.iterrows()):
        values = np.array([r[c] for c in cols], dtype=float)
        lo = np.array([r.get(f"{c}_lo", np.nan) for c in cols], dtype=float)
        hi = np.array([r.get(f"{c}_hi", np.nan) for c in cols], dtype=float)
        err = np.nan_to_num(np.vstack([values - lo, hi - values]), nan=0.0).clip(0)
        look = {"color": colors[r["method"]], "hatch": TRACK_HATCHES.get(r["track"], "xx"), "edgecolor": "white"}
        offset = y - 0.4 + (k + 0.5) * height
        ax.barh(offset, values, height, xerr=err, label=f"{r['method']} ({r['track']})", capsize=3, **look)
        for yy, v in zip(offset, values):
            ax.text(v + 1, yy, f"{v:.1f}", va="center", fontsize=7)
    ax.set_yticks(y, [f"R@{HEADLINE_RECALLS[c]}" for c in cols])
    ax.invert_yaxis()
    ax.set(xlabel="recall [%] with its 95% interval", xlim=(0, 105), title=f"Recall on the {HEADLINE_SPLIT} split")
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    _save(fig, path)
    return ax


def plot_scene_recall(scenes: pd.DataFrame, path: Path, colors: dict[str, Any] | None = None) -> plt.Axes:
    """Recall@50cm (light) and @25cm (dark) per scene and (method, track) on the plain query split: the
    method's colour, the track's hatch. Returns the plot."""
    s = scenes[scenes["split"] == HEADLINE_SPLIT]
    runs = sorted({(m, t) for m, t in zip(s["method"], s["track"])}, key=lambda r: (track_rank(r[1]), r))
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
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))  # beside the bars, never on them
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


LIGHT_LABELS = tuple(QUERY_SPLIT_BY_NAME[s].label for s in LIGHT_SPLITS)
"""The ticks of the lighting plot: the plain query split's, then each lighting variant's (the split table's labels)."""


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
    runs = sorted(s.groupby(["method", "track"]), key=lambda r: (track_rank(r[0][1]), r[0]))
    for (method, track), g in runs:
        g = g.set_index("split").reindex(LIGHT_SPLITS)
        ran = g["recall_50cm"].notna().to_numpy()  # a line joins the levels run, skipping the others
        alone = "" if ran.sum() > 1 else f", {LIGHT_LABELS[int(ran.argmax())]} only"
        look = {"marker": TRACK_MARKERS.get(track, "D"), "color": colors[method]}
        ax.plot(x[ran], g["recall_50cm"][ran], "-", **look, label=f"{method} ({track}){alone}")
        ax.plot(x[ran], g["recall_25cm"][ran], "--", **look, mfc="none", alpha=0.7)
    ax.set_xticks(x, LIGHT_LABELS)
    ax.set(xlabel="lighting decay level", ylabel="recall [%]  (solid @50cm, dashed @25cm)", ylim=(-3, 103))
    ax.set_title("Recall vs lighting")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="center left", bbox_to_anchor=(1.0, 0.5))
    _save(fig, path)
    return [ax]


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
"""The same beyond the true cameras, for a scene whose floor plan is unknown."""
RECALL_RADIUS_M = 0.5


def topdown_extent(gt_xy: np.ndarray, scene: Scene | None = None) -> tuple[np.ndarray, np.ndarray, str]:
    """(min xy, max xy, what it is) of a top-down plot: the building's floor plan and the true cameras with
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
    floor_legend: dict[str, matplotlib.artist.Artist] = {}
    panels = list(grid.flat[: len(runs)])
    for ax, (method, track) in zip(panels, runs):
        g = s[(s["method"] == method) & (s["track"] == track)]
        if scene_data is not None:
            from generators.preview import draw_floor, floor_index

            for f in sorted(set(floor_index(scene_data, g["gt_z"].to_numpy()).tolist())):
                for h in draw_floor(ax, scene_data, f, room_names=False, displaced=False):
                    floor_legend.setdefault(h.get_label(), h)
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
    if floor_legend:
        handles = list(floor_legend.values())
        fig.legend(handles=handles, loc="outside lower center", ncol=min(len(handles), 5), fontsize=7)
    over = " over its floor plan" if floor_legend else ""
    fig.suptitle(f"{scene}: camera positions, top-down{over}")
    _save(fig, path)
    return panels


def board_scene(data: Path | None, name: str, spec_hashes: Sequence[str] = ()) -> Scene | None:
    """Scene ``name`` under ``data``, whose floor plan a top-down plot draws; None (the plot goes without,
    with a warning where it was expected) when there is no ``data``, no such scene, an unreadable one, or
    one of another spec than the runs' (``spec_hashes``: its floor plan would not be theirs)."""
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
