"""Preview pictures of a generated scene (through the CLI)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from generators.generate import generate_scene
from generators.spec import SceneSpec
from openreloc_bench.cli import main
from openreloc_bench.data import io


def test_preview_cli(tmp_path: Path) -> None:
    scene = generate_scene(
        SceneSpec(
            name="p",
            seed=2,
            width=64,
            height=48,
            objects_per_room=8,
            max_mapping_frames=6,
            n_query=2,
            n_displaced=1,
            query_min_objects=1,  # few of its 8 objects fill 0.5% of a 64x48 frame seen from the mapping path
        ),
        tmp_path,
        progress=False,
    )
    out = tmp_path / "pics" / "sheet.png"
    assert main(["preview", str(scene), "--out", str(out), "--frames", "2"]) == 0
    for p in (out, out.with_name("sheet_plan.png")):
        img = io.read_rgb(p)
        assert img.shape[0] > 200 and img.shape[1] > 200
        assert np.unique(img.reshape(-1, 3), axis=0).shape[0] > 50  # not blank


def test_preview_missing_scene(tmp_path: Path, capsys) -> None:
    assert main(["preview", str(tmp_path / "nope")]) != 0
    assert "scene directory not found" in capsys.readouterr().err
