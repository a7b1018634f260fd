"""The board's verdict, table order, robustness table, provenance line, data version, recall against
difficulty and top-down plots."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from openreloc_bench.data.runs import backfill_difficulty
from openreloc_bench.data.scene import DIFFICULTY_AXES
from openreloc_bench.harness.leaderboard import (
    ABLATIONS,
    binned_recall,
    board_scene,
    clip_to_extent,
    data_versions,
    method_colors,
    plot_cumulative,
    plot_recall_vs_difficulty,
    plot_recall_vs_lighting,
    plot_recall_vs_map_size,
    plot_scene_recall,
    plot_topdown,
    provenance,
    robustness_drops,
    to_html,
    to_markdown,
    topdown_extent,
    verdict,
    write_leaderboard,
)
from tests.generators.test_preview import write_plan_scene


def rows(method: str, track: str, recalls: dict[str, tuple[float, float]], seeds: dict[str, int]) -> pd.DataFrame:
    return pd.DataFrame(
        [
            {"method": method, "track": track, "split": split, "recall_50cm": r50, "recall_25cm": r25,
             "n_seeds": seeds.get(split, 1), "git_commit": "abc"}
            for split, (r50, r25) in recalls.items()
        ]
    )  # fmt: skip


def runs(*rows: tuple[str, str, float, float, float], split: str = "query") -> pd.DataFrame:
    """Board rows: (method, track, R@50cm, R@25cm, map MB) on one split."""
    return pd.DataFrame(
        [{"method": m, "track": t, "split": split, "recall_50cm": r50, "recall_25cm": r25, "map_mb": mb}
         for m, t, r50, r25, mb in rows]
    )  # fmt: skip


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


def test_boards_open_with_the_verdict_then_the_predicted_table_then_the_oracle_mask_table() -> None:
    b = runs(("openreloc", "oracle-mask", 88.7, 82.7, 0.68), ("sift-pnp", "mask-free", 66.3, 66.0, 12.1),
             ("openreloc", "predicted", 32.7, 20.3, 0.74))  # fmt: skip
    scenes = pd.DataFrame(columns=["method", "track", "split", "scene", "map_mb"])
    md = to_markdown(b, scenes).splitlines()
    assert md[2] == f"**Verdict (query split, recall [%]):** {verdict(b)}" and md[2].count("\n") == 0
    headings = [ln for ln in md if ln.startswith("## ")]
    assert headings[0].startswith("## Predicted track (headline)") and headings[1].startswith("## Oracle-mask track")
    page = to_html(b, [])
    assert page.index("<h1>") < page.index('<p class="verdict"><strong>Verdict (query split, recall [%]):</strong>')
    assert page.index('class="verdict"') < page.index("<h2>Predicted track (headline)") < page.index("<h2>Oracle-mask")


def legend(ax) -> list[str]:
    return [t.get_text() for t in ax.get_legend().get_texts()]


def test_recall_vs_map_size_has_a_panel_per_track_with_every_method(tmp_path: Path) -> None:
    png = tmp_path / "p.png"
    suite = pd.concat(
        [
            runs(("a", "predicted", 60.0, 40.0, 0.7), ("a", "oracle-mask", 90.0, 80.0, 0.68),
                 ("free", "mask-free", 66.0, 65.0, 221.0), ("sub", "predicted", 50.0, 30.0, np.nan)),
            runs(("a", "predicted", 10.0, 5.0, 0.7), split="query_light4"),
        ]
    )  # fmt: skip
    pred, oracle = plot_recall_vs_map_size(suite, png)
    assert (pred.get_title(), oracle.get_title()) == ("Predicted track", "Oracle-mask track")
    assert legend(pred) == ["a", "free (mask-free)", "sub: no map size, on the axis"]
    assert legend(oracle) == ["a", "free (mask-free)"]  # the mask-free method stands in both panels
    filled = {c.get_label(): c.get_offsets().tolist() for c in pred.collections if not c.get_label().startswith("_")}
    assert filled["a"] == [[0.7, 40.0]] and filled["free (mask-free)"] == [[221.0, 65.0]]
    assert filled["sub: no map size, on the axis"] == [[0.0, 30.0]]  # x in axes units: the left edge
    assert plot_recall_vs_map_size(suite[suite["split"] != "query"], png) == []


def test_every_plot_of_a_board_draws_every_method(tmp_path: Path) -> None:
    png = tmp_path / "p.png"
    methods = [("a", "predicted"), ("a", "oracle-mask"), ("free", "mask-free"), ("sub", "predicted")]
    q = pd.DataFrame(
        [{"method": m, "track": t, "split": sp, "t_err_m": 0.1, "r_err_deg": 1.0}
         for m, t in methods for sp in ("query", "query_light4")]
    )  # fmt: skip
    labels = ["a (predicted)", "a (oracle-mask)", "free (mask-free)", "sub (predicted)"]
    for col in ("t_err_m", "r_err_deg"):
        assert sorted(legend(plot_cumulative(q, col, 1.0, "error", png))) == sorted(labels)
    scenes = pd.DataFrame(
        [{"method": m, "track": t, "split": "query", "scene": sc, "recall_50cm": 50.0, "recall_25cm": 40.0}
         for m, t in methods for sc in ("s1", "s2")]
    )  # fmt: skip
    assert legend(plot_scene_recall(scenes, png)) == [
        "a (predicted)", "sub (predicted)", "a (oracle-mask)", "free (mask-free)"
    ]  # fmt: skip
    suite = pd.concat(
        [
            runs(*[(m, t, 50.0, 40.0, 1.0) for m, t in methods]),
            runs(("a", "predicted", 20.0, 10.0, 1.0), split="query_light2"),
        ]
    )
    (ax,) = plot_recall_vs_lighting(suite, png)
    assert legend(ax) == [
        "a (predicted)", "sub (predicted), original only", "a (oracle-mask), original only", "free (mask-free), original only"
    ]  # fmt: skip
    assert plot_recall_vs_lighting(suite[suite["split"] == "query"], png) == []  # no decayed level


def test_each_method_keeps_one_colour_and_a_whole_plan_repeats_none() -> None:
    colors = method_colors(["b", "a", "b"])
    assert list(colors) == ["a", "b"] and colors["a"] != colors["b"]
    plan = ["openreloc", "openreloc-paper", "goreloc", "sift-pnp", "orb-reloc", "retrieval", "posenet", "nearest-frame",
            "openreloc-oracle-association", *ABLATIONS]  # fmt: skip
    assert len(set(method_colors(plan).values())) == len(plan)


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


def errors(t: list[float]) -> dict[str, np.ndarray]:
    """Translation errors as given, 1° of rotation where localized (inf where not)."""
    t_err = np.array(t, dtype=float)
    return {"t_err_m": t_err, "r_err_deg": np.where(np.isfinite(t_err), 1.0, np.inf)}


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
    light = binned_recall(q[q["method"] == "a"], "light_level", None).set_index("bin")
    assert list(light.index) == ["0.5", "1"] and light["n"].tolist() == [2, 4] and light.loc["0.5", "lo"] == 0.5
    with pytest.raises(ValueError, match="increasing edges"):
        binned_recall(q, "gap_m", (0, 0.5, 0.25))
    with pytest.raises(ValueError, match="no column 'gap_deg'"):
        binned_recall(q, "gap_deg", (0, 10))


def results_dir(root: Path, method: str, versioned: bool = True) -> Path:
    """A results folder whose tables/queries.csv holds eight queries of one scene on two splits, with their
    difficulty and data v2, or (not ``versioned``) as tables were written before either existed."""
    q = pd.DataFrame(
        {
            "method": method, "track": "predicted", "scene": "s1", "split": ["query"] * 4 + ["query_light1"] * 4,
            "query": [f"{s}/{i:06d}" for s in ("query", "query_light1") for i in range(4)],
            "success": True, **errors([0.1, 0.3, 0.6, 0.1, 0.3, 0.3, 0.6, 0.6]), "runtime_s": 0.01, "reason": "",
            **{f"{p}_{a}": 0.0 for p in ("gt", "est") for a in "xyz"},
            "map_hash": "h", "config_hash": "c", "spec_hash": "spec", "git_commit": "abc",
            "gap_m": [0.1, 0.3, 0.6, 0.1] * 2, "gap_deg": np.nan, "light_level": [1.0] * 4 + [0.5] * 4,
            "visible_objects": 3, "object_area": np.nan, "displaced_in_view": 0, "lookalikes_in_view": [0, 1] * 4,
        }
    )  # fmt: skip
    if versioned:
        q["data_version"] = 2
    else:
        q = q.drop(columns=list(DIFFICULTY_AXES))
    (root / "tables").mkdir(parents=True)
    q.to_csv(root / "tables" / "queries.csv", index=False)
    return root


def test_boards_plot_recall_against_each_difficulty_axis_with_values(tmp_path: Path) -> None:
    out = tmp_path / "board"
    files = write_leaderboard([results_dir(tmp_path / "r", "m")], out)
    png = out / "plots" / "difficulty_predicted.png"
    assert png in files and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    md = (out / "leaderboard.md").read_text()
    assert md.startswith("# openreloc-bench leaderboard (data v2)\n")
    assert "## Recall vs difficulty" in md and "![recall vs difficulty](plots/difficulty_predicted.png)" in md
    page = (out / "index.html").read_text()
    assert "<h1>openreloc-bench leaderboard (data v2)</h1>" in page and 'src="plots/difficulty_predicted.png"' in page
    numbers = pd.read_csv(out / "difficulty.csv").set_index(["axis", "bin"])
    # pooled over both splits: gap 0.1 m twice per split (errors 0.1, 0.1, 0.3, 0.6 m); light 1 and 0.5 vary
    assert numbers.loc[("gap_m", "0–0.25"), ["n", "recall_50cm", "recall_25cm"]].tolist() == [4, 75, 50]
    assert numbers.loc[("light_level", "0.5"), ["n", "recall_50cm", "recall_25cm"]].tolist() == [4, 50, 0]
    drawn = plot_recall_vs_difficulty(numbers.reset_index(), "predicted track", tmp_path / "p.png")
    assert drawn == ["gap_m", "light_level", "lookalikes_in_view"]  # all NaN or one value: no panel


def test_boards_name_the_data_version_they_score(tmp_path: Path) -> None:
    out = tmp_path / "board"
    write_leaderboard([results_dir(tmp_path / "old", "m", versioned=False)], out)
    md = (out / "leaderboard.md").read_text()
    assert md.startswith("# openreloc-bench leaderboard (data v1)\n")  # tables without the column: v1 data
    assert "Recall vs difficulty" not in md and not (out / "plots" / "difficulty_predicted.png").exists()
    q = pd.DataFrame({"spec_hash": ["a", "file:0f3e", "b"], "data_version": [2, 2, 2]})
    assert (
        data_versions(backfill_difficulty(q.drop(columns="data_version"))) == "data v1, scenes without a data version"
    )
    assert data_versions(q.assign(data_version=[1, 2, 2])) == "data v1 + v2"
    assert data_versions(q) == "data v2"


def topdown_queries(scene: str = "plan") -> pd.DataFrame:
    """Three queries of one run: one estimate 10 cm off, one 17 m away (outside the building), one failed."""
    gt = np.array([[1.0, 1.0], [-2.0, 1.0], [2.0, -2.0]])
    est = np.array([[1.1, 1.0], [19.0, 1.0], [np.nan, np.nan]])
    return pd.DataFrame(
        {
            "method": "m", "track": "predicted", "scene": scene, "split": "query",
            "query": [f"query/{i:06d}" for i in range(3)], "success": [True, True, False],
            "gt_x": gt[:, 0], "gt_y": gt[:, 1], "gt_z": 1.5, "est_x": est[:, 0], "est_y": est[:, 1], "est_z": 1.5,
            "t_err_m": [0.1, 17.0, np.inf], "spec_hash": "tiny-0",
        }
    )  # fmt: skip


def test_topdown_extent_is_the_building_or_the_true_cameras() -> None:
    gt = np.array([[0.0, 0.0], [1.0, 2.0], [np.nan, np.nan]])
    lo, hi, what = topdown_extent(gt)
    assert what == "view" and lo.tolist() == [-2.0, -2.0] and hi.tolist() == [3.0, 4.0]
    drawn, outside = clip_to_extent(np.array([[0.5, 0.5], [20.0, -9.0]]), lo, hi)
    assert outside.tolist() == [False, True] and drawn.tolist() == [[0.5, 0.5], [3.0, -2.0]]


def test_topdown_over_the_floor_plan_shows_estimates_that_left_the_building(tmp_path: Path) -> None:
    scene = write_plan_scene(tmp_path / "plan")
    lo, hi, what = topdown_extent(np.zeros((1, 2)), scene)
    assert what == "building" and lo.tolist() == [-4.5, -4.5] and hi.tolist() == [4.5, 4.5]
    (ax,) = plot_topdown(topdown_queries(), "plan", tmp_path / "t.png", scene)
    assert ax.get_title() == "m (predicted)\n2/3 returned a pose, 1 within 50 cm"
    assert [t.get_text() for t in ax.get_legend().get_texts()] == [
        "true position (3)",
        "estimate (1)",
        "estimate outside the building (1), drawn at the edge",
        "no pose returned (1)",
    ]
    edge = next(c for c in ax.collections if c.get_label().startswith("estimate outside"))
    assert edge.get_offsets().tolist() == [[4.5, 1.0]]
    plan = [t.get_text() for t in ax.figure.legends[0].get_texts()]
    assert plan == ["room: kitchen", "room: office", "walls", "doors", "objects (2)"]  # moves belong to another split
    assert ax.figure.get_suptitle() == "plan: camera positions, top-down over its floor plan"
    (ax,) = plot_topdown(topdown_queries(), "plan", tmp_path / "t.png")
    assert not ax.figure.legends and "estimate outside the view (1), drawn at the edge" in [
        t.get_text() for t in ax.get_legend().get_texts()
    ]


def test_board_scene_only_draws_the_plan_of_the_scene_the_runs_ran_on(tmp_path: Path, caplog) -> None:
    write_plan_scene(tmp_path / "data" / "plan")
    assert board_scene(None, "plan") is None
    assert board_scene(tmp_path / "data", "plan", ["tiny-0"]).name == "plan"
    assert board_scene(tmp_path / "data", "plan", ["tiny-7"]) is None and "is spec tiny-0" in caplog.text
    assert board_scene(tmp_path / "data", "elsewhere") is None and "no scene elsewhere" in caplog.text
    out = tmp_path / "board"
    write_leaderboard([results_dir(tmp_path / "r", "m")], out, tmp_path / "data")  # scene s1: not there, no plan
    assert (out / "plots" / "topdown_s1.png").is_file()
