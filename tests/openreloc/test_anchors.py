"""Object-anchored keypoints: thinning per landmark, the ratio test against anchors lying elsewhere, and
the keypoint pose of a generated room's queries."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from generators.generate import generate_scene
from generators.spec import SceneSpec
from openreloc_bench import geometry
from openreloc_bench.data.scene import Scene
from openreloc_bench.methods import DRAWN_POINTS, PoseEstimate, QueryFrame, create_method
from openreloc_bench.openreloc.anchors import (
    AnchorBuildConfig,
    AnchorConfig,
    AnchorPose,
    DescriptorCodec,
    _most_seen,
    in_some_view,
    match_anchors,
    refined_or_prior,
)
from openreloc_bench.openreloc.map import ObjectMap
from openreloc_bench.vision.local_features import root_sift

TINY = dict(
    width=320, height=240, objects_per_room=12, room_side_min=3.5, room_side_max=4.0, mapping_step_m=0.5,
    mapping_step_deg=30.0, max_mapping_frames=16, n_query=4, displaced_share=0.2,
)  # fmt: skip


def test_each_cell_keeps_the_points_seen_most_once_each() -> None:
    rng = np.random.default_rng(0)
    looks = root_sift(rng.integers(0, 255, (3, 128)).astype(np.uint8))  # three unlike points
    views = np.array([0, 1, 1, 1, 2, 2, 0, 0])  # point 1 seen thrice, point 2 twice, point 0 once (cell 1)
    root = looks[views] + rng.normal(0, 0.003, (8, 128)).astype(np.float32)  # views differ a little
    root /= np.linalg.norm(root, axis=1, keepdims=True)
    xyz = np.array([[0.01, 0.01, 0.01]] * 6 + [[0.3, 0.01, 0.01], [0.01, 0.01, 0.01]], np.float32)
    landmark = np.array([1] * 7 + [2], np.int32)  # the last shares cell 1's space but is another landmark's
    one = _most_seen(xyz, root, landmark, AnchorBuildConfig(voxel=0.1, per_voxel=1))
    assert one.tolist() == [1, 6, 7]  # point 1's first view; the lone keypoints of the other cells
    two = _most_seen(xyz, root, landmark, AnchorBuildConfig(voxel=0.1, per_voxel=2))
    assert two.tolist() == [1, 4, 6, 7]  # then point 2 (two views) before point 0 (one)
    assert _most_seen(xyz, root, landmark, AnchorBuildConfig(voxel=0.1, per_voxel=3)).tolist() == [0, 1, 4, 6, 7]


def test_the_codec_keeps_the_nearest_descriptor_nearest_and_is_seeded() -> None:
    rng = np.random.default_rng(1)
    root = root_sift(rng.integers(0, 40, (2000, 128)).astype(np.uint8))
    codec, codes = DescriptorCodec.fit(root, 32)
    assert codes.shape == (2000, 32) and codes.dtype == np.uint8 and codec.centroids.shape == (32, 256, 4)
    decoded = codec.decode(codes)
    assert decoded.shape == (2000, 128) and np.linalg.norm(decoded - root, axis=1).mean() < 0.3
    noisy = root[:300] + rng.normal(0, 0.01, (300, 128)).astype(np.float32)  # other views of the same points
    found = np.argmin(((noisy[:, None] - decoded[None]) ** 2).sum(-1), axis=1)
    assert (found == np.arange(300)).mean() > 0.95
    again, codes_again = DescriptorCodec.fit(root, 32)
    assert np.array_equal(codes, codes_again) and np.array_equal(codec.centroids, again.centroids)
    few, few_codes = DescriptorCodec.fit(root[:5], 128)  # fewer descriptors than centroids: each its own
    assert np.abs(few.decode(few_codes) - root[:5]).max() < 1e-6


def test_ratio_test_rivals_only_anchors_lying_elsewhere() -> None:
    d = np.zeros((4, 128), np.float32)
    d[:, 0] = 1.0
    d[1, 1] = 0.05  # another view of the same point: nearly the same descriptor
    d[2, 1] = 0.3  # a different point that looks somewhat alike
    d[3, 2] = 1.0  # unlike
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    xyz = np.array([[0, 0, 0], [0.01, 0, 0], [1, 0, 0], [2, 0, 0]], np.float32)
    query = np.zeros((1, 128), np.float32)
    query[0, :2] = [1.0, 0.024]  # nearest anchor 0, anchor 1 just behind it
    query /= np.linalg.norm(query)
    cfg = AnchorConfig(neighbours=4)
    q, a = match_anchors(query, d, xyz, cfg)
    assert q.tolist() == [0] and a.tolist() == [0]  # anchor 1 is the same point: no rival
    apart = xyz.copy()
    apart[1] = [0.5, 0, 0]  # now it lies elsewhere, and is too alike to pass the ratio test
    assert len(match_anchors(query, d, apart, cfg)[0]) == 0


def test_only_anchors_near_some_view_are_candidates() -> None:
    K = geometry.intrinsics(100.0, 100.0, 50.0, 40.0)
    T = geometry.look_at([0.0, 0.0, 0.0], [0.0, 1.0, 0.0])  # looking along +y, image 100x80
    xyz = np.array([[0, 2, 0], [1.4, 2, 0], [3, 2, 0], [0, -2, 0]], np.float32)  # centre, margin, far, behind
    assert in_some_view(xyz, [T], K, (100, 80), 0.5).tolist() == [True, True, False, False]
    assert in_some_view(xyz, [T], K, (100, 80), 0.0).tolist() == [True, False, False, False]
    behind = geometry.look_at([0.0, 0.0, 0.0], [0.0, -1.0, 0.0])
    assert in_some_view(xyz, [T, behind], K, (100, 80), 0.0).tolist() == [True, False, False, True]


def keypoint_evidence(T_wc: np.ndarray, K: np.ndarray, n: int) -> AnchorPose:
    """``n`` keypoint matches of points 2-4 m in front of ``T_wc``, exact at it."""
    rng = np.random.default_rng(0)
    xyz_c = np.column_stack([rng.uniform(-1, 1, (n, 2)), rng.uniform(2, 4, n)])
    xyz = geometry.transform_points(T_wc, xyz_c)
    return AnchorPose(T_wc, n, n, {}, geometry.project(K, T_wc, xyz)[0], xyz)


def test_a_refinement_that_leaves_its_keypoint_evidence_keeps_the_prior() -> None:
    K = geometry.intrinsics(300.0, 300.0, 160.0, 120.0)
    prior = geometry.look_at([0.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    evidence = keypoint_evidence(prior, K, 30)
    drifted = prior.copy()
    drifted[:3, 3] += [0.3, 0.0, 0.0]  # 30 cm sideways: the keypoints no longer reproject
    cfg = AnchorConfig()
    assert evidence.support(prior, K, 8.0) == 30 and evidence.support(drifted, K, 8.0) < 30
    T, confidence = refined_or_prior(evidence, prior, drifted, K, cfg)
    assert T is prior and confidence == 30
    assert refined_or_prior(evidence, prior, drifted, K, AnchorConfig(keep_prior=False))[0] is drifted
    near = prior.copy()
    near[:3, 3] += [0.001, 0.0, 0.0]  # a millimetre: the same support, the refinement stands
    assert refined_or_prior(evidence, prior, near, K, cfg) == (near, 30.0)
    weak = keypoint_evidence(prior, K, cfg.seed_inliers - 1)  # too little evidence to overrule refinement
    assert refined_or_prior(weak, prior, drifted, K, cfg)[0] is drifted
    assert refined_or_prior(None, prior, drifted, K, cfg) == (drifted, 0.0)  # the keypoints found no pose
    T, confidence = refined_or_prior(None, prior, drifted, K, AnchorConfig(enabled=False))  # none were sought
    assert T is drifted and np.isnan(confidence)


@pytest.fixture(scope="module")
def room(tmp_path_factory: pytest.TempPathFactory) -> tuple[Scene, Path]:
    root = tmp_path_factory.mktemp("anchors")
    scene = Scene(generate_scene(SceneSpec(name="room", seed=11, **TINY), root, progress=False))
    method = create_method("openreloc", mapping={"instances_from": "masks"})
    method.build_map(scene.sequence("mapping"), root / "map")
    return scene, root / "map"


def test_map_keeps_keypoints_on_landmarks_only(room: tuple[Scene, Path]) -> None:
    _, map_dir = room
    m = ObjectMap.load(map_dir)
    assert len(m.anchors) > 100 and m.stats["anchors"] == len(m.anchors)
    assert set(np.unique(m.anchors.landmark)) <= set(m.landmarks)
    # every anchor lies on its landmark's surface (within the sensor's depth noise and the points' spacing)
    for lid in np.unique(m.anchors.landmark)[:5]:
        pts = m.landmarks[int(lid)].points
        on = m.anchors.xyz[m.anchors.landmark == lid]
        nearest = np.min(np.linalg.norm(on[:, None] - pts[None], axis=-1), axis=1)
        assert np.percentile(nearest, 90) < 0.05 + m.config["landmark_voxel"]


def test_queries_are_placed_by_their_keypoints_within_centimetres(room: tuple[Scene, Path]) -> None:
    scene, map_dir = room
    method = create_method("openreloc")
    method.load_map(map_dir)
    seq = scene.sequence("query_near")
    anchored = 0
    for i in range(len(seq)):
        f = seq[i]
        res = method.localize(QueryFrame(f.name, f.color, f.K, f.instance))
        assert isinstance(res, PoseEstimate)
        if res.diagnostics["chosen"] == "anchors":
            anchored += 1
            assert res.diagnostics["anchors"]["inliers"] >= method.config.anchors.min_inliers
            assert res.confidence == res.diagnostics["anchors"]["inliers"]
            kept = [p for p in res.diagnostics["anchors"][DRAWN_POINTS] if p[2]]  # what `localize --draw` shows
            assert len(kept) == res.diagnostics["anchors"]["inliers"]
            t, r = geometry.pose_errors(f.T_wc, res.T_wc)
            assert t < 0.05 and r < 2.0
    assert anchored >= len(seq) // 2


def test_switched_off_the_object_pose_stands(room: tuple[Scene, Path]) -> None:
    scene, map_dir = room
    method = create_method("openreloc", anchors={"enabled": False})
    method.load_map(map_dir)
    f = scene.sequence("query_near")[0]
    res = method.localize(QueryFrame(f.name, f.color, f.K, f.instance))
    assert "anchors" not in res.diagnostics and res.diagnostics.get("chosen") != "anchors"


def test_too_few_objects_still_place_the_camera_by_the_keypoints_they_retrieve(room: tuple[Scene, Path]) -> None:
    scene, map_dir = room
    f = scene.sequence("query_near")[0]
    query = QueryFrame(f.name, f.color, f.K, f.instance)
    for anchors in (True, False):
        method = create_method("openreloc", min_objects=50, anchors={"enabled": anchors})  # every view "sees too few"
        method.load_map(map_dir)
        res = method.localize(query)
        if anchors:
            assert isinstance(res, PoseEstimate) and res.diagnostics["chosen"] == "anchors"
            assert geometry.pose_errors(f.T_wc, res.T_wc)[0] < 0.05
        else:
            assert res.reason.endswith("object(s) detected, need at least 50")
