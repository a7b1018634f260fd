"""Multi-view landmark descriptors (paper section 3.1, Eq. 1).

f_i = mean of the image-encoder embeddings of the landmark's top-k most visible crops, re-normalised
(cosine similarity is what association compares). A crop is the landmark's 2D box in that frame
(the box of its seen, depth-tested projected points), padded for context.
"""

from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass

import numpy as np

from openreloc_bench.bars import tqdm
from openreloc_bench.config import check_ranges
from openreloc_bench.data.types import SceneSequence
from openreloc_bench.openreloc.reference_frames import Sightings
from openreloc_bench.reconstruction.frames import read_color
from openreloc_bench.vision.base import ImageTextEncoder, l2_normalize


@dataclass
class DescriptorConfig:
    """Which crops describe a landmark."""

    top_k: int = 5
    """Number of most-visible views averaged (k in the paper)."""
    padding: float = 0.1
    """Crop = 2D box grown by this share of its width/height on each side (clipped to the image)."""
    min_crop_px: int = 8
    """Views whose box is narrower or shorter than this many pixels are used only if nothing else is."""
    batch_size: int = 64
    """Crops per encoder call."""

    def __post_init__(self) -> None:
        check_ranges(self, at_least_one=("top_k", "batch_size"), non_negative=("padding", "min_crop_px"))


def pad_box(box: np.ndarray, padding: float, width: int, height: int) -> tuple[int, int, int, int]:
    """Integer crop window [x0, y0, x1, y1) of a box grown by ``padding`` and clipped to the image."""
    x0, y0, x1, y1 = (float(v) for v in box)
    px, py = padding * (x1 - x0), padding * (y1 - y0)
    return (
        max(0, int(np.floor(x0 - px))),
        max(0, int(np.floor(y0 - py))),
        min(width, int(np.ceil(x1 + px))),
        min(height, int(np.ceil(y1 + py))),
    )


def top_views(sightings: Sightings, landmark: int, cfg: DescriptorConfig) -> np.ndarray:
    """Indices (into ``sightings``) of the landmark's ``top_k`` most visible, large-enough views."""
    idx = np.flatnonzero(sightings.landmark == landmark)
    side = np.minimum(sightings.box[idx, 2] - sightings.box[idx, 0], sightings.box[idx, 3] - sightings.box[idx, 1])
    large = side >= cfg.min_crop_px
    pool = idx[large] if large.any() else idx
    order = np.lexsort((sightings.frame[pool], -sightings.n_points[pool], -sightings.visibility[pool]))
    return pool[order[: cfg.top_k]]


@dataclass
class LandmarkDescriptors:
    """Every landmark's descriptor and how well its crops from different views agree."""

    descriptors: dict[int, np.ndarray]
    """Landmark -> unit descriptor."""
    crops: dict[int, int]
    """Landmark -> number of crops averaged."""
    cross_view_recall: float | None
    """Share of crops whose nearest descriptor is their own landmark's, that descriptor made of the
    landmark's other crops (leave one out): how a new view of the object would be associated. Needs
    no labels, so it measures the encoder on any recording; None when no landmark has two crops."""


def compute_descriptors(
    seq: SceneSequence,
    sightings: Sightings,
    landmarks: list[int],
    encoder: ImageTextEncoder,
    cfg: DescriptorConfig,
    progress: bool = True,
) -> LandmarkDescriptors:
    """Each landmark's mean crop embedding; each frame is read once."""
    jobs: dict[int, list[tuple[int, np.ndarray]]] = defaultdict(list)  # frame -> [(landmark, box)]
    for lid in landmarks:
        for s in top_views(sightings, lid, cfg):
            jobs[int(sightings.frame[s])].append((lid, sightings.box[s]))
    crops, owners = [], []
    for f in tqdm(sorted(jobs), desc="crops", disable=not progress, leave=False):
        rgb = read_color(seq, f)
        for lid, box in jobs[f]:
            x0, y0, x1, y1 = pad_box(box, cfg.padding, seq.width, seq.height)
            crops.append(np.ascontiguousarray(rgb[y0:y1, x0:x1]))
            owners.append(lid)
    feats = [encoder.encode_images(crops[i : i + cfg.batch_size]) for i in range(0, len(crops), cfg.batch_size)]
    emb = np.concatenate(feats) if feats else np.zeros((0, encoder.dim), np.float32)
    owners_arr = np.array(owners)
    out, used = {}, {}
    for lid in landmarks:
        rows = emb[owners_arr == lid]
        used[lid] = len(rows)
        out[lid] = l2_normalize(rows.mean(axis=0)) if len(rows) else np.zeros(encoder.dim, np.float32)
    return LandmarkDescriptors(out, used, cross_view_recall(emb, owners_arr, landmarks, out))


def cross_view_recall(
    emb: np.ndarray, owners: np.ndarray, landmarks: list[int], descriptors: dict[int, np.ndarray]
) -> float | None:
    """Leave-one-out recall@1 of crop embeddings ``emb`` (owned by ``owners``) against the landmark
    descriptors (see :attr:`LandmarkDescriptors.cross_view_recall`)."""
    counts = {lid: int((owners == lid).sum()) for lid in landmarks}
    if not any(n >= 2 for n in counts.values()):
        return None
    ids = list(landmarks)
    table = np.stack([descriptors[i] for i in ids])
    sums = {lid: emb[owners == lid].sum(axis=0) for lid in ids if counts[lid] >= 2}
    hits = total = 0
    for k in np.flatnonzero(np.isin(owners, list(sums))):
        lid = int(owners[k])
        own = l2_normalize(sums[lid] - emb[k])  # the descriptor without this crop
        sims = table @ emb[k]
        sims[ids.index(lid)] = own @ emb[k]
        hits += int(ids[int(np.argmax(sims))] == lid)
        total += 1
    return hits / total
