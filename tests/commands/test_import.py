"""``openreloc-bench import``: real recordings in, then ``eval --scenes`` on them."""

from __future__ import annotations

from pathlib import Path

import pytest

from openreloc_bench.cli import main
from openreloc_bench.data.runs import load_run_queries
from openreloc_bench.methods import uses_masks
from tests.data.test_convert import write_sens_export, write_tum_sequence
from tests.data.test_sevenscenes import write_7scenes_scene
from tests.data.test_twelvescenes import write_12scenes_scene


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


def test_imported_7scenes_scene_is_evaluated_on_its_test_sequences(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    src = write_7scenes_scene(tmp_path / "7scenes" / "chess")
    data = tmp_path / "data"
    assert main(["import", "7scenes", str(src), "--protocol", "splits", "--out", str(data / "chess")]) == 0
    assert "3 mapping, 1 query frames (1 frame(s) skipped" in capsys.readouterr().out
    args = ["eval", "--scenes", "chess", "--data", str(data), "--methods", "nearest-frame", "--track", "predicted"]
    assert main([*args, "--out", str(tmp_path / "r")]) == 0
    queries = load_run_queries(tmp_path / "r", uses_masks)
    assert list(queries["query"]) == ["query/000000"]
    # the query (seq-03's frame 10, x = 3.1) is 0.9, 1.1 and 2.1 m from the three mapping cameras
    assert queries["t_err_m"].round(6).tolist()[0] in {0.9, 1.1, 2.1}


def test_12scenes_and_7scenes_options_reach_the_import(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    src = write_12scenes_scene(tmp_path / "apt1_kitchen")
    argv = ["import", "12scenes", str(src), "--protocol", "splits", "--stride", "10", "--offset", "0"]
    assert main([*argv, "--max-depth", "5", "--out", str(tmp_path / "twelve")]) == 0
    assert "2 mapping, 2 query frames (2 frame(s) skipped" in capsys.readouterr().out
    seven = write_7scenes_scene(tmp_path / "chess", n=12)
    argv = ["import", "7scenes", str(seven), "--sequence", "seq-02", "--stride", "4", "--offset", "2"]
    assert main([*argv, "--intrinsics", "50,50,32,24", "--out", str(tmp_path / "seven")]) == 0
    assert "3 mapping, 3 query frames\n" == capsys.readouterr().out.split(": ", 1)[1]


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["tum", "{src}", "--aggregation", "a.json"], "--aggregation is for scannet"),
        (["tum", "{src}", "--intrinsics", "1,2,3"], "--intrinsics expects FX,FY,CX,CY"),
        (["12scenes", "{src}", "--intrinsics", "1,2,3,4"], "--intrinsics is for tum and 7scenes"),
        (["scannet", "{src}", "--sequence", "seq-01"], "--sequence is for 7scenes"),
        (["tum", "{src}", "--protocol", "splits"], "--protocol splits is for 7scenes and 12scenes: tum has no split"),
        (["7scenes", "{src}", "--max-depth", "70"], "--max-depth must be in (0, 65.534] metres, got 70.0"),
        (["7scenes", "{src}", "--stride", "20", "--offset", "0"], "the stride protocol needs --stride >= 2 and 1 <="),
        (["scannet", "{src}"], "not a ScanNet export: expected color/, depth/, pose/ and intrinsic/"),
        (["tum", "{src}"], "not a TUM RGB-D sequence: expected rgb.txt, depth.txt and groundtruth.txt; it holds"),
    ],
)
def test_import_errors_are_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture, argv: list[str], message: str
) -> None:
    argv = [a.format(src=tmp_path) for a in argv]
    assert main(["import", *argv, "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1


@pytest.mark.parametrize(
    ("fmt", "write", "message"),
    [
        ("7scenes", write_tum_sequence, "not a 7-Scenes scene: expected seq-XX/ folders of frame-XXXXXX.color.png"),
        ("tum", write_7scenes_scene, "not a TUM RGB-D sequence: expected rgb.txt"),
        ("scannet", write_7scenes_scene, "it looks like a 7-Scenes scene (`import 7scenes`)"),
        ("12scenes", write_sens_export, "not a 12-Scenes scene: expected info.txt and data/"),
    ],
)
def test_a_recording_of_another_layout_is_refused_in_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture, fmt: str, write, message: str
) -> None:
    src = write(tmp_path / "rec")
    before = sorted((p, p.stat().st_mtime_ns) for p in src.rglob("*"))
    assert main(["import", fmt, str(src), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert sorted((p, p.stat().st_mtime_ns) for p in src.rglob("*")) == before and not (tmp_path / "out").exists()
