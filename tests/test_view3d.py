"""The 3D figure of a map's points (``view``): its traces, the point cap, the frustums and the estimates out of view."""

from __future__ import annotations

import numpy as np
import pytest

from openreloc_bench import geometry, view3d
from tests.openreloc.test_map import make_map as make_object_map


def make_map():
    """An OpenReLoc map's points: 4 valid landmarks and a filtered one (a wall), 50 points each."""
    return make_object_map().drawn()


def traces_by_name(fig) -> dict[str, list]:
    out: dict[str, list] = {}
    for t in fig.data:
        out.setdefault(t.name, []).append(t)
    return out


def legend(fig) -> list[str]:
    return [t.name for t in fig.data if t.showlegend is not False]


def queries() -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """Three queries: one estimated 10 cm off, one 1 m off, one 17 m away (out of the building), one missed."""
    true = {f"query/00000{i}": geometry.look_at([i, -2.0, 1.5], [i, 0.0, 0.5]) for i in range(4)}
    est = {}
    for i, shift in enumerate((0.1, 1.0, 17.0)):
        T = true[f"query/00000{i}"].copy()
        T[0, 3] += shift
        est[f"query/00000{i}"] = T
    return true, est


def test_point_strides_keep_every_point_under_the_cap_and_a_share_above() -> None:
    assert view3d.point_strides([10, 20], 100) == [1, 1]
    counts = [10_000, 1_000, 3]
    strides = view3d.point_strides(counts, 1_100)
    kept = [len(range(0, n, s)) for n, s in zip(counts, strides)]
    assert kept[2] >= 1 and sum(kept) <= 1_100 + len(counts)
    assert kept[0] > kept[1] > 0


def test_frustums_have_their_apex_at_the_camera_and_their_base_in_front() -> None:
    T = geometry.look_at([1.0, 2.0, 3.0], [1.0, 5.0, 3.0])  # looking along +y
    K = geometry.intrinsics_from_fov(64, 48, 60.0)
    x, y, z = view3d.frustum_lines(np.stack([T, T]), K, 64, 48, depth=0.5)
    assert len(x) == 22 and x[10] is None and x[21] is None
    pts = np.array([x[:10], y[:10], z[:10]], dtype=float).T
    assert np.allclose(pts[5], [1, 2, 3]) and np.allclose(pts[8], [1, 2, 3])  # the apex, twice per strip
    assert np.allclose(pts[:4, 1], 2.5)  # the four base corners, 0.5 m ahead


def test_map_figure_draws_landmarks_cameras_and_the_mapping_path() -> None:
    m = make_map()
    mapping = np.stack([geometry.look_at([x, -3.0, 1.5], [x, 0.0, 0.5]) for x in np.linspace(0, 5, 20)])
    fig = view3d.map_figure(m, mapping)
    names = traces_by_name(fig)
    assert legend(fig) == [
        "landmarks (4)",
        "filtered landmarks (walls, floors...) (1)",
        "reference frames (2)",
        "mapping path (20 frames)",
    ]
    assert all(t.type == "scatter3d" for t in fig.data)
    (valid,) = names["landmarks (4)"]
    assert valid.text[0] == "landmark 1: cat1<br>valid, 50 points, seen in 1 frame"
    (filtered,) = names["filtered landmarks (walls, floors...) (1)"]
    assert filtered.text[0].startswith("landmark 5: wall<br>filtered") and filtered.marker.color == view3d.MUTED_COLOR
    assert len(set(valid.marker.color)) == 4  # one colour per valid landmark
    centres = [t for t in names["reference frames (2)"] if t.mode == "markers"][0]
    assert centres.text[0].startswith("reference frame ") and centres.text[0].endswith("landmarks in view")
    assert len(names["mapping path (20 frames)"][0].x) == 20
    mapping_frustums = [t for t in fig.data if t.legendgroup == "mapping" and t.mode == "lines"][0]
    assert sum(v is None for v in mapping_frustums.x) == view3d.MAX_MAPPING_FRUSTUMS
    assert fig.layout.title.text.startswith("5 landmarks (4 valid), 2 reference frames, 250 points")


def test_map_figure_caps_the_points_drawn() -> None:
    fig = view3d.map_figure(make_map(), max_points=40)
    drawn = sum(len(t.x) for t in fig.data if t.legendgroup in (view3d.POINTS_GROUP, view3d.MUTED_GROUP))
    assert 5 <= drawn <= 45


def test_estimates_are_joined_to_the_true_cameras_and_coloured_by_distance() -> None:
    true, est = queries()
    fig = view3d.map_figure(make_map(), true_poses=true, estimates=est)
    names = traces_by_name(fig)
    assert "true cameras (3 returned a pose)" in legend(fig)
    assert "no pose returned (1, true cameras)" in legend(fig)
    assert "estimated, within 50 cm (1)" in legend(fig)
    beyond = "estimated, beyond 50 cm (2; 1 outside the view, drawn at its edge)"
    assert beyond in legend(fig)
    within_markers = [t for t in names["estimated, within 50 cm (1)"] if t.mode == "markers"][0]
    assert within_markers.marker.color == view3d.WITHIN_COLOR and "error 10.0 cm" in within_markers.text[0]
    markers = [t for t in names[beyond] if t.mode == "markers"][0]
    assert markers.marker.color == view3d.BEYOND_COLOR
    assert list(markers.marker.symbol) == ["circle", "x"]
    # the 17 m estimate sits at the view's edge: 1 m beyond the farthest landmark, camera or true query
    assert markers.x[1] == pytest.approx(6.0 + view3d.VIEW_MARGIN_M, abs=0.01)
    assert "outside the view" in markers.text[1] and "estimated at (19.0, -2.0, 1.5)" in markers.text[1]
    lines = [t for t in names[beyond] if t.mode == "lines" and t.line.dash == "dash"][0]
    assert sum(v is None for v in lines.x) == 2  # one segment per estimate
    assert "3/4 queries returned a pose, 1 within 50 cm (recall 25%)" in fig.layout.title.text


def test_an_estimate_without_a_true_pose_is_refused() -> None:
    true, est = queries()
    del true["query/000000"]
    with pytest.raises(ValueError, match="query/000000"):
        view3d.map_figure(make_map(), true_poses=true, estimates=est)
