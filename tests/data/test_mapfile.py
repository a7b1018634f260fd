from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from openreloc_bench.data import mapfile
from openreloc_bench.errors import ConfigError, DataError

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


def test_a_manifest_naming_a_file_elsewhere_is_refused(tmp_path: Path) -> None:
    write(tmp_path / "set")
    (tmp_path / "secret").write_text("x")
    manifest = json.loads((tmp_path / "set" / mapfile.MANIFEST).read_text())
    manifest["files"]["../secret"] = {"sha256": "0", "bytes": 1}
    (tmp_path / "set" / mapfile.MANIFEST).write_text(json.dumps(manifest))
    with pytest.raises(DataError, match="lists '../secret', which is not a file name"):
        mapfile.read_file_set(tmp_path / "set", *FORMAT)


def test_clearing_removes_exactly_a_previous_set(tmp_path: Path) -> None:
    mapfile.clear_file_set(tmp_path / "new")  # missing: nothing to do
    write(tmp_path / "old")
    mapfile.clear_file_set(tmp_path / "old")
    assert list((tmp_path / "old").iterdir()) == []


@pytest.mark.parametrize(
    "prepare, message",
    [
        (lambda d: (d / "notes.txt").write_text("mine"), "holds 'notes.txt' that no manifest.json there lists"),
        (lambda d: (write(d), (d / "notes.txt").write_text("mine")), "holds 'notes.txt'"),
        (lambda d: (write(d), (d / mapfile.MANIFEST).unlink()), "holds 'arrays.npz'"),  # an interrupted build
    ],
    ids=["a-user-folder", "a-set-with-foreign-files", "payload-without-manifest"],
)
def test_clearing_refuses_anything_but_a_set_and_removes_nothing(tmp_path: Path, prepare, message: str) -> None:
    d = tmp_path / "d"
    d.mkdir()
    prepare(d)
    before = sorted(p.name for p in d.iterdir())
    with pytest.raises(ConfigError, match=message):
        mapfile.clear_file_set(d)
    assert sorted(p.name for p in d.iterdir()) == before


def test_a_cache_can_tell_an_intact_set_of_any_format(tmp_path: Path) -> None:
    write(tmp_path / "ok")
    assert mapfile.is_intact(tmp_path / "ok")
    write(tmp_path / "cut")
    (tmp_path / "cut" / "arrays.npz").write_bytes(b"x")
    assert not mapfile.is_intact(tmp_path / "cut") and not mapfile.is_intact(tmp_path / "none")


def test_a_set_records_what_it_was_built_from(tmp_path: Path) -> None:
    mapfile.write_file_set(tmp_path / "s", "fmt", 1, {"a.bin": b"x"})
    assert mapfile.recorded_source(tmp_path / "s") is None
    mapfile.record_source(tmp_path / "s", {"scene": "room1", "spec_hash": "abc"})
    assert mapfile.recorded_source(tmp_path / "s") == {"scene": "room1", "spec_hash": "abc"}
    assert mapfile.read_file_set(tmp_path / "s", "fmt", 1) == {"a.bin": b"x"}  # still an intact set
    mapfile.clear_file_set(tmp_path / "s")
    assert not any((tmp_path / "s").iterdir())
    mapfile.record_source(tmp_path / "none", {"scene": "x"})  # nothing there: nothing written
    assert not (tmp_path / "none").exists()
    plugin = tmp_path / "plugin"  # a map in a method's own format: listed, so it is checked and replaced
    plugin.mkdir()
    (plugin / "map.npz").write_bytes(b"y")
    mapfile.record_source(plugin, {"scene": "x"})
    assert mapfile.read_file_set(plugin, *mapfile.FOREIGN_FORMAT) == {"map.npz": b"y"}
    assert mapfile.recorded_source(plugin) == {"scene": "x"}
    (nested := tmp_path / "nested" / "sub").mkdir(parents=True)
    mapfile.record_source(nested.parent, {"scene": "x"})  # sub-folders: cannot be listed, left alone
    assert [p.name for p in nested.parent.iterdir()] == ["sub"]
