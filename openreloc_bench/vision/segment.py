"""2D object segmenters for query images: oracle masks, a simulated noisy detector, and a weight-free
class-agnostic graph segmenter (the predicted track).

The graph segmenter runs Felzenszwalb-Huttenlocher merging on a region adjacency graph of watershed
superpixels (OpenCV + scipy only): superpixels keep it fast in Python, the adaptive merge criterion
(merge when the edge is weaker than both regions' internal variation + k/size) keeps object-sized
regions, and size filtering drops speckle and the large wall/floor planes.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from typing import Literal

import cv2
import numpy as np
from scipy import ndimage

from openreloc_bench.vision.base import ObjectMask, Segmenter, register_segmenter
from openreloc_bench.vision.preprocess import InputError, as_rgb_uint8, mask_box


def _check_instance(rgb: np.ndarray, instance: np.ndarray | None, who: str) -> np.ndarray:
    if instance is None:
        raise InputError(f"segmenter '{who}' needs the dataset instance image (oracle-mask track)")
    inst = np.asarray(instance)
    if inst.shape != rgb.shape[:2]:
        raise InputError(f"instance image shape {inst.shape} does not match the RGB image {rgb.shape[:2]}")
    if not np.issubdtype(inst.dtype, np.integer):
        raise InputError(f"instance image must hold integer ids, got {inst.dtype}")
    return inst


def _masks_from_ids(inst: np.ndarray, min_area: int, ids: set[int] | None, exclude: set[int]) -> list[ObjectMask]:
    labels, counts = np.unique(inst, return_counts=True)
    out = []
    for oid, n in zip(labels.tolist(), counts.tolist()):
        if oid == 0 or n < min_area or oid in exclude or (ids is not None and oid not in ids):
            continue
        m = inst == oid
        out.append(ObjectMask(mask=m, box=mask_box(m), instance_id=int(oid)))
    return out


@register_segmenter("gt")
class GtSegmenter(Segmenter):
    """Dataset instance masks (a perfect detector): the oracle-mask track."""

    name = "gt"

    def __init__(self, min_area: int = 100, ids: list[int] | None = None, exclude_ids: list[int] | None = None):
        """``min_area`` pixels; ``ids`` keeps only these instances, ``exclude_ids`` drops these (e.g. walls)."""
        self.min_area = int(min_area)
        self.ids = set(ids) if ids is not None else None
        self.exclude = set(exclude_ids or ())

    def segment(self, rgb: np.ndarray, instance: np.ndarray | None = None) -> list[ObjectMask]:
        rgb = as_rgb_uint8(rgb)
        return _masks_from_ids(_check_instance(rgb, instance, self.name), self.min_area, self.ids, self.exclude)


@register_segmenter("noisy-gt")
class NoisyGtSegmenter(GtSegmenter):
    """Ground-truth masks corrupted like a real detector's output, seeded per (seed, image).

    Per object, independently: dropped (missed detection), eroded or dilated by a few pixels (loose
    or tight masks), merged with a touching neighbour (under-segmentation), box jittered.
    """

    name = "noisy-gt"

    def __init__(
        self,
        seed: int = 0,
        drop_rate: float = 0.1,
        morph_rate: float = 0.5,
        max_morph_px: int = 3,
        merge_rate: float = 0.05,
        box_jitter: float = 0.05,
        min_area: int = 100,
        ids: list[int] | None = None,
        exclude_ids: list[int] | None = None,
    ):
        super().__init__(min_area, ids, exclude_ids)
        for key, v in (("drop_rate", drop_rate), ("morph_rate", morph_rate), ("merge_rate", merge_rate)):
            if not 0.0 <= v <= 1.0:
                raise InputError(f"noisy-gt: '{key}' must be in [0, 1], got {v}")
        if box_jitter < 0 or max_morph_px < 0:
            raise InputError("noisy-gt: 'box_jitter' and 'max_morph_px' must be >= 0")
        self.seed, self.drop_rate, self.morph_rate = int(seed), drop_rate, morph_rate
        self.max_morph_px, self.merge_rate, self.box_jitter = int(max_morph_px), merge_rate, box_jitter

    def _rng(self, rgb: np.ndarray, inst: np.ndarray) -> np.random.Generator:
        h = hashlib.sha1(np.ascontiguousarray(inst).tobytes())
        h.update(rgb[::7, ::7].tobytes())
        return np.random.default_rng([self.seed, int.from_bytes(h.digest()[:8], "little")])

    def segment(self, rgb: np.ndarray, instance: np.ndarray | None = None) -> list[ObjectMask]:
        rgb = as_rgb_uint8(rgb)
        inst = _check_instance(rgb, instance, self.name)
        objs = _masks_from_ids(inst, self.min_area, self.ids, self.exclude)
        rng = self._rng(rgb, inst)
        # draw every random number per object in a fixed order, so one rate does not shift the others
        draws = [
            (
                rng.random(),
                rng.random(),
                rng.random(),
                rng.integers(1, self.max_morph_px + 1) if self.max_morph_px else 0,
                rng.random(),
                rng.uniform(-1, 1, 4),
            )
            for _ in objs
        ]
        merged_into: dict[int, int] = {}
        kernel = np.ones((3, 3), np.uint8)
        for i, (o, d) in enumerate(zip(objs, draws)):
            if d[4] < self.merge_rate and i not in merged_into:
                ring = cv2.dilate(o.mask.astype(np.uint8), kernel, iterations=2).astype(bool) & ~o.mask
                touching = [j for j, p in enumerate(objs) if j != i and j not in merged_into and (p.mask & ring).any()]
                if touching:
                    j = max(touching, key=lambda j: int(objs[j].mask.sum()))
                    merged_into[j] = i
                    o.mask = o.mask | objs[j].mask
        out = []
        for i, (o, (drop, morph, grow, px, _, jit)) in enumerate(zip(objs, draws)):
            if i in merged_into or drop < self.drop_rate:
                continue
            m = o.mask
            if morph < self.morph_rate and px:
                k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * px + 1, 2 * px + 1))
                op = cv2.dilate if grow < 0.5 else cv2.erode
                m2 = op(m.astype(np.uint8), k).astype(bool)
                m = m2 if m2.sum() >= self.min_area else m
            box = mask_box(m).astype(np.float64)
            size = np.array([box[2] - box[0], box[3] - box[1]] * 2)
            box = box + jit * self.box_jitter * size
            h, w = m.shape
            box = np.clip(np.round(box), 0, [w, h, w, h]).astype(np.int64)
            if box[2] <= box[0] or box[3] <= box[1]:
                box = mask_box(m)
            out.append(ObjectMask(mask=m, box=box, instance_id=o.instance_id, score=float(1.0 - 0.5 * drop)))
        return out


@dataclass
class _Region:
    size: int
    internal: float


@register_segmenter("graph")
class GraphSegmenter(Segmenter):
    """Weight-free, class-agnostic segmentation: superpixels + graph-based region merging + size filter."""

    name = "graph"

    def __init__(
        self,
        k: float = 6000.0,
        superpixel_px: int = 10,
        work_width: int = 320,
        min_area_frac: float = 0.002,
        max_area_frac: float = 0.25,
        min_fill: float = 0.3,
        smooth: Literal["mean-shift", "bilateral"] = "mean-shift",
        cv_threads: int | None = 1,
    ):
        """``k``: merge strength (larger -> bigger regions); ``superpixel_px``: seed spacing at work resolution;
        ``min/max_area_frac``: kept region sizes as image fractions; ``min_fill``: minimum mask/box area ratio;
        ``smooth``: edge-preserving smoothing before superpixels (mean-shift flattens textures better);
        ``cv_threads``: OpenCV's global thread count (1 by default: on a shared, loaded CPU its thread pool
        makes colour conversion many times slower; None leaves OpenCV's setting alone)."""
        if k <= 0 or superpixel_px < 2 or work_width < 32:
            raise InputError("graph segmenter: need k > 0, superpixel_px >= 2, work_width >= 32")
        if not 0 <= min_area_frac < max_area_frac <= 1:
            raise InputError("graph segmenter: need 0 <= min_area_frac < max_area_frac <= 1")
        self.k, self.step, self.work_width = float(k), int(superpixel_px), int(work_width)
        self.min_area_frac, self.max_area_frac, self.min_fill = min_area_frac, max_area_frac, min_fill
        self.smooth = smooth
        if cv_threads is not None:
            cv2.setNumThreads(int(cv_threads))

    def superpixels(self, rgb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Watershed superpixels (labels 0..n-1) from grid seeds at local gradient minima, and the smoothed image."""
        h, w = rgb.shape[:2]
        smooth = (
            cv2.pyrMeanShiftFiltering(rgb, 6, 18) if self.smooth == "mean-shift" else cv2.bilateralFilter(rgb, 5, 30, 5)
        )
        lab = cv2.cvtColor(smooth, cv2.COLOR_RGB2LAB)
        grad = np.zeros((h, w), np.float32)
        for c in range(3):
            ch = lab[..., c].astype(np.float32)
            grad = np.maximum(grad, cv2.magnitude(cv2.Sobel(ch, cv2.CV_32F, 1, 0), cv2.Sobel(ch, cv2.CV_32F, 0, 1)))
        markers = np.zeros((h, w), np.int32)
        s = self.step
        ys, xs = np.mgrid[s // 2 : h : s, s // 2 : w : s]
        r = max(1, s // 3)
        label = 1
        for y, x in zip(ys.ravel(), xs.ravel()):
            y0, x0 = max(0, y - r), max(0, x - r)
            win = grad[y0 : y + r + 1, x0 : x + r + 1]
            dy, dx = np.unravel_index(int(win.argmin()), win.shape)
            markers[y0 + dy, x0 + dx] = label
            label += 1
        markers = cv2.watershed(cv2.cvtColor(smooth, cv2.COLOR_RGB2BGR), markers)
        # watershed lines (-1) take the label of the nearest labelled pixel
        lines = markers <= 0
        if lines.any():
            idx = ndimage.distance_transform_edt(lines, return_distances=False, return_indices=True)
            markers = markers[idx[0], idx[1]]
        return markers - 1, smooth

    def regions(self, rgb: np.ndarray) -> np.ndarray:
        """Label image (work resolution) after Felzenszwalb-Huttenlocher merging on the superpixel graph."""
        sp, smooth = self.superpixels(rgb)
        n = int(sp.max()) + 1
        lab = cv2.cvtColor(smooth, cv2.COLOR_RGB2LAB).reshape(-1, 3).astype(np.float64)
        flat = sp.ravel()
        size = np.bincount(flat, minlength=n).astype(np.float64)
        mean = np.stack([np.bincount(flat, lab[:, c], minlength=n) for c in range(3)], 1) / np.maximum(size, 1)[:, None]
        pairs = np.concatenate(
            [np.stack([sp[:, :-1].ravel(), sp[:, 1:].ravel()], 1), np.stack([sp[:-1].ravel(), sp[1:].ravel()], 1)]
        )
        pairs = np.sort(pairs[pairs[:, 0] != pairs[:, 1]], 1).astype(np.int64)
        code = np.unique(pairs[:, 0] * n + pairs[:, 1])
        pairs = np.stack([code // n, code % n], 1)
        weight = np.linalg.norm(mean[pairs[:, 0]] - mean[pairs[:, 1]], axis=1)
        parent = np.arange(n)

        def find(a: int) -> int:
            while parent[a] != a:
                parent[a] = parent[parent[a]]
                a = parent[a]
            return a

        comp = {i: _Region(int(size[i]), 0.0) for i in range(n)}
        for e in np.argsort(weight, kind="stable"):
            a, b = find(int(pairs[e, 0])), find(int(pairs[e, 1]))
            if a == b:
                continue
            ra, rb = comp[a], comp[b]
            wgt = float(weight[e])
            if wgt <= min(ra.internal + self.k / ra.size, rb.internal + self.k / rb.size):
                parent[b] = a
                comp[a] = _Region(ra.size + rb.size, max(ra.internal, rb.internal, wgt))
        roots = np.array([find(i) for i in range(n)])
        return roots[sp]

    def segment(self, rgb: np.ndarray, instance: np.ndarray | None = None) -> list[ObjectMask]:
        rgb = as_rgb_uint8(rgb)
        H, W = rgb.shape[:2]
        scale = min(1.0, self.work_width / W)
        small = (
            cv2.resize(rgb, (max(8, round(W * scale)), max(8, round(H * scale))), interpolation=cv2.INTER_AREA)
            if scale < 1
            else rgb
        )
        labels = self.regions(small)
        if scale < 1:
            labels = cv2.resize(labels.astype(np.int32), (W, H), interpolation=cv2.INTER_NEAREST).astype(np.int64)
        counts = np.bincount(labels.ravel())
        lo, hi = self.min_area_frac * H * W, self.max_area_frac * H * W
        out = []
        for rid, sl in enumerate(ndimage.find_objects(labels + 1)):
            if sl is None or not lo <= counts[rid] <= hi:
                continue
            sub = ndimage.binary_fill_holes(labels[sl] == rid)
            fill = sub.sum() / sub.size
            if fill < self.min_fill:
                continue
            m = np.zeros((H, W), bool)
            m[sl] = sub
            box = np.array([sl[1].start, sl[0].start, sl[1].stop, sl[0].stop], dtype=np.int64)
            out.append(ObjectMask(mask=m, box=box, score=float(fill)))
        return sorted(out, key=lambda o: -int(o.mask.sum()))
