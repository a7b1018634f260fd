"""The instance step: each config lifts by what it offers (voting, clustering, or grouping and repair)."""

from __future__ import annotations

import numpy as np

from openreloc_bench.reconstruction.gravity import estimate_up, levelling
from openreloc_bench.reconstruction.instances import GroupedInstanceConfig, InstanceConfig, label_instances
from openreloc_bench.reconstruction.lifting import instance_sets, lift_by_clustering, lift_by_voting
from tests.reconstruction.conftest import VOXEL


def test_an_instance_config_votes_the_dataset_masks_and_clusters_a_segmenters(room: tuple) -> None:
    seq, rec, obs = room
    up, cameras = estimate_up(seq.poses[rec.usable], rec.points, VOXEL), seq.poses[:, :3, 3]
    cfg = InstanceConfig(min_points=30)
    voted, sets = label_instances(rec.points, obs, cfg, False, up, cameras, VOXEL)
    assert np.array_equal(voted, lift_by_voting(len(rec.points), obs, cfg.voting))
    assert sets.keys() == instance_sets(voted, 30).keys() and sets
    clustered, _ = label_instances(rec.points, obs, cfg, True, up, cameras, VOXEL)
    assert np.array_equal(clustered, lift_by_clustering(rec.points, obs, cfg.clustering))


def test_a_grouped_config_groups_the_levelled_cloud_and_repairs_what_it_grouped(room: tuple) -> None:
    seq, rec, obs = room
    up, cameras = np.array([0.0, 0.6, 0.8]), seq.poses[:, :3, 3]  # a tilted up: the grouping sees it levelled
    cfg = GroupedInstanceConfig(grouping="clustering")
    cfg.clustering.split_distance = 0.1  # parts connected in the levelled cloud's cells
    grouped, _ = label_instances(rec.points, obs, cfg, True, up, cameras, VOXEL)
    assert np.array_equal(grouped, lift_by_clustering(rec.points @ levelling(up).T, obs, cfg.clustering))
    cfg.repair.fill = True
    repaired, _ = label_instances(rec.points, obs, cfg, True, up, cameras, VOXEL)
    assert not np.array_equal(repaired, grouped)
