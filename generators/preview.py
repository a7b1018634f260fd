"""Pictures of a generated scene for a quick visual check: contact sheet and top-down floor plan.

Reads only the on-disk scene (through :class:`openreloc_bench.data.scene.Scene`), so it also works on
converted real datasets that have ``objects.json`` boxes.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.artist import Artist  # noqa: E402
from matplotlib.colors import hsv_to_rgb  # noqa: E402
from matplotlib.patches import Patch, Rectangle  # noqa: E402

from openreloc_bench.data.scene import Scene  # noqa: E402

_KIND_COLOURS = {
    "bedroom": "#cfe3ff",
    "kitchen": "#ffe8c2",
    "living": "#d8f5d0",
    "office": "#eadcff",
    "bathroom": "#c9f1f1",
    "dining": "#ffd6d6",
    "corridor": "#eeeeee",
}


def instance_colours(instance: np.ndarray) -> np.ndarray:
    """Distinct RGB per id (golden-ratio hues), black for 0."""
    ids = instance.astype(np.int64)
    hsv = np.stack([(ids * 0.618034) % 1.0, np.full(ids.shape, 0.65), np.where(ids > 0, 0.95, 0.0)], axis=-1)
    return hsv_to_rgb(hsv)


def contact_sheet(scene: Scene, frames_per_split: int = 4) -> plt.Figure:
    """Rows = splits, columns = sample frames x (RGB, depth, instances)."""
    splits = scene.splits()
    fig, axes = plt.subplots(
        len(splits), 3 * frames_per_split, figsize=(2.0 * 3 * frames_per_split, 1.7 * len(splits)), squeeze=False
    )
    for r, split in enumerate(splits):
        seq = scene.sequence(split)
        picks = np.unique(np.round(np.linspace(0, len(seq) - 1, min(frames_per_split, len(seq)))).astype(int))
        for c in range(frames_per_split):
            cells = axes[r, 3 * c : 3 * c + 3]
            for ax in cells:
                ax.axis("off")
            if c >= len(picks):
                continue
            fr = seq[int(picks[c])]
            cells[0].imshow(fr.color)
            if fr.depth is not None:
                cells[1].imshow(np.where(fr.depth > 0, fr.depth, np.nan), cmap="turbo")
            if fr.instance is not None:
                cells[2].imshow(instance_colours(fr.instance))
            cells[0].set_title(fr.name, fontsize=7, loc="left")
    fig.suptitle(f"{scene.name}: RGB / depth / instances", fontsize=10)
    fig.tight_layout()
    return fig


OPENINGS = ("door", "window", "stairs", "railing")
"""Structural categories drawn as outlines (the walls are filled; other structure is not drawn)."""


def floor_index(scene: Scene, z: np.ndarray) -> np.ndarray:
    """The floor (index into ``scene.json``'s ``floors``; 0 when it lists none) each height ``z`` is on."""
    zs = np.array([f["z"] for f in scene.info.get("floors") or [{"z": 0.0}]])
    return np.clip(np.searchsorted(zs, np.asarray(z) + 1e-6) - 1, 0, len(zs) - 1)


def plan_extent(scene: Scene) -> tuple[np.ndarray, np.ndarray] | None:
    """(min xy, max xy) of the building: its rooms, else its objects' boxes; None for a scene with neither."""
    rects = [r["rect"] for r in scene.info.get("rooms", [])]
    if not rects:
        rects = [[*o.aabb[0][:2], *o.aabb[1][:2]] for o in scene.objects.values()]
    if not rects:
        return None
    r = np.asarray(rects, dtype=np.float64)
    return r[:, :2].min(axis=0), r[:, 2:].max(axis=0)


def draw_floor(ax: plt.Axes, scene: Scene, floor: int, room_names: bool = True, displaced: bool = True) -> list[Artist]:
    """Draw one floor's plan on ``ax``: rooms (coloured by kind), walls, doors/windows/stairs, the other
    objects' boxes and, with ``displaced``, which objects ``query_displaced`` changed (moved, removed or added) and where to. Returns
    a legend entry for each kind of thing drawn (the plan's patches carry no labels of their own)."""
    moved = {d["id"]: d for d in scene.displacements()} if displaced else {}
    kinds: list[str] = []
    for room in scene.info.get("rooms", []):
        if room["floor"] != floor:
            continue
        x0, y0, x1, y1 = room["rect"]
        ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, color=_KIND_COLOURS.get(room["kind"], "#f4f4f4"), zorder=0))
        if room_names:
            ax.text((x0 + x1) / 2, y1 - 0.15, room["name"], ha="center", va="top", fontsize=7, zorder=5)
        kinds.append(room["kind"])
    drawn: dict[str, int] = {}
    for o in scene.objects.values():
        if o.floor != floor:
            continue
        (x0, y0, _), (x1, y1, _) = o.aabb
        if o.category == "wall":
            ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, color="#333333", zorder=2))
            drawn["walls"] = drawn.get("walls", 0) + 1
        elif o.category in OPENINGS:
            ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, ec="#8a5a2b", lw=1.2, zorder=3))
            drawn[o.category] = drawn.get(o.category, 0) + 1
        elif not o.structural:
            ec = "red" if o.id in moved else "#555555"
            ax.add_patch(
                Rectangle((x0, y0), x1 - x0, y1 - y0, fill=True, fc="#bbbbbb", ec=ec, lw=0.6, alpha=0.6, zorder=1)
            )
            drawn["objects"] = drawn.get("objects", 0) + 1
    n_moved = 0
    for d in moved.values():
        if scene.objects[d["id"]].floor == floor:
            (x0, y0, _), (x1, y1, _) = d["aabb_after"]
            ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, ec="red", ls="--", lw=0.8, zorder=4))
            n_moved += 1
    handles: list[Artist] = [
        Patch(color=_KIND_COLOURS.get(k, "#f4f4f4"), label=f"room: {k}") for k in dict.fromkeys(sorted(kinds))
    ]
    if "walls" in drawn:
        handles.append(Patch(color="#333333", label="walls"))
    openings = [c for c in OPENINGS if c in drawn]
    if openings:
        handles.append(
            Patch(
                fill=False, ec="#8a5a2b", lw=1.2, label=", ".join(c if c.endswith("s") else f"{c}s" for c in openings)
            )
        )
    if "objects" in drawn:
        handles.append(Patch(fc="#bbbbbb", ec="#555555", lw=0.6, alpha=0.6, label=f"objects ({drawn['objects']})"))
    if n_moved:
        handles.append(Patch(fc="#bbbbbb", ec="red", lw=0.6, alpha=0.6, label=f"changed objects, before ({n_moved})"))
        handles.append(Patch(fill=False, ec="red", ls="--", lw=0.8, label="changed objects, after (query_displaced)"))
    return handles


