"""One query as its method saw it, as hloc's ``visualize_loc`` shows it: the query image with the
keypoints the method matched (green where its pose kept them, red where it rejected them) and the objects
it matched to the map (boxes labelled with the landmark), titled with the query's error or the reason it
failed. ``localize --draw DIR`` writes one such picture per query.

A method shows what it matched through its diagnostics: :data:`~openreloc_bench.methods.DRAWN_POINTS`
for keypoints, and a ``matches`` list whose entries have a ``box`` (OpenReLoc's) for objects."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from openreloc_bench import geometry
from openreloc_bench.methods import DRAWN_POINTS, Answer

KEPT_COLOR, REJECTED_COLOR, BOX_COLOR = "#22a046", "#d72828", "#ffb000"


def drawn_points_of(diagnostics: dict[str, Any]) -> np.ndarray:
    """(N, 3) [x, y, kept] of the matched keypoints a method's diagnostics hold (top level, or in a dict
    one level down); (0, 3) when they hold none."""
    found = [diagnostics.get(DRAWN_POINTS)] + [v.get(DRAWN_POINTS) for v in diagnostics.values() if isinstance(v, dict)]
    rows = [np.asarray(p, dtype=float).reshape(-1, 3) for p in found if p]
    return np.concatenate(rows) if rows else np.zeros((0, 3))


def matched_boxes(diagnostics: dict[str, Any]) -> list[tuple[list[float], str]]:
    """(box x0 y0 x1 y1, label) of each matched object in the diagnostics' ``matches`` list."""
    matches = diagnostics.get("matches")
    if not isinstance(matches, list):
        return []
    return [
        (m["box"], f"{m.get('landmark', '?')}: {m.get('category') or m.get('phrase') or 'no category'}")
        for m in matches
        if isinstance(m, dict) and len(m.get("box") or ()) == 4
    ]


def caption(answer: Answer, T_true: np.ndarray | None) -> str:
    """'query/000003: 4.2 cm, 0.8°' (against ``T_true``), or 'query/000003: no pose (<reason>)'."""
    if answer.T_wc is None:
        return f"{answer.name}: no pose ({answer.reason})"
    if T_true is None:
        return f"{answer.name}: a pose (no ground truth)"
    te, re = geometry.translation_error(T_true, answer.T_wc), geometry.rotation_error(T_true, answer.T_wc)
    return f"{answer.name}: {te * 100:.1f} cm, {re:.1f}°"


def draw_query(rgb: np.ndarray, answer: Answer, T_true: np.ndarray | None, method: str, path: Path) -> None:
    """Write the picture of one query (PNG at ``path``)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Rectangle

    h, w = rgb.shape[:2]
    fig, ax = plt.subplots(figsize=(8, 8 * h / w + 0.6))
    ax.imshow(rgb)
    pts = drawn_points_of(answer.diagnostics)
    for kept, color in ((False, REJECTED_COLOR), (True, KEPT_COLOR)):
        sel = pts[pts[:, 2].astype(bool) == kept]
        label = f"{'kept' if kept else 'rejected'} by the pose ({len(sel)})"
        ax.scatter(sel[:, 0], sel[:, 1], s=6, c=color, label=label if len(pts) else None, linewidths=0)
    for (x0, y0, x1, y1), label in matched_boxes(answer.diagnostics):
        ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, ec=BOX_COLOR, lw=1.5))
        ax.text(x0 + 2, y0 + 2, label, color="black", fontsize=7, va="top", bbox={"fc": BOX_COLOR, "lw": 0, "pad": 1})
    ax.set(xlim=(0, w), ylim=(h, 0), xticks=[], yticks=[])
    ax.set_title(f"{method}: {caption(answer, T_true)}", fontsize=9)
    if len(pts):
        ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), markerscale=2)
    fig.savefig(path, dpi=100, bbox_inches="tight")
    plt.close(fig)
