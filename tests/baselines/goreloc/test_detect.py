import numpy as np
import pytest

from baselines.goreloc.detect import (
    DetectionFilterConfig,
    TableLabeller,
    ZeroShotLabeller,
    box_iou,
    detect,
    mask_ellipse_box,
)
from baselines.goreloc.vocabulary import COCO_CLASSES
from openreloc_bench.vision.base import ImageTextEncoder, ObjectMask


def _mask(box, hw=(240, 320), instance_id=None):
    m = np.zeros(hw, bool)
    x0, y0, x1, y1 = box
    m[y0:y1, x0:x1] = True
    return ObjectMask(m, np.array(box), instance_id=instance_id)


def test_box_iou_and_the_ellipse_of_a_disc():
    assert box_iou([0, 0, 10, 10], [[0, 0, 10, 10], [5, 0, 15, 10], [20, 20, 30, 30]])[0] == pytest.approx(
        [1, 1 / 3, 0]
    )
    yy, xx = np.mgrid[0:100, 0:100]
    disc = (xx - 50) ** 2 + (yy - 40) ** 2 <= 20**2
    assert np.allclose(mask_ellipse_box(disc), [30, 20, 71, 61], atol=1.5)


def test_filter_drops_small_huge_cut_and_duplicate_detections_and_unknown_labels():
    masks = [
        _mask([50, 50, 100, 100], instance_id=1),  # kept
        _mask([60, 60, 100, 100], instance_id=2),  # same label, IoU 0.64 > 0.3 with the first: duplicate
        _mask([150, 50, 200, 100], instance_id=3),  # other label, no overlap: kept
        _mask([2, 50, 40, 100], instance_id=4),  # within 5 px of the border
        _mask([200, 150, 210, 160], instance_id=5),  # 100 px^2 < 300
        _mask([10, 10, 300, 230], instance_id=6),  # > 0.3 of the image
        _mask([220, 150, 280, 200], instance_id=7),  # not a COCO object
    ]
    table = TableLabeller({1: 56, 2: 56, 3: 57, 4: 56, 5: 56, 6: 56})
    dets = detect(np.zeros((240, 320, 3), np.uint8), masks, table, DetectionFilterConfig())
    assert [d.instance_id for d in dets] == [1, 3] and [d.mask_index for d in dets] == [0, 2]
    assert all(d.score == 1.0 for d in dets)


class _ColourEncoder(ImageTextEncoder):
    """Red crops are chairs, green ones potted plants, grey ones walls."""

    name, dim = "colour", 3
    words = {"chair": 0, "potted plant": 1, "wall": 2}

    def encode_images(self, crops):
        out = []
        for c in crops:
            m = c.reshape(-1, 3).mean(0)
            out.append(2 if np.ptp(m) < 20 else int(np.argmax(m[:2])))
        return np.eye(3, dtype=np.float32)[out]

    def encode_texts(self, texts):
        nouns = [t.split(" ", 4)[-1] for t in texts]  # 'a photo of a(n) <noun>'
        return np.array([np.eye(3)[self.words[n]] if n in self.words else np.full(3, 0.1) for n in nouns], np.float32)


def test_zero_shot_labels_with_background_rejection_and_scores():
    rgb = np.zeros((240, 320, 3), np.uint8)
    rgb[50:100, 50:100] = (200, 0, 0)
    rgb[50:100, 150:200] = (0, 200, 0)
    rgb[150:200, 150:200] = (120, 120, 120)
    masks = [_mask([50, 50, 100, 100]), _mask([150, 50, 200, 100]), _mask([150, 150, 200, 200])]
    labels, scores = ZeroShotLabeller(_ColourEncoder(), ["wall"], 100.0)(rgb, masks)
    assert [COCO_CLASSES[i] for i in labels[:2]] == ["chair", "potted plant"] and labels[2] == -1
    assert np.all(scores > 0.9)
