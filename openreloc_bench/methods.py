"""The method contract shared by OpenReLoc, the baselines and third-party plugins, plus the registry.

Callers ask a method through :func:`localize_safely`, which sorts its answer into a pose or a failure.

A method is a class satisfying :class:`Relocalizer`, found by name: this project's in
:data:`BUILTIN_METHODS`, an outside package's through the entry-point group ``openreloc_bench.methods``
(declared in its ``pyproject.toml``, so it adds a method without touching this repository), and methods
defined in plugins, scripts and tests through :func:`register`.
"""

from __future__ import annotations

import inspect
import logging
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, is_dataclass
from functools import cache
from importlib.metadata import EntryPoint, entry_points
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

import numpy as np

from openreloc_bench import config as cfglib
from openreloc_bench import geometry
from openreloc_bench.data.types import Frame, SceneSequence
from openreloc_bench.errors import ConfigError, raised_at
from openreloc_bench.tracks import MASK_FREE, ORACLE_MASK, PREDICTED, RecordedTrack, Track

ENTRY_POINT_GROUP = "openreloc_bench.methods"
log = logging.getLogger(__name__)


@dataclass
class QueryFrame:
    """What a method's ``localize`` receives of a query: never its ground-truth pose, nor its depth."""

    name: str
    """``<split>/<frame id>``."""
    color: np.ndarray
    """RGB uint8 (H, W, 3)."""
    K: np.ndarray
    """3x3 intrinsics."""
    instance: np.ndarray | None = None
    """Instance ids (oracle-mask track only: a perfect detector); None in the predicted track."""
    track: RecordedTrack | None = None
    """The track the query was made for (:meth:`from_frame`), which a method reads rather than guess it
    from ``instance``. A query made without one (by hand: plugins, tests) is taken for the oracle-mask
    track when it carries instances, else for the predicted track, when it is made (never None after)."""

    def __post_init__(self) -> None:
        if self.track is None:
            self.track = ORACLE_MASK if self.instance is not None else PREDICTED

    @classmethod
    def from_frame(cls, frame: Frame, track: RecordedTrack) -> QueryFrame:
        """What a method sees of a dataset frame on ``track``: the image and intrinsics, the dataset's
        instance masks on the oracle-mask track only, and the track."""
        return cls(frame.name, frame.color, frame.K, frame.instance if track == ORACLE_MASK else None, track)


@dataclass
class PoseEstimate:
    """A method's answer for one query."""

    T_wc: np.ndarray
    """4x4 camera-to-world pose, OpenCV axes."""
    diagnostics: dict[str, Any] = field(default_factory=dict)
    """Free-form, JSON-serialisable: matches, timings, explanation..."""
    confidence: float = float("nan")
    """How sure the method is of this pose (higher is surer, on the method's own scale, e.g. inliers),
    NaN when it does not say; the harness records it with the query's error."""


DRAWN_POINTS = "drawn_points"
"""Diagnostics key (top level, or in a dict one level down) of the query keypoints a method matched:
``[[x, y, 1 if the pose kept it else 0], ...]`` (:func:`drawn_points`), which ``localize --draw`` draws."""


def drawn_points(xy: np.ndarray, inlier: np.ndarray) -> list[list[float]]:
    """Matched query keypoints ``xy`` (N, 2) and whether the pose kept each, as :data:`DRAWN_POINTS`
    holds them (to 0.1 px: the diagnostics stay small)."""
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    return [[round(x, 1), round(y, 1), int(k)] for (x, y), k in zip(xy.tolist(), np.asarray(inlier, bool).tolist())]


@dataclass
class Failure:
    """An explicit failure with a reason; the harness counts it like ``None`` (infinite error)."""

    reason: str
    diagnostics: dict[str, Any] = field(default_factory=dict)


