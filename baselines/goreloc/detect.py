"""Closed-vocabulary detections from object masks, and GOReloc's detection filter.

GOReloc consumes YOLOv8-seg detections: a COCO label, a score, a box and an ellipse fitted to the
mask. Here the masks come from the project's segmenters and the label from a :class:`Labeller`:
- :class:`TableLabeller` (oracle-mask track): the dataset instance id's category through the
  committed COCO table (:mod:`.vocabulary`), score 1 (a perfect detector);
- :class:`ZeroShotLabeller` (predicted track): the mask's crop classified zero-shot against the 80
  COCO names with the project's image-text encoder, the softmax probability as score.
Objects the labeller cannot name (label -1) are invisible, as for the real detector.

The filter is GOReloc's (thresholds in :class:`DetectionFilterConfig`): score, box area, distance to
the image border, agreement of the box with the mask's ellipse, then greedy de-duplication.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Protocol

import cv2
import numpy as np

from baselines.goreloc.vocabulary import COCO_CLASSES
from openreloc_bench import config as cfglib
from openreloc_bench.vision import vocabulary as voc
from openreloc_bench.vision.base import ImageTextEncoder, ObjectMask
from openreloc_bench.vision.preprocess import square_crop


@dataclass
class DetectionFilterConfig:
    """GOReloc's detection filter (its relocalisation thresholds; mapping raises ``min_score``)."""

    min_score: float = 0.1
    """Detections scoring below this are dropped."""
    min_box_area: float = 300.0
    """Boxes smaller than this (px^2) are dropped."""
    max_box_share: float = 0.3
    """Boxes larger than this share of the image are dropped."""
    border_px: float = 5.0
    """Boxes within this many pixels of the image border are dropped (the object is cut)."""
    min_ellipse_iou: float = 0.4
    """The box must overlap the box of the ellipse fitted to the mask by this IoU."""
    same_label_iou: float = 0.3
    """A detection overlapping an already kept one of its label by more than this IoU is a duplicate."""
    other_label_iou: float = 0.6
    """...and one of another label by more than this."""

    def __post_init__(self) -> None:
        cfglib.check_ranges(
            self,
            non_negative=("min_box_area",),
            share=("min_score", "max_box_share", "min_ellipse_iou", "same_label_iou", "other_label_iou"),
        )
        if not self.border_px >= -1e6:  # negative: boxes touching the border are kept too
            raise ValueError(f"'border_px' must be a number, got {self.border_px!r}")


@dataclass
class Detection:
    """One detection that passed the filter."""

    label: int
    """COCO label id."""
    score: float
    box: np.ndarray
    """[x0, y0, x1, y1] float pixels."""
    mask_index: int
    """Index of its mask in the segmenter's output (links mapping detections to lifted objects)."""
    instance_id: int | None = field(default=None, repr=False)
    """Dataset instance id when the mask is ground truth (diagnostics only)."""


class Labeller(Protocol):
    """Names masks with COCO labels: (labels (N,) int, -1 = not a COCO object; scores (N,))."""

    def __call__(self, rgb: np.ndarray, masks: Sequence[ObjectMask]) -> tuple[np.ndarray, np.ndarray]: ...


class TableLabeller:
    """Oracle-mask track: the label of each mask's dataset instance from an id -> COCO label table."""

    def __init__(self, instance_labels: dict[int, int]):
        self.instance_labels = instance_labels

    def __call__(self, rgb: np.ndarray, masks: Sequence[ObjectMask]) -> tuple[np.ndarray, np.ndarray]:
        labels = np.array([self.instance_labels.get(int(m.instance_id or 0), -1) for m in masks], np.int64)
        return labels, np.ones(len(masks))


