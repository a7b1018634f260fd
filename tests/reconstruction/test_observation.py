"""Depth-tested observation of the fused box room: occlusion, the segmenter's boundaries, frustum culling."""

from __future__ import annotations

import numpy as np

from openreloc_bench import geometry
from openreloc_bench.reconstruction.frames import read_color, read_depth
from openreloc_bench.reconstruction.observation import ObservationConfig, observe
from tests.openreloc.boxworld import NoisyMaskSegmenter


def test_observation_discards_occluded_points(room: tuple) -> None:
    seq, rec, obs = room
    o = obs[0]
    uv, z = geometry.project(seq.K, seq.records[0].T_wc, rec.points[o.point_idx])
    depth = read_depth(seq, 0)
    assert np.all(np.abs(z - depth[o.uv[:, 1], o.uv[:, 0]]) < 0.2)
    # points of a box hidden behind another are not in the frame's seen set
    assert len(o.point_idx) < 0.5 * len(rec.points)


def test_observation_keeps_the_segmenters_boundaries_and_colours_at_seen_pixels(room: tuple) -> None:
    seq, _, obs = room
    o = obs[3]
    rgb = read_color(seq, o.index)
    np.testing.assert_array_equal(o.rgb, rgb[o.uv[:, 1], o.uv[:, 0]])
    assert o.boundary.shape == o.point_idx.shape and set(np.unique(o.boundary)) <= {0.0, 1.0}
    assert 0 < o.boundary.mean() < 0.5  # mask borders only
    rec = room[1]
    blind = observe(seq, rec.points, rec.usable, ObservationConfig(), None, progress=False)[3]
    assert blind.boundary is None and blind.rgb is None and not blind.masks
    plain = observe(seq, rec.points, rec.usable, ObservationConfig(), NoisyMaskSegmenter(), progress=False)[3]
    assert plain.masks and plain.boundary is None and plain.rgb is None  # kept only when asked for


def test_frustum_culling_sees_exactly_what_full_projection_sees(room: tuple) -> None:
    seq, rec, obs = room
    full = observe(seq, rec.points, rec.usable, ObservationConfig(cell_size=0.0), progress=False)
    fine = observe(seq, rec.points, rec.usable, ObservationConfig(cell_size=0.3), progress=False)
    for a, b, c in zip(full, fine, obs):
        np.testing.assert_array_equal(a.point_idx, b.point_idx)
        np.testing.assert_array_equal(a.point_idx, c.point_idx)  # the fixture's default cell size
        np.testing.assert_array_equal(a.uv, b.uv)