@runtime_checkable
class Relocalizer(Protocol):
    """The contract every method satisfies. Everything needed at query time lives in ``map_dir``.

    The constructor receives the method's settings as keyword arguments (``eval --method-config``,
    ``map --set``; none for the defaults). Optional: ``config``, a dataclass of those settings (recorded
    with every result, printed by ``openreloc-bench config``); ``uses_masks = False``, declaring that the
    method reads no instance masks (it is then given none, and its results are recorded as
    ``mask-free``, standing for both tracks); ``map_config()`` (see :func:`map_config`); ``reference``,
    the paper and code the method follows (the boards cite it); ``map_points(map_dir)``, what a map of the
    method holds in 3D (:class:`MapPoints`, drawn by ``openreloc-bench view``; no ``load_map`` needed).
    """

    name: str

    def build_map(self, mapping: SceneSequence, map_dir: Path) -> None: ...

    def load_map(self, map_dir: Path) -> None: ...

    def localize(self, query: QueryFrame) -> PoseEstimate | Failure | None: ...


@dataclass
class MapPoints:
    """What a map holds in 3D, for drawing: its points, each in a group (a landmark, an object, the
    mapping frame it was seen from), and the cameras it keeps."""

    points: np.ndarray
    """(N, 3) world points."""
    group: np.ndarray
    """(N,) int: the group of each point; points of a group share a colour and a hover text."""
    labels: dict[int, str]
    """Hover text of each group."""
    K: np.ndarray
    """3x3 intrinsics of the map's camera."""
    size: tuple[int, int]
    """(width, height) of the map's images."""
    cameras: np.ndarray = field(default_factory=lambda: np.zeros((0, 4, 4)))
    """(F, 4, 4) T_wc of the frames the map keeps (keyframes, reference frames)."""
    camera_labels: tuple[str, ...] = ()
    """Hover text of each camera (none: the cameras' legend name and index)."""
    muted: frozenset[int] = frozenset()
    """Groups drawn grey, apart (e.g. landmarks a filter set aside)."""
    names: tuple[str, str, str] = ("points", "set aside", "cameras")
    """Legend names of the points, the muted points and the cameras."""
    summary: str = ""
    """One line on the map's content, e.g. "40 landmarks (31 valid), 12 reference frames"."""


@dataclass
class Answer:
    """A method's answer to one query as :func:`localize_safely` sorts it out: a pose, or none and why."""

    name: str
    """The query's name."""
    T_wc: np.ndarray | None
    """The estimated camera-to-world pose (a finite rigid 4x4 transform), or None."""
    seconds: float
    """Time of the method's own call."""
    reason: str = ""
    """Why there is no pose ("" when there is one)."""
    diagnostics: dict[str, Any] = field(default_factory=dict)
    """The method's diagnostics of its pose or failure (none when it raised or answered something else)."""
    confidence: float = float("nan")
    """The method's confidence in the pose (NaN when none, or when it is not a real number)."""


def localize_safely(method: Relocalizer, query: QueryFrame) -> Answer:
    """Ask ``method`` about ``query``, timing only its own call. Never raises: an exception or a
    ``sys.exit``, no answer, a :class:`Failure`, another return type and a pose that is not a finite
    rigid 4x4 transform are each a failure with its reason, so that a bug in a method fails one query,
    never a run or an episode."""
    t0 = time.perf_counter()
    try:
        res = method.localize(query)
    except Exception as e:  # noqa: BLE001 -- a method bug fails this query
        seconds = time.perf_counter() - t0
        log.debug("query %s raised", query.name, exc_info=True)
        return Answer(query.name, None, seconds, f"raised {type(e).__name__}: {e}"[:300])
    except SystemExit as e:  # sys.exit in a method would end the run as if it had finished
        return Answer(query.name, None, time.perf_counter() - t0, f"called sys.exit({e.code})"[:300])
    seconds = time.perf_counter() - t0
    if res is None:
        return Answer(query.name, None, seconds, "no estimate")
    if isinstance(res, Failure):
        return Answer(query.name, None, seconds, res.reason or "failure", res.diagnostics)
    if not isinstance(res, PoseEstimate):
        return Answer(query.name, None, seconds, f"invalid return type {type(res).__name__}")
    try:
        T = np.asarray(res.T_wc, dtype=np.float64)
    except (TypeError, ValueError):  # not numbers at all
        T = None
    if T is None or T.shape != (4, 4) or not geometry.is_rigid(T):
        return Answer(query.name, None, seconds, "invalid pose (not a finite rigid 4x4 transform)", res.diagnostics)
    return Answer(query.name, T, seconds, "", res.diagnostics, _real(res.confidence))


