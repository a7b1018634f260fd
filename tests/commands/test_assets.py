"""``openreloc-bench assets``: the example pack validates clean with a gallery; problems are one line each."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from openreloc_bench.cli import main
from openreloc_bench.data import io


@pytest.mark.parametrize("backend", ["mujoco", "pyrender"])
def test_example_pack_validates_and_writes_a_gallery(tmp_path: Path, capsys, backend: str) -> None:
    if backend == "pyrender":
        pytest.importorskip("pyrender", reason="the pyrender extra is not installed")
    pack, gallery = tmp_path / "pack", tmp_path / "gallery.png"
    assert main(["assets", str(pack), "--example", "--gallery", str(gallery), "--backend", backend]) == 0
    assert "3 assets, 3 categories" in capsys.readouterr().out
    sheet = io.read_rgb(gallery)
    assert sheet.shape == (240, 960, 3) and sheet.std() > 10
    tiles = np.split(sheet[:200], 3, axis=1)  # above the labels: three different renders
    assert not np.array_equal(tiles[0], tiles[1]) and not np.array_equal(tiles[1], tiles[2])


def test_problems_exit_1_and_user_errors_exit_2(tmp_path: Path, capsys) -> None:
    pack = tmp_path / "pack"
    pack.mkdir()
    (pack / "manifest.yaml").write_text(
        "name: bad\nassets:\n  - {file: a.glb, category: c, description: d, placement: hanging}\n"
    )
    before = (pack / "manifest.yaml").read_bytes()
    assert main(["assets", str(pack), "--gallery", str(tmp_path / "g.png")]) == 1
    lines = capsys.readouterr().out.strip().splitlines()
    assert len(lines) == 2 and "unknown placement 'hanging'" in lines[0] and "missing file" in lines[1]
    assert (pack / "manifest.yaml").read_bytes() == before and not (tmp_path / "g.png").exists()
    assert main(["assets", str(pack), "--gallery", str(pack / "g.png")]) == 2  # never inside the pack
    assert "overlaps the input" in capsys.readouterr().err
    assert main(["assets", str(pack), "--example"]) == 2  # --example wants a new directory
    assert main(["assets", str(tmp_path / "nothing")]) == 2
