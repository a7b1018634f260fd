"""The three small interfaces OpenReLoc needs from vision and language models, and their registries.

- :class:`ImageTextEncoder`: crops and texts into one L2-normalised embedding space (CLIP's role).
- :class:`Describer`: a short text description of one object in a query image (the paper's LLM).
- :class:`Segmenter`: object masks in a query image (oracle, simulated-noisy or predicted).

Backends register under a name (``@register_encoder("clip")``) and are built from config with
:func:`create_encoder` / :func:`create_describer` / :func:`create_segmenter`.
"""

from __future__ import annotations

import abc
import importlib
import inspect
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from openreloc_bench.errors import ConfigError


class ImageTextEncoder(abc.ABC):
    """Maps RGB crops and texts into one space; outputs are float32, L2-normalised, row per input."""

    name: str = "encoder"
    dim: int

    @abc.abstractmethod
    def encode_images(self, crops: Sequence[np.ndarray]) -> np.ndarray:
        """RGB uint8 crops of any size -> (N, dim) float32, unit norm. Deterministic on CPU."""

    @abc.abstractmethod
    def encode_texts(self, texts: Sequence[str]) -> np.ndarray:
        """Texts -> (N, dim) float32, unit norm."""

    def config(self) -> dict[str, Any]:
        """What is needed to rebuild this encoder (recorded in maps and results)."""
        return {"name": self.name}

    @classmethod
    def weights_fingerprint(cls, **options: Any) -> str:
        """Identifies the weights the encoder with these constructor options would load, without loading
        them. Maps record it, so a map is never queried (or reused from a cache) with other weights."""
        return ""


@dataclass
class ObjectMask:
    """One object proposal in an image."""

    mask: np.ndarray
    """bool (H, W)."""
    box: np.ndarray
    """[x0, y0, x1, y1] in pixels, inclusive-exclusive (x1 = last column + 1)."""
    instance_id: int | None = None
    """Dataset instance id when it comes from ground truth (for diagnostics only)."""
    score: float = 1.0


class Segmenter(abc.ABC):
    """Finds objects in a query image."""

    name: str = "segmenter"

    @abc.abstractmethod
    def segment(self, rgb: np.ndarray, instance: np.ndarray | None = None) -> list[ObjectMask]:
        """RGB uint8 (H, W, 3) (+ dataset instance ids for the oracle tracks) -> object masks."""

    def segment_with_boundaries(
        self, rgb: np.ndarray, instance: np.ndarray | None = None
    ) -> tuple[list[ObjectMask], np.ndarray]:
        """The masks and a (H, W) float32 boundary strength in [0, 1] (mapping projects it onto the scene
        cloud to judge where one 3D instance ends). Default: 1 on the masks' own borders, else 0;
        segmenters that predict boundaries return their probabilities."""
        masks = self.segment(rgb, instance)
        return masks, mask_borders(masks, rgb.shape[:2])


def label_image(masks: Sequence[ObjectMask], shape: tuple[int, int]) -> np.ndarray:
    """(H, W) int32: mask k (from 1) where it lies, 0 in no mask; where masks overlap the first wins."""
    labels = np.zeros(shape, np.int32)
    for k, m in enumerate(masks, start=1):
        labels[m.mask & (labels == 0)] = k
    return labels


def mask_borders(masks: Sequence[ObjectMask], shape: tuple[int, int]) -> np.ndarray:
    """(H, W) float32: 1 where a pixel and its right or lower neighbour lie in different masks (or one in
    none), on both sides of the border; else 0."""
    labels = label_image(masks, shape)
    edge = np.zeros(shape, bool)
    for axis in (0, 1):
        diff = np.diff(labels, axis=axis) != 0
        lo = [slice(None)] * 2
        hi = [slice(None)] * 2
        lo[axis], hi[axis] = slice(None, -1), slice(1, None)
        edge[tuple(lo)] |= diff
        edge[tuple(hi)] |= diff
    return edge.astype(np.float32)


class Describer(abc.ABC):
    """Describes one object of an image in a short phrase, using the crop and its context."""

    name: str = "describer"

    @abc.abstractmethod
    def describe(self, rgb: np.ndarray, mask: np.ndarray) -> str:
        """RGB uint8 (H, W, 3) and a bool mask of one object -> e.g. 'a red armchair'."""

    def describe_many(self, rgb: np.ndarray, masks: list[np.ndarray]) -> list[str]:
        """One phrase per mask of the same image; backends override it to batch their model calls."""
        return [self.describe(rgb, m) for m in masks]

    def prepare(self) -> None:  # noqa: B027 -- an optional hook, not abstract
        """Compute what every query needs (vocabulary embeddings...) now, when a map loads, so that the
        first queries do not pay for it in their latency. Default: nothing to prepare."""


