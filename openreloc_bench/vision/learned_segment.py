"""The learned, class-agnostic instance segmenter (``segmenter: learned``): a small U-Net predicts
instance boundaries from RGB, and the regions they enclose become the segments.

Why boundaries: the generator labels every pixel with an instance, so "where does one instance end"
is a dense, class-free target a small network learns from generated scenes alone, and it turns into
instances with two OpenCV calls (connected components of the non-boundary pixels, then each boundary
pixel to its nearest region), with no proposal or clustering stage to tune. Walls, floors and
ceilings come out as segments of their own, as in the oracle masks (the methods filter them).

The network runs at a working resolution (``work_width``, the frame downscaled by area averaging);
its boundary probabilities are upsampled to the frame before thresholding, so segments are cut at
full resolution. Weights are a versioned, checksummed file set (``model.pt`` + ``card.json``) written
by ``openreloc-bench train-segmenter``; the shipped ones live in ``vision/weights/segmenter/``.
"""

from __future__ import annotations

import hashlib
import io as _io
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import asdict, dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import torch
import torch.nn.functional as F
from scipy import ndimage
from torch import nn

from openreloc_bench import config as cfgmod
from openreloc_bench.data import mapfile
from openreloc_bench.errors import DataError
from openreloc_bench.vision.base import ObjectMask, Segmenter, register_segmenter
from openreloc_bench.vision.preprocess import InputError, as_rgb_uint8

WEIGHTS_FORMAT = ("openreloc-segmenter", 1)
MODEL_FILE = "model.pt"
CARD_FILE = "card.json"
DEFAULT_WEIGHTS = Path(__file__).parent / "weights" / "segmenter"


@dataclass
class NetConfig:
    """Shape of the boundary network (saved with its weights)."""

    widths: tuple[int, ...] = (16, 24, 48, 96, 128)
    """Channels of the stem (full working resolution) and of each encoder stage (each halves the size)."""
    work_width: int = 320
    """Frames are downscaled to this width (aspect kept) before the network; the boundaries it predicts
    are upsampled back to the frame."""

    def __post_init__(self) -> None:
        if len(self.widths) < 2 or min(self.widths) < 1:
            raise ValueError(f"'widths' needs >= 2 positive channel counts, got {self.widths}")
        if self.work_width < 32:
            raise ValueError(f"'work_width' must be >= 32, got {self.work_width}")

    @property
    def stride(self) -> int:
        """Input sides must be multiples of this (the network pads to it)."""
        return 2 ** (len(self.widths) - 1)


def _conv(cin: int, cout: int, stride: int = 1) -> nn.Sequential:
    return nn.Sequential(nn.Conv2d(cin, cout, 3, stride, 1, bias=False), nn.BatchNorm2d(cout), nn.ReLU(inplace=True))


class BoundaryNet(nn.Module):
    """A light U-Net: a strided encoder, a decoder that adds 1x1-projected skips (cheaper than
    concatenation at high resolution), and a 1-channel boundary logit at the input resolution."""

    def __init__(self, cfg: NetConfig):
        super().__init__()
        w = cfg.widths
        self.stem = _conv(3, w[0])
        self.down = nn.ModuleList(nn.Sequential(_conv(a, b, 2), _conv(b, b)) for a, b in zip(w[:-1], w[1:]))
        self.lateral = nn.ModuleList(nn.Conv2d(b, a, 1) for a, b in zip(w[:-1], w[1:]))
        self.up = nn.ModuleList(_conv(a, a) for a in w[:-1])
        self.head = nn.Conv2d(w[0], 1, 1)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        skips = [self.stem(x)]
        for stage in self.down:
            skips.append(stage(skips[-1]))
        y = skips.pop()
        for lateral, up in zip(reversed(self.lateral), reversed(self.up)):
            skip = skips.pop()
            y = up(skip + F.interpolate(lateral(y), size=skip.shape[-2:], mode="bilinear", align_corners=False))
        return self.head(y)


def standardize(rgb: np.ndarray) -> torch.Tensor:
    """(N, H, W, 3) uint8 -> (N, 3, H, W) float, each image to zero mean and unit variance: brightness and
    contrast (the lighting-decay splits) matter less to the network."""
    x = torch.from_numpy(np.ascontiguousarray(rgb)).permute(0, 3, 1, 2).float()
    mean = x.mean(dim=(1, 2, 3), keepdim=True)
    std = x.std(dim=(1, 2, 3), keepdim=True)
    return (x - mean) / std.clamp_min(2.0)


