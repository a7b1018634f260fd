"""Draw a saved OpenReLoc map from above: landmarks by category (coloured as the legend says; invalid
ones grey; labelled ``id:category`` where a label covers no other, the rest left out and counted),
scene-graph edges (kNN solid, box overlap dashed) and reference-frame poses (camera arrows)."""

from __future__ import annotations

import argparse
from collections import Counter
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from openreloc_bench.data import paths

if TYPE_CHECKING:
    import matplotlib.pyplot as plt

    from openreloc_bench.openreloc.map import ObjectMap

NAME = "show-map"
HELP = "top-down PNG of an OpenReLoc map (landmarks, scene graph, reference frames)"
ORDER = 45


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("map_dir", type=Path, metavar="MAPDIR", help="map directory written by `openreloc-bench map`")
    parser.add_argument(
        "--out",
        type=Path,
        default=None,
        help="PNG path (default: MAP_DIR.png next to the map, so the map size is unchanged)",
    )


LABEL_FONT_PT = 6.0
LABEL_OFFSETS_PT = [(0.0, 0.0)] + [
    (r * dx, r * dy)
    for r in (9.0, 18.0, 27.0)
    for dx, dy in ((0, 1), (0, -1), (1, 0), (-1, 0), (1, 1), (-1, 1), (1, -1), (-1, -1))
]
"""Where a landmark's label may go, in points from its centre: on it, else ever farther around it."""


def label_size_pt(text: str, font_pt: float = LABEL_FONT_PT) -> tuple[float, float]:
    """A label's (width, height) in points, estimated from its length (no renderer needed)."""
    return 0.65 * font_pt * len(text) + 3.0, 1.4 * font_pt


def place_labels(
    anchors: np.ndarray, sizes: list[tuple[float, float]], offsets: list[tuple[float, float]] = LABEL_OFFSETS_PT
) -> list[tuple[float, float] | None]:
    """Each label's offset (points) from its anchor such that no two labels' boxes overlap, or None where
    none of ``offsets`` is free (the label is left out). Labels are placed in the order given: put the
    ones that matter most first. ``anchors``: (N, 2) positions in points; ``sizes``: (width, height)."""
    placed: list[tuple[float, float, float, float]] = []  # x0, y0, x1, y1
    result: list[tuple[float, float] | None] = []
    for (ax_, ay), (w, h) in zip(np.asarray(anchors, dtype=np.float64).reshape(-1, 2), sizes):
        choice = None
        for dx, dy in offsets:
            x0, y0 = ax_ + dx - w / 2, ay + dy - h / 2
            box = (x0, y0, x0 + w, y0 + h)
            if all(box[2] <= b[0] or box[0] >= b[2] or box[3] <= b[1] or box[1] >= b[3] for b in placed):
                choice = (dx, dy)
                placed.append(box)
                break
        result.append(choice)
    return result


def draw_map(m: ObjectMap, out: Path) -> plt.Axes:
    """Write the picture to ``out``; returns its axes (for tests: legend, labels)."""
    import matplotlib  # here, not at module level: every CLI call imports all command modules

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    fig, ax = plt.subplots(figsize=(9, 9), dpi=110)
    counts = Counter(lm.category or "?" for lm in m.landmarks.values() if lm.valid)
    palette = [c for name in ("tab20", "tab20b", "tab20c") for c in plt.get_cmap(name).colors]
    if set(counts) == {"?"}:  # a predicted map names no category: its landmarks are told apart by id
        colours = {lm.id: palette[lm.id % len(palette)] for lm in m.landmarks.values()}
        legend = [("0.3", f"landmarks, coloured by id (a predicted map names no category) ({counts['?']})")]
    else:
        by_category = {c: palette[k % len(palette)] for k, c in enumerate(sorted(counts))}
        colours = {lm.id: by_category.get(lm.category or "?", "0.6") for lm in m.landmarks.values()}
        legend = [(by_category[c], f"{c if c != '?' else 'no category'} ({counts[c]})") for c in sorted(counts)]
    for lm in m.landmarks.values():
        pts = lm.points[:: max(1, len(lm.points) // 400)]
        c = colours[lm.id] if lm.valid else "0.75"
        ax.scatter(pts[:, 0], pts[:, 1], s=2, color=c, alpha=0.5 if lm.valid else 0.25, linewidths=0)
    for u, v, d in m.graph.edges(data=True):
        a, b = m.landmarks[u].center, m.landmarks[v].center
        ax.plot([a[0], b[0]], [a[1], b[1]], "--" if d["kind"] == "overlap" else "-", color="k", lw=0.5, alpha=0.4)
    handles = [Line2D([], [], ls="", marker="o", ms=5, color=c, label=label) for c, label in legend]
    n_filtered = sum(not lm.valid for lm in m.landmarks.values())
    if n_filtered:
        handles.append(
            Line2D([], [], ls="", marker="o", ms=5, color="0.75", label=f"filtered ({n_filtered}: walls, floors...)")
        )
    edge_kinds = {d["kind"] for _, _, d in m.graph.edges(data=True)}
    for kind, ls, label in (("knn", "-", "graph edge: nearest"), ("overlap", "--", "graph edge: boxes overlap")):
        if kind in edge_kinds:
            handles.append(Line2D([], [], ls=ls, color="k", lw=0.5, alpha=0.6, label=label))
    if m.reference_frames:
        T = np.stack([rf.T_wc for rf in m.reference_frames])
        fwd = T[:, :3, 2]
        handles.append(
            ax.quiver(
                T[:, 0, 3],
                T[:, 1, 3],
                fwd[:, 0],
                fwd[:, 1],
                color="tab:red",
                scale=25,
                width=0.003,
                label=f"reference frames ({len(T)})",
            )
        )
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    # labels: the valid landmarks first, the biggest first; one that would cover another is left out
    order = sorted(m.landmarks.values(), key=lambda lm: (not lm.valid, -len(lm.points), lm.id))
    texts = [f"{lm.id}:{lm.category or '?'}" for lm in order]
    ax.apply_aspect()
    to_pt = 72.0 / fig.dpi
    anchors = ax.transData.transform(np.array([lm.center[:2] for lm in order]).reshape(-1, 2)) * to_pt
    dropped = 0
    for lm, text, offset in zip(order, texts, place_labels(anchors, [label_size_pt(t) for t in texts])):
        if offset is None:
            dropped += 1
            continue
        ax.annotate(
            text,
            lm.center[:2],
            xytext=offset,
            textcoords="offset points",
            fontsize=LABEL_FONT_PT,
            ha="center",
            va="center",
            color="k" if lm.valid else "0.5",
            arrowprops={"arrowstyle": "-", "lw": 0.3, "color": "0.5"} if offset != (0.0, 0.0) else None,
        )
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7, ncol=1 + len(handles) // 30)
    n_valid = len(m.valid_ids())
    title = f"{len(m.landmarks)} landmarks ({n_valid} valid), {m.graph.number_of_edges()} graph edges"
    if dropped:
        title += f"; {dropped} labels left out where they would cover others"
    ax.set_title(title, fontsize=9)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, bbox_inches="tight")
    plt.close(fig)
    return ax


def run(args: argparse.Namespace) -> int:
    out = args.out or args.map_dir.parent / f"{args.map_dir.resolve().name}.png"
    paths.check_output_file(out, [args.map_dir], "--out", suffix=".png")
    from openreloc_bench.openreloc.map import ObjectMap  # torch and open3d: not for every `--help`

    m = ObjectMap.load(args.map_dir)
    draw_map(m, out)
    print(out)
    return 0
