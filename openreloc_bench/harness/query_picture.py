"""One query as ``diagnose`` draws it: its segments, and its matched landmarks at the estimated and the true pose.

Three panels side by side: the query image under its segments, each matched segment's box in its
landmark's colour; the matched landmarks' points projected at the estimated pose; the same at the
true pose. Where the estimate is wrong, the middle panel shows what the method believed it saw and the
right one where those landmarks really are in the image.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")  # headless: no display on benchmark machines
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from openreloc_bench import geometry  # noqa: E402
from openreloc_bench.data.types import Frame  # noqa: E402
from openreloc_bench.openreloc.map import ObjectMap  # noqa: E402
from openreloc_bench.vision.base import ObjectMask, label_image  # noqa: E402

PANEL_INCHES = 4.0


def draw_query(
    frame: Frame, masks: list[ObjectMask], diag: dict[str, Any], T_est: np.ndarray | None, m: ObjectMap, out: Path
) -> None:
    """Write the query's picture (see the module doc) to ``out`` (PNG)."""
    matches = diag.get("matches", [])
    colours = plt.get_cmap("tab10")
    aspect = frame.color.shape[0] / frame.color.shape[1]
    fig, axes = plt.subplots(1, 3, figsize=(3 * PANEL_INCHES, PANEL_INCHES * aspect + 0.6))
    labels = label_image(masks, frame.color.shape[:2]) if masks else np.zeros(frame.color.shape[:2], int)
    segments = np.ma.masked_equal(labels, 0)
    axes[0].imshow(frame.color)
    axes[0].imshow(segments % 20, cmap="tab20", alpha=0.45, interpolation="nearest")
    for k, mt in enumerate(matches):
        if "box" in mt:
            x0, y0, x1, y1 = mt["box"]
            axes[0].add_patch(plt.Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, lw=2, color=colours(k % 10)))
    axes[0].set_title(f"{len(masks)} segments, {len(matches)} matched", fontsize=9)
    for ax, T, title in ((axes[1], T_est, "estimated pose"), (axes[2], frame.T_wc, "true pose")):
        ax.imshow(frame.color, alpha=0.45)
        if T is None:
            ax.set_title(f"{title}: none ({diag.get('reason', 'failure')})", fontsize=9)
            continue
        for k, mt in enumerate(matches):
            uv, z = geometry.project(frame.K, T, m.landmarks[int(mt["landmark"])].points)
            ax.scatter(*uv[z > 0].T, s=2, color=colours(k % 10))
        ax.set_xlim(0, frame.color.shape[1])
        ax.set_ylim(frame.color.shape[0], 0)
        ax.set_title(title, fontsize=9)
    if T_est is not None:
        t, r = geometry.pose_errors(frame.T_wc, T_est)
        axes[1].set_title(f"estimated pose: {float(t):.2f} m, {float(r):.1f} deg off", fontsize=9)
    for ax in axes:
        ax.set_axis_off()
    fig.suptitle(frame.name, fontsize=10)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=80)
    plt.close(fig)
