"""Scene and suite specifications: what to generate, validated strictly before anything is written.

A suite YAML lists scenes; each scene is a :class:`SceneSpec` (name, kind, seed, size parameters).
Everything the generator does is a deterministic function of the spec, so :func:`spec_hash` identifies a
scene's content (it is recorded in ``scene.json``).

Seeds come in three disjoint ranges, so that no benchmark scene is ever trained on or used to choose a
model: benchmark suites use seeds below :data:`TRAINING_SEED_MIN`; seeds from it up to
:data:`VALIDATION_SEED_MIN` are reserved for the scenes that train models (the encoder, the segmenter and
the merger, each on its own part of the range); seeds
from :data:`VALIDATION_SEED_MIN` on belong to validation suites (``purpose: validation``), on which
models and recipes are selected.
"""

from __future__ import annotations

import hashlib
import json
import math
import re
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Literal

from generators.sensor import SensorSpec
from openreloc_bench import __version__, config
from openreloc_bench.data.splits import LIGHT, QUERY_SPLIT_TABLE, split_names
from openreloc_bench.errors import ConfigError

GENERATOR_VERSION = f"{__version__}+gen5"
"""Recorded in scene.json and part of :func:`spec_hash`; bump the suffix whenever output for the same spec
changes, so cached maps and results of scenes from an older generator are not reused.
gen2: rooms stay connected (pendant lights and one-cell gaps no longer cut corridors) and queries are
drawn only from the walkable region the mapping sequence covers.
gen3: benchmark data v2 (:data:`~openreloc_bench.data.scene.DATA_VERSION`): surfaces without exact
periodicity, the ``query_near`` split, ``difficulty.csv``.
gen4: benchmark data v3: a sensor model, changes among the objects the queries see (moved, removed,
added), queries without a minimum of visible objects, dark splits without the camera's light.
gen5: benchmark data v3 continued: photographed materials on half the objects' parts, bare painted walls
in half the rooms, and the ``query_walk`` split (a second walk through the rooms)."""

TRAINING_SEED_MIN = 1_000_000
"""Seeds >= this are reserved for TRAINING scenes (below :data:`VALIDATION_SEED_MIN`; the encoder's,
the segmenter's and the merger's); benchmark suites reject them."""

VALIDATION_SEED_MIN = 10_000_000
"""Seeds >= this are for VALIDATION suites only: selecting encoder weights, recipes or thresholds by
relocalization on the suites themselves would tune to the test set, and held-out crop retrieval does not
predict relocalization (see ``TrainConfig.epochs``)."""

MIN_ROOM_SIDE_M = 2.0
"""Smallest room side that still fits furniture and a camera path."""
MAX_ROOM_SIDE_M = 30.0
"""Largest room side: the layout grids grow with the square of it (1e6 m would ask for hundreds of TiB)."""

MAX_OBJECTS_PER_M2 = 2.5
"""Upper bound on objects per square metre of the smallest possible room (floor + surface + wall items)."""

MAX_QUERIES = 10_000
"""Upper bound on ``n_query``: each query is rendered in every query split, so more is a typo, not a benchmark."""

MIN_MAPPING_STEP_M = 0.01
MIN_MAPPING_STEP_DEG = 0.5
"""Finer mapping steps emit frames faster than the renderer can draw them usefully (a typo, e.g. 0.0025 m)."""

_NAME_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")


@dataclass
class AssetsSpec:
    """Where a scene's objects come from (structure -- walls, floors, doors, stairs -- is always procedural)."""

    packs: list[Path] = field(default_factory=list)
    """Asset pack directories (a ``manifest.yaml`` and its meshes; relative paths in a suite file are
    relative to the suite file). Their categories join, or replace by name, the procedural ones."""
    procedural: bool = True
    """Also draw from the procedural library (false: only the packs' categories)."""


