"""One query's picture: the keypoints and objects a method says it matched, and the query's error."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from openreloc_bench import matchview
from openreloc_bench.methods import DRAWN_POINTS, Answer, drawn_points


def test_drawn_points_round_and_flag_what_the_pose_kept() -> None:
    assert drawn_points(np.array([[1.234, 5.0], [7.0, 8.06]]), np.array([True, False])) == [
        [1.2, 5.0, 1],
        [7.0, 8.1, 0],
    ]


def test_points_are_found_at_the_top_or_one_level_down_and_boxes_in_matches() -> None:
    diag = {DRAWN_POINTS: [[1, 2, 1]], "anchors": {DRAWN_POINTS: [[3, 4, 0]]}, "matches": 12}
    assert matchview.drawn_points_of(diag).tolist() == [[1, 2, 1], [3, 4, 0]]
    assert matchview.drawn_points_of({}).shape == (0, 3) and matchview.matched_boxes(diag) == []
    matches = [{"box": [0, 0, 5, 5], "landmark": 7, "category": None, "phrase": "a red chair"}, {"box": None}]
    assert matchview.matched_boxes({"matches": matches}) == [([0, 0, 5, 5], "7: a red chair")]


def test_the_caption_gives_the_error_or_the_reason(tmp_path: Path) -> None:
    T = np.eye(4)
    off = T.copy()
    off[0, 3] = 0.042
    assert matchview.caption(Answer("query/000003", off, 0.1), T) == "query/000003: 4.2 cm, 0.0°"
    failed = Answer("query/000003", None, 0.1, "3 inliers")
    assert matchview.caption(failed, T) == "query/000003: no pose (3 inliers)"
    rgb = np.zeros((24, 32, 3), np.uint8)
    answer = Answer("query/000003", off, 0.1, diagnostics={DRAWN_POINTS: [[3, 4, 1], [10, 12, 0]]})
    matchview.draw_query(rgb, answer, T, "m", tmp_path / "q.png")
    assert (tmp_path / "q.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
