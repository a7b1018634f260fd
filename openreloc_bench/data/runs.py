"""An evaluation's results folder, read back: the per-query rows of every finished job, and the cached
maps' records (written by ``harness/runner.py`` and ``harness/cache.py``)::

    RESULTS/runs/<label>/<track>/<scene>/<split>.queries.csv   per-query rows (QUERY_COLUMNS, difficulty)
                                         <split>.done.json     the job's provenance, written last
    RESULTS/maps/<method>/<map key>/<scene>.done.json          a cached map's record (size, build time)

Also the reader of every per-query table (``<split>.queries.csv``, ``tables/queries.csv``), which
reads tables written before the difficulty columns existed too.
"""

from __future__ import annotations

import io as _io
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from openreloc_bench.data import io
from openreloc_bench.data.scene import DIFFICULTY_AXES
from openreloc_bench.errors import DataError
from openreloc_bench.tracks import MASK_FREE

QUERY_COLUMNS = (
    "query", "success", "t_err_m", "r_err_deg", "runtime_s", "reason",
    "gt_x", "gt_y", "gt_z", "est_x", "est_y", "est_z",
)  # fmt: skip
"""The columns of every per-query table (then each query's difficulty and the scene's data version)."""
MARKER_KEYS = ("git_commit", "spec_hash", "config_hash", "split", "scene", "track", "method")
"""What every finished job's marker records (the provenance columns of its per-query rows)."""
MAP_RECORD_KEYS = ("map_bytes", "mapping_time_s")
"""The numbers every finished map's record holds (its size and build time in the tables)."""


def read_query_csv(path: Path, columns: tuple[str, ...]) -> pd.DataFrame:
    """A per-query table (``<split>.queries.csv``, ``tables/queries.csv``) with at least ``columns``;
    DataError naming the file when it is not UTF-8 CSV, lacks a column, or holds a non-number where
    an error, position, difficulty or data version is expected (a truncated or edited file)."""
    try:
        df = pd.read_csv(_io.StringIO(io.read_text(path)), dtype={"reason": str})
    except (pd.errors.ParserError, pd.errors.EmptyDataError, ValueError) as e:
        raise DataError(path, f"not a readable CSV table ({' '.join(str(e).split())})") from None
    missing = [c for c in columns if c not in df]
    if missing:
        raise DataError(path, f"no column '{missing[0]}': not a per-query table of openreloc-bench")
    numeric = [c for c in df if c.endswith(("_m", "_deg", "_s")) or c[:3] in ("gt_", "est")]
    checked = [c for c in df if (c in numeric and c in columns) or c in (*DIFFICULTY_AXES, "data_version")]
    bad = [c for c in checked if not pd.api.types.is_numeric_dtype(df[c])]
    if len(df) and (bad or ("success" in columns and not pd.api.types.is_bool_dtype(df["success"]))):
        raise DataError(
            path, f"column '{(bad or ['success'])[0]}' holds values of the wrong type (truncated or edited)"
        )
    if "reason" in df:
        df["reason"] = df["reason"].fillna("")
    return df


def backfill_difficulty(queries: pd.DataFrame) -> pd.DataFrame:
    """Per-query rows (with their ``spec_hash``) given the difficulty and ``data_version`` columns that tables
    written before those existed lack: no difficulty, and data v1 for generated scenes (the data before versions
    were recorded), none for imported ones (their spec hash is ``file:`` and a hash of their scene.json)."""
    out = queries.assign(**{c: np.nan for c in DIFFICULTY_AXES if c not in queries})
    if "data_version" not in out:
        imported = out["spec_hash"].astype(str).str.startswith("file:")
        out["data_version"] = pd.Series(1, index=out.index, dtype="Int64").mask(imported)
    return out


def load_run_queries(out: Path, uses_masks: Callable[[str], bool]) -> pd.DataFrame:
    """Every finished job's per-query rows under ``out/runs``, with the job's provenance columns and
    ``uses_masks``; where two jobs answered the same query on the same recorded track, the later one.

    ``uses_masks``: whether the method registered under a name reads masks (``methods.uses_masks``),
    which decides the track of markers written before it was recorded (:func:`marker_track`).
    """
    frames = []
    for marker in sorted((out / "runs").glob("*/*/*/*.done.json")):
        rec = io.read_json(marker)
        missing = [k for k in MARKER_KEYS if not isinstance(rec, dict) or k not in rec]
        if missing:
            raise DataError(marker, f"no '{missing[0]}': not a finished job's marker (remove it to recompute the job)")
        df = read_query_csv(marker.with_name(f"{rec['split']}.queries.csv"), QUERY_COLUMNS)
        df.insert(0, "map_hash", rec.get("map_hash", rec["config_hash"]))  # older runs keyed maps by the full config
        rec = {**rec, **marker_track(rec, uses_masks)}
        for key in MARKER_KEYS:
            df.insert(0, key, rec[key])
        df["uses_masks"] = rec["uses_masks"]
        df["variant"] = rec.get("variant", rec["method"])  # runs from before seeds: their own variant
        df["seed"] = pd.array([rec.get("seed")] * len(df), dtype="Int64")
        df["_finished"] = rec.get("finished", "")
        frames.append(backfill_difficulty(df))
    if not frames:
        return pd.DataFrame()
    q = pd.concat(frames, ignore_index=True).sort_values("_finished", kind="stable")
    q = q.drop_duplicates(["method", "track", "scene", "split", "query"], keep="last").sort_index()
    return q.drop(columns="_finished").reset_index(drop=True)


def marker_track(rec: dict[str, Any], uses_masks: Callable[[str], bool]) -> dict[str, Any]:
    """A finished job's recorded ``track`` and ``uses_masks``. Markers written before the track was
    recorded from the method's declaration (no ``uses_masks``) name the track the run was asked for:
    a method registered here as reading no masks is read as ``mask-free`` (the rule the board applied
    when drawing them), any other keeps its track."""
    if "uses_masks" in rec:
        return {"track": rec["track"], "uses_masks": bool(rec["uses_masks"])}
    masks = uses_masks(rec.get("registry_name", rec["method"]))
    return {"track": rec["track"] if masks else MASK_FREE, "uses_masks": masks}


def load_map_records(out: Path) -> pd.DataFrame:
    """Mapping time and map size of every cached map, one row per (map hash, scene)."""
    rows = []
    for p in sorted((out / "maps").glob("*/*/*.done.json")):
        r = io.read_json(p)
        if not isinstance(r, dict) or not all(isinstance(r.get(k), (int, float)) for k in MAP_RECORD_KEYS):
            raise DataError(p, "not a finished map's record (remove it: the map is rebuilt by the next eval)")
        rows.append(
            {
                "map_hash": p.parent.name,
                "scene": p.name[: -len(".done.json")],
                "map_mb": r["map_bytes"] / 1e6,
                "mapping_time_s": r["mapping_time_s"],
            }
        )
    return pd.DataFrame(rows, columns=["map_hash", "scene", "map_mb", "mapping_time_s"])