@dataclass
class SceneSpec:
    """One synthetic scene: layout kind, seed and size parameters."""

    name: str = "scene"
    """Directory name of the scene (letters, digits, '-', '_', '.')."""
    kind: Literal["single-room", "multi-room", "multi-floor"] = "single-room"
    """Layout family: one room, 3-8 rooms on one floor joined by doorways, or 2-3 floors joined by stairs."""
    seed: int = 0
    """Random seed; everything (layout, assets, trajectories, variants) derives from it."""
    rooms: int = 1
    """Rooms per floor (1 for single-room, 3-8 for multi-room, 2-8 per floor for multi-floor)."""
    floors: int = 1
    """Number of storeys (1, or 2-3 for multi-floor)."""
    objects_per_room: int = 20
    """Non-structural objects per room (floor furniture, items on surfaces, wall and ceiling items)."""
    room_side_min: float = 3.5
    """Smallest room side in metres."""
    room_side_max: float = 5.0
    """Largest room side in metres."""
    ceiling_height: float = 2.7
    """Floor-to-ceiling height in metres (storeys are ceiling_height + 0.3 apart)."""
    width: int = 640
    """Image width in pixels."""
    height: int = 480
    """Image height in pixels."""
    fov_y: float = 60.0
    """Vertical field of view in degrees (centred pinhole, square pixels)."""
    mapping_step_m: float = 0.25
    """A mapping frame is emitted every this many metres of camera travel..."""
    mapping_step_deg: float = 15.0
    """...or every this many degrees of camera rotation, whichever comes first."""
    max_mapping_frames: int = 0
    """Cap on mapping frames (subsampled evenly along the path); 0 = no cap."""
    n_query: int = 50
    """Query poses (shared by the query split and its variants); query_near has as many of its own, along
    the mapping path, and query_walk as many frames of a second walk through the rooms."""
    query_min_distance: float = 0.3
    """Every query camera centre is at least this far (m) from every mapping camera centre..."""
    query_min_angle: float = 20.0
    """...and differs by at least this rotation (deg) from every mapping frame within 1 m."""
    query_min_objects: int = 0
    """Non-structural objects that must be visible (>= 0.5% of pixels each) in every query (0: views of
    bare walls and floors are part of the test, as in a real recording)."""
    displaced_share: float = 0.25
    """Share of each room's objects moved or rotated in the query_displaced variant..."""
    removed_share: float = 0.05
    """...removed from it..."""
    added_share: float = 0.05
    """...and added to it (absent from every other split); each drawn among the objects the queries see."""
    bare_wall_share: float = 0.5
    """Share of rooms whose walls are bare paint: the plaster's fine grain without the metre-scale stains
    and wear of the others (real painted walls are mostly plain, and hard for keypoints)."""
    photo_share: float = 0.5
    """Share of the objects' parts textured with a photograph of their material (wood, plaster, ceramic,
    metal, fabric, stone; robosuite's MIT-licensed images) rather than its procedural pattern."""
    light_levels: list[float] = field(default_factory=lambda: [s.level for s in QUERY_SPLIT_TABLE if s.kind == LIGHT])
    """Brightness of each lighting variant relative to the mapping lighting, in the split table's order
    (progressive decay, each in (0, 1]; default: the table's levels)."""
    backend: Literal["mujoco", "pyrender"] = "mujoco"
    """Renderer backend: MuJoCo (exact, fast), or pyrender (the optional extra; physically based shading).
    Both draw the same geometry and textures, asset packs' included."""
    assets: AssetsSpec = field(default_factory=AssetsSpec)
    """Object sources: asset packs and / or the procedural library."""
    mapping_poses: Literal["ground-truth", "odometry"] = "ground-truth"
    """The mapping poses methods are given: the renderer's, or those RGB-D odometry with loop closures
    and a pose graph estimates from the recorded mapping frames (:mod:`generators.odometry`), aligned to
    the true world frame as trajectory evaluation does, as a user who mapped with SLAM has them (the
    truth is kept in ``mapping/pose_truth``, the drift in ``scene.json``)."""
    sensor: SensorSpec = field(default_factory=SensorSpec)
    """The camera that records the frames: a structured-light RGB-D camera, or ``{model: ideal}`` for the
    noiseless render (ablations)."""

    def __post_init__(self) -> None:
        validate_scene(self)


