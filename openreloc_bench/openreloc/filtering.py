"""Invalid-object filtering (paper section 3.1): walls, floors and ceilings are seen from everywhere,
so they cannot narrow down where the camera is. They are found by how often they occur in the
reference frames.

Frequency is measured *locally*: the share of reference frames that contain the landmark among the
reference frames of its co-visibility neighbourhood (every reference frame that shows the landmark
or any landmark seen together with it). In one room this equals the global share; in a multi-room
scene a room's wall is compared with the frames of that room, not with every frame of the house,
where even a wall would look rare. ``scope: global`` gives the paper's plain share.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
import scipy.sparse as sp

from openreloc_bench.openreloc.map import ReferenceFrame


@dataclass
class FilterConfig:
    """Invalid-object filtering by frequency in reference frames."""

    enabled: bool = True
    """Mark frequent landmarks invalid (the 'no invalid-object filtering' ablation turns this off)."""
    max_frequency: float = 0.75
    """Landmarks in more than this share of (neighbourhood) reference frames are invalid. Measured
    (benchmarks/bench_mapping.py, oracle masks): smoke room: floor 1.0, armchair 1.0, fan 0.9, walls
    0.3-0.7, so 0.75 removes the floor but also the armchair and fan; 4-room scene: floors 0.35-0.48,
    walls 0.10-0.33, furniture up to 0.38, so 0.75 removes nothing. No threshold on this frequency
    separates structure from furniture on the generated scenes; a geometric criterion is needed."""
    scope: Literal["local", "global"] = "local"
    """'local': share within the landmark's co-visibility neighbourhood; 'global': share of all."""


def reference_frequency(rfs: list[ReferenceFrame], ids: list[int], scope: str = "local") -> dict[int, float]:
    """Landmark id -> share of (neighbourhood) reference frames containing it."""
    if not rfs or not ids:
        return {i: 0.0 for i in ids}
    col = {lid: k for k, lid in enumerate(ids)}
    rows, cols = zip(*((r, col[i]) for r, rf in enumerate(rfs) for i in rf.boxes if i in col)) or ((), ())
    A = sp.csr_matrix((np.ones(len(rows)), (rows, cols)), shape=(len(rfs), len(ids)))  # frames x landmarks
    count = np.asarray(A.sum(axis=0)).ravel()
    if scope == "global":
        return {i: float(count[col[i]] / len(rfs)) for i in ids}
    covis = (A.T @ A).astype(bool).astype(np.float64)  # landmarks seen together (incl. itself)
    neighbourhood = np.asarray(((A @ covis) > 0).sum(axis=0)).ravel()  # frames showing any co-visible landmark
    return {i: float(count[col[i]] / max(neighbourhood[col[i]], 1)) for i in ids}


def invalid_landmarks(rfs: list[ReferenceFrame], ids: list[int], cfg: FilterConfig) -> tuple[set[int], dict[int, float]]:
    """(ids to mark invalid, frequency per id)."""
    freq = reference_frequency(rfs, ids, cfg.scope)
    bad = {i for i, f in freq.items() if cfg.enabled and f > cfg.max_frequency}
    return bad, freq
