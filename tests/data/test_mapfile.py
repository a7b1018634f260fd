from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from openreloc_bench.data import mapfile
from openreloc_bench.errors import DataError

FORMAT = ("test-map", 3)


def write(directory: Path) -> dict[str, bytes]:
    payload = {
        "arrays.npz": mapfile.npz_bytes({"a": np.arange(6, dtype=np.int32).reshape(2, 3), "b": np.ones(2)}),
        "meta.json": mapfile.json_bytes({"k": 1, "name": "x"}),
    }
    mapfile.write_file_set(directory, *FORMAT, payload)
    return payload


def test_round_trip_is_verified_and_byte_identical(tmp_path: Path) -> None:
    payload = write(tmp_path / "a")
    write(tmp_path / "b")
    for name in (*payload, mapfile.MANIFEST):
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes()
    blobs = mapfile.read_file_set(tmp_path / "a", *FORMAT, {"arrays.npz", "meta.json"})
    assert blobs == payload
    arrays = mapfile.load_npz(blobs["arrays.npz"], tmp_path / "a" / "arrays.npz")
    assert arrays["a"].tolist() == [[0, 1, 2], [3, 4, 5]]
    assert mapfile.load_json(blobs["meta.json"], tmp_path / "a" / "meta.json") == {"k": 1, "name": "x"}


@pytest.mark.parametrize(
    ("damage", "message"),
    [
        (lambda d: (d / "arrays.npz").write_bytes((d / "arrays.npz").read_bytes()[:-10]), "arrays.npz: checksum"),
        (lambda d: (d / "meta.json").write_text('{"k": 2, "name": "x"}\n'), "meta.json: checksum"),
        (lambda d: (d / "meta.json").unlink(), "meta.json: file not found"),
        (lambda d: (d / mapfile.MANIFEST).unlink(), "manifest.json: missing: no test-map here"),
        (lambda d: (d / mapfile.MANIFEST).write_bytes(b"\xff\xfe binary"), "manifest.json: not UTF-8 text"),
    ],
)
def test_damaged_file_sets_fail_with_one_line_naming_the_file(tmp_path: Path, damage, message: str) -> None:
    write(tmp_path)
    damage(tmp_path)
    with pytest.raises(DataError, match=message) as e:
        mapfile.read_file_set(tmp_path, *FORMAT)
    assert "\n" not in str(e.value)


def test_other_format_or_version_is_refused(tmp_path: Path) -> None:
    write(tmp_path)
    with pytest.raises(DataError, match="format version 3, but this openreloc-bench reads version 4"):
        mapfile.read_file_set(tmp_path, "test-map", 4)
    with pytest.raises(DataError, match="not a other-map file"):
        mapfile.read_file_set(tmp_path, "other-map", 3)
    manifest = json.loads((tmp_path / mapfile.MANIFEST).read_text())
    manifest["files"].pop("meta.json")
    (tmp_path / mapfile.MANIFEST).write_text(json.dumps(manifest))
    with pytest.raises(DataError, match="must list exactly arrays.npz, meta.json"):
        mapfile.read_file_set(tmp_path, *FORMAT, {"arrays.npz", "meta.json"})


def test_malformed_payloads_are_data_errors(tmp_path: Path) -> None:
    with pytest.raises(DataError, match="x.npz: malformed arrays"):
        mapfile.load_npz(b"not a zip", tmp_path / "x.npz")
    with pytest.raises(DataError, match="x.json: not valid JSON"):
        mapfile.load_json(b"{", tmp_path / "x.json")
