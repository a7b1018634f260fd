"""Map cache and provenance: a map is built once per (method config, scene spec) and reused.

Layout: ``RESULTS/maps/<method>/<config hash>/<scene>/`` holds only what the method wrote (so its
size is the method's map size); ``<scene>.done.json`` next to it is written last and records the
scene spec hash, mapping time and map size. A map whose marker is missing, damaged or names another
spec hash, or whose files no longer match its manifest, is rebuilt from scratch.
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

from openreloc_bench.data import io, mapfile
from openreloc_bench.errors import DataError

REPO_ROOT = Path(__file__).resolve().parents[2]


def config_hash(config: dict[str, Any]) -> str:
    """Short stable hash of a method's full config (as given by ``methods.method_config``)."""
    blob = json.dumps(config, sort_keys=True, default=str).encode()
    return hashlib.sha256(blob).hexdigest()[:12]


def dir_bytes(path: Path) -> int:
    """Bytes of every regular file under ``path`` (the map size the benchmark reports)."""
    return sum(p.stat().st_size for p in Path(path).rglob("*") if p.is_file() and not p.is_symlink())


@lru_cache(maxsize=1)
def git_commit() -> str:
    """The project's commit (``git rev-parse HEAD``), with ``-dirty`` if tracked files changed; "unknown" outside git."""
    try:
        head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=REPO_ROOT, capture_output=True, text=True, timeout=10)
        if head.returncode != 0:
            return "unknown"
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no"],
            cwd=REPO_ROOT,
            capture_output=True,
            text=True,
            timeout=10,
        ).stdout.strip()
        return head.stdout.strip() + ("-dirty" if dirty else "")
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


def build_map_cached(method: Any, mapping: Any, map_dir: Path, spec_hash: str, extra: dict[str, Any]) -> dict[str, Any]:
    """Build ``method``'s map into ``map_dir`` unless a valid cached one exists; return its record."""
    rec = read_map_record(map_dir, spec_hash)
    if rec is not None:
        return rec
    map_marker(map_dir).unlink(missing_ok=True)
    if map_dir.exists():
        shutil.rmtree(map_dir)
    map_dir.mkdir(parents=True)
    t0 = time.perf_counter()
    method.build_map(mapping, map_dir)
    seconds = time.perf_counter() - t0
    rec = {
        **extra,
        "spec_hash": spec_hash,
        "mapping_time_s": seconds,
        "map_bytes": dir_bytes(map_dir),
        "n_mapping_frames": len(mapping),
        "git_commit": git_commit(),
    }
    io.write_json(map_marker(map_dir), rec)
    return rec
