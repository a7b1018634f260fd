"""Encoder weights a method loads are a versioned, checksummed file set: damaged or foreign weights
passed as ``encoder_options: {weights: DIR}`` are one line naming the file, never a decoder's traceback."""

from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path

import pytest

from openreloc_bench.data import mapfile
from openreloc_bench.errors import DataError
from openreloc_bench.vision.offline import CONFIG_FILE, TOWER_FILE, WEIGHTS_DIR, WEIGHTS_FORMAT, load_tower
from tests.reliability.conftest import World, checksums, one_line_error, run


def test_the_committed_weights_are_a_verified_file_set() -> None:
    blobs = mapfile.read_file_set(WEIGHTS_DIR, *WEIGHTS_FORMAT, {CONFIG_FILE, TOWER_FILE})
    assert json.loads(blobs[CONFIG_FILE])["tower"]["dim"] == 384


def rewrite(weights: Path, name: str, content: bytes) -> None:
    """Replace one file and fix its checksum: a consistent set whose content is wrong."""
    (weights / name).write_bytes(content)
    manifest = json.loads((weights / mapfile.MANIFEST).read_text())
    manifest["files"][name] = {"sha256": hashlib.sha256(content).hexdigest(), "bytes": len(content)}
    (weights / mapfile.MANIFEST).write_text(json.dumps(manifest))


def other_format(manifest: Path) -> None:
    manifest.write_text(json.dumps({**json.loads(manifest.read_text()), "format": "learned-segmenter-weights"}))


def tower_config(weights: Path, **tower: int) -> bytes:
    meta = json.loads((weights / CONFIG_FILE).read_text())
    return json.dumps({**meta, "tower": {**meta["tower"], **tower}}).encode()


DAMAGES = {
    "truncated tower": (lambda w: (w / TOWER_FILE).write_bytes((w / TOWER_FILE).read_bytes()[:1000]), "image_tower.pt: checksum mismatch"),
    "edited config": (lambda w: (w / CONFIG_FILE).write_text("{}"), "config.json: checksum mismatch"),
    "no manifest (weights of an older version)": (lambda w: (w / mapfile.MANIFEST).unlink(), "manifest.json: missing"),
    "another format": (lambda w: other_format(w / mapfile.MANIFEST), "not a offline-encoder-weights file"),
    "config without the tower": (lambda w: rewrite(w, CONFIG_FILE, b"{}"), "weights do not fit the tower in config.json"),
    "config of another tower": (lambda w: rewrite(w, CONFIG_FILE, tower_config(w, dim=128)), "weights do not fit the tower"),
    "config with a NaN size": (lambda w: rewrite(w, CONFIG_FILE, b'{"tower": {"input_size": NaN}}'), "weights do not fit the tower"),
    "tower not a state dict": (lambda w: rewrite(w, TOWER_FILE, b"garbage" * 10), "weights do not fit the tower"),
}  # fmt: skip


@pytest.mark.parametrize("damage", list(DAMAGES))
def test_damaged_weights_are_one_line_naming_the_file(tmp_path: Path, damage: str) -> None:
    weights = tmp_path / "weights"
    shutil.copytree(WEIGHTS_DIR, weights)
    corrupt, message = DAMAGES[damage]
    corrupt(weights)
    with pytest.raises(DataError) as e:
        load_tower(weights)
    assert message in str(e.value) and "\n" not in str(e.value) and "train-encoder" in str(e.value)


def test_the_map_command_reports_damaged_weights_in_one_line(world: World, capsys) -> None:
    weights = world.inputs / "weights"
    shutil.copytree(WEIGHTS_DIR, weights)
    (weights / TOWER_FILE).write_bytes((weights / TOWER_FILE).read_bytes()[:-100])
    before = checksums(world.inputs)
    argv = ["map", "--method", "openreloc", "--scene", str(world.scene), "--out", str(world.tmp / "m")]
    code, _, err = run([*argv, "--set", f"encoder_options.weights={weights}"], capsys)
    one_line_error(code, err, "map", "image_tower.pt: checksum mismatch")
    assert checksums(world.inputs) == before
