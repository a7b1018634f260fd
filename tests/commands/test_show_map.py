"""`show-map`: labels that cover no other, a legend of the categories and what else is drawn."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from openreloc_bench.commands.show_map import LABEL_OFFSETS_PT, draw_map, label_size_pt, place_labels
from tests.openreloc.test_map import make_map


def boxes(anchors: np.ndarray, sizes: list[tuple[float, float]], offsets: list) -> list[tuple[float, ...]]:
    return [
        (x + dx - w / 2, y + dy - h / 2, x + dx + w / 2, y + dy + h / 2)
        for (x, y), (w, h), o in zip(anchors, sizes, offsets)
        if o is not None
        for dx, dy in [o]
    ]


def overlap(a: tuple[float, ...], b: tuple[float, ...]) -> bool:
    return a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]


def test_labels_apart_stay_on_their_landmark() -> None:
    anchors = np.array([[0.0, 0.0], [200.0, 0.0], [0.0, 200.0]])
    assert place_labels(anchors, [label_size_pt("12:chair")] * 3) == [(0.0, 0.0)] * 3


def test_labels_that_would_collide_move_aside_or_are_left_out() -> None:
    rng = np.random.default_rng(0)
    anchors = rng.uniform(0, 60, (40, 2))  # 40 labels crowded into 60 x 60 points
    sizes = [label_size_pt(f"{i}:side_table") for i in range(40)]
    offsets = place_labels(anchors, sizes)
    placed = boxes(anchors, sizes, offsets)
    assert not any(overlap(a, b) for i, a in enumerate(placed) for b in placed[i + 1 :])
    assert offsets[0] == (0.0, 0.0)  # the first (the most important) keeps its place
    assert 0 < offsets.count(None) < 40 and all(o is None or o in LABEL_OFFSETS_PT for o in offsets)
    same = place_labels(np.zeros((2, 2)), [(20.0, 8.0)] * 2)
    assert same[0] == (0.0, 0.0) and same[1] == (0.0, 9.0)  # one on the spot, the other just above


def test_show_map_has_a_category_legend(tmp_path: Path) -> None:
    ax = draw_map(make_map(), tmp_path / "m.png")
    assert (tmp_path / "m.png").stat().st_size > 10_000
    assert [t.get_text() for t in ax.get_legend().get_texts()] == [
        "cat1 (1)",
        "cat2 (1)",
        "cat3 (1)",
        "cat4 (1)",
        "filtered (1: walls, floors...)",
        "graph edge: nearest",
        "graph edge: boxes overlap",
        "reference frames (2)",
    ]
    labels = [t.get_text() for t in ax.texts]
    assert labels[0] == "1:cat1" and len(labels) == 5  # landmarks a metre apart: every label fits


def test_a_predicted_maps_landmarks_are_told_apart_by_id(tmp_path: Path) -> None:
    m = make_map()
    for lm in m.landmarks.values():
        lm.category = None  # a segmenter's landmarks carry no ground-truth category
    ax = draw_map(m, tmp_path / "m.png")
    legend = [t.get_text() for t in ax.get_legend().get_texts()]
    assert legend[0] == "landmarks, coloured by id (a predicted map names no category) (4)"
    assert not any(t.startswith("no category") for t in legend)
    colours = {tuple(c.get_facecolor()[0][:3]) for c in ax.collections[:5] if len(c.get_offsets())}
    assert len(colours) >= 4  # four valid landmarks, four colours (the filtered one grey)
