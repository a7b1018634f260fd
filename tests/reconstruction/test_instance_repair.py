from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from openreloc_bench.data.scene import Scene
from openreloc_bench.errors import DataError
from openreloc_bench.harness.merger_training import dominant_objects, scene_examples
from openreloc_bench.openreloc.build import MappingConfig, lift_instances
from openreloc_bench.reconstruction import instance_repair as R
from openreloc_bench.reconstruction.incidence import view_evidence
from openreloc_bench.reconstruction.instance_eval import box_point_labels, instance_report
from openreloc_bench.reconstruction.lifting import instance_sets
from openreloc_bench.reconstruction.observation import FrameObservation
from openreloc_bench.vision import create_segmenter
from tests.openreloc.boxworld import ROOM, Box, write_boxworld

# the bookshelf (id 14) rendered as three stacked boxes: a segmenter of the instance images keeps them
# apart in every view, as the learned one keeps a cabinet's doors apart from its body
SHELF = next(b for b in ROOM if b.id == 14)
CUTS = (0.0, 0.45, 0.95, SHELF.hi[2])  # about a third of the seen points each
PARTS = [b for b in ROOM if b.id != 14] + [
    Box(14 + k, "bookshelf", (*SHELF.lo[:2], lo), (*SHELF.hi[:2], hi), SHELF.color)
    for k, (lo, hi) in enumerate(zip(CUTS[:-1], CUTS[1:]))
]


def observation(point_idx: list[int], masks: list[list[int]]) -> FrameObservation:
    idx = np.array(point_idx, np.int32)
    return FrameObservation(
        index=0,
        point_idx=idx,
        uv=np.zeros((len(idx), 2), np.int16),
        masks=[np.array([point_idx.index(p) for p in m], np.int32) for m in masks],
    )


def test_fill_gives_unlabelled_points_the_instance_their_masks_hold() -> None:
    labels = np.array([1, 1, 1, 0, 2, 2, 0, 0, 0, 0])
    obs = [
        observation(list(range(10)), [[0, 1, 2, 3], [4, 5, 6]]),
        observation(list(range(10)), [[0, 1, 3], [4, 5, 6, 7]]),
    ]
    views = view_evidence(10, obs, min_mask_points=1)
    filled = R.fill_from_masks(labels, views, purity=0.6, share=0.5)
    np.testing.assert_array_equal(filled, [1, 1, 1, 1, 2, 2, 2, 2, 0, 0])


def test_fill_revotes_assigned_points_too() -> None:
    labels = np.array([1, 2, 0])
    obs = [observation([0, 1, 2], [[0, 1, 2]]), observation([0, 1, 2], [[0, 2]])]
    views = view_evidence(3, obs, min_mask_points=1)
    assert R.fill_from_masks(labels, views, 0.5, 0.5)[1] == 1  # re-voted: both masks vote for instance 1


def test_fit_merger_separates_separable_pairs_and_round_trips(tmp_path: Path) -> None:
    rng = np.random.default_rng(0)
    X = rng.normal(size=(400, len(R.FEATURES)))
    same = X[:, 0] + 0.5 * X[:, 3] > 0.8
    clf = R.fit_merger(X, same)
    assert np.mean((clf.probability(X) > 0.5) == same) > 0.95
    clf.card = {"note": "test"}
    clf.save(tmp_path / "m")
    back = R.MergeClassifier.load(tmp_path / "m")
    np.testing.assert_allclose(back.probability(X), clf.probability(X))
    assert back.card == {"note": "test"}


def test_a_merger_made_for_other_features_is_refused(tmp_path: Path) -> None:
    clf = R.fit_merger(np.eye(len(R.FEATURES)), np.arange(len(R.FEATURES)) % 2 == 0)
    clf.save(tmp_path / "m")
    body = json.loads((tmp_path / "m" / R.MERGER_FILE).read_text())
    body["features"] = body["features"][:-1]
    R.MergeClassifier(clf.mean, clf.scale, clf.weights, clf.bias, {}).save(tmp_path / "other")
    (tmp_path / "other" / R.MERGER_FILE).write_text(json.dumps(body))
    with pytest.raises(DataError, match="other features|manifest|checksum|changed"):
        R.MergeClassifier.load(tmp_path / "other")
    with pytest.raises(DataError, match="train-merger"):
        R.MergeClassifier.load(tmp_path / "missing")


@pytest.fixture(scope="module")
def shelf_in_parts(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_boxworld(
        tmp_path_factory.mktemp("parts") / "scene", n_frames=16, hw=(96, 128), boxes=PARTS, objects=ROOM
    )


def clustered() -> MappingConfig:
    """Instances by view-consensus clustering and fill, which keep the shelf's parts apart on this
    16-view room (affinity grouping needs a denser walk-through: test_affinity_grouping)."""
    cfg = MappingConfig()
    cfg.instances.grouping = "clustering"
    cfg.instances.repair.fill = True
    return cfg


def no_crease_classifier() -> R.MergeClassifier:
    """Joins touching instances whose border has no concave crease (parts of one box), nothing else:
    a box stands on the floor and a room's walls meet at concave edges."""
    n = len(R.FEATURES)
    weights = np.zeros(n)
    weights[R.FEATURES.index("concave_share")] = -40.0
    return R.MergeClassifier(np.zeros(n), np.ones(n), weights, 3.0, {})


def test_merge_joins_the_parts_of_an_object_and_nothing_else(shelf_in_parts: Path) -> None:
    seq = Scene(shelf_in_parts).sequence("mapping")
    cfg = clustered()
    inst = lift_instances(seq, cfg, create_segmenter("gt", min_area=1), progress=False, boundaries=True)
    points, labels = inst.reconstruction.points, inst.labels
    truth = instance_sets(box_point_labels(points, Scene(shelf_in_parts).objects, 0.03), 20)
    before = instance_report(points, inst.sets, truth)
    views = view_evidence(len(points), inst.observations, 10)
    attrs = R.point_attributes(points, inst.observations, seq.poses[:, :3, 3])
    merged = R.merge_instances(points, labels, attrs, views, no_crease_classifier(), R.RepairConfig(fill=False))
    after = instance_report(points, instance_sets(merged, 20), truth)
    assert before["objects"]["split"]["large"] == 1 and after["objects"]["split"]["large"] == 0
    assert after["n_pred"] == before["n_pred"] - 2 and after["recall"] > before["recall"]
    owner = dominant_objects(merged, box_point_labels(points, Scene(shelf_in_parts).objects, 0.03))
    assert sum(o == 14 for o, _ in owner.values()) == 1


def test_scene_examples_label_the_parts_of_one_object_as_one(shelf_in_parts: Path) -> None:
    examples = scene_examples(shelf_in_parts, create_segmenter("gt", min_area=1), clustered())
    assert examples.features.shape == (len(examples.same), len(R.FEATURES))
    assert examples.same.sum() == 2 and len(examples.same) > 5  # the shelf's parts; floor, walls, table... apart


def test_repair_needs_boundaries_to_merge(shelf_in_parts: Path) -> None:
    seq = Scene(shelf_in_parts).sequence("mapping")
    cfg = MappingConfig()
    cfg.instances.repair = R.RepairConfig(merge=False)
    inst = lift_instances(seq, cfg, create_segmenter("gt", min_area=1), progress=False, boundaries=True)
    for o in inst.observations:
        o.boundary = None
    with pytest.raises(ValueError, match="boundary"):
        R.repair_instances(
            inst.reconstruction.points,
            inst.labels,
            inst.observations,
            seq.poses[:, :3, 3],
            R.RepairConfig(merge=True),
            10,
        )
