"""The one map builder, the map cache and provenance: a map is built once per (map config, masks, scene
spec) and reused.

Every map is built by :func:`build_map` (``map`` into a folder of the user's, the cache for ``eval``,
``diagnose`` and the environments), which records what it was built from (``built_from``: the scene's
name and spec hash, and the track). The cache's layout: ``RESULTS/maps/<method>/<map key>/<scene>/``
holds only what the method wrote (so its size is the method's map size); ``<scene>.done.json`` next to
it is written last and records ``built_from``, the mapping time and the map size. A map whose record is
missing, damaged or names another spec hash, or whose files no longer match its manifest, is rebuilt
from scratch. ``map`` notes ``built_from`` in the map's manifest instead; :func:`check_map_source` reads
either, so ``localize`` and ``view`` refuse every map of another scene.
"""

from __future__ import annotations

import hashlib
import json
import shutil
import subprocess
import time
from functools import lru_cache
from pathlib import Path
from typing import Any

from openreloc_bench.data import io, mapfile, paths
from openreloc_bench.data.scene import Scene
from openreloc_bench.errors import ConfigError, DataError, OpenRelocError, PluginError, raised_at
from openreloc_bench.methods import Relocalizer, foreign_source, map_config
from openreloc_bench.tracks import MASK_FREE, RecordedTrack

REPO_ROOT = Path(__file__).resolve().parents[2]


def config_hash(config: dict[str, Any]) -> str:
    """Short stable hash of a method's full config (as given by ``methods.method_config``)."""
    blob = json.dumps(config, sort_keys=True, default=str).encode()
    return hashlib.sha256(blob).hexdigest()[:12]


def map_key(method: Relocalizer, track: RecordedTrack) -> str:
    """The hash ``method``'s maps are cached under: its map config, the track whose masks they are built
    from and, for a method from outside this package, its code (:func:`foreign_code`)."""
    code = foreign_code(method)
    return config_hash({**map_config(method), "masks": track, **({"code": code} if code else {})})


def foreign_code(method: Relocalizer) -> str | None:
    """The sha256 of the file that defines ``method``'s class when that is not this project's
    (:func:`~openreloc_bench.methods.foreign_source`), so that editing a plugin's ``build_map`` rebuilds
    its maps instead of scoring the old code's; None for this project's methods, whose code version every
    result records (:func:`git_commit`)."""
    source = foreign_source(type(method))
    return _file_hash(source) if source is not None else None


def method_source(method: Relocalizer) -> str:
    """Where ``method``'s code came from, as its results record it: its class and, for a method from
    outside this project, the file defining it and that file's hash (:func:`foreign_code`)."""
    name = f"{type(method).__module__}:{type(method).__qualname__}"
    source = foreign_source(type(method))
    return name if source is None else f"{name} in {source} (sha256 {_file_hash(source)})"