class ZeroShotLabeller:
    """Predicted track: CLIP-style zero-shot classification of mask crops against the COCO names.

    The prompts are the project's zero-shot template over the 80 COCO names plus ``background``
    prompts (walls, floors...), which play the role of a detector's background class: a crop closest
    to one of them is no detection. The score is the softmax probability of the winning COCO class
    over all prompts at logit scale ``scale``.
    """

    def __init__(self, encoder: ImageTextEncoder, background: Sequence[str], scale: float):
        self.encoder = encoder
        self.scale = float(scale)
        prompts = [voc.with_article(voc.ZERO_SHOT_TEMPLATE.format(noun=n)) for n in (*COCO_CLASSES, *background)]
        self.text = encoder.encode_texts(prompts)

    def __call__(self, rgb: np.ndarray, masks: Sequence[ObjectMask]) -> tuple[np.ndarray, np.ndarray]:
        if not masks:
            return np.zeros(0, np.int64), np.zeros(0)
        crops = [square_crop(rgb, m.box) for m in masks]
        logits = self.scale * (self.encoder.encode_images(crops) @ self.text.T)
        prob = np.exp(logits - logits.max(axis=1, keepdims=True))
        prob /= prob.sum(axis=1, keepdims=True)
        best = prob.argmax(axis=1)
        labels = np.where(best < len(COCO_CLASSES), best, -1)
        return labels.astype(np.int64), prob[np.arange(len(best)), best]


def box_iou(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(N, M) IoU of [x0, y0, x1, y1] boxes."""
    a, b = np.asarray(a, np.float64).reshape(-1, 4), np.asarray(b, np.float64).reshape(-1, 4)
    lo = np.maximum(a[:, None, :2], b[None, :, :2])
    hi = np.minimum(a[:, None, 2:], b[None, :, 2:])
    inter = np.prod(np.clip(hi - lo, 0, None), axis=2)
    area_a = np.prod(a[:, 2:] - a[:, :2], axis=1)
    area_b = np.prod(b[:, 2:] - b[:, :2], axis=1)
    return inter / np.maximum(area_a[:, None] + area_b[None, :] - inter, 1e-12)


def mask_ellipse_box(mask: np.ndarray) -> np.ndarray:
    """Box of the ellipse ``cv2.fitEllipse`` fits to the mask's largest outer contour (YOLOv8-seg's
    ellipse in GOReloc's detections); the mask's own box when the contour is too short to fit."""
    contours, _ = cv2.findContours(mask.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    contour = max(contours, key=len)
    if len(contour) < 5:
        x, y, w, h = cv2.boundingRect(contour)
        return np.array([x, y, x + w, y + h], np.float64)
    (cx, cy), (w, h), angle = cv2.fitEllipse(contour)
    t = np.deg2rad(angle)
    a, b = w / 2, h / 2
    hx = np.hypot(a * np.cos(t), b * np.sin(t))
    hy = np.hypot(a * np.sin(t), b * np.cos(t))
    return np.array([cx - hx, cy - hy, cx + hx, cy + hy])


def detect(
    rgb: np.ndarray, masks: Sequence[ObjectMask], labeller: Labeller, cfg: DetectionFilterConfig
) -> list[Detection]:
    """The filtered detections of an image's masks (geometric checks first: only their survivors
    are labelled, which keeps zero-shot classification off most of the segmenter's output)."""
    h, w = rgb.shape[:2]
    keep = []
    for i, m in enumerate(masks):
        box = np.asarray(m.box, np.float64)
        area = float(np.prod(box[2:] - box[:2]))
        near_border = box[0] < cfg.border_px or box[1] < cfg.border_px
        near_border |= box[2] > w - cfg.border_px or box[3] > h - cfg.border_px
        if not cfg.min_box_area <= area <= cfg.max_box_share * w * h or near_border:
            continue
        if box_iou(box, mask_ellipse_box(m.mask))[0, 0] < cfg.min_ellipse_iou:
            continue
        keep.append(i)
    labels, scores = labeller(rgb, [masks[i] for i in keep])
    found = [
        Detection(int(lab), float(s), np.asarray(masks[i].box, np.float64), i, masks[i].instance_id)
        for i, lab, s in zip(keep, labels, scores)
        if lab >= 0 and s >= cfg.min_score
    ]
    return deduplicate(sorted(found, key=lambda d: -d.score), cfg)


def deduplicate(dets: list[Detection], cfg: DetectionFilterConfig) -> list[Detection]:
    """Greedy: a detection is kept unless it overlaps an already kept one too much (a same-label
    overlap above ``same_label_iou``, another label's above ``other_label_iou``)."""
    kept: list[Detection] = []
    for d in dets:
        if kept:
            iou = box_iou(d.box, np.array([k.box for k in kept]))[0]
            same = np.array([k.label == d.label for k in kept])
            if np.any(np.where(same, iou > cfg.same_label_iou, iou > cfg.other_label_iou)):
                continue
        kept.append(d)
    return kept
