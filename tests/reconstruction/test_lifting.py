"""Both instance-lifting paths (voting, view-consensus clustering) on the fused box room."""

from __future__ import annotations

import numpy as np

from openreloc_bench.reconstruction import lifting
from openreloc_bench.reconstruction.incidence import incidence
from openreloc_bench.reconstruction.instance_eval import instance_report
from openreloc_bench.reconstruction.lifting import (
    ClusteringConfig,
    VotingConfig,
    instance_sets,
    lift_by_clustering,
    lift_by_voting,
)
from openreloc_bench.reconstruction.observation import FrameObservation
from tests.openreloc.boxworld import ROOM


def test_voting_labels_points_with_the_box_they_lie_on(room: tuple) -> None:
    _, rec, obs = room
    labels = lift_by_voting(len(rec.points), obs, VotingConfig())
    sets = instance_sets(labels, 20)
    assert {1, 2, 3, 4, 5, 11, 12, 14} <= set(sets)
    for b in ROOM:
        if b.id in sets:
            pts = rec.points[sets[b.id]]
            inside = np.all((pts >= np.array(b.lo) - 0.06) & (pts <= np.array(b.hi) + 0.06), axis=1)
            assert inside.mean() > 0.95, b.category


def test_clustering_of_noisy_masks_recovers_instances(room: tuple) -> None:
    _, rec, obs = room
    gt = instance_sets(lift_by_voting(len(rec.points), obs, VotingConfig()), 20)
    pred = instance_sets(lift_by_clustering(rec.points, obs, ClusteringConfig()), 20)
    q = instance_report(rec.points, pred, gt)
    assert q["recall"] >= 0.85 and q["precision"] >= 0.75, q


def test_undersegmented_masks_are_dropped(room: tuple) -> None:
    """A mask spanning two objects of similar size in one frame is split in the other frames, so it
    is dropped instead of fusing the two objects into one cluster."""
    _, rec, obs = room
    vote = lift_by_voting(len(rec.points), obs, VotingConfig())
    o, pair = obs[4], (12, 2)  # frame 4 sees the sofa and the wall behind it about equally (~500 points each)
    assert 0.6 < (vote[o.point_idx] == 12).sum() / (vote[o.point_idx] == 2).sum() < 1.6
    merged = np.flatnonzero(np.isin(vote[o.point_idx], pair)).astype(np.int32)
    obs2 = [FrameObservation(x.index, x.point_idx, x.uv, x.gt_ids, list(x.masks)) for x in obs]
    others = [m for m in o.masks if not np.isin(np.bincount(vote[o.point_idx[m]]).argmax(), pair)]
    obs2[obs.index(o)].masks = others + [merged]  # the two objects' masks replaced by one
    cfg = ClusteringConfig()
    masks = [(f, m) for f, ob in enumerate(obs2) for m in ob.masks if len(m) >= cfg.min_mask_points]
    Mx = incidence(
        np.concatenate([np.full(len(m), k) for k, (_, m) in enumerate(masks)]),
        np.concatenate([obs2[f].point_idx[m] for f, m in masks]),
        (len(masks), len(rec.points)),
    )
    _, _, keep = lifting._mask_frame_stats(Mx, np.array([f for f, _ in masks]), len(obs2), cfg)
    k = next(k for k, (_, m) in enumerate(masks) if m is merged)
    assert not keep[k] and keep.mean() > 0.8
    labels = lift_by_clustering(rec.points, obs2, cfg)
    assert instance_report(rec.points, instance_sets(labels, 20), instance_sets(vote, 20))["recall"] >= 0.85


def test_instance_sets_groups_labels() -> None:
    sets = instance_sets(np.array([0, 3, 1, 3, 3, 1, 0, 7]), 2)
    assert set(sets) == {1, 3}
    np.testing.assert_array_equal(sets[3], [1, 3, 4])
    np.testing.assert_array_equal(sets[1], [2, 5])