def work_size(width: int, height: int, work_width: int, stride: int) -> tuple[int, int]:
    """(w, h) the network sees: ``work_width`` wide (never upscaled), aspect kept, multiples of ``stride``."""
    w = min(width, work_width)
    h = round(height * w / width)
    return max(stride, round(w / stride) * stride), max(stride, round(h / stride) * stride)


def segments_from_boundaries(prob: np.ndarray, threshold: float, min_area: int) -> np.ndarray:
    """Instance labels (int32, 1..n, no 0) from a boundary probability map.

    Regions are the 4-connected components of the pixels below ``threshold``; regions smaller than
    ``min_area`` are dissolved; every remaining pixel (boundaries, dissolved regions) takes the label
    of its nearest region.
    """
    interior = (prob < threshold).astype(np.uint8)
    n, labels, stats, _ = cv2.connectedComponentsWithStats(interior, connectivity=4)
    keep = np.zeros(n, bool)
    keep[1:] = stats[1:, cv2.CC_STAT_AREA] >= min_area
    if not keep.any():
        return np.ones(prob.shape, np.int32)
    relabel = np.zeros(n, np.int32)
    relabel[keep] = np.arange(1, int(keep.sum()) + 1)
    labels = relabel[labels]
    # nearest kept region for everything else: the distance transform's labels index its zero pixels
    _, nearest = cv2.distanceTransformWithLabels(
        (labels == 0).astype(np.uint8), cv2.DIST_L2, 3, labelType=cv2.DIST_LABEL_PIXEL
    )
    seeds = labels[labels > 0]
    order = np.zeros(int(nearest.max()) + 1, np.int32)
    order[nearest[labels > 0]] = seeds
    return np.where(labels > 0, labels, order[nearest]).astype(np.int32)


def save_weights(directory: Path, net: BoundaryNet, net_cfg: NetConfig, card: dict[str, Any]) -> None:
    """Write ``model.pt`` (fp16 state dict) and ``card.json`` (net shape + recipe + metrics) as a file set."""
    buf = _io.BytesIO()
    torch.save({k: v.half() if v.is_floating_point() else v for k, v in net.state_dict().items()}, buf)
    card = {**card, "net": cfgmod.to_dict(net_cfg)}
    mapfile.write_file_set(
        directory, *WEIGHTS_FORMAT, {MODEL_FILE: buf.getvalue(), CARD_FILE: mapfile.json_bytes(card)}
    )


@lru_cache(maxsize=4)
def load_weights(directory: Path) -> tuple[BoundaryNet, NetConfig, dict[str, Any]]:
    """The network (eval mode, float32) and card of a weights directory; DataError naming the file and
    how to make weights if anything is missing, truncated or mismatched."""
    hint = "train weights with `openreloc-bench train-segmenter --out DIR` and pass segmenter_options: {weights: DIR}"
    try:
        blobs = mapfile.read_file_set(directory, *WEIGHTS_FORMAT, {MODEL_FILE, CARD_FILE})
    except DataError as e:
        raise DataError(e.path, f"{e.problem}; {hint}") from None
    card = mapfile.load_json(blobs[CARD_FILE], directory / CARD_FILE)
    try:
        net_cfg = cfgmod.from_dict(NetConfig, {**card["net"], "widths": tuple(card["net"]["widths"])}, "net")
        net = BoundaryNet(net_cfg)
        state = torch.load(_io.BytesIO(blobs[MODEL_FILE]), map_location="cpu", weights_only=True)
        net.load_state_dict({k: v.float() if v.is_floating_point() else v for k, v in state.items()})
    except (KeyError, TypeError, RuntimeError, ValueError) as e:
        raise DataError(
            directory / MODEL_FILE, f"weights do not fit the network in {CARD_FILE} ({e}); {hint}"
        ) from None
    return net.eval(), net_cfg, card


@contextmanager
def torch_threads(n: int) -> Iterator[None]:
    """Run torch ops with ``n`` intra-op threads, restoring the previous setting."""
    before = torch.get_num_threads()
    torch.set_num_threads(n)
    try:
        yield
    finally:
        torch.set_num_threads(before)