def validate_scene(spec: SceneSpec) -> None:
    """Raise a one-line :class:`ConfigError` naming the offending key."""
    n = spec.name
    if not isinstance(n, str) or not _NAME_RE.match(n):
        raise ConfigError(f"scene '{n}': 'name' must be letters, digits, '-', '_' or '.'")
    for f in fields(spec):  # a spec built in code: YAML values are checked by config.from_dict already
        v = getattr(spec, f.name)
        if isinstance(v, float) and not math.isfinite(v):
            raise ConfigError(f"scene '{n}': '{f.name}' must be a finite number, got {v}")
    positive = {
        "width": spec.width,
        "height": spec.height,
        "fov_y": spec.fov_y,
        "room_side_min": spec.room_side_min,
        "room_side_max": spec.room_side_max,
        "ceiling_height": spec.ceiling_height,
        "mapping_step_m": spec.mapping_step_m,
        "mapping_step_deg": spec.mapping_step_deg,
        "n_query": spec.n_query,
        "rooms": spec.rooms,
        "floors": spec.floors,
    }
    for key, v in positive.items():
        if v <= 0:
            raise ConfigError(f"scene '{n}': '{key}' must be positive, got {v}")
    nonneg = {
        "objects_per_room": spec.objects_per_room,
        "seed": spec.seed,
        "max_mapping_frames": spec.max_mapping_frames,
        "query_min_distance": spec.query_min_distance,
        "query_min_angle": spec.query_min_angle,
        "query_min_objects": spec.query_min_objects,
    }
    for key, v in nonneg.items():
        if v < 0:
            raise ConfigError(f"scene '{n}': '{key}' must be >= 0, got {v}")
    if spec.fov_y >= 170:
        raise ConfigError(f"scene '{n}': 'fov_y' must be below 170 degrees, got {spec.fov_y}")
    if spec.room_side_min < MIN_ROOM_SIDE_M:
        raise ConfigError(f"scene '{n}': 'room_side_min' must be >= {MIN_ROOM_SIDE_M} m, got {spec.room_side_min}")
    if spec.room_side_max > MAX_ROOM_SIDE_M:
        raise ConfigError(f"scene '{n}': 'room_side_max' must be at most {MAX_ROOM_SIDE_M} m, got {spec.room_side_max}")
    if spec.room_side_max < spec.room_side_min:
        raise ConfigError(
            f"scene '{n}': 'room_side_max' ({spec.room_side_max}) is below 'room_side_min' ({spec.room_side_min})"
        )
    if not 2.2 <= spec.ceiling_height <= 5.0:
        raise ConfigError(f"scene '{n}': 'ceiling_height' must be in [2.2, 5.0] m, got {spec.ceiling_height}")
    rooms_ok = {"single-room": (1, 1), "multi-room": (3, 8), "multi-floor": (2, 8)}[spec.kind]
    if not rooms_ok[0] <= spec.rooms <= rooms_ok[1]:
        raise ConfigError(
            f"scene '{n}': 'rooms' must be in [{rooms_ok[0]}, {rooms_ok[1]}] for kind {spec.kind}, got {spec.rooms}"
        )
    floors_ok = (2, 3) if spec.kind == "multi-floor" else (1, 1)
    if not floors_ok[0] <= spec.floors <= floors_ok[1]:
        raise ConfigError(
            f"scene '{n}': 'floors' must be in [{floors_ok[0]}, {floors_ok[1]}] for kind {spec.kind}, got {spec.floors}"
        )
    if spec.kind == "multi-floor" and spec.room_side_max < 4.5:
        raise ConfigError(f"scene '{n}': 'room_side_max' must be >= 4.5 m for multi-floor scenes (stairs need 4 m)")
    capacity = int(MAX_OBJECTS_PER_M2 * spec.room_side_min**2)
    if spec.objects_per_room > capacity:
        raise ConfigError(
            f"scene '{n}': 'objects_per_room' = {spec.objects_per_room} does not fit a {spec.room_side_min} m room "
            f"(at most {capacity}); raise room_side_min or lower objects_per_room"
        )
    shares = {
        "displaced_share": spec.displaced_share,
        "removed_share": spec.removed_share,
        "added_share": spec.added_share,
    }
    for key, v in {**shares, "bare_wall_share": spec.bare_wall_share, "photo_share": spec.photo_share}.items():
        if not 0 <= v <= 1:
            raise ConfigError(f"scene '{n}': '{key}' must be in [0, 1], got {v}")
    if sum(shares.values()) > 1:
        raise ConfigError(f"scene '{n}': 'displaced_share' + 'removed_share' + 'added_share' must be at most 1")
    if spec.query_min_objects > spec.objects_per_room * spec.rooms * spec.floors:
        raise ConfigError(f"scene '{n}': 'query_min_objects' exceeds the number of objects")
    if spec.n_query > MAX_QUERIES:
        raise ConfigError(f"scene '{n}': 'n_query' must be at most {MAX_QUERIES}, got {spec.n_query}")
    if spec.mapping_step_m < MIN_MAPPING_STEP_M or spec.mapping_step_deg < MIN_MAPPING_STEP_DEG:
        raise ConfigError(
            f"scene '{n}': 'mapping_step_m' / 'mapping_step_deg' must be at least {MIN_MAPPING_STEP_M} m / "
            f"{MIN_MAPPING_STEP_DEG} deg, got {spec.mapping_step_m} / {spec.mapping_step_deg}"
        )
    n_light = len(split_names(LIGHT))
    if len(spec.light_levels) != n_light or any(not 0 < v <= 1 for v in spec.light_levels):
        raise ConfigError(f"scene '{n}': 'light_levels' must be {n_light} values in (0, 1], got {spec.light_levels}")
    if not 16 <= spec.width <= 4096 or not 16 <= spec.height <= 4096:
        raise ConfigError(f"scene '{n}': 'width'/'height' must be in [16, 4096]")
    for pack in spec.assets.packs:
        if not (Path(pack) / "manifest.yaml").is_file():
            raise ConfigError(f"scene '{n}': 'assets.packs': {pack} is not an asset pack (no manifest.yaml)")
    if not spec.assets.procedural and not spec.assets.packs:
        raise ConfigError(f"scene '{n}': 'assets.procedural' is false and no pack is given: no objects to place")


