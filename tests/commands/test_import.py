"""``openreloc-bench import``: real recordings in, then ``eval --scenes`` on them."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "data"))
from test_convert import write_sens_export, write_tum_sequence  # noqa: E402

from openreloc_bench.cli import main  # noqa: E402
from openreloc_bench.data.runs import load_run_queries  # noqa: E402
from openreloc_bench.methods import uses_masks  # noqa: E402


def test_imported_scannet_scene_is_evaluated(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    src = write_sens_export(tmp_path / "scans" / "scene0000_00")
    data = tmp_path / "data"
    assert main(["import", "scannet", str(src), "--out", str(data / "scene0000_00")]) == 0
    assert "2 mapping, 2 query frames, 3 objects (1 frame(s) skipped" in capsys.readouterr().out
    rc = main(
        [
            "eval",
            "--scenes",
            "scene0000_00",
            "--data",
            str(data),
            "--methods",
            "nearest-frame",
            "--out",
            str(tmp_path / "r"),
        ]
    )
    assert rc == 0
    queries = load_run_queries(tmp_path / "r", uses_masks)
    assert sorted(queries["query"]) == ["query/000010", "query/000030"]
    # the cameras slide along y: queries at 0.1 and 0.3 m, mapping frames at 0 and 0.4 m
    assert set(queries["t_err_m"].round(6)) <= {0.1, 0.3}


def test_imported_tum_sequence_is_evaluated_on_the_predicted_track(tmp_path: Path) -> None:
    src = write_tum_sequence(tmp_path / "rgbd_dataset_freiburg1_xyz")
    data = tmp_path / "data"
    assert (
        main(["import", "tum", str(src), "--out", str(data / "fr1_xyz"), "--intrinsics", "517.3,516.5,318.6,255.3"])
        == 0
    )
    args = ["eval", "--scenes", "fr1_xyz", "--data", str(data), "--methods", "nearest-frame", "--track", "predicted"]
    assert main([*args, "--out", str(tmp_path / "r")]) == 0
    assert len(load_run_queries(tmp_path / "r", uses_masks)) == 2


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["tum", "{src}", "--aggregation", "a.json"], "--aggregation is for scannet"),
        (["tum", "{src}", "--intrinsics", "1,2,3"], "--intrinsics expects FX,FY,CX,CY"),
        (["scannet", "{src}"], "is this a ScanNet export"),
        (["tum", "{src}"], "rgb.txt: file not found"),
    ],
)
def test_import_errors_are_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture, argv: list[str], message: str
) -> None:
    argv = [a.format(src=tmp_path) for a in argv]
    assert main(["import", *argv, "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1
