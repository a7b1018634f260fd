"""Per-query difficulty: what makes each query frame hard, measured from what the generator knows.

One row per frame of every query split, written to ``<scene>/difficulty.csv`` (columns:
:data:`~openreloc_bench.data.scene.DIFFICULTY_COLUMNS`). ``eval`` carries the columns into its per-query
tables, so a board can plot recall against each axis: how far the query stands from the mapping path,
how dark it is, how many objects it sees, moved or look alike. A real dataset cannot vary one factor
alone; a generated one knows every factor of every frame.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Mapping

import numpy as np
import pandas as pd

from generators.trajectories import visible_ids
from openreloc_bench import geometry
from openreloc_bench.data.scene import DIFFICULTY_COLUMNS, ObjectInfo


def lookalike_ids(objects: list[ObjectInfo]) -> set[int]:
    """Non-structural objects with an identical twin in the scene (same :attr:`ObjectInfo.model`)."""
    counts = Counter(o.model for o in objects if not o.structural)
    return {o.id for o in objects if not o.structural and counts[o.model] > 1}


NEAR_M = 1.0
"""Mapping frames within this distance of a query count for its rotation gap."""


def viewpoint_gap(poses: np.ndarray, mapping: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per pose, the distance (m) to the nearest mapping camera centre and the smallest rotation (deg) to
    a mapping frame within :data:`NEAR_M` (to any mapping frame if none is that close): whether some
    nearby mapping view looks the same way."""
    d = np.linalg.norm(poses[:, None, :3, 3] - mapping[None, :, :3, 3], axis=2)
    angle = geometry.rotation_error(mapping[None], poses[:, None])
    near = d <= NEAR_M
    near[~near.any(axis=1)] = True
    return d.min(axis=1), np.where(near, angle, np.inf).min(axis=1)


def changes_in_view(
    after: list[np.ndarray], before: list[np.ndarray], shown: set[int], removed: set[int], objects: list[ObjectInfo]
) -> list[int]:
    """Per ``query_displaced`` frame, the changes its view holds: moved or added objects it shows
    (``after``: its instance images) and removed ones the unchanged view showed (``before``: the query
    split's instance images of the same poses)."""
    structural = {o.id for o in objects if o.structural}
    return [
        len(visible_ids(a, structural) & shown) + len(visible_ids(b, structural) & removed)
        for a, b in zip(after, before, strict=True)
    ]


def frame_difficulty(
    instance: np.ndarray, structural: set[int], lookalikes: set[int], changes: int
) -> dict[str, float]:
    """Object counts and image area of one frame's instance image (``changes``: see :func:`changes_in_view`)."""
    visible = visible_ids(instance, structural)
    ids, counts = np.unique(instance[instance > 0], return_counts=True)
    objects = np.array([int(i) not in structural for i in ids], dtype=bool)
    return {
        "visible_objects": len(visible),
        "object_area": round(float(counts[objects].sum() / instance.size), 4),
        "displaced_in_view": changes,
        "lookalikes_in_view": len(visible & lookalikes),
    }


def measure_difficulty(
    mapping: np.ndarray,
    splits: Mapping[str, tuple[np.ndarray, float, list[np.ndarray], list[int] | None]],
    objects: list[ObjectInfo],
) -> pd.DataFrame:
    """The difficulty table of a scene.

    ``splits``: per query split, its poses (N,4,4), its light level, its instance images and the changes
    each frame sees (:func:`changes_in_view`; None for a split without changes). Rows follow ``splits``'
    order and each split's frame order.
    """
    structural = {o.id for o in objects if o.structural}
    lookalikes = lookalike_ids(objects)
    rows = []
    for split, (poses, level, instances, changes) in splits.items():
        gap_m, gap_deg = viewpoint_gap(np.asarray(poses).reshape(-1, 4, 4), mapping)
        for i, inst in enumerate(instances):
            rows.append(
                {
                    "split": split,
                    "frame": f"{i:06d}",
                    "gap_m": round(float(gap_m[i]), 4),
                    "gap_deg": round(float(gap_deg[i]), 3),
                    "light_level": float(level),
                    **frame_difficulty(inst, structural, lookalikes, changes[i] if changes else 0),
                }
            )
    return pd.DataFrame(rows, columns=list(DIFFICULTY_COLUMNS))
