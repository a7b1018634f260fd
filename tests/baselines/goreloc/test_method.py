import numpy as np
import pytest

from baselines.goreloc.method import GOReloc
from openreloc_bench import geometry
from openreloc_bench.data.scene import Scene
from openreloc_bench.errors import ConfigError
from openreloc_bench.methods import Failure, PoseEstimate, QueryFrame, create_method
from openreloc_bench.vision.base import ImageTextEncoder, ObjectMask, Segmenter, register_encoder, register_segmenter
from openreloc_bench.vision.preprocess import mask_box
from tests.baselines.goreloc.ellipsoid_world import BLOBS, write_ellipsoid_world


@pytest.fixture(scope="module")
def world(tmp_path_factory):
    return write_ellipsoid_world(tmp_path_factory.mktemp("goreloc") / "world")


def _localize_all(method, scene, track):
    seq = scene.sequence("query")
    out = [method.localize(QueryFrame.from_frame(f, track)) for f in seq]
    est = np.array([r.T_wc if isinstance(r, PoseEstimate) else np.full((4, 4), np.nan) for r in out])
    return out, *geometry.pose_errors(seq.poses, est)


def test_goreloc_localizes_a_scene_of_ellipsoids_on_the_oracle_track(world, tmp_path):
    method = create_method("goreloc")
    scene = Scene(world)
    method.build_map(scene.sequence("mapping"), tmp_path / "map")
    method.load_map(tmp_path / "map")
    out, t_err, r_err = _localize_all(method, scene, "oracle-mask")
    assert all(isinstance(r, PoseEstimate) and r.diagnostics["returned_pose"] for r in out)
    assert (t_err < 0.5).all() and (r_err < 5.0).all()  # box centres are not the centres' images: a bias of cm
    assert all(r.diagnostics["final"] == "lm" and r.diagnostics["inliers"] >= 4 for r in out)


def test_too_few_detections_is_a_failure_with_its_reason(world, tmp_path):
    method = GOReloc()
    scene = Scene(world)
    method.build_map(scene.sequence("mapping"), tmp_path / "map")
    method.load_map(tmp_path / "map")
    f = scene.sequence("query")[0]
    inst = np.where(np.isin(f.instance, [1, 2, 3]), f.instance, 0)  # three objects left
    res = method.localize(QueryFrame(f.name, f.color, f.K, inst))
    assert isinstance(res, Failure) and "needs 4" in res.reason and res.diagnostics["returned_pose"] is False
    res = method.localize(QueryFrame(f.name, f.color[:100], f.K, None))
    assert isinstance(res, Failure) and "camera" in res.reason


class _ColourSegmenter(Segmenter):
    """The world's objects by their exact flat colours (a perfect RGB-only segmenter for the test)."""

    name = "goreloc-test-colour"

    def segment(self, rgb, instance=None):
        out = []
        for b in BLOBS:
            hue = rgb.astype(float) / np.maximum(rgb.max(axis=2, keepdims=True), 1)
            ref = np.array(b.colour, float) / max(b.colour)
            m = (np.abs(hue - ref).max(axis=2) < 0.02) & (rgb.max(axis=2) > 20)
            if m.sum() >= 50:
                out.append(ObjectMask(m, mask_box(m)))
        return out


class _ColourEncoder(ImageTextEncoder):
    """Knows each world object's category by its colour (a perfect zero-shot classifier for the test)."""

    name, dim = "goreloc-test-colour", 16
    nouns = {
        "couch": 0,
        "potted plant": 1,
        "tv": 2,
        "dining table": 3,
        "clock": 4,
        "bed": 5,
        "toilet": 6,
        "vase": 7,
        "refrigerator": 8,
    }

    def encode_images(self, crops):
        centre = np.array([c[c.shape[0] // 2, c.shape[1] // 2].astype(float) for c in crops])
        refs = np.array([b.colour for b in BLOBS[:9]], float)
        hue = centre / np.maximum(centre.max(1, keepdims=True), 1)
        k = np.abs(hue[:, None] - refs / refs.max(1, keepdims=True)).sum(2).argmin(1)
        return np.eye(self.dim, dtype=np.float32)[k]

    def encode_texts(self, texts):
        nouns = [t.split(" ", 4)[-1] for t in texts]
        return np.array([np.eye(self.dim)[self.nouns.get(n, 15)] for n in nouns], np.float32)


register_segmenter(_ColourSegmenter.name)(_ColourSegmenter)
register_encoder(_ColourEncoder.name)(_ColourEncoder)


def test_predicted_track_segments_and_labels_for_itself(world, tmp_path):
    method = GOReloc(
        segmenter="goreloc-test-colour",
        encoder="goreloc-test-colour",
        mapping={"instances_from": "segmenter"},
    )
    scene = Scene(world)
    method.build_map(scene.sequence("mapping"), tmp_path / "map")
    method.load_map(tmp_path / "map")
    assert method.map.stats["instances_from"] == "segmenter" and method.map.encoder["name"] == "goreloc-test-colour"
    assert len(method.map.ids) >= 8
    out, t_err, _ = _localize_all(method, scene, "predicted")
    assert all(r.diagnostics["track"] == "predicted" for r in out)
    assert np.mean(t_err < 0.5) >= 0.75


def test_config_errors_name_the_key():
    with pytest.raises(ConfigError, match="ransac.iteration"):
        GOReloc(ransac={"iteration": 3})
    with pytest.raises(ConfigError, match="instances_from"):
        GOReloc(mapping={"instances_from": "boxes"})


def test_map_config_holds_only_what_the_map_depends_on():
    base = GOReloc().map_config()
    assert GOReloc(ransac={"iterations": 5}, detection={"min_score": 0.5}).map_config() == base
    assert GOReloc(mapping={"min_detections": 1}).map_config() != base
    oracle = GOReloc(mapping={"instances_from": "masks"})
    assert (
        "segmenter" not in oracle.map_config()
        and oracle.map_config() == GOReloc(mapping={"instances_from": "masks"}, segmenter="noisy-gt").map_config()
    )
