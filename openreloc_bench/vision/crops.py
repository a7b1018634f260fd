"""Object crops from scenes on disk (the project layout): training and evaluation data for encoders.

Every crop is the instance's bounding box squared with 10% padding (:func:`preprocess.square_crop`),
the same view the encoders get at query time, resized to a fixed size and stored with its labels.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from tqdm import tqdm

from openreloc_bench.data.scene import Scene
from openreloc_bench.vision.base import Segmenter
from openreloc_bench.vision.preprocess import resize_square, square_crop
from openreloc_bench.vision.segment import GtSegmenter


@dataclass
class CropSet:
    """Crops and their labels, row-aligned."""

    images: np.ndarray
    """uint8 (N, S, S, 3)."""
    scene: list[str] = field(default_factory=list)
    split: list[str] = field(default_factory=list)
    frame: list[str] = field(default_factory=list)
    object_id: list[int] = field(default_factory=list)
    category: list[str] = field(default_factory=list)
    colour: list[str] = field(default_factory=list)
    material: list[str] = field(default_factory=list)
    description: list[str] = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.images)

    @property
    def instance_keys(self) -> list[str]:
        """'scene/object id': one key per physical object (views of it share the key)."""
        return [f"{s}/{o}" for s, o in zip(self.scene, self.object_id)]

    def subset(self, idx: np.ndarray | list[int]) -> CropSet:
        idx = list(np.asarray(idx, dtype=int))
        lists = {k: [getattr(self, k)[i] for i in idx] for k in self._label_fields()}
        return CropSet(self.images[idx], **lists)

    @staticmethod
    def _label_fields() -> tuple[str, ...]:
        return ("scene", "split", "frame", "object_id", "category", "colour", "material", "description")

    def save(self, path: Path) -> None:
        np.savez_compressed(path, images=self.images, **{k: np.asarray(getattr(self, k)) for k in self._label_fields()})

    @classmethod
    def load(cls, path: Path) -> CropSet:
        with np.load(path, allow_pickle=False) as z:
            return cls(z["images"], **{k: z[k].tolist() for k in cls._label_fields()})

    @classmethod
    def concat(cls, sets: Iterable[CropSet]) -> CropSet:
        sets = list(sets)
        if not sets:
            return cls(np.zeros((0, 1, 1, 3), np.uint8))
        return cls(
            np.concatenate([s.images for s in sets]),
            **{k: [v for s in sets for v in getattr(s, k)] for k in cls._label_fields()},
        )


def scene_crops(
    scene_dir: Path,
    splits: Iterable[str] | None = None,
    size: int = 64,
    min_area: int = 150,
    max_views_per_object: int = 0,
    rng: np.random.Generator | None = None,
    segmenter: Segmenter | None = None,
    min_purity: float = 0.6,
) -> CropSet:
    """Crops of every non-structural object visible with >= ``min_area`` pixels, per frame of ``splits``.

    ``max_views_per_object`` > 0 keeps that many random views per (split, object) (needs ``rng``),
    so large scenes do not flood the data with near-identical neighbouring frames. With a
    ``segmenter`` the crops are cut by its masks instead of the dataset's (noisy borders, parts, what
    the predicted track sees): each mask is labelled with the object holding at least ``min_purity``
    of its pixels, and masks on no single object are skipped.
    """
    scene = Scene(scene_dir)
    objects = {i: o for i, o in scene.objects.items() if not o.structural}
    chosen = [s for s in scene.splits() if splits is None or s in set(splits)]
    rows: list[tuple[str, str, int, np.ndarray]] = []
    for split in chosen:
        seq = scene.sequence(split)
        per_obj: dict[int, list[tuple[str, str, int, np.ndarray]]] = {}
        for frame in seq:
            if frame.instance is None:
                continue
            for oid, box in _labelled_boxes(frame.color, frame.instance, objects, min_area, segmenter, min_purity):
                crop = resize_square(square_crop(frame.color, box), size)
                per_obj.setdefault(oid, []).append((split, frame.name.split("/")[-1], oid, crop))
        for oid in sorted(per_obj):
            views = per_obj[oid]
            if max_views_per_object and len(views) > max_views_per_object:
                assert rng is not None, "max_views_per_object needs an rng"
                views = [views[i] for i in sorted(rng.choice(len(views), max_views_per_object, replace=False))]
            rows.extend(views)
    if not rows:
        return CropSet(np.zeros((0, size, size, 3), np.uint8))
    obj = [objects[r[2]] for r in rows]
    return CropSet(
        np.stack([r[3] for r in rows]),
        scene=[scene.name] * len(rows),
        split=[r[0] for r in rows],
        frame=[r[1] for r in rows],
        object_id=[r[2] for r in rows],
        category=[o.category for o in obj],
        colour=[str(o.attributes.get("colour", "")) for o in obj],
        material=[str(o.attributes.get("material", "")) for o in obj],
        description=[o.description for o in obj],
    )


def _labelled_boxes(
    rgb: np.ndarray,
    instance: np.ndarray,
    objects: dict,
    min_area: int,
    segmenter: Segmenter | None,
    min_purity: float,
) -> list[tuple[int, np.ndarray]]:
    """(object id, box) of each crop of a frame: the dataset's masks, or the segmenter's labelled by purity."""
    if segmenter is None:
        masks = GtSegmenter(min_area=min_area, ids=list(objects)).segment(rgb, instance)
        return [(int(m.instance_id), m.box) for m in masks]
    out = []
    for m in segmenter.segment(rgb):
        area = int(m.mask.sum())
        if area < min_area:
            continue
        ids, counts = np.unique(instance[m.mask], return_counts=True)
        k = int(np.argmax(counts))
        if int(ids[k]) in objects and counts[k] >= min_purity * area:
            out.append((int(ids[k]), m.box))
    return out


def crops_from_scenes(scene_dirs: list[Path], progress: bool = True, **kwargs: object) -> CropSet:
    """:func:`scene_crops` over many scenes, concatenated (tqdm progress)."""
    return CropSet.concat(scene_crops(d, **kwargs) for d in tqdm(scene_dirs, desc="crops", disable=not progress))  # type: ignore[arg-type]