def _real(value: Any) -> float:
    """``value`` as a float, NaN when it is not a real number (a method's confidence is never an error)."""
    try:
        return float(value)
    except (TypeError, ValueError):
        return float("nan")


BUILTIN_METHODS = {
    "openreloc": "openreloc_bench.openreloc.method:OpenReLoc",
    "openreloc-paper": "openreloc_bench.openreloc.paper:OpenReLocPaper",
    "openreloc-oracle-association": "openreloc_bench.openreloc.method:OpenReLocOracleAssociation",
    "goreloc": "baselines.goreloc.method:GOReloc",
    "sift-pnp": "baselines.sift_pnp:SiftPnP",
    "orb-reloc": "baselines.orb_reloc:OrbReloc",
    "retrieval": "baselines.image_retrieval:ImageRetrieval",
    "posenet": "baselines.posenet:PoseNet",
    "nearest-frame": "baselines.nearest_frame:NearestFrame",
}
"""This project's methods, name -> ``module:Class``, each imported when first used (hloc's plugins by
name: the core names the methods without importing them). A new baseline is its module, its test and a
line here (and one in ``leaderboard/plan.yaml`` to put it on the boards); no reinstall."""

_REGISTRY: dict[str, Callable[..., Relocalizer]] = {}


@cache
def _named_methods() -> dict[str, EntryPoint]:
    """The built-in methods, then the installed packages' entry points, by name (read once per process).
    An entry point cannot take a built-in's name: one naming the built-in's own class (an install of this
    project from when its methods were entry points) is dropped silently, any other with a one-line warning,
    so that no result of another method is filed under a built-in's name."""
    found = {name: EntryPoint(name, value, ENTRY_POINT_GROUP) for name, value in BUILTIN_METHODS.items()}
    for ep in entry_points(group=ENTRY_POINT_GROUP):
        if ep.name not in BUILTIN_METHODS:
            found[ep.name] = ep
        elif ep.value != BUILTIN_METHODS[ep.name]:
            log.warning(
                "entry point %s = %s ignored: '%s' is the built-in method %s; declare yours under another name",
                ep.name,
                ep.value,
                ep.name,
                BUILTIN_METHODS[ep.name],
            )
    return found


def register(name: str, factory: Callable[..., Relocalizer]) -> None:
    """Register a method factory under ``name`` (in-process; packages should use entry points). A name a
    built-in method or an installed package's entry point holds is refused: its results would be filed
    under the other method's name."""
    taken = _named_methods().get(name)
    if taken is not None:
        raise ConfigError(f"method name '{name}' is taken by {taken.value}: register yours under another name")
    _REGISTRY[name] = factory


def registered() -> dict[str, Callable[..., Relocalizer]]:
    """The in-process registrations (:func:`register`) by name: a copy."""
    return dict(_REGISTRY)


def available_methods() -> dict[str, Callable[..., Relocalizer]]:
    """All method factories by name: the built-ins, the entry points, then in-process registrations."""
    return {**{name: _lazy(ep) for name, ep in _named_methods().items()}, **_REGISTRY}


def _lazy(ep: EntryPoint) -> Callable[..., Relocalizer]:
    def factory(**kwargs: Any) -> Relocalizer:
        return ep.load()(**kwargs)

    factory.__doc__ = f"{'built-in' if ep.name in BUILTIN_METHODS else 'entry point'} {ep.value}"
    return factory


def method_reference(name: str) -> str:
    """The paper and code the registered method ``name`` follows (its class's ``reference``; "" when it
    gives none, or for a name no method is registered under)."""
    return str(getattr(_method_class(name), "reference", ""))