_ENCODERS: dict[str, Callable[..., ImageTextEncoder]] = {}
_DESCRIBERS: dict[str, Callable[..., Describer]] = {}
_SEGMENTERS: dict[str, Callable[..., Segmenter]] = {}


def _registrar(table: dict[str, Callable[..., Any]]) -> Callable[[str], Callable[[Any], Any]]:
    def register(name: str) -> Callable[[Any], Any]:
        def deco(factory: Any) -> Any:
            table[name] = factory
            return factory

        return deco

    return register


register_encoder = _registrar(_ENCODERS)
register_describer = _registrar(_DESCRIBERS)
register_segmenter = _registrar(_SEGMENTERS)


_TABLES = {"encoder": _ENCODERS, "describer": _DESCRIBERS, "segmenter": _SEGMENTERS}
BACKEND_MODULES = ("clip", "describe", "learned_segment", "offline", "segment")
"""The modules under ``openreloc_bench.vision`` whose import registers the built-in backends."""


def _load_backends() -> None:
    """Import the built-in backends by module name (hloc's plugins-by-name): the registry does not import
    its own package, whose ``__init__`` imports this module."""
    for name in BACKEND_MODULES:
        importlib.import_module(f"{__package__}.{name}")


def check_backend(kind: str, name: str, options: dict[str, Any], partial: bool = False) -> Callable[..., Any]:
    """The factory of the ``kind`` backend ``name`` (encoder, describer or segmenter), once its options
    are known to fit it (``partial``: the caller adds others, such as a describer's encoder): ConfigError
    otherwise. Configs call it when they are made, so that a mistyped name fails at once, not after a
    map's worth of work."""
    _load_backends()

    table = _TABLES[kind]
    if name not in table:
        raise ConfigError(f"unknown {kind} '{name}' (available: {', '.join(sorted(table)) or 'none'})")
    factory = table[name]
    try:  # options come from the user's config (``encoder_options`` ...): a wrong name is theirs to fix
        signature = inspect.signature(factory)
        signature.bind_partial(**options) if partial else signature.bind(**options)
    except TypeError as e:
        raise ConfigError(f"{kind} '{name}': {e}") from None
    return factory


def _create(kind: str, name: str, kwargs: dict[str, Any]) -> Any:
    return check_backend(kind, name, kwargs)(**kwargs)


def create_encoder(name: str, **kwargs: Any) -> ImageTextEncoder:
    return _create("encoder", name, kwargs)


def encoder_fingerprint(name: str, options: dict[str, Any]) -> str:
    """The registered encoder's ``weights_fingerprint`` for these options ("" when it defines none)."""
    return _fingerprint(_ENCODERS, name, options)


def segmenter_fingerprint(name: str, options: dict[str, Any]) -> str:
    """The registered segmenter's ``weights_fingerprint`` for these options ("" when it defines none):
    maps built from a segmenter's masks record it, so retrained weights rebuild cached maps."""
    return _fingerprint(_SEGMENTERS, name, options)


def _fingerprint(table: dict[str, Callable[..., Any]], name: str, options: dict[str, Any]) -> str:
    _load_backends()

    fingerprint = getattr(table.get(name), "weights_fingerprint", None)
    return fingerprint(**options) if callable(fingerprint) else ""


def create_describer(name: str, **kwargs: Any) -> Describer:
    return _create("describer", name, kwargs)


def create_segmenter(name: str, **kwargs: Any) -> Segmenter:
    return _create("segmenter", name, kwargs)


def l2_normalize(x: np.ndarray, eps: float = 1e-12) -> np.ndarray:
    x = np.asarray(x, dtype=np.float32)
    return x / np.maximum(np.linalg.norm(x, axis=-1, keepdims=True), eps)


class TextCache(ImageTextEncoder):
    """An encoder whose text embeddings are memoised per string (images pass through): the offline
    describer encodes the same colour/material/noun phrases for every query object."""

    def __init__(self, encoder: ImageTextEncoder, max_entries: int = 100_000):
        self.inner, self.max_entries = encoder, max_entries
        self.name, self.dim = encoder.name, encoder.dim
        self._cache: dict[str, np.ndarray] = {}

    def encode_images(self, crops: Any) -> np.ndarray:
        return self.inner.encode_images(crops)

    def encode_texts(self, texts: Any) -> np.ndarray:
        texts = list(texts)
        missing = list(dict.fromkeys(t for t in texts if t not in self._cache))
        if missing:
            if len(self._cache) + len(missing) > self.max_entries:
                self._cache.clear()
            self._cache.update(zip(missing, self.inner.encode_texts(missing)))
        if not texts:
            return np.zeros((0, self.dim), np.float32)
        return np.stack([self._cache[t] for t in texts]).astype(np.float32)

    def config(self) -> dict[str, Any]:
        return self.inner.config()