def _file_hash(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()[:12]


def map_folder(root: Path, name: str, key: str, scene_key: str) -> Path:
    """Where a results or cache folder ``root`` keeps the map of method ``name`` with map key ``key``
    (:func:`map_key`) of a scene: ``maps/<name>/<key>/<scene key>``, confined to ``root/maps`` whatever a
    plugin names its method."""
    return paths.confined(root / "maps" / name / key / scene_key, root / "maps", "map cache")


def dir_bytes(path: Path) -> int:
    """Bytes of every regular file under ``path`` (the map size the benchmark reports)."""
    return sum(p.stat().st_size for p in Path(path).rglob("*") if p.is_file() and not p.is_symlink())


CODE_PATHS = ("openreloc_bench", "generators", "baselines", "scenes", "pyproject.toml")
"""The files that decide a result's numbers: the package, the generators, the baselines, the suites and
the dependencies."""
DRAWING_PATHS = ("openreloc_bench/harness/leaderboard", "openreloc_bench/harness/browser.py")
"""Of :data:`CODE_PATHS`, what only draws boards from finished rows: changing it changes no number."""


def _git(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(["git", *args], cwd=REPO_ROOT, capture_output=True, text=True, timeout=10)


@lru_cache(maxsize=1)
def git_commit() -> str:
    """The code version results are recorded under: the last commit that changed :data:`CODE_PATHS` (less
    :data:`DRAWING_PATHS`), with ``-dirty`` if tracked files there have uncommitted changes; "unknown"
    outside git. A commit of results, docs or tests keeps it, so a run that spans such commits (a campaign
    over several sittings, committing its boards as they finish) is still one code version, and checking
    that commit out gives the code of every row."""
    pathspec = ["--", *CODE_PATHS, *(f":(exclude){p}" for p in DRAWING_PATHS)]
    try:
        last = _git("log", "-1", "--format=%H", *pathspec)
        if last.returncode != 0 or not last.stdout.strip():
            return "unknown"
        dirty = _git("status", "--porcelain", "--untracked-files=no", *pathspec).stdout.strip()
        return last.stdout.strip() + ("-dirty" if dirty else "")
    except (OSError, subprocess.SubprocessError):
        return "unknown"


def map_marker(map_dir: Path) -> Path:
    return map_dir.with_name(map_dir.name + ".done.json")


def read_map_record(map_dir: Path, spec_hash: str) -> dict[str, Any] | None:
    """The completion record of a cached map, or None if it is absent, stale, from another spec, or if
    the map's own manifest (where it has one) no longer matches its files."""
    marker = map_marker(map_dir)
    if not marker.is_file() or not map_dir.is_dir():
        return None
    try:
        rec = io.read_json(marker)
    except DataError:  # a damaged marker: the map is rebuilt
        return None
    if (map_dir / mapfile.MANIFEST).exists() and not mapfile.is_intact(map_dir):
        return None  # a damaged map (truncated, edited): rebuilt, never loaded by every query job to fail
    return rec if isinstance(rec, dict) and rec.get("spec_hash") == spec_hash else None


def build_map(method: Relocalizer, scene: Scene, track: RecordedTrack, map_dir: Path) -> dict[str, Any]:
    """Build ``method``'s map of ``scene``'s mapping split into ``map_dir`` (absent or empty), from the
    dataset's masks on the oracle-mask track only; return what it was built from (``built_from``) and
    what it cost. A failed or interrupted build leaves ``map_dir`` empty: what is there is a part of a map,
    never a map."""
    mapping = scene.sequence("mapping", track)
    map_dir.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    try:
        try:
            method.build_map(mapping, map_dir)
        except OpenRelocError:
            raise
        except Exception as e:
            if (source := foreign_source(type(method))) is None:
                raise  # this project's bug: its traceback is wanted
            raise PluginError(f"method '{method.name}': build_map raised at {raised_at(e, source)}") from e
    except BaseException:
        for p in map_dir.iterdir():
            if p.is_dir() and not p.is_symlink():
                shutil.rmtree(p)
            else:
                p.unlink()
        raise
    return {
        mapfile.SOURCE_KEY: {"scene": scene.name, "spec_hash": scene.spec_hash, "track": track},
        "mapping_time_s": time.perf_counter() - t0,
        "map_bytes": dir_bytes(map_dir),
        "n_mapping_frames": len(mapping),
    }


def cached_map(
    method: Relocalizer, scene: Scene, track: RecordedTrack, map_dir: Path, provenance: dict[str, Any]
) -> dict[str, Any]:
    """The record of ``method``'s map of ``scene`` on ``track`` in the cache folder ``map_dir``: the map is
    built (:func:`build_map`) unless a valid one is there. ``provenance`` is recorded with it."""
    rec = read_map_record(map_dir, scene.spec_hash)
    if rec is not None:
        return rec
    map_marker(map_dir).unlink(missing_ok=True)
    if map_dir.exists():
        shutil.rmtree(map_dir)
    rec = {**provenance, "spec_hash": scene.spec_hash, **build_map(method, scene, track, map_dir)}
    rec["git_commit"] = git_commit()
    io.write_json(map_marker(map_dir), rec)
    return rec


def map_source(map_dir: Path) -> dict[str, Any] | None:
    """What the map in ``map_dir`` was built from: its cache record's ``built_from``, or its manifest's
    (maps of ``map``); None for a map from before it was recorded, or of a plugin's own format."""
    marker = map_marker(map_dir)
    try:
        rec = io.read_json(marker) if marker.is_file() else None
    except DataError:
        rec = None
    source = rec.get(mapfile.SOURCE_KEY) if isinstance(rec, dict) else None
    return source if isinstance(source, dict) else mapfile.recorded_source(map_dir)


def check_map_source(map_dir: Path, scene: Scene, track: RecordedTrack | None = None) -> None:
    """ConfigError when ``map_dir`` recorded being built from another scene than ``scene`` (every pose
    would be in the other scene's frame: silently wrong), or on another track than ``track`` (the map
    would hold the dataset's masks, or lack them; maps from before tracks were recorded are not checked)."""
    source = map_source(map_dir)
    if source is not None and source.get("spec_hash") != scene.spec_hash:
        raise ConfigError(
            f"{map_dir} is a map of scene '{source.get('scene')}' (spec {source.get('spec_hash')}), not of "
            f"{scene.root} (spec {scene.spec_hash}): give the scene it was built from, or build "
            "a map of this one with 'openreloc-bench map'"
        )
    built = source.get("track") if source is not None else None
    if track is not None and built is not None and built != track:
        other = "" if built == MASK_FREE else f"localize with --track {built}, or "  # no --track takes mask-free
        raise ConfigError(
            f"{map_dir} is a map of the {built} track, not of the {track} track: {other}"
            f"build a map with 'openreloc-bench map --track {track}'"
        )
