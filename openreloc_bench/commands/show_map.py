"""Draw a saved OpenReLoc map from above: landmarks by category (labelled; invalid ones grey),
scene-graph edges (kNN solid, box overlap dashed) and reference-frame poses (camera arrows)."""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from openreloc_bench.data import paths
from openreloc_bench.openreloc.map import ObjectMap

NAME = "show-map"
HELP = "top-down PNG of an OpenReLoc map (landmarks, scene graph, reference frames)"
ORDER = 45


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("map_dir", type=Path, help="map directory written by `openreloc-bench map`")
    parser.add_argument(
        "--out",
        type=Path,
        default=None,
        help="PNG path (default: MAP_DIR.png next to the map, so the map size is unchanged)",
    )


def draw_map(m: ObjectMap, out: Path) -> None:
    import matplotlib  # here, not at module level: every CLI call imports all command modules

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(9, 9), dpi=110)
    cats = sorted({lm.category or "?" for lm in m.landmarks.values() if lm.valid})
    cmap = plt.get_cmap("tab20")
    color = {c: cmap(k % 20) for k, c in enumerate(cats)}
    for lm in m.landmarks.values():
        pts = lm.points[:: max(1, len(lm.points) // 400)]
        c = color.get(lm.category or "?", "0.6") if lm.valid else "0.75"
        ax.scatter(pts[:, 0], pts[:, 1], s=2, color=c, alpha=0.5 if lm.valid else 0.25, linewidths=0)
    for u, v, d in m.graph.edges(data=True):
        a, b = m.landmarks[u].center, m.landmarks[v].center
        ax.plot([a[0], b[0]], [a[1], b[1]], "--" if d["kind"] == "overlap" else "-", color="k", lw=0.5, alpha=0.4)
    for lm in m.landmarks.values():
        ax.annotate(
            f"{lm.id}:{lm.category or '?'}", lm.center[:2], fontsize=6, ha="center", color="k" if lm.valid else "0.5"
        )
    if m.reference_frames:
        T = np.stack([rf.T_wc for rf in m.reference_frames])
        fwd = T[:, :3, 2]
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
        ax.legend(loc="upper right", fontsize=7)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    n_valid = len(m.valid_ids())
    ax.set_title(f"{len(m.landmarks)} landmarks ({n_valid} valid), {m.graph.number_of_edges()} graph edges", fontsize=9)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, bbox_inches="tight")
    plt.close(fig)


def run(args: argparse.Namespace) -> int:
    out = args.out or args.map_dir.parent / f"{args.map_dir.resolve().name}.png"
    paths.check_output_file(out, [args.map_dir], "--out", suffix=".png")
    m = ObjectMap.load(args.map_dir)
    draw_map(m, out)
    print(out)
    return 0
