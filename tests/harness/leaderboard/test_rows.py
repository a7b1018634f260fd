"""The board's rows: robustness changes, the provenance line and recall per difficulty bin."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from openreloc_bench.harness.leaderboard.rows import binned_recall, paired_differences, provenance, robustness_drops
from tests.harness.leaderboard.boards import errors


def queries(method: str, track: str, split: str, t_err: list[float], seed: int | None = None) -> pd.DataFrame:
    """Per-query rows of one run: one query per translation error."""
    return pd.DataFrame(
        {"method": method, "track": track, "split": split, "seed": pd.array([seed] * len(t_err), dtype="Int64"),
         **errors(t_err)}
    )  # fmt: skip


def test_drops_are_changes_from_the_query_split_over_the_same_seeds_in_points() -> None:
    q = pd.concat(
        [
            queries("m", "predicted", "query", [0.1, 0.1, 0.3, 0.6]),
            queries("m", "predicted", "query_light4", [0.1, 0.3, 0.3, 0.6]),
            queries("m", "oracle-mask", "query", [0.1, 0.1, 0.1, 0.1], seed=0),
            queries("m", "oracle-mask", "query", [0.6, 0.6, 0.6, 0.6], seed=1),
            queries("m", "oracle-mask", "query_displaced", [0.1, 0.1, 0.3, 0.3], seed=0),
            queries("m", "oracle-mask", "query_light1", [0.1, 0.1, 0.1, 0.1], seed=2),
            queries("only-query", "predicted", "query", [0.1]),
        ]
    )
    d = robustness_drops(q).set_index(["Method", "Track"])
    assert list(d.index) == [("m", "predicted"), ("m", "oracle-mask")]  # a method run on the query split only has none
    assert d.loc[("m", "predicted"), "query"] == "75.0 / 50.0"
    assert d.loc[("m", "predicted"), "query_light4"] == "+0.0 / -25.0"
    assert d.loc[("m", "predicted"), "query_displaced"] == "-"
    assert d.loc[("m", "oracle-mask"), "query"] == "50.0 / 50.0"  # both seeds
    assert d.loc[("m", "oracle-mask"), "query_displaced"] == "+0.0 / -50.0"  # against seed 0 alone
    assert d.loc[("m", "oracle-mask"), "query_light1"] == "+50.0 / +50.0 (query split over seed(s) [0, 1])"  # no seed 2
    assert "query_light2" not in d.columns  # no method ran it


def test_the_displaced_change_is_measured_on_the_views_that_see_a_change() -> None:
    def rows(split: str, t_err: list[float], changes: list[int]) -> pd.DataFrame:
        frames = [f"{split}/{i:06d}" for i in range(len(t_err))]
        return queries("m", "predicted", split, t_err).assign(scene="s", query=frames, displaced_in_view=changes)

    q = pd.concat(
        [rows("query", [0.1, 0.1, 0.6, 0.6], [0] * 4), rows("query_displaced", [0.6, 0.1, 0.6, 0.6], [1, 0, 2, 0])]
    )
    d = robustness_drops(q).set_index(["Method", "Track"])
    assert d.loc[("m", "predicted"), "query"] == "50.0 / 50.0"
    assert d.loc[("m", "predicted"), "query_displaced"] == "-50.0 / -50.0 (2 views see a change)"  # frames 0 and 2
    none = pd.concat([rows("query", [0.1], [0]), rows("query_displaced", [0.6], [0])])
    assert robustness_drops(none)["query_displaced"].iloc[0] == "no query sees a change"


def test_provenance_names_one_commit_or_each() -> None:
    assert provenance(pd.DataFrame({"git_commit": ["abc", "abc"]})) == "Every row comes from commit abc."
    two = pd.DataFrame({"git_commit": ["def", "abc"]})
    assert provenance(two) == "Rows from 2 commits (see the Commit column): abc, def."


def test_binned_recall_counts_queries_and_pools_seeds_per_bin() -> None:
    q = pd.DataFrame(
        {
            "track": "predicted", "method": ["a"] * 6 + ["b"] * 2 + ["c"] * 2, "scene": "s", "split": "query",
            "query": [f"query/{i:06d}" for i in (0, 1, 2, 3, 4, 5, 0, 1, 0, 0)],  # c: one query, two seeds
            **errors([0.1, 0.4, 0.2, np.inf, 0.1, 0.3, 0.6, 0.2, 0.1, 0.4]),
            "gap_m": [0.1, 0.2, 0.3, 0.6, np.nan, 3.0, 0.1, 0.2, 0.1, 0.1],
            "visible_objects": [0, 1, 2, 5, 3, 9, 0, 1, 0, 0],
            "light_level": [1.0, 0.5, 0.5, 1.0, 1.0, 1.0, 1.0, 0.5, 1.0, 1.0],
        }
    )  # fmt: skip
    gap = binned_recall(q, "gap_m", (0, 0.25, 0.5, 2)).set_index(["method", "bin"])
    assert list(gap.loc["a"].index) == ["0–0.25", "0.25–0.5", "0.5–2"]  # no value, or past the last edge: left out
    assert gap.loc["a", ["n", "recall_50cm", "recall_25cm"]].values.tolist() == [[2, 100, 50], [1, 100, 100], [1, 0, 0]]
    assert gap.loc[("a", "0.5–2"), ["lo", "hi"]].tolist() == [0.5, 2.0] and set(gap["axis"]) == {"gap_m"}
    assert gap.loc[("b", "0–0.25"), ["n", "recall_50cm", "recall_25cm"]].tolist() == [2, 50, 50]
    assert gap.loc[("c", "0–0.25"), ["n", "recall_50cm", "recall_25cm"]].tolist() == [1, 100, 50]
    objects = binned_recall(q[q["method"] == "a"], "visible_objects", (0, 1, 2, 4, np.inf)).set_index("bin")
    assert list(objects.index) == ["0", "1", "2–3", "4+"]  # whole numbers: the counts a bin holds
    assert objects.loc["4+", ["n", "recall_50cm", "recall_25cm"]].tolist() == [2, 50, 0]
    far = q.assign(gap_m=q["gap_m"].replace(3.0, np.inf))  # an infinite gap lands in the open last bin
    assert binned_recall(far, "gap_m", (0, 1, np.inf)).groupby("bin")["n"].sum().to_dict() == {"0–1": 7, "≥1": 1}
    light = binned_recall(q[q["method"] == "a"], "light_level", None).set_index("bin")
    assert list(light.index) == ["0.5", "1"] and light["n"].tolist() == [2, 4] and light.loc["0.5", "lo"] == 0.5
    with pytest.raises(ValueError, match="increasing edges"):
        binned_recall(q, "gap_m", (0, 0.5, 0.25))
    with pytest.raises(ValueError, match="no column 'gap_deg'"):
        binned_recall(q, "gap_deg", (0, 10))


def test_paired_differences_compare_every_two_methods_of_a_track_on_the_queries_both_answered() -> None:
    """sift-pnp reads no masks, so it stands in the predicted track; a query only one method answered
    is not compared; seeds are averaged per query."""
    t_or = [0.1, 0.1, 0.1, 0.7, 0.1, 0.7]
    t_sift = [0.1, 0.7, 0.7, 0.7, 0.1]  # the sixth query: no row
    q = pd.concat(
        [
            queries("openreloc", "predicted", "query", t_or),
            queries("sift-pnp", "mask-free", "query", t_sift),
            queries("openreloc", "predicted", "query_light4", [0.7] * 6),
        ]
    )
    q["scene"], q["query"] = (
        "s",
        [f"query/{i}" for i in range(6)] + [f"query/{i}" for i in range(5)] + [f"query_light4/{i}" for i in range(6)],
    )
    p = paired_differences(q)
    row = p[(p.method == "openreloc") & (p.other == "sift-pnp") & (p.column == "recall_25cm")].iloc[0]
    assert row.track == "predicted" and row.n_queries == 5 and row["diff"] == pytest.approx(40.0)
    back = p[(p.method == "sift-pnp") & (p.other == "openreloc") & (p.column == "recall_25cm")].iloc[0]
    assert back["diff"] == pytest.approx(-40.0) and set(p.column) == {"recall_50cm", "recall_25cm"}
