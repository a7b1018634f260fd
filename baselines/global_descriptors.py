"""Whole-image descriptors for image retrieval, and the project's image encoder as a dense backbone.

Three descriptors, each an L2-normalised float32 vector compared by cosine:

- ``encoder-grid``: the conv stack of the project's image encoder (:mod:`openreloc_bench.vision.offline`,
  trained on object crops of generated training-seed scenes) run over the whole image, its feature
  map mean-pooled over a ``grid x grid`` layout, each cell L2-normalised (a spatial pyramid's finest level).
- ``encoder-vlad``: the same dense features aggregated by a per-scene VLAD (NetVLAD's pooling with
  k-means centres in place of learned ones).
- ``sift-vlad``: a per-scene VLAD over RootSIFT (DenseVLAD's recipe on detected keypoints), as
  ``sift-pnp`` retrieves.

The encoder's conv layers are fully convolutional, so an image of any size gives a feature map at
1/16 of its resolution; :func:`encoder_backbone` hands them to other methods (``posenet``).
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any

import cv2
import numpy as np
import torch
from threadpoolctl import ThreadpoolController
from torch import nn
from torch.nn import functional as F

from baselines.frame_retrieval import Vlad, VladConfig
from openreloc_bench import config as cfglib
from openreloc_bench.vision.base import l2_normalize
from openreloc_bench.vision.learned_segment import torch_threads
from openreloc_bench.vision.local_features import SiftConfig, extract_sift, root_sift
from openreloc_bench.vision.offline import WEIGHTS_DIR, OfflineEncoder, load_tower, uint8_batch_to_tensor

DESCRIPTORS = ("encoder-grid", "encoder-vlad", "sift-vlad")


@lru_cache(maxsize=1)
def _blas() -> ThreadpoolController:
    return ThreadpoolController()


@contextmanager
def single_threaded() -> Iterator[None]:
    """Torch and BLAS on one thread, for one query's small forward pass and products: more threads
    only add synchronisation, and OpenBLAS's idle workers busy-wait and take the cores from torch."""
    with torch_threads(1), _blas().limit(limits=1, user_api="blas"):
        yield


def encoder_backbone() -> nn.Sequential:
    """A fresh copy of the committed image encoder's conv stack (trainable, in train mode)."""
    tower, _, _ = load_tower(WEIGHTS_DIR)
    return tower.features.train()


def encoder_fingerprint() -> str:
    """sha256 prefix of the committed encoder weights (a map records the weights it was built with)."""
    return OfflineEncoder.weights_fingerprint()


def resize_width(rgb: np.ndarray, width: int) -> np.ndarray:
    """``rgb`` resized to ``width`` pixels wide, aspect kept (area interpolation)."""
    h, w = rgb.shape[:2]
    return cv2.resize(rgb, (width, max(1, round(h * width / w))), interpolation=cv2.INTER_AREA)


@dataclass
class GlobalDescriptorConfig:
    """Which whole-image descriptor and its settings."""

    kind: str = "encoder-vlad"
    """``encoder-grid``, ``encoder-vlad`` or ``sift-vlad`` (see the module doc)."""
    image_width: int = 160
    """Images are resized to this width (aspect kept) before the encoder or SIFT."""
    grid: int = 2
    """``encoder-grid``: the feature map is pooled over grid x grid cells."""
    vlad: VladConfig = field(default_factory=lambda: VladConfig(clusters=64))
    """``*-vlad``: the per-scene vocabulary (dimension = clusters x 256 for the encoder, x 128 for SIFT)."""
    sift: SiftConfig = field(default_factory=lambda: SiftConfig(max_keypoints=1000))
    """``sift-vlad``: the detector."""

    def __post_init__(self) -> None:
        if self.kind not in DESCRIPTORS:
            raise ValueError(f"'kind' must be one of {', '.join(DESCRIPTORS)}, got {self.kind!r}")
        cfglib.check_ranges(self, at_least_one=("image_width", "grid"))


def grid_pool(fmap: torch.Tensor, grid: int) -> np.ndarray:
    """A (C, h, w) feature map mean-pooled over grid x grid cells, each cell L2-normalised, then the
    whole: a unit (C x grid^2,) float32 vector."""
    cells = F.adaptive_avg_pool2d(fmap[None], grid)[0].flatten(1).T.numpy()
    return l2_normalize(l2_normalize(cells).ravel()[None])[0].astype(np.float32)


class GlobalDescriptor:
    """Describes whole images; for the VLAD kinds, ``fit`` first learns the per-scene vocabulary."""

    def __init__(self, cfg: GlobalDescriptorConfig, vlad: Vlad | None = None):
        self.cfg = cfg
        self.vlad = vlad
        self._net = load_tower(WEIGHTS_DIR)[0].features.eval() if cfg.kind.startswith("encoder") else None

    @property
    def needs_fit(self) -> bool:
        return self.cfg.kind.endswith("vlad")

    def dense(self, rgb: np.ndarray) -> torch.Tensor:
        """(256, h/16, w/16) encoder feature map of one image at ``image_width``."""
        if self._net is None:
            raise RuntimeError(f"'{self.cfg.kind}' has no dense encoder features")
        with torch.no_grad():
            return self._net(uint8_batch_to_tensor(resize_width(rgb, self.cfg.image_width)[None]))[0]

    def local(self, rgb: np.ndarray) -> np.ndarray:
        """(n, D) float32 local descriptors of one image: dense encoder features or RootSIFT."""
        if self._net is None:
            return root_sift(extract_sift(resize_width(rgb, self.cfg.image_width), self.cfg.sift).descriptors)
        return self.dense(rgb).flatten(1).T.contiguous().numpy()

    def fit(self, locals_: list[np.ndarray]) -> None:
        """Learn the VLAD centres from the :meth:`local` descriptors of the mapping frames."""
        self.vlad = Vlad.fit(np.concatenate(locals_), self.cfg.vlad)

    def aggregate(self, local: np.ndarray) -> np.ndarray:
        """The VLAD of one image's :meth:`local` descriptors."""
        if self.vlad is None:
            raise RuntimeError("fit() must run before a VLAD descriptor is computed")
        return self.vlad.describe(local)

    def describe(self, rgb: np.ndarray) -> np.ndarray:
        """Unit-norm float32 descriptor of one image."""
        return self.aggregate(self.local(rgb)) if self.needs_fit else grid_pool(self.dense(rgb), self.cfg.grid)

    def to_arrays(self) -> dict[str, Any]:
        return self.vlad.to_arrays() if self.vlad is not None else {}
