"""The board's robustness table and provenance line."""

from __future__ import annotations

import pandas as pd

from openreloc_bench.harness.leaderboard import provenance, robustness_drops


def rows(method: str, track: str, recalls: dict[str, tuple[float, float]], seeds: dict[str, int]) -> pd.DataFrame:
    return pd.DataFrame(
        [
            {"method": method, "track": track, "split": split, "recall_50cm": r50, "recall_25cm": r25,
             "n_seeds": seeds.get(split, 1), "git_commit": "abc"}
            for split, (r50, r25) in recalls.items()
        ]
    )  # fmt: skip


def test_drops_are_changes_from_the_query_split_in_points() -> None:
    b = pd.concat(
        [
            rows("m", "predicted", {"query": (40.0, 30.0), "query_light4": (35.5, 30.0)}, {}),
            rows("m", "oracle-mask", {"query": (90.0, 80.0), "query_displaced": (91.0, 79.0)}, {"query": 3}),
            rows("only-query", "predicted", {"query": (10.0, 5.0)}, {}),
        ]
    )
    d = robustness_drops(b).set_index(["Method", "Track"])
    assert list(d.index) == [("m", "predicted"), ("m", "oracle-mask")]  # a method run on the query split only has none
    assert d.loc[("m", "predicted"), "query"] == "40.0 / 30.0"
    assert d.loc[("m", "predicted"), "query_light4"] == "-4.5 / +0.0"
    assert d.loc[("m", "predicted"), "query_displaced"] == "-"
    assert d.loc[("m", "oracle-mask"), "query_displaced"] == "+1.0 / -1.0 (over 1 seed(s))"  # query pooled 3 seeds
    assert "query_light1" not in d.columns  # no method ran it


def test_provenance_names_one_commit_or_each() -> None:
    one = rows("m", "predicted", {"query": (1.0, 1.0)}, {})
    assert provenance(one) == "Every row comes from commit abc."
    two = pd.concat([one, one.assign(git_commit="def")])
    assert provenance(two) == "Rows from 2 commits (see the Commit column): abc, def."