@dataclass
class SuiteSpec:
    """A named list of scenes generated together (one YAML file in ``scenes/``)."""

    name: str = "suite"
    """Suite name (used in leaderboards)."""
    purpose: Literal["benchmark", "validation"] = "benchmark"
    """"benchmark": reported results, seeds below :data:`TRAINING_SEED_MIN`. "validation": model
    selection, seeds from :data:`VALIDATION_SEED_MIN` on."""
    description: str = ""
    """What the suite is for."""
    defaults: dict = field(default_factory=dict)
    """Scene keys applied to every scene unless the scene sets them."""
    scenes: list[dict] = field(default_factory=list)
    """The scenes, each a mapping of SceneSpec keys."""

    def scene_specs(self) -> list[SceneSpec]:
        """Validated scene specs, defaults merged in; one-line ConfigError on the first bad scene."""
        specs = []
        for i, raw in enumerate(self.scenes):
            if not isinstance(raw, dict):
                raise ConfigError(f"'scenes[{i}]': expected a mapping")
            spec = config.from_dict(SceneSpec, {**self.defaults, **raw}, where=f"scenes[{i}]")
            if self.purpose == "benchmark" and spec.seed >= TRAINING_SEED_MIN:
                raise ConfigError(
                    f"'scenes[{i}].seed' = {spec.seed}: a benchmark suite's seeds must be below "
                    f"{TRAINING_SEED_MIN} (higher ones are reserved for training and validation)"
                )
            if self.purpose == "validation" and spec.seed < VALIDATION_SEED_MIN:
                raise ConfigError(
                    f"'scenes[{i}].seed' = {spec.seed}: a validation suite's seeds must be at least "
                    f"{VALIDATION_SEED_MIN} (lower ones are benchmark or training scenes)"
                )
            specs.append(spec)
        names = [s.name for s in specs]
        dupes = sorted({x for x in names if names.count(x) > 1})
        if dupes:
            raise ConfigError(f"'scenes': duplicate scene name '{dupes[0]}'")
        if not specs:
            raise ConfigError("'scenes': a suite needs at least one scene")
        return specs


def load_suite(path: Path | str) -> SuiteSpec:
    """Read and fully validate a suite YAML (every scene spec is checked here, before generation).

    Relative asset pack paths are taken relative to the suite file and made absolute."""
    data = config.load_yaml(path)
    try:
        suite = config.from_dict(SuiteSpec, data)
        base = Path(path).resolve().parent
        for raw in [suite.defaults, *suite.scenes]:
            assets = raw.get("assets") if isinstance(raw, dict) else None
            if isinstance(assets, dict) and isinstance(assets.get("packs"), list):
                assets["packs"] = [str(base / p) if isinstance(p, str) else p for p in assets["packs"]]
        suite.scene_specs()
    except ConfigError as e:
        raise ConfigError(f"{path}: {e}") from None
    return suite


def spec_record(spec: SceneSpec) -> dict:
    """The spec as scene.json records it and :func:`spec_hash` hashes it: asset packs as their name and
    content fingerprint (not where they lie on disk), and no ``assets`` key for a procedural scene, so
    specs that predate packs keep their hash."""
    from generators.asset_packs import load_manifest, pack_fingerprint

    record = config.to_dict(spec)
    if spec.assets == AssetsSpec():
        del record["assets"]
    else:
        record["assets"]["packs"] = [
            {"name": load_manifest(p).name, "sha256": pack_fingerprint(p)} for p in spec.assets.packs
        ]
    return record


def spec_hash(spec: SceneSpec) -> str:
    """Stable short hash of everything that determines a scene's content: the spec and the generator version."""
    payload = json.dumps({"generator": GENERATOR_VERSION, "spec": spec_record(spec)}, sort_keys=True).encode()
    return hashlib.sha256(payload).hexdigest()[:16]
