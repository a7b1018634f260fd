from __future__ import annotations

from pathlib import Path

import numpy as np
from vision_scenes import write_shapes_scene

from openreloc_bench.data.scene import Scene
from openreloc_bench.vision.base import ObjectMask, Segmenter
from openreloc_bench.vision.crops import CropSet, crops_from_scenes, scene_crops
from openreloc_bench.vision.preprocess import mask_box


def test_scene_crops_labels_and_structural_filter(tmp_path: Path) -> None:
    root = write_shapes_scene(tmp_path / "s0", seed=0, n_objects=3, frames=2)
    c = scene_crops(root, size=32, min_area=20)
    assert c.images.shape[1:] == (32, 32, 3) and c.images.dtype == np.uint8
    assert "wall" not in c.category
    assert set(c.split) == {"mapping", "query", "query_light1"}
    assert len(c) == 3 * 2 * 3  # objects x frames x splits
    assert set(c.colour) <= {"red", "blue", "green", "yellow"}
    # a crop of a red object is mostly red in its centre
    for img, col in zip(c.images, c.colour):
        centre = img[12:20, 12:20].reshape(-1, 3).mean(0)
        if col == "red" and c.split[0] == "mapping":
            assert centre[0] > 2 * centre[2]


def test_views_cap_min_area_save_load_concat(tmp_path: Path) -> None:
    roots = [write_shapes_scene(tmp_path / f"s{i}", seed=i, frames=4) for i in range(2)]
    c = crops_from_scenes(
        roots, progress=False, splits=["mapping"], min_area=20, max_views_per_object=2, rng=np.random.default_rng(0)
    )
    assert len(c) == 2 * 4 * 2
    assert len(set(c.instance_keys)) == 8
    assert len(scene_crops(roots[0], min_area=10**6)) == 0
    c.save(tmp_path / "c.npz")
    d = CropSet.load(tmp_path / "c.npz")
    assert d.instance_keys == c.instance_keys and np.array_equal(d.images, c.images)
    assert len(CropSet.concat([d.subset([0, 1]), d.subset([2])])) == 3


class HalfSegmenter(Segmenter):
    """Test segmenter: each object's left half exactly, and one mask spanning two objects."""

    def segment(self, rgb, instance=None):
        inst = self.instance
        out = []
        for oid in np.unique(inst):
            ys, xs = np.nonzero(inst == oid)
            m = (inst == oid) & (np.arange(inst.shape[1])[None, :] <= (xs.min() + xs.max()) // 2)
            out.append(ObjectMask(m, mask_box(m)))
        out.append(ObjectMask(np.ones(inst.shape, bool), np.array([0, 0, inst.shape[1], inst.shape[0]])))
        return out


def test_crops_cut_by_a_segmenter_keep_only_masks_mostly_on_one_object(tmp_path: Path) -> None:
    root = write_shapes_scene(tmp_path / "s0", seed=0, n_objects=3, frames=1)
    seg = HalfSegmenter()
    by_gt = scene_crops(root, splits=["mapping"], min_area=20)
    seg.instance = Scene(root).sequence("mapping")[0].instance
    cut = scene_crops(root, splits=["mapping"], min_area=10, segmenter=seg)
    assert sorted(cut.object_id) == sorted(by_gt.object_id)  # the image-wide mask is on no single object
    assert not np.array_equal(cut.images, by_gt.images)  # cut by the half masks' boxes
