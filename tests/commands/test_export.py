"""``openreloc-bench export colmap``: a model pycolmap reads, and an hloc round trip through ``score``."""

from __future__ import annotations

import sys
from pathlib import Path

import pandas as pd
import pycolmap

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "data"))
from test_colmap import write_wall_scene  # noqa: E402

from openreloc_bench import geometry  # noqa: E402
from openreloc_bench.cli import main  # noqa: E402
from openreloc_bench.data.scene import Scene  # noqa: E402


def test_export_then_score_hloc_named_poses(tmp_path: Path, capsys) -> None:
    data = tmp_path / "data"
    write_wall_scene(data / "wall")
    assert main(["export", "colmap", str(data / "wall"), "--out", str(tmp_path / "exp")]) == 0
    assert "5 images" in capsys.readouterr().out
    assert pycolmap.Reconstruction(tmp_path / "exp" / "sparse").num_images() == 5
    names = [line.split()[0] for line in (tmp_path / "exp" / "queries_with_intrinsics.txt").read_text().splitlines()]
    assert all((data / "wall" / n).is_file() for n in names)  # the scene is the image directory
    # what an hloc pipeline writes for these queries: its image names with T_cw
    lines = []
    for name, T in zip(names, Scene(data / "wall").sequence("query").poses):
        q, t = geometry.pose_to_qt(geometry.invert(T))
        lines.append(f"{name} " + " ".join(f"{v:.12g}" for v in (*q, *t)))
    (tmp_path / "hloc").mkdir()
    (tmp_path / "hloc" / "wall.txt").write_text("\n".join(lines) + "\n")
    argv = ["score", str(tmp_path / "hloc"), "--data", str(data), "--names", "hloc", "--out", str(tmp_path / "s")]
    assert main(argv) == 0
    suite = pd.read_csv(tmp_path / "s" / "tables" / "suite.csv")
    assert suite.loc[0, "recall_25cm"] == 100.0 and suite.loc[0, "n_queries"] == 2


def test_export_refuses_bad_input_in_one_line(tmp_path: Path, capsys) -> None:
    scene = write_wall_scene(tmp_path / "wall")
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "x").write_text("keep")
    cases = [
        (["--out", str(tmp_path / "full")], "is not empty"),
        (["--out", str(scene / "exp")], "overlaps the input"),
        (["--out", str(tmp_path / "e"), "--splits", "query_light1"], "no split 'query_light1'"),
        (["--out", str(tmp_path / "e"), "--voxel", "0"], "--voxel must be > 0"),
    ]
    for extra, message in cases:
        assert main(["export", "colmap", str(scene), *extra]) == 2
        err = capsys.readouterr().err.strip()
        assert message in err and len(err.splitlines()) == 1
    assert (tmp_path / "full" / "x").read_text() == "keep" and not (tmp_path / "e").exists()
