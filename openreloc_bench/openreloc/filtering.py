"""Invalid-object filtering (paper section 3.1): walls, floors and ceilings are seen from everywhere,
so they cannot narrow down where the camera is. They are found by how often they occur in the
reference frames.

Frequency is measured *locally*: the share of reference frames that contain the landmark among the
reference frames of its co-visibility neighbourhood (every reference frame that shows the landmark
or any landmark seen together with it). In one room this equals the global share; in a multi-room
scene a room's wall is compared with the frames of that room, not with every frame of the house,
where even a wall would look rare. ``scope: global`` gives the paper's plain share.

Frequency alone does not separate structure from furniture on the generated scenes (see
:attr:`FilterConfig.max_frequency`), so a second, geometric cue is on by default: a landmark whose
points form a large thin slab (principal extents: longest >= ``plane_min_span``, thinnest <=
``plane_max_thickness``) is a wall, floor or ceiling piece. This is beyond the paper (which only names
frequency); ``shape_filter: false`` restores the paper-literal rule.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
import scipy.sparse as sp

from openreloc_bench.config import check_ranges
from openreloc_bench.openreloc.map import ReferenceFrame


@dataclass
class FilterConfig:
    """Invalid-object filtering by frequency in reference frames."""

    enabled: bool = True
    """Mark frequent landmarks invalid (the 'no invalid-object filtering' ablation turns this off)."""
    max_frequency: float = 1.0
    """Landmarks in more than this share of (neighbourhood) reference frames are invalid; 1.0 turns the
    frequency cue off. The paper's rule is frequency alone, "objects that appear in most reference
    frames" (``openreloc-paper``: 0.5 with ``scope: global`` and ``shape_filter: false``). On the
    generated scenes no threshold separates structure from furniture (``benchmarks/bench_mapping.py``
    prints the frequencies): a large piece of furniture in a small room is seen as often as its floor,
    and in a house every landmark is rare; the shape cue finds the floor, wall and ceiling pieces."""
    scope: Literal["local", "global"] = "local"
    """'local': share within the landmark's co-visibility neighbourhood; 'global': share of all."""
    shape_filter: bool = True
    """Also mark large thin slabs (walls, floors, ceilings) invalid, whatever their frequency."""
    plane_min_span: float = 2.5
    """Metres: a slab's longest principal extent must reach this. Wall pieces are room-height (2.7 m in
    the generator) or longer; the longest thin furniture of the asset library, runner rugs, reaches 2.44 m."""
    plane_max_thickness: float = 0.15
    """Metres: a slab's thinnest principal extent (robust 2-98 percentile range) is at most this."""

    def __post_init__(self) -> None:
        check_ranges(self, non_negative=("plane_min_span", "plane_max_thickness"), share=("max_frequency",))


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


def principal_extents(points: np.ndarray) -> np.ndarray:
    """Robust (2-98 percentile) extents along the points' principal axes, ascending. Oriented, so a
    wall that is not axis-aligned (real scans) is still thin along its normal."""
    p = np.asarray(points, dtype=np.float64)
    if len(p) < 4:
        return np.zeros(3)
    centred = p - p.mean(0)
    _, vecs = np.linalg.eigh(centred.T @ centred)
    proj = centred @ vecs
    lo, hi = np.percentile(proj, [2, 98], axis=0)
    return np.sort(hi - lo)


def is_slab(points: np.ndarray, cfg: FilterConfig) -> bool:
    ext = principal_extents(points)
    return bool(ext[2] >= cfg.plane_min_span and ext[0] <= cfg.plane_max_thickness)


def invalid_landmarks(
    rfs: list[ReferenceFrame], ids: list[int], cfg: FilterConfig, points: dict[int, np.ndarray] | None = None
) -> tuple[set[int], dict[int, float]]:
    """(ids to mark invalid, frequency per id). ``points`` (id -> world points) enables the shape cue."""
    freq = reference_frequency(rfs, ids, cfg.scope)
    if not cfg.enabled:
        return set(), freq
    bad = {i for i, f in freq.items() if f > cfg.max_frequency}
    if cfg.shape_filter and points is not None:
        bad |= {i for i in ids if i in points and is_slab(points[i], cfg)}
    return bad, freq