def floor_plan(scene: Scene) -> plt.Figure:
    """One panel per floor: rooms, walls, objects, the mapping path, ``query_walk``'s path and the query poses
    (arrows = viewing direction)."""
    floors = scene.info.get("floors") or [{"index": 0, "z": 0.0}]
    fig, axes = plt.subplots(1, len(floors), figsize=(7 * len(floors) + 2, 6), squeeze=False, layout="constrained")
    paths = {"mapping": dict(color="tab:blue", lw=1.0), "query_walk": dict(color="tab:green", lw=1.0)}
    styles = {**paths, "query": dict(color="tab:red", lw=0)}
    seqs = {s: scene.sequence(s) for s in styles if s in scene.splits()}
    for f, ax in enumerate(axes[0]):
        handles = draw_floor(ax, scene, f)
        for split, style in styles.items():
            if split not in seqs:
                continue
            T = np.array([r.T_wc for r in seqs[split].records])
            m = floor_index(scene, T[:, 2, 3]) == f
            if not m.any():
                continue
            pos, fwd = T[m, :2, 3], T[m, :2, 2]
            if split in paths:
                ax.plot(pos[:, 0], pos[:, 1], "-", alpha=0.7, zorder=6, **style)
            ax.quiver(
                pos[:, 0],
                pos[:, 1],
                fwd[:, 0],
                fwd[:, 1],
                color=style["color"],
                angles="xy",
                scale_units="xy",
                scale=2.5,
                width=0.004,
                zorder=7,
                label=f"{split} cameras ({m.sum()})",
            )
        ax.set_aspect("equal")
        ax.autoscale_view()
        ax.set_title(f"{scene.name}, floor {f}", fontsize=10)
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        ax.legend(
            handles=handles + ax.get_legend_handles_labels()[0], loc="upper left", bbox_to_anchor=(1.01, 1), fontsize=7
        )
    return fig


def write_previews(scene_dir: Path | str, out: Path | str | None = None, frames_per_split: int = 4) -> list[Path]:
    """Write the contact sheet to ``out`` (default ``<scene>/preview.png``) and the plan next to it."""
    scene = Scene(scene_dir)
    out = Path(out) if out is not None else scene.root / "preview.png"
    out.parent.mkdir(parents=True, exist_ok=True)
    plan = out.with_name(out.stem + "_plan.png")
    for fig, path in ((contact_sheet(scene, frames_per_split), out), (floor_plan(scene), plan)):
        fig.savefig(path, dpi=90)
        plt.close(fig)
    return [out, plan]
