"""Training the instance merge classifier (:mod:`instance_repair`) on generated training scenes.

On a training scene the truth of every pair of touching instances is free: the scene's object boxes
label the scene points (:func:`.instance_eval.box_point_labels`), each grouped instance takes the object
most of its points lie in, and a pair is one object when both take the same one. Pairs with an
instance mostly outside any one object (under half its points) teach nothing clean and are left out.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from openreloc_bench.bars import tqdm
from openreloc_bench.data.scene import Scene
from openreloc_bench.errors import DataError
from openreloc_bench.openreloc.build import MappingConfig, lift_instances
from openreloc_bench.reconstruction import instance_repair as repair
from openreloc_bench.reconstruction.incidence import view_evidence
from openreloc_bench.reconstruction.instance_eval import box_point_labels, boxed_objects
from openreloc_bench.vision.base import Segmenter


@dataclass
class MergeExamples:
    """Border features of touching instance pairs and whether each pair is one object."""

    features: np.ndarray
    """(P, len(FEATURES))."""
    same: np.ndarray
    """(P,) bool."""

    @classmethod
    def concatenate(cls, parts: Sequence[MergeExamples]) -> MergeExamples:
        return cls(
            np.concatenate([p.features for p in parts]) if parts else np.zeros((0, len(repair.FEATURES))),
            np.concatenate([p.same for p in parts]) if parts else np.zeros(0, bool),
        )


def dominant_objects(labels: np.ndarray, truth: np.ndarray) -> dict[int, tuple[int, float]]:
    """Instance id -> (the true object holding most of its points, that share)."""
    fg = np.flatnonzero(labels > 0)
    pairs, count = np.unique(np.stack([labels[fg], truth[fg]]), axis=1, return_counts=True)
    out: dict[int, tuple[int, float]] = {}
    total = {int(i): int(n) for i, n in zip(*np.unique(labels[fg], return_counts=True))}
    for (inst, obj), n in zip(pairs.T, count):
        if int(inst) not in out or n / total[int(inst)] > out[int(inst)][1]:
            out[int(inst)] = (int(obj), n / total[int(inst)])
    return out


def scene_examples(scene_dir: Path, segmenter: Segmenter, config: MappingConfig) -> MergeExamples:
    """The pairs of touching instances the repair's merge step sees on one scene (after grouping, and
    fill when it is on), with their truth from the scene's object boxes."""
    scene = Scene(scene_dir)
    seq = scene.sequence("mapping")
    objects = boxed_objects(scene.objects)
    if not objects:
        raise DataError(scene_dir / "objects.json", "no object boxes: merge training needs generated scenes")
    # the instances as grouped, without repair: fill is applied below, as the merge step sees it
    no_repair = replace(config.instances.repair, fill=False, merge=False)
    cfg = replace(config, instances=replace(config.instances, repair=no_repair))
    inst = lift_instances(seq, cfg, segmenter, progress=False, boundaries=True)
    points, obs = inst.reconstruction.points, inst.observations
    rc = config.instances.repair
    views = view_evidence(len(points), obs, config.instances.min_mask_points)
    labels = repair.fill_from_masks(inst.labels, views, rc.fill_purity, rc.fill_share) if rc.fill else inst.labels
    attrs = repair.point_attributes(points, obs, seq.poses[:, :3, 3])
    neighbours = cKDTree(points).query_pairs(rc.contact_radius, output_type="ndarray")
    pairs = repair.border_features(points, labels, attrs, views, neighbours, rc)
    truth = box_point_labels(points, objects, config.instances.gt_box_margin)
    owner = dominant_objects(labels, truth)
    first = [owner[int(a)] for a in pairs.first]
    second = [owner[int(b)] for b in pairs.second]
    same = np.array([a[0] == b[0] and a[0] > 0 for a, b in zip(first, second)], bool)
    clean = np.array([min(a[1], b[1]) >= 0.5 for a, b in zip(first, second)], bool)
    return MergeExamples(pairs.features[clean], same[clean])


def collect_examples(
    scene_dirs: Sequence[Path], segmenter: Segmenter, config: MappingConfig, progress: bool = True
) -> MergeExamples:
    return MergeExamples.concatenate(
        [scene_examples(d, segmenter, config) for d in tqdm(scene_dirs, desc="merge examples", disable=not progress)]
    )


def pair_accuracy(classifier: repair.MergeClassifier, examples: MergeExamples, threshold: float) -> dict[str, float]:
    """Accuracy, precision and recall of 'one object' at ``threshold`` on held-out pairs."""
    said = classifier.probability(examples.features) > threshold
    same = examples.same
    return {
        "pairs": int(len(same)),
        "one_object": int(same.sum()),
        "accuracy": float(np.mean(said == same)) if len(same) else float("nan"),
        "precision": float(np.mean(same[said])) if said.any() else float("nan"),
        "recall": float(np.mean(said[same])) if same.any() else float("nan"),
    }
