"""TSDF fusion, depth-tested observation and both instance-lifting paths on an analytic box room."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from openreloc_bench.data import io
from openreloc_bench.data.scene import ObjectInfo, Scene
from openreloc_bench.errors import DataError
from openreloc_bench.openreloc import mapping as M
from openreloc_bench.openreloc.incidence import incidence
from openreloc_bench.openreloc.instance_eval import instance_report
from tests.openreloc.boxworld import ROOM, NoisyMaskSegmenter, boxworld_sequence

FUSION = M.FusionConfig(voxel_size=0.05)


@pytest.fixture(scope="module")
def room(tmp_path_factory: pytest.TempPathFactory) -> tuple:
    seq = boxworld_sequence(tmp_path_factory.mktemp("room"), n_frames=16, hw=(96, 128))
    rec = M.fuse_tsdf(seq, FUSION, progress=False)
    obs = M.observe(
        seq,
        rec.points,
        rec.usable,
        M.ObservationConfig(),
        NoisyMaskSegmenter(split_prob=0.0),
        progress=False,
        boundaries=True,
    )
    return seq, rec, obs


def box_distance(points: np.ndarray) -> np.ndarray:
    """Distance of each point to the nearest box surface of the room (exact, analytic)."""
    d = []
    for b in ROOM:
        lo, hi = np.array(b.lo), np.array(b.hi)
        outside = np.linalg.norm(np.maximum(0, np.maximum(lo - points, points - hi)), axis=1)
        inside = np.min(np.minimum(points - lo, hi - points), axis=1)
        d.append(np.where(outside > 0, outside, inside))
    return np.min(d, axis=0)


def test_fused_cloud_lies_on_the_boxes(room: tuple) -> None:
    _, rec, _ = room
    assert len(rec.points) > 5000 and rec.usable.all() and not rec.skipped
    assert np.median(box_distance(rec.points)) < 0.02
    assert np.quantile(box_distance(rec.points), 0.95) < FUSION.voxel_size


def test_voting_labels_points_with_the_box_they_lie_on(room: tuple) -> None:
    _, rec, obs = room
    labels = M.lift_by_voting(len(rec.points), obs, M.VotingConfig())
    sets = M.instance_sets(labels, 20)
    assert {1, 2, 3, 4, 5, 11, 12, 14} <= set(sets)
    for b in ROOM:
        if b.id in sets:
            pts = rec.points[sets[b.id]]
            inside = np.all((pts >= np.array(b.lo) - 0.06) & (pts <= np.array(b.hi) + 0.06), axis=1)
            assert inside.mean() > 0.95, b.category


def test_observation_discards_occluded_points(room: tuple) -> None:
    seq, rec, obs = room
    o = obs[0]
    uv, z = M.geometry.project(seq.K, seq.records[0].T_wc, rec.points[o.point_idx])
    depth = M.read_depth(seq, 0)
    assert np.all(np.abs(z - depth[o.uv[:, 1], o.uv[:, 0]]) < 0.2)
    # points of a box hidden behind another are not in the frame's seen set
    assert len(o.point_idx) < 0.5 * len(rec.points)


def test_observation_keeps_the_segmenters_boundaries_and_colours_at_seen_pixels(room: tuple) -> None:
    seq, _, obs = room
    o = obs[3]
    rgb = M.read_color(seq, o.index)
    np.testing.assert_array_equal(o.rgb, rgb[o.uv[:, 1], o.uv[:, 0]])
    assert o.boundary.shape == o.point_idx.shape and set(np.unique(o.boundary)) <= {0.0, 1.0}
    assert 0 < o.boundary.mean() < 0.5  # mask borders only
    rec = room[1]
    blind = M.observe(seq, rec.points, rec.usable, M.ObservationConfig(), None, progress=False)[3]
    assert blind.boundary is None and blind.rgb is None and not blind.masks
    plain = M.observe(seq, rec.points, rec.usable, M.ObservationConfig(), NoisyMaskSegmenter(), progress=False)[3]
    assert plain.masks and plain.boundary is None and plain.rgb is None  # kept only when asked for


def test_clustering_of_noisy_masks_recovers_instances(room: tuple) -> None:
    _, rec, obs = room
    gt = M.instance_sets(M.lift_by_voting(len(rec.points), obs, M.VotingConfig()), 20)
    pred = M.instance_sets(M.lift_by_clustering(rec.points, obs, M.ClusteringConfig()), 20)
    q = instance_report(rec.points, pred, gt)
    assert q["recall"] >= 0.85 and q["precision"] >= 0.75, q


def test_frustum_culling_sees_exactly_what_full_projection_sees(room: tuple) -> None:
    seq, rec, obs = room
    full = M.observe(seq, rec.points, rec.usable, M.ObservationConfig(cell_size=0.0), progress=False)
    fine = M.observe(seq, rec.points, rec.usable, M.ObservationConfig(cell_size=0.3), progress=False)
    for a, b, c in zip(full, fine, obs):
        np.testing.assert_array_equal(a.point_idx, b.point_idx)
        np.testing.assert_array_equal(a.point_idx, c.point_idx)  # the fixture's default cell size
        np.testing.assert_array_equal(a.uv, b.uv)


def test_fusion_of_subsampled_depth_stays_on_the_surfaces(room: tuple) -> None:
    seq, rec, _ = room
    half = M.fuse_tsdf(seq, M.FusionConfig(voxel_size=0.05, max_fusion_width=64), progress=False)
    assert len(half.points) > 0.8 * len(rec.points)
    assert np.median(box_distance(half.points)) < 0.02


def test_undersegmented_masks_are_dropped(room: tuple) -> None:
    """A mask spanning two objects of similar size in one frame is split in the other frames, so it
    is dropped instead of fusing the two objects into one cluster."""
    _, rec, obs = room
    vote = M.lift_by_voting(len(rec.points), obs, M.VotingConfig())
    o, pair = obs[4], (12, 2)  # frame 4 sees the sofa and the wall behind it about equally (~500 points each)
    assert 0.6 < (vote[o.point_idx] == 12).sum() / (vote[o.point_idx] == 2).sum() < 1.6
    merged = np.flatnonzero(np.isin(vote[o.point_idx], pair)).astype(np.int32)
    obs2 = [M.FrameObservation(x.index, x.point_idx, x.uv, x.gt_ids, list(x.masks)) for x in obs]
    others = [m for m in o.masks if not np.isin(np.bincount(vote[o.point_idx[m]]).argmax(), pair)]
    obs2[obs.index(o)].masks = others + [merged]  # the two objects' masks replaced by one
    cfg = M.ClusteringConfig()
    masks = [(f, m) for f, ob in enumerate(obs2) for m in ob.masks if len(m) >= cfg.min_mask_points]
    Mx = incidence(
        np.concatenate([np.full(len(m), k) for k, (_, m) in enumerate(masks)]),
        np.concatenate([obs2[f].point_idx[m] for f, m in masks]),
        (len(masks), len(rec.points)),
    )
    _, _, keep = M._mask_frame_stats(Mx, np.array([f for f, _ in masks]), len(obs2), cfg)
    k = next(k for k, (_, m) in enumerate(masks) if m is merged)
    assert not keep[k] and keep.mean() > 0.8
    labels = M.lift_by_clustering(rec.points, obs2, cfg)
    assert instance_report(rec.points, M.instance_sets(labels, 20), M.instance_sets(vote, 20))["recall"] >= 0.85


def test_box_point_labels_prefer_the_smallest_box_and_absorb_surface_noise() -> None:
    objects = {
        1: ObjectInfo(1, "floor", aabb=[[-2, -2, -0.1], [2, 2, 0.0]], structural=True),
        2: ObjectInfo(2, "table", aabb=[[0, 0, 0], [1, 1, 0.8]]),
        3: ObjectInfo(3, "lamp", aabb=[[0.4, 0.4, 0.8], [0.6, 0.6, 1.2]]),
    }
    pts = np.array(
        [
            [-1, -1, 0.01],  # floor with surface noise above it: only within the margin of the floor
            [0.5, 0.5, 0.79],  # table top
            [0.5, 0.5, 0.81],  # lamp base (inside the table box's margin too: the strict lamp box wins)
            [0.5, 0.5, -0.005],  # floor under the table: strictly inside the floor only
            [3, 3, 3],  # nowhere
        ]
    )
    np.testing.assert_array_equal(M.box_point_labels(pts, objects, 0.03), [1, 2, 3, 1, 0])


def test_instance_sets_groups_labels() -> None:
    sets = M.instance_sets(np.array([0, 3, 1, 3, 3, 1, 0, 7]), 2)
    assert set(sets) == {1, 3}
    np.testing.assert_array_equal(sets[3], [1, 3, 4])
    np.testing.assert_array_equal(sets[1], [2, 5])


def test_frames_without_depth_are_skipped_and_reported(tmp_path: Path) -> None:
    seq = boxworld_sequence(tmp_path / "s", n_frames=8)
    io.write_png(seq.records[2].depth_path, np.zeros((seq.height, seq.width), np.uint16))
    seq.records[5].depth_path.unlink()
    cfg = M.FusionConfig(voxel_size=0.05, min_weight=1.0)
    rec = M.fuse_tsdf(Scene(tmp_path / "s").sequence("mapping"), cfg, progress=False)
    assert set(rec.skipped) == {"mapping/000002", "mapping/000005"}
    assert rec.usable.sum() == 6


def test_non_rigid_pose_names_the_frame(tmp_path: Path) -> None:
    seq = boxworld_sequence(tmp_path / "s", n_frames=4)
    seq.records[1].T_wc = seq.records[1].T_wc * np.array([2.0, 1, 1, 1])[:, None]
    with pytest.raises(DataError, match="mapping/000001.*rigid"):
        M.fuse_tsdf(seq, FUSION, progress=False)
