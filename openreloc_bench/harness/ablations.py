"""The paper's ablation rows and robustness settings: the single mapping from a table row to what runs.

An ablation row is an OpenReLoc config override (the switches of ``OpenReLocConfig`` in
``openreloc_bench/openreloc/method.py``); the harness runs each row as its own method variant,
labelled ``openreloc+<key>``, so its results, map cache and config hash stay separate.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from openreloc_bench.data.splits import QUERY_SPLIT_TABLE

ABLATED_METHOD = "openreloc"
"""Registry name of the method the ablation rows switch parts of."""


@dataclass(frozen=True)
class Row:
    """One row of a paper table."""

    key: str
    """Short id, used in labels (``openreloc+no_refine``) and file names."""
    title: str
    """The row title as printed in the paper."""
    overrides: dict[str, Any] = field(default_factory=dict)
    """Config overrides (ablations) -- unused for robustness rows."""


_SINGLE_PRIOR: dict[str, Any] = {"coarse": {"top_frames": 1, "pnp": False}, "verification": {"hypothesis": False}}
"""Refine only the best-ranked reference frame, as the paper does. The full method also refines the next
frames, a PnP pose and the verification's pose, so the frame ranking of #5 rarely decides there."""

ABLATION_ROWS: tuple[Row, ...] = (
    Row("no_refine", "#1 w/o Refine Stage", {"no_refine": True}),
    Row("no_coarse", "#2 w/o Coarse Stage", {"no_coarse": True}),
    Row("no_scene_graph", "#3 w/o Scene Graph", {"no_scene_graph": True}),
    Row("no_language", "#4 w/o Language Modality", {"no_language": True}),
    Row("visibility_retrieval", "#5 w/o DIoU-based Retrieval", {"retrieval": "visibility"}),
    Row("no_filtering", "#6 w/o Invalid Object Filtering", {"no_filtering": True}),
    Row("no_verification", "#7 w/o Geometric Verification (beyond the paper)", {"verification": {"enabled": False}}),
    Row(
        "no_render_compare", "#8 w/o Render-and-Compare Choice (beyond the paper)", {"consistency": {"enabled": False}}
    ),
    Row("single_prior", "#9 Single Coarse Prior, DIoU (the paper's coarse stage)", _SINGLE_PRIOR),
    Row(
        "single_prior_visibility",
        "#10 Single Coarse Prior, w/o DIoU-based Retrieval (#5 on #9)",
        {**_SINGLE_PRIOR, "retrieval": "visibility"},
    ),
    Row("no_anchors", "#11 w/o Object-Anchored Keypoints (beyond the paper)", {"anchors": {"enabled": False}}),
)
FULL_ROW = Row("full", "Ours Full")

ROBUSTNESS_ROWS: tuple[Row, ...] = tuple(Row(s.name, s.title) for s in QUERY_SPLIT_TABLE if s.shares_query_poses)
"""Robustness settings: the query split and its variants (key = split name), from the split table."""


def ablation_label(row: Row) -> str:
    """Result label of an ablation variant (the full method keeps its plain name)."""
    return ABLATED_METHOD if row is FULL_ROW else f"{ABLATED_METHOD}+{row.key}"
