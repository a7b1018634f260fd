from __future__ import annotations

import numpy as np
import pytest

from openreloc_bench.reconstruction import affinity_grouping as A
from openreloc_bench.reconstruction.fusion import FusionConfig, fuse_tsdf
from openreloc_bench.reconstruction.instance_eval import instance_report
from openreloc_bench.reconstruction.lifting import VotingConfig, instance_sets, lift_by_voting
from openreloc_bench.reconstruction.observation import ObservationConfig, observe
from tests.openreloc.boxworld import NoisyMaskSegmenter, boxworld_sequence
from tests.reconstruction.test_instance_repair import observation

STEP = 0.02  # the point grid of the synthetic patches (m)


def grid(nx: int, ny: int, x0: float = 0.0) -> np.ndarray:
    x, y = np.meshgrid(np.arange(nx) * STEP + x0, np.arange(ny) * STEP)
    return np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], 1).astype(np.float32)


def test_edge_evidence_counts_frames_seeing_both_and_masks_holding_both() -> None:
    edges = np.array([[0, 1], [1, 2], [2, 3]])
    obs = [
        observation([0, 1, 2, 3], [[0, 1], [2, 3]]),
        observation([0, 1, 2], [[0, 1, 2]]),
        observation([1, 2, 3], [[1]]),  # 2 and 3 seen in no mask: seen together, held by none
    ]
    both, same = A.edge_evidence(4, obs, edges, min_mask_points=1)
    np.testing.assert_array_equal(both, [2, 3, 2])
    np.testing.assert_array_equal(same, [2, 1, 1])


def two_patches_seen_noisily(n_frames: int = 20, seed: int = 0) -> tuple[np.ndarray, list, np.ndarray]:
    """Two 0.4 x 0.4 m patches side by side; each frame's masks keep them apart but split one of them at
    a random column (over-segmentation that moves between views), and every fifth frame holds both in
    one mask (under-segmentation)."""
    rng = np.random.default_rng(seed)
    points = np.concatenate([grid(20, 20), grid(20, 20, x0=20 * STEP)])
    truth = np.repeat([1, 2], 400)
    obs = []
    for f in range(n_frames):
        if f % 5 == 0:
            masks = [list(range(800))]
        else:
            split, cut = rng.integers(1, 3), rng.integers(4, 16) * STEP
            masks = []
            for obj in (1, 2):
                idx = np.flatnonzero(truth == obj)
                if obj == split:
                    left = points[idx, 0] - points[idx, 0].min() < cut
                    masks += [idx[left].tolist(), idx[~left].tolist()]
                else:
                    masks.append(idx.tolist())
        obs.append(observation(list(range(800)), masks))
    return points, obs, truth


def test_affinity_grouping_repairs_moving_splits_and_occasional_merges() -> None:
    points, obs, truth = two_patches_seen_noisily()
    labels = A.lift_by_affinity(points, obs, A.AffinityConfig(min_region_area=0.02), STEP)
    assert len(np.unique(labels)) == 2 and (labels > 0).all()
    for obj in (1, 2):
        assert len(np.unique(labels[truth == obj])) == 1


def test_a_split_every_view_agrees_on_stays_a_split() -> None:
    points = grid(20, 20)
    left = points[:, 0] < 10 * STEP
    obs = [observation(list(range(400)), [np.flatnonzero(left).tolist(), np.flatnonzero(~left).tolist()])] * 5
    labels = A.lift_by_affinity(points, obs, A.AffinityConfig(min_region_area=0.02), STEP)
    assert len(np.unique(labels[left])) == 1 and len(np.unique(labels[~left])) == 1
    assert labels[left][0] != labels[~left][0]


def test_slivers_join_their_best_large_neighbour_and_isolated_specks_are_dropped() -> None:
    regions = np.array([0] * 300 + [1] * 300 + [2] * 5 + [3] * 5)
    # sliver 2 borders 0 (held together once in 4 views) and 1 (3 of 4); speck 3 touches nothing
    edges = np.array([[0, 600], [300, 601], [10, 20]])
    both, same = np.array([4, 4, 3]), np.array([1, 3, 3])
    out = A.absorb_small(regions, edges, both, same, min_points=100)
    np.testing.assert_array_equal(out[600:605], 1)
    np.testing.assert_array_equal(out[605:], -1)
    np.testing.assert_array_equal(out[:600], regions[:600])


def test_agglomeration_pools_the_whole_border_so_one_leaking_edge_does_not_merge() -> None:
    # regions 0 and 1 share ten border edges; one says "same object" in every view, nine say "apart"
    regions = np.repeat([0, 1], 10)
    edges = np.stack([np.arange(10), np.arange(10, 20)], 1)
    both = np.full(10, 10)
    same = np.r_[10, np.zeros(9, int)]
    np.testing.assert_array_equal(A.agglomerate(regions, edges, both, same, stop=0.8), regions)
    np.testing.assert_array_equal(A.agglomerate(regions, edges, both, same, stop=0.05), 0)


@pytest.mark.parametrize("bad", [{"merge_affinity": 1.5}, {"neighbour_spacings": 0.0}, {"min_region_area": -1}])
def test_config_refuses_out_of_range_values(bad: dict) -> None:
    with pytest.raises(ValueError):
        A.AffinityConfig(**bad)


@pytest.fixture(scope="module")
def dense_room(tmp_path_factory: pytest.TempPathFactory) -> tuple:
    """32 views (16 leave parts of the floor that no view sees side by side: those stay apart)."""
    seq = boxworld_sequence(tmp_path_factory.mktemp("room"), n_frames=32, hw=(96, 128))
    return seq, fuse_tsdf(seq, FusionConfig(voxel_size=0.05), progress=False)


@pytest.mark.parametrize(("split_prob", "precision", "recall"), [(0.0, 0.85, 0.95), (0.3, 0.4, 0.85)])
def test_noisy_masks_of_a_rendered_room_become_its_objects(dense_room, split_prob, precision, recall) -> None:
    seq, rec = dense_room
    segmenter = NoisyMaskSegmenter(split_prob=split_prob)
    obs = observe(seq, rec.points, rec.usable, ObservationConfig(), segmenter, False)
    truth = instance_sets(lift_by_voting(len(rec.points), obs, VotingConfig()), 20)
    labels = A.lift_by_affinity(rec.points, obs, A.AffinityConfig(min_region_area=0.05), spacing=0.05)
    q = instance_report(rec.points, instance_sets(labels, 20), truth)
    assert q["recall"] >= recall and q["precision"] >= precision, q


def test_no_points_and_no_views_give_no_instances() -> None:
    assert A.lift_by_affinity(np.zeros((0, 3), np.float32), [], A.AffinityConfig(), 0.02).shape == (0,)
    # nothing seen: no evidence joins any two points, and single points are too small to keep
    assert (A.lift_by_affinity(grid(5, 5), [], A.AffinityConfig(), STEP) == 0).all()
