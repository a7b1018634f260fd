from __future__ import annotations

import argparse
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from generators.generate import generate_scene
from generators.spec import SceneSpec
from openreloc_bench.cli import main
from openreloc_bench.harness.diagnose import boundary_counts, boundary_f, pool

TINY = dict(
    width=320, height=240, objects_per_room=12, room_side_min=3.5, room_side_max=4.0, mapping_step_m=0.5,
    mapping_step_deg=30.0, max_mapping_frames=16, n_query=3, displaced_share=0.2,
)  # fmt: skip


def test_boundary_f_is_one_on_the_truth_and_drops_with_a_shift() -> None:
    truth = np.zeros((60, 80), np.int32)
    truth[20:40, 20:50] = 1
    assert boundary_f(boundary_counts(truth, truth, 2)) == 1.0
    near, far = np.roll(truth, 1, axis=1), np.roll(truth, 6, axis=1)
    assert boundary_f(boundary_counts(near, truth, 2)) == 1.0  # within the tolerance
    assert boundary_f(boundary_counts(far, truth, 2)) < 0.6  # the side edges are 6 px off


def test_pool_weights_scenes_by_their_objects_and_queries() -> None:
    def row(name: str, p: float, n: int, r50: float, q: int) -> dict:
        objects = {e: {"small": 0, "medium": 1, "large": 0} for e in ("found", "split", "merged", "missed")}
        m = {"precision": p, "recall": p, "precision_25": p, "recall_25": p, "n_pred": n, "n_gt": n}
        loc = {
            "query": {
                "queries": q,
                "recall_50cm": r50,
                "recall_25cm": r50,
                "association_precision": 1.0,
                "accepted_matches": 1,
            }
        }
        return {"scene": name, "map": {**m, "objects": objects, "instances": {"matched": n}}, "localization": loc}

    pooled = pool([row("a", 1.0, 10, 100.0, 10), row("b", 0.0, 30, 0.0, 30)])
    assert pooled["map"]["precision"] == pytest.approx(0.25) and pooled["map"]["objects"]["found"]["medium"] == 2
    assert pooled["localization"]["query"]["recall_50cm"] == pytest.approx(25.0)


@pytest.fixture(scope="module")
def scene(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return generate_scene(SceneSpec(name="room", seed=7, **TINY), tmp_path_factory.mktemp("diag"), progress=False)


def test_diagnose_measures_every_stage(scene: Path, tmp_path: Path, capsys) -> None:
    argv = ["diagnose", "--scenes", str(scene), "--work", str(tmp_path / "w"), "--out", str(tmp_path / "o"), "--swap"]
    assert main(argv) == 0
    captured = capsys.readouterr()
    result = json.loads(captured.out.strip().splitlines()[-1])
    assert 0 <= result["map_precision"] <= 1 and 0 <= result["map_recall"] <= 1 and 0 < result["query_iou"] <= 1
    pooled = result["pooled"]
    assert set(pooled["swap"]) == {"dataset map + predicted queries", "predicted map + dataset queries"}
    assert pooled["localization"]["query"]["queries"] == 3
    assert "map P/R@.5" in captured.err and (tmp_path / "o" / "diagnose.md").is_file()
    # maps are reused while their config is unchanged
    markers = (tmp_path / "w" / "maps").rglob("room.done.json")
    marker = next(p for p in markers if json.loads(p.read_text())["built_from"]["track"] == "predicted")
    before = marker.stat().st_mtime_ns
    assert main([*argv, "--no-localize"]) == 0
    assert marker.stat().st_mtime_ns == before


def test_diagnose_refuses_a_missing_scene(tmp_path: Path, capsys) -> None:
    assert main(["diagnose", "--scenes", str(tmp_path / "nope"), "--work", str(tmp_path / "w")]) == 2
    err = capsys.readouterr().err
    assert "no scene at" in err and "Traceback" not in err


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        ([], "--suite needs --data"),
        (["--data", "DATA"], "no scene at"),
        (["--data", "DATA", "--frames", "0"], "no scene at"),
    ],
)
def test_diagnose_suite_form_needs_its_generated_scenes(tmp_path: Path, capsys, extra: list[str], message: str) -> None:
    suite = Path(__file__).resolve().parents[2] / "scenes" / "smoke.yaml"
    argv = ["diagnose", "--suite", str(suite), "--work", str(tmp_path / "w")]
    assert main(argv + [str(tmp_path) if e == "DATA" else e for e in extra]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err


def test_diagnose_refuses_zero_frames(scene: Path, tmp_path: Path, capsys) -> None:
    assert main(["diagnose", "--scenes", str(scene), "--work", str(tmp_path / "w"), "--frames", "0"]) == 2
    assert "--frames must be >= 1" in capsys.readouterr().err


@pytest.fixture(scope="module")
def recording(scene: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The generated room as a real recording comes: posed RGB-D frames, no instance image, no objects."""
    out = tmp_path_factory.mktemp("recording") / "room"
    shutil.copytree(scene, out)
    for folder in out.glob("*/instance"):
        shutil.rmtree(folder)
    (out / "objects.json").unlink()
    return out


def test_diagnose_names_the_stages_of_a_recording_without_labels(recording: Path, tmp_path: Path, capsys) -> None:
    argv = ["diagnose", "--scenes", str(recording), "--work", str(tmp_path / "w"), "--out", str(tmp_path / "o")]
    assert main([*argv, "--pictures", "2"]) == 0
    captured = capsys.readouterr()
    result = json.loads((tmp_path / "o" / "diagnose.json").read_text(), parse_constant=pytest.fail)
    loc = result["pooled"]["localization"]["query"]
    assert loc["association_precision"] is None and "segmentation" not in result["pooled"]
    stages = loc["stages"]
    assert stages["queries"] == 3 and set(stages["coarse_prior"]) >= {"recall_50cm", "median_te_m"}
    assert len(result["scenes"][0]["localization"]["query"]["per_query"]) == 3
    assert result["scenes"][0]["landmarks"]["landmarks"] > 0
    assert "coarse prior (first reference frame)" in captured.err
    assert len(list((tmp_path / "o" / "pictures" / "room").glob("query_*.png"))) == 2


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--track", "oracle-mask"], "has no instance images: diagnose it with --track predicted"),
        (["--swap"], "--swap needs the dataset's instance images"),
        (["--pictures", "2"], "--pictures takes a count >= 0 and needs --out"),
    ],
)
def test_diagnose_refuses_what_a_recording_cannot_give(
    recording: Path, tmp_path: Path, capsys, extra: list[str], message: str
) -> None:
    assert main(["diagnose", "--scenes", str(recording), "--work", str(tmp_path / "w"), *extra]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err


def test_diagnose_takes_scene_names_under_data_as_eval_does(tmp_path: Path) -> None:
    from openreloc_bench.commands.diagnose import _scene_dirs

    for name in ("sA", "sB"):
        (tmp_path / name).mkdir()
        (tmp_path / name / "scene.json").write_text("{}")
    args = argparse.Namespace(suite=None, data=tmp_path, scenes="sA,sB")
    assert _scene_dirs(args) == [tmp_path / "sA", tmp_path / "sB"]
    args = argparse.Namespace(suite=None, data=None, scenes=f"{tmp_path / 'sA'}")  # paths still work
    assert _scene_dirs(args) == [tmp_path / "sA"]