@register_segmenter("learned")
class LearnedSegmenter(Segmenter):
    """Boundary U-Net + connected components: class-agnostic instance masks from RGB alone."""

    name = "learned"

    def __init__(
        self,
        weights: str | Path | None = None,
        threshold: float | None = None,
        min_area_frac: float = 0.0005,
        threads: int = 1,
    ):
        """``weights``: a directory from ``train-segmenter`` (default: the shipped weights);
        ``threshold``: boundary probability above which a pixel separates regions (default: the one the
        weights' card chose on the validation scenes); ``min_area_frac``: smaller regions are merged into
        their neighbours (share of the image); ``threads``: torch threads of the network (1: the harness runs
        a query job per core, where two threads each made the network twice as slow; same segments)."""
        self.weights = Path(weights) if weights is not None else DEFAULT_WEIGHTS
        self.net, self.net_cfg, self.card = load_weights(self.weights.resolve())
        self.threshold = float(threshold if threshold is not None else self.card.get("threshold", 0.5))
        if not 0.0 < self.threshold < 1.0:
            raise InputError(f"learned segmenter: 'threshold' must be in (0, 1), got {self.threshold}")
        if not 0.0 <= min_area_frac < 0.5:
            raise InputError(f"learned segmenter: 'min_area_frac' must be in [0, 0.5), got {min_area_frac}")
        if threads < 1:
            raise InputError(f"learned segmenter: 'threads' must be >= 1, got {threads}")
        self.min_area_frac, self.threads = min_area_frac, int(threads)

    @classmethod
    def weights_fingerprint(cls, weights: str | Path | None = None, **_: Any) -> str:
        """sha256 (12 hex digits) of the network file the options name, without loading it."""
        pt = (Path(weights) if weights is not None else DEFAULT_WEIGHTS) / MODEL_FILE
        return hashlib.sha256(pt.read_bytes()).hexdigest()[:12] if pt.is_file() else "missing"

    def config(self) -> dict[str, Any]:
        return {"name": self.name, "card": self.card.get("id", ""), "threshold": self.threshold, **asdict(self.net_cfg)}

    def boundary_probability(self, rgb: np.ndarray) -> np.ndarray:
        """(H, W) float32 boundary probability at the frame's resolution."""
        H, W = rgb.shape[:2]
        w, h = work_size(W, H, self.net_cfg.work_width, self.net_cfg.stride)
        small = cv2.resize(rgb, (w, h), interpolation=cv2.INTER_AREA) if (w, h) != (W, H) else rgb
        with torch_threads(self.threads), torch.inference_mode():
            logit = self.net(standardize(small[None]))[0, 0]
        prob = torch.sigmoid(logit).numpy()
        return cv2.resize(prob, (W, H), interpolation=cv2.INTER_LINEAR) if (w, h) != (W, H) else prob

    def segment(self, rgb: np.ndarray, instance: np.ndarray | None = None) -> list[ObjectMask]:
        return self.segment_with_boundaries(rgb, instance)[0]

    def segment_with_boundaries(
        self, rgb: np.ndarray, instance: np.ndarray | None = None
    ) -> tuple[list[ObjectMask], np.ndarray]:
        """The segments and the network's boundary probability they were cut from."""
        rgb = as_rgb_uint8(rgb)
        H, W = rgb.shape[:2]
        prob = self.boundary_probability(rgb)
        labels = segments_from_boundaries(prob, self.threshold, max(1, round(self.min_area_frac * H * W)))
        return masks_from_labels(labels, prob), prob


def segment_scores(labels: np.ndarray, prob: np.ndarray) -> np.ndarray:
    """Confidence of each segment (labels 1..n): 1 - its mean boundary probability."""
    flat = labels.ravel()
    edge = np.bincount(flat, weights=prob.ravel()) / np.maximum(np.bincount(flat), 1)
    return 1.0 - edge[1:]


def masks_from_labels(labels: np.ndarray, boundary: np.ndarray) -> list[ObjectMask]:
    """One :class:`ObjectMask` per label 1..n, largest first, scored by :func:`segment_scores`."""
    n = int(labels.max())
    scores = segment_scores(labels, boundary)
    out = []
    for k, sl in enumerate(ndimage.find_objects(labels, max_label=n), start=1):
        if sl is None:
            continue
        m = np.zeros(labels.shape, bool)
        m[sl] = labels[sl] == k
        box = np.array([sl[1].start, sl[0].start, sl[1].stop, sl[0].stop], dtype=np.int64)
        out.append(ObjectMask(mask=m, box=box, score=float(scores[k - 1])))
    return sorted(out, key=lambda o: -int(o.mask.sum()))
