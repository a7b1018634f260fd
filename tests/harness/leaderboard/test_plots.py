"""The board's plots: every method in each, one colour per method, and the top-down camera positions."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from openreloc_bench.harness.leaderboard import write_leaderboard
from openreloc_bench.harness.leaderboard.plots import (
    board_scene,
    clip_to_extent,
    method_colors,
    plot_cumulative,
    plot_recall_vs_lighting,
    plot_recall_vs_map_size,
    plot_scene_recall,
    plot_topdown,
    topdown_extent,
)
from openreloc_bench.harness.leaderboard.verdict import ABLATIONS
from tests.generators.test_preview import write_plan_scene
from tests.harness.leaderboard.boards import results_dir, runs


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
    assert sorted(colors) == ["a", "b"] and colors["a"] != colors["b"]
    # a method's colour does not depend on which others a board shows
    one = method_colors(["openreloc", "nearest-frame"])
    other = method_colors(["sift-pnp", "posenet", "openreloc", "my-plugin"])
    assert one["openreloc"] == other["openreloc"] and one["nearest-frame"] not in other.values()
    plan = ["openreloc", "openreloc-paper", "goreloc", "sift-pnp", "orb-reloc", "retrieval", "posenet", "nearest-frame",
            "openreloc-oracle-association", *ABLATIONS]  # fmt: skip
    assert len(set(method_colors(plan).values())) == len(plan)


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


def test_board_scene_only_draws_the_floor_plan_of_the_scene_the_runs_ran_on(tmp_path: Path, caplog) -> None:
    write_plan_scene(tmp_path / "data" / "plan")
    assert board_scene(None, "plan") is None
    assert board_scene(tmp_path / "data", "plan", ["tiny-0"]).name == "plan"
    assert board_scene(tmp_path / "data", "plan", ["tiny-7"]) is None and "is spec tiny-0" in caplog.text
    assert board_scene(tmp_path / "data", "elsewhere") is None and "no scene elsewhere" in caplog.text
    out = tmp_path / "board"
    write_leaderboard([results_dir(tmp_path / "r", "m")], out, tmp_path / "data")  # scene s1: not there, no plan
    assert (out / "plots" / "topdown_s1.png").is_file()
