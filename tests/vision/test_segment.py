from __future__ import annotations

import numpy as np
import pytest
from vision_scenes import COLOURS, draw_object

from openreloc_bench.vision import create_segmenter
from openreloc_bench.vision.preprocess import InputError


def _scene(h: int = 120, w: int = 160) -> tuple[np.ndarray, np.ndarray]:
    img = np.full((h, w, 3), 110, np.uint8)
    img[: h // 3] = 170
    inst = np.zeros((h, w), np.int32)
    draw_object(img, inst, 1, "box", COLOURS["red"], 30, 80, 14)
    draw_object(img, inst, 2, "ball", COLOURS["blue"], 80, 80, 15)
    draw_object(img, inst, 3, "box", COLOURS["yellow"], 130, 80, 12)
    inst[60:62, 100:102] = 4  # a 4-pixel speck
    return img, inst


def test_gt_masks_filters_and_boxes() -> None:
    img, inst = _scene()
    objs = create_segmenter("gt", min_area=20).segment(img, inst)
    assert [o.instance_id for o in objs] == [1, 2, 3]
    for o in objs:
        assert o.mask.dtype == bool and o.mask.shape == inst.shape
        np.testing.assert_array_equal(o.mask, inst == o.instance_id)
        ys, xs = np.nonzero(o.mask)
        assert o.box.tolist() == [xs.min(), ys.min(), xs.max() + 1, ys.max() + 1]
    assert [o.instance_id for o in create_segmenter("gt", min_area=1, ids=[2, 4]).segment(img, inst)] == [2, 4]
    assert [o.instance_id for o in create_segmenter("gt", min_area=1, exclude_ids=[4]).segment(img, inst)] == [1, 2, 3]


@pytest.mark.parametrize("name", ["gt", "noisy-gt"])
def test_oracle_segmenters_need_a_matching_instance_image(name: str) -> None:
    img, inst = _scene()
    seg = create_segmenter(name)
    with pytest.raises(InputError, match="instance image"):
        seg.segment(img)
    with pytest.raises(InputError, match="does not match"):
        seg.segment(img, inst[:10])
    with pytest.raises(InputError, match="integer"):
        seg.segment(img, inst.astype(np.float32))
    assert seg.segment(img, np.zeros_like(inst)) == []


def test_noisy_gt_is_seeded_per_image_and_rates_work() -> None:
    img, inst = _scene()
    a = create_segmenter("noisy-gt", seed=3, morph_rate=1.0, box_jitter=0.2, min_area=20)
    r1, r2 = a.segment(img, inst), a.segment(img.copy(), inst.copy())
    assert [o.instance_id for o in r1] == [o.instance_id for o in r2]
    assert all(np.array_equal(x.mask, y.mask) and np.array_equal(x.box, y.box) for x, y in zip(r1, r2))
    gt = {o.instance_id: o.mask for o in create_segmenter("gt", min_area=20).segment(img, inst)}
    assert any(not np.array_equal(o.mask, gt[o.instance_id]) for o in r1)  # masks were eroded/dilated
    others = [
        create_segmenter("noisy-gt", seed=s, morph_rate=1.0, box_jitter=0.2, min_area=20).segment(img, inst)
        for s in range(4, 8)
    ]
    assert any([o.box.tolist() for o in r1] != [o.box.tolist() for o in x] for x in others)
    clean = create_segmenter("noisy-gt", drop_rate=0, morph_rate=0, merge_rate=0, box_jitter=0, min_area=20).segment(
        img, inst
    )
    assert [o.instance_id for o in clean] == [1, 2, 3]
    assert all(np.array_equal(o.mask, gt[o.instance_id]) for o in clean)
    assert create_segmenter("noisy-gt", drop_rate=1.0).segment(img, inst) == []
    for o in r1:
        assert 0 <= o.box[0] < o.box[2] <= img.shape[1] and 0 <= o.box[1] < o.box[3] <= img.shape[0]


def test_noisy_gt_merges_touching_neighbours() -> None:
    img = np.zeros((40, 60, 3), np.uint8)
    inst = np.zeros((40, 60), np.int32)
    inst[10:30, 5:25] = 1
    inst[10:30, 25:45] = 2  # touches 1
    objs = create_segmenter("noisy-gt", drop_rate=0, morph_rate=0, merge_rate=1.0, box_jitter=0, min_area=10).segment(
        img, inst
    )
    assert len(objs) == 1 and objs[0].mask.sum() == 800


def test_noisy_gt_rejects_bad_rates() -> None:
    with pytest.raises(InputError, match="drop_rate"):
        create_segmenter("noisy-gt", drop_rate=1.5)


def test_graph_segmenter_recovers_objects() -> None:
    img, inst = _scene(240, 320)
    objs = create_segmenter("graph", min_area_frac=0.001).segment(img)
    assert objs, "no regions"
    ious = []
    for oid in (1, 2, 3):
        gt = inst == oid
        ious.append(max((o.mask & gt).sum() / (o.mask | gt).sum() for o in objs))
    assert min(ious) > 0.8, ious
    for o in objs:
        assert o.mask.shape == inst.shape and o.mask.sum() <= 0.25 * inst.size


@pytest.mark.parametrize(
    "img",
    [np.zeros((60, 80, 3), np.uint8), np.full((60, 80), 128, np.uint8), np.random.default_rng(0).random((60, 80, 4))],
)
def test_graph_segmenter_odd_images(img: np.ndarray) -> None:
    objs = create_segmenter("graph").segment(img)
    assert isinstance(objs, list)
    if img.ndim == 2 or img.max() == 0:
        assert objs == []  # a uniform image is one background region, above max_area_frac


def test_graph_segmenter_is_deterministic() -> None:
    img, _ = _scene()
    seg = create_segmenter("graph")
    a, b = seg.segment(img), seg.segment(img)
    assert len(a) == len(b) and all(np.array_equal(x.mask, y.mask) for x, y in zip(a, b))


def test_default_boundaries_are_the_masks_own_borders() -> None:
    inst = np.zeros((6, 8), np.int32)
    inst[1:4, 2:5] = 7
    masks, border = create_segmenter("gt", min_area=1).segment_with_boundaries(np.zeros((6, 8, 3), np.uint8), inst)
    assert len(masks) == 1 and border.dtype == np.float32
    inside, outside = masks[0].mask, ~masks[0].mask
    assert border[2, 3] == 0 and border[0, 0] == 0  # deep inside, far outside
    assert border[1, 2] == 1 and border[1, 1] == 1  # both sides of the mask's edge
    assert border[inside].sum() == 8 and border[outside].sum() == 12
