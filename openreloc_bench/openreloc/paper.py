"""``openreloc-paper``: OpenReLoc as the paper describes it, for comparison beside the project's ``openreloc``.

The registered ``openreloc`` is the paper's pipeline plus stages the paper does not have. This preset
is the same code with each of those stages switched off, so that what remains is the paper's
pipeline (sections 3.1-3.3): invalid objects found by their frequency in the reference frames alone
-> landmark association (uniqueness, vision and language top-3, sub-graph matching) -> the single
reference frame with the best DIoU as the coarse prior -> dual-path 2D ICP from it, with moved
objects masked out by the 5x-median rule of the paper's robustness section.

Switched off (:data:`PAPER_CONFIG`), each by its own setting of :class:`~.method.OpenReLocConfig`:

- the geometric slab filter (``mapping.filtering.shape_filter``), which replaces the frequency rule in
  ``openreloc``; the frequency rule is back, as a share of all reference frames (``scope: global``,
  not of the landmark's co-visibility neighbourhood). The paper names no threshold for "objects that
  appear in most reference frames", so "most" is read literally: more than half (``max_frequency: 0.5``);
- the object-level RANSAC/P3P verification (``verification.enabled``) and, inside it, the place
  prior (``place_frames``), the co-visibility-guided sampling (``covisible_weight``) and its further
  modes (``modes``, ``hypothesis``);
- the further coarse hypotheses: the next-ranked reference frames (``coarse.top_frames``) and the
  PnP pose (``coarse.pnp``);
- the render-and-compare choice among refined hypotheses (``consistency.enabled``) and the restarts
  of the chosen refinement (``refinement.restart_degrees``);
- the landmarks' keypoints and the keypoint pose (``mapping.anchors.enabled``, ``anchors.enabled``).

Choices the paper leaves open keep the project's settings: the encoder and describer (the offline
ones instead of CLIP ViT-L/14 and an online LLM, so that the benchmark runs without a GPU or a
network), the uniqueness threshold, the subsampling of landmark points and mask pixels with the
backward path on the mask contour, and the refinement's stopping rules.

Keyword overrides apply on top of the preset (section by section), so ``openreloc-paper`` with one
addition switched back on measures that addition alone.
"""

from __future__ import annotations

from typing import Any

from openreloc_bench import config as cfglib
from openreloc_bench.openreloc.method import OpenReLoc

PAPER_CONFIG: dict[str, Any] = {
    "mapping": {
        "filtering": {"shape_filter": False, "scope": "global", "max_frequency": 0.5},
        "anchors": {"enabled": False},
    },
    "verification": {"enabled": False, "place_frames": 0, "covisible_weight": 1.0, "modes": 1, "hypothesis": False},
    "coarse": {"top_frames": 1, "pnp": False},
    "consistency": {"enabled": False},
    "refinement": {"restart_degrees": 0.0},
    "anchors": {"enabled": False},
}
"""The :class:`~.method.OpenReLocConfig` overrides that turn ``openreloc`` into the paper's pipeline."""


class OpenReLocPaper(OpenReLoc):
    """OpenReLoc with every stage beyond the paper switched off (registered as ``openreloc-paper``)."""

    name = "openreloc-paper"
    reference = "Cui et al., OpenReLoc: Compact Object-Level Representations with Open-Vocabulary Understanding for Indoor Visual Relocalization, arXiv:2606.24767: the paper's pipeline alone"

    def __init__(self, **overrides: Any):
        super().__init__(**cfglib.merge(PAPER_CONFIG, overrides))