def _method_class(name: str) -> Any:
    """What ``name`` is registered as (in-process first, as :func:`available_methods`); None if nothing."""
    if name in _REGISTRY:
        return _REGISTRY[name]
    ep = _named_methods().get(name)
    return None if ep is None else ep.load()


def uses_masks(name: str) -> bool:
    """Whether the registered method ``name`` reads instance masks: its class's ``uses_masks``
    (True when it does not say, or for a name no method is registered under). The harness builds the
    maps of methods that do not from no masks, and they serve both tracks."""
    return bool(getattr(_method_class(name), "uses_masks", True))


def recorded_track(method: Relocalizer, track: Track) -> RecordedTrack:
    """The track ``method``'s maps and results belong to when run on ``track``: ``MASK_FREE`` for a method
    that declares it reads no masks (``uses_masks = False``; it is then given none), else ``track``."""
    return track if getattr(method, "uses_masks", True) else MASK_FREE


def create_method(name: str, **config: Any) -> Relocalizer:
    """Instantiate a registered method; unknown names raise a ConfigError listing the known ones. A
    method from outside this project (:func:`foreign_source`) has its settings checked against its
    dataclass ``config`` (keys and types, as this project's methods check theirs), and a constructor that
    raises is a ConfigError naming the plugin's file and line."""
    methods = available_methods()
    if name not in methods:
        known = ", ".join(sorted(methods)) or "none"
        raise ConfigError(f"unknown method '{name}' (registered: {known})")
    factory = methods[name]
    try:
        method = factory(**config)
    except ConfigError:
        raise
    except Exception as e:  # noqa: BLE001 -- a plugin's bug, told in one line
        if config:  # a typo in a setting is the likelier cause: say which
            _check_settings(name, _default_instance(factory), config)
        raise ConfigError(
            f"method '{name}': its constructor raised at {raised_at(e, foreign_source(factory))}"
        ) from None
    missing = [a for a in RELOCALIZER_ATTRIBUTES if not hasattr(method, a)]
    if missing:
        raise ConfigError(
            f"method '{name}': its {type(method).__name__} has no {', '.join(repr(a) for a in missing)}; a method "
            f"needs {', '.join(RELOCALIZER_ATTRIBUTES)} (see openreloc_bench.methods.Relocalizer)"
        )
    if foreign_source(type(method)) is not None:
        _check_settings(name, method, config)
    return method


def _default_instance(factory: Callable[..., Relocalizer]) -> Relocalizer | None:
    """``factory()`` with its default settings, None where that raises too."""
    try:
        return factory()
    except Exception:  # noqa: BLE001 -- only its config is read
        return None


def _check_settings(name: str, method: Any, settings: dict[str, Any]) -> None:
    """ConfigError for a setting that ``method``'s dataclass ``config`` does not have or types otherwise
    (nothing to check without one)."""
    cfg = getattr(method, "config", None)
    if settings and is_dataclass(cfg) and not isinstance(cfg, type):
        cfglib.from_dict(type(cfg), settings, name)


PROJECT_PACKAGES = ("openreloc_bench", "baselines")
"""The packages whose methods are this project's own code (versioned by its git commit)."""


def foreign_source(obj: Any) -> Path | None:
    """The file defining ``obj`` (a method class or factory) when it is not this project's own code: a
    ``--plugin`` file or another package's module; None for this project's, or without a file."""
    try:
        source = Path(inspect.getfile(obj)).resolve()
    except (TypeError, OSError):  # built in a notebook or by exec
        return None
    root = Path(__file__).resolve().parents[1]
    if not source.is_file() or any(source.is_relative_to(root / p) for p in PROJECT_PACKAGES):
        return None
    return source


RELOCALIZER_ATTRIBUTES = ("name", "build_map", "load_map", "localize")
"""What every method has (:class:`Relocalizer`): checked when it is created, so a plugin missing one is
a one-line error rather than a traceback deep in a run."""


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
