"""The board's verdict line."""

from __future__ import annotations

import numpy as np
import pandas as pd

from openreloc_bench.harness.leaderboard.verdict import verdict
from tests.harness.leaderboard.boards import runs


def test_verdict_names_each_tracks_leaders_at_50_and_25_cm_and_their_map_sizes() -> None:
    b = pd.concat(
        [
            runs(("openreloc", "oracle-mask", 88.7, 82.7, 0.684), ("sift-pnp", "mask-free", 66.3, 66.0, 12.1),
                 ("openreloc", "predicted", 66.7, 54.3, 0.74), ("goreloc", "predicted", 4.0, 2.0, 0.02)),
            runs(("goreloc", "predicted", 99.0, 99.0, 0.02), split="query_near"),  # not the headline split
        ]
    )  # fmt: skip
    assert verdict(b) == (
        "Predicted track: openreloc leads at 50 cm (66.7 vs sift-pnp 66.3), sift-pnp at 25 cm (66.0 vs "
        "openreloc 54.3); map size: openreloc 0.74 MB, sift-pnp 12.1 MB. "
        "Oracle-mask track: openreloc leads at 50 cm (88.7 vs sift-pnp 66.3) and at 25 cm (82.7 vs sift-pnp "
        "66.0); map size: openreloc 0.684 MB, sift-pnp 12.1 MB."
    )  # sift-pnp reads no masks: it stands in both tracks' comparisons
    assert verdict(b, "query_near").startswith("Predicted track: only goreloc ran (99.0 at 50 cm, 99.0 at 25 cm;")
    assert verdict(b, "query_light4") == "No method ran the query_light4 split: no verdict."


def test_verdict_reads_ties_as_the_board_prints_them() -> None:
    b = runs(
        ("b", "predicted", 50.04, 40.0, 1.0), ("a", "predicted", 49.96, 45.0, 2.0), ("c", "mask-free", 10.0, 45.0, 3.0)
    )
    assert verdict(b) == (
        "Predicted track: a and b tie at 50 cm (50.0 vs c 10.0), a and c tie at 25 cm (45.0 vs b 40.0); "
        "map size: a 2 MB, b 1 MB, c 3 MB."
    )
    even = runs(("a", "oracle-mask", 50.0, 40.0, 1.0), ("b", "oracle-mask", 50.0, 40.0, np.nan))
    assert verdict(even) == (
        "Oracle-mask track: a and b tie at 50 cm (50.0) and at 25 cm (40.0); map size: a 1 MB, b not recorded."
    )


def test_verdict_of_one_method_of_mask_free_methods_only_and_of_diagnostics() -> None:
    assert verdict(runs(("openreloc", "predicted", 36.0, 25.9, 0.71))) == (
        "Predicted track: only openreloc ran (36.0 at 50 cm, 25.9 at 25 cm; map size 0.71 MB)."
    )
    free = runs(("sift-pnp", "mask-free", 66.3, 66.0, 221.0), ("retrieval", "mask-free", 4.0, 0.3, 6.0))
    assert verdict(free) == (
        "Both tracks (no method reads masks): sift-pnp leads at 50 cm (66.3 vs retrieval 4.0) and at 25 cm "
        "(66.0 vs retrieval 0.3); map size: sift-pnp 221 MB, retrieval 6 MB."
    )
    b = runs(
        ("openreloc-oracle-association", "oracle-mask", 97.7, 94.3, 0.68), ("openreloc", "oracle-mask", 88.7, 83.8, 0.68),
        ("openreloc+no_refine", "oracle-mask", 90.0, 60.0, 0.68), ("openreloc+no_coarse", "oracle-mask", 1.0, 1.0, 0.68),
        ("nearest-frame", "mask-free", 0.0, 0.0, 0.71),
    )  # fmt: skip
    assert verdict(b) == (
        "Oracle-mask track: openreloc leads at 50 cm (88.7 vs nearest-frame 0.0) and at 25 cm (83.8 vs "
        "nearest-frame 0.0); map size: openreloc 0.68 MB, nearest-frame 0.71 MB. Not weighed: the diagnostic "
        "openreloc-oracle-association and 2 ablation variants of openreloc."
    )
    alone = runs(("openreloc-oracle-association", "oracle-mask", 97.7, 94.3, 0.68))
    assert verdict(alone).startswith("Oracle-mask track: only openreloc-oracle-association ran")


def test_verdict_calls_overlapping_intervals_level_not_a_lead() -> None:
    b = runs(("openreloc", "predicted", 67.0, 55.4, 0.75), ("sift-pnp", "mask-free", 66.3, 66.0, 221.0))
    b["recall_50cm_lo"], b["recall_50cm_hi"] = [61.5, 60.8], [72.3, 71.7]  # 0.7 points: well inside both
    b["recall_25cm_lo"], b["recall_25cm_hi"] = [49.8, 60.6], [60.2, 71.4]  # 10.6 points: apart
    assert verdict(b) == (
        "Predicted track: openreloc and sift-pnp are level at 50 cm (67.0 [61.5, 72.3] vs 66.3 [60.8, 71.7]), "
        "sift-pnp at 25 cm (66.0 [60.6, 71.4] vs openreloc 55.4 [49.8, 60.2]); "
        "map size: openreloc 0.75 MB, sift-pnp 221 MB."
    )


def test_verdict_weighs_the_difference_on_the_same_queries_where_the_board_has_it() -> None:
    """Overlapping intervals, but openreloc ahead on the same queries: a lead; a paired interval across
    zero keeps the two level."""
    b = runs(("openreloc", "predicted", 77.5, 77.5, 2.9), ("sift-pnp", "mask-free", 67.5, 67.5, 21.0))
    b["recall_25cm_lo"], b["recall_25cm_hi"] = [68.5, 55.4], [86.3, 80.6]
    b["recall_50cm_lo"], b["recall_50cm_hi"] = [68.5, 55.4], [86.3, 80.6]
    assert "are level" in verdict(b)

    def paired(lo: float, hi: float) -> pd.DataFrame:
        return pd.DataFrame(
            [("predicted", "openreloc", "sift-pnp", col, 10.0, lo, hi, 320) for col in ("recall_50cm", "recall_25cm")],
            columns=["track", "method", "other", "column", "diff", "lo", "hi", "n_queries"],
        )

    assert verdict(b, paired=paired(3.1, 16.4)) == (
        "Predicted track: openreloc leads at 50 cm (77.5 vs sift-pnp 67.5, +10.0 [+3.1, +16.4] on the same "
        "queries) and at 25 cm (77.5 vs sift-pnp 67.5, +10.0 [+3.1, +16.4] on the same queries); "
        "map size: openreloc 2.9 MB, sift-pnp 21 MB."
    )
    assert "openreloc and sift-pnp are level at 50 cm (77.5 vs 67.5, +10.0 [-0.5, +16.4]" in verdict(
        b, paired=paired(-0.5, 16.4)
    )
