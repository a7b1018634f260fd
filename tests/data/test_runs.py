"""An evaluation's results folder read back: finished jobs' rows, markers of older versions, map records."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from openreloc_bench.data import io
from openreloc_bench.data.runs import (
    QUERY_COLUMNS,
    backfill_difficulty,
    load_map_records,
    load_run_queries,
    read_query_csv,
)
from openreloc_bench.data.scene import DIFFICULTY_AXES
from openreloc_bench.errors import DataError
from openreloc_bench.tracks import MASK_FREE, ORACLE_MASK, PREDICTED


def write_job(out: Path, method: str, track: str, finished: str, reasons: list[str], **marker) -> Path:
    """A finished query job of split ``query`` of scene ``s``: its per-query table, then its marker."""
    job = out / "runs" / method / track / "s"
    job.mkdir(parents=True, exist_ok=True)
    n = len(reasons)
    rows = {c: [0.0] * n for c in QUERY_COLUMNS}
    rows.update(query=[f"query/{i:06d}" for i in range(n)], success=[not r for r in reasons], reason=reasons)
    pd.DataFrame(rows).to_csv(job / "query.queries.csv", index=False)
    rec = dict(git_commit="c", spec_hash="h", config_hash="k", split="query", scene="s", track=track, method=method)
    io.write_json(job / "query.done.json", {**rec, "finished": finished, **marker})
    return job / "query.done.json"


def test_every_finished_job_gives_its_rows_with_its_provenance(tmp_path: Path) -> None:
    write_job(tmp_path, "m", PREDICTED, "2024-01-02", ["", "too few"], uses_masks=True, map_hash="mk")
    write_job(tmp_path, "f", MASK_FREE, "2024-01-02", [""], uses_masks=False, registry_name="f", seed=3)
    q = load_run_queries(tmp_path, lambda name: pytest.fail("a recorded track needs no registry"))
    m, f = q[q.method == "m"], q[q.method == "f"]
    assert m["reason"].tolist() == ["", "too few"] and set(m["map_hash"]) == {"mk"} and m["uses_masks"].all()
    assert f["track"].tolist() == [MASK_FREE] and f["seed"].tolist() == [3] and set(q["variant"]) == {"m", "f"}
    assert q["data_version"].tolist() == [1, 1, 1] and q[list(DIFFICULTY_AXES)].isna().all().all()


def test_markers_from_before_tracks_were_recorded_are_read_by_the_method_declaration(tmp_path: Path) -> None:
    """Markers without ``uses_masks``: a method registered as reading no masks ran on both tracks at once."""
    write_job(tmp_path, "free", PREDICTED, "2024-01-01", [""])
    write_job(tmp_path, "masked", ORACLE_MASK, "2024-01-01", [""])
    q = load_run_queries(tmp_path, lambda name: name != "free").set_index("method")
    assert q.loc["free", "track"] == MASK_FREE and not q.loc["free", "uses_masks"]
    assert q.loc["masked", "track"] == ORACLE_MASK and q.loc["masked", "uses_masks"]


def test_of_two_jobs_answering_the_same_queries_the_later_one_counts(tmp_path: Path) -> None:
    write_job(tmp_path, "free", PREDICTED, "2024-01-01", ["old"])  # an older eval's folder, read as mask-free
    write_job(tmp_path, "free", MASK_FREE, "2024-02-01", [""], uses_masks=False)
    q = load_run_queries(tmp_path, lambda name: False)
    assert len(q) == 1 and q["reason"].tolist() == [""]


def test_a_marker_missing_provenance_is_a_data_error(tmp_path: Path) -> None:
    marker = write_job(tmp_path, "m", PREDICTED, "2024-01-01", [""])
    rec = io.read_json(marker)
    del rec["scene"]
    io.write_json(marker, rec)
    with pytest.raises(DataError, match="no 'scene': not a finished job's marker"):
        load_run_queries(tmp_path, lambda name: True)
    assert load_run_queries(tmp_path / "none", lambda name: True).empty


def test_per_query_tables_are_checked_and_older_ones_backfilled(tmp_path: Path) -> None:
    path = tmp_path / "q.csv"
    pd.DataFrame({"query": ["query/000000"], "t_err_m": ["far"], "reason": [np.nan]}).to_csv(path, index=False)
    with pytest.raises(DataError, match="column 't_err_m' holds values of the wrong type"):
        read_query_csv(path, ("query", "t_err_m"))
    with pytest.raises(DataError, match="no column 'success'"):
        read_query_csv(path, ("query", "success"))
    rows = pd.DataFrame({"spec_hash": ["abc", "file:123"]})
    assert backfill_difficulty(rows)["data_version"].tolist() == [1, pd.NA]  # imported scenes have none


def test_map_records_give_size_and_time_per_map_and_scene(tmp_path: Path) -> None:
    io.write_json(tmp_path / "maps" / "m" / "key" / "s.done.json", {"map_bytes": 2_000_000, "mapping_time_s": 1.5})
    assert load_map_records(tmp_path).to_dict("records") == [
        {"map_hash": "key", "scene": "s", "map_mb": 2.0, "mapping_time_s": 1.5}
    ]
    io.write_json(tmp_path / "maps" / "m" / "key" / "t.done.json", {"map_bytes": "big"})
    with pytest.raises(DataError, match="not a finished map's record"):
        load_map_records(tmp_path)
