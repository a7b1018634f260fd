"""The method contract shared by OpenReLoc, the baselines and third-party plugins, plus the registry.

A method is a class satisfying :class:`Relocalizer`. It is found by name through the entry-point
group ``openreloc_bench.methods`` (declared in a package's ``pyproject.toml``), so an outside package
adds a method without touching this repository; :func:`register` exists for methods defined in
scripts and tests.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass, field, is_dataclass
from importlib.metadata import entry_points
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

import cv2
import numpy as np

from openreloc_bench import config
from openreloc_bench.bars import tqdm
from openreloc_bench.data import mapfile
from openreloc_bench.data.types import SceneSequence
from openreloc_bench.errors import ConfigError, DataError

ENTRY_POINT_GROUP = "openreloc_bench.methods"
TRACKS = ("oracle-mask", "predicted")
"""Oracle-mask: queries and mapping frames carry the dataset's instance masks (a perfect detector).
Predicted: neither does; a method segments for itself."""


@dataclass
class QueryFrame:
    """What a method sees of a query: never its ground-truth pose."""

    name: str
    """``<split>/<frame id>``."""
    color: np.ndarray
    """RGB uint8 (H, W, 3)."""
    K: np.ndarray
    """3x3 intrinsics."""
    instance: np.ndarray | None = None
    """Instance ids (oracle-mask track only: a perfect detector); None in the predicted track."""

    @property
    def track(self) -> str:
        return "oracle-mask" if self.instance is not None else "predicted"


@dataclass
class PoseEstimate:
    """A method's answer for one query."""

    T_wc: np.ndarray
    """4x4 camera-to-world pose, OpenCV axes."""
    diagnostics: dict[str, Any] = field(default_factory=dict)
    """Free-form, JSON-serialisable: matches, timings, explanation..."""


@dataclass
class Failure:
    """An explicit failure with a reason; the harness counts it like ``None`` (infinite error)."""

    reason: str
    diagnostics: dict[str, Any] = field(default_factory=dict)


@runtime_checkable
class Relocalizer(Protocol):
    """The contract every method satisfies. Everything needed at query time lives in ``map_dir``."""

    name: str

    def build_map(self, mapping: SceneSequence, map_dir: Path) -> None: ...

    def load_map(self, map_dir: Path) -> None: ...

    def localize(self, query: QueryFrame) -> PoseEstimate | Failure | None: ...


_REGISTRY: dict[str, Callable[..., Relocalizer]] = {}


def register(name: str, factory: Callable[..., Relocalizer]) -> None:
    """Register a method factory under ``name`` (in-process; packages should use entry points)."""
    _REGISTRY[name] = factory


def available_methods() -> dict[str, Callable[..., Relocalizer]]:
    """All method factories by name: entry points first, then in-process registrations."""
    found: dict[str, Callable[..., Relocalizer]] = {}
    for ep in entry_points(group=ENTRY_POINT_GROUP):
        found[ep.name] = _lazy(ep)
    found.update(_REGISTRY)
    return found


def _lazy(ep: Any) -> Callable[..., Relocalizer]:
    def factory(**kwargs: Any) -> Relocalizer:
        return ep.load()(**kwargs)

    factory.__doc__ = f"entry point {ep.value}"
    return factory


def create_method(name: str, **config: Any) -> Relocalizer:
    """Instantiate a registered method; unknown names raise a ConfigError listing the known ones."""
    methods = available_methods()
    if name not in methods:
        known = ", ".join(sorted(methods)) or "none"
        raise ConfigError(f"unknown method '{name}' (registered: {known})")
    return methods[name](**config)


def method_config(method: Relocalizer) -> dict[str, Any]:
    """The method's full config as plain data (recorded with every result for reproducibility)."""
    cfg = getattr(method, "config", None)
    return {"name": method.name, "config": asdict(cfg) if is_dataclass(cfg) else {}}


def map_config(method: Relocalizer) -> dict[str, Any]:
    """The part of the config that determines the map, from the method's optional ``map_config()``
    (default: the full config). The harness caches maps by its hash, so runs that differ only in
    query-time settings (ablations of the query stages, refinement, verification) share one map."""
    own = getattr(method, "map_config", None)
    return {"name": method.name, "config": own()} if callable(own) else method_config(method)


# --------------------------------------------------------------------------------------------
# nearest-frame: the simplest honest method (image retrieval over the mapping frames)
# --------------------------------------------------------------------------------------------


@dataclass
class NearestFrameConfig:
    """Config of :class:`NearestFrame`."""

    thumb_size: int = 32
    """Side of the square grey thumbnail each mapping frame is reduced to (pixels, 4-256)."""

    def __post_init__(self) -> None:
        if not 4 <= self.thumb_size <= 256:
            raise ValueError(f"'thumb_size' must be in [4, 256], got {self.thumb_size}")


class NearestFrame:
    """Returns the pose of the mapping frame whose thumbnail is closest to the query's.

    A floor for every leaderboard: what pure global-image retrieval without geometry achieves.
    The thumbnail is zero-mean, unit-norm grey so global brightness changes cost little.
    """

    name = "nearest-frame"
    map_format = ("nearest-frame-map", 1)

    def __init__(self, **overrides: Any):
        self.config = config.from_dict(NearestFrameConfig, overrides, "nearest-frame")
        self._thumbs: np.ndarray | None = None
        self._poses: np.ndarray | None = None

    def _thumb(self, rgb: np.ndarray) -> np.ndarray:
        s = self.config.thumb_size
        grey = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)
        t = cv2.resize(grey, (s, s), interpolation=cv2.INTER_AREA).astype(np.float32).ravel()
        t -= t.mean()
        return t / max(float(np.linalg.norm(t)), 1e-6)

    def build_map(self, mapping: SceneSequence, map_dir: Path) -> None:
        thumbs = np.stack([self._thumb(f.color) for f in tqdm(mapping, desc="nearest-frame map", leave=False)])
        arrays = {"thumbs": thumbs.astype(np.float16), "poses": mapping.poses}
        payload = {"thumbs.npz": mapfile.npz_bytes(arrays), "config.json": mapfile.json_bytes(asdict(self.config))}
        mapfile.write_file_set(map_dir, *self.map_format, payload)

    def load_map(self, map_dir: Path) -> None:
        path = Path(map_dir) / "thumbs.npz"
        blobs = mapfile.read_file_set(map_dir, *self.map_format, {"thumbs.npz", "config.json"})
        built = mapfile.load_json(blobs["config.json"], Path(map_dir) / "config.json")
        if built != asdict(self.config):
            raise DataError(
                Path(map_dir) / "config.json", f"map built with {built}, this method has {asdict(self.config)}"
            )
        a = mapfile.load_npz(blobs["thumbs.npz"], path)
        thumbs, poses = a.get("thumbs"), a.get("poses")
        s = self.config.thumb_size
        if thumbs is None or poses is None or thumbs.shape[1:] != (s * s,) or poses.shape != (len(thumbs), 4, 4):
            raise DataError(path, "malformed map arrays (expected thumbs (N, thumb_size^2) and poses (N, 4, 4))")
        self._thumbs, self._poses = thumbs.astype(np.float32), poses

    def localize(self, query: QueryFrame) -> PoseEstimate | Failure:
        if self._thumbs is None or self._poses is None:
            raise RuntimeError("load_map() must be called before localize()")
        scores = self._thumbs @ self._thumb(query.color)
        best = int(np.argmax(scores))
        return PoseEstimate(self._poses[best].copy(), {"mapping_index": best, "score": float(scores[best])})
