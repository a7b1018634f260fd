"""Outputs never land in or around an input: default output paths sit beside the command's inputs,
never inside them, and a map directory holds one map (a previous one is replaced, not mixed in)."""

from __future__ import annotations

import contextlib
from pathlib import Path

import pandas as pd
import pytest

from openreloc_bench.data import mapfile
from tests.reliability.conftest import World, checksums, one_line_error, run

REPO = Path(__file__).resolve().parents[2]


def test_a_map_replaces_a_previous_map_of_another_method_whole(world: World, capsys) -> None:
    out = world.tmp / "m"
    mapfile.write_file_set(out, "other-method-map", 2, {"arrays.npz": b"x" * 1000, "meta.json": b"{}"})
    code, stdout, _ = run(["map", "--method", "nearest-frame", "--scene", str(world.scene), "--out", str(out)], capsys)
    assert code == 0 and "(0.008 MB" in stdout  # the old map's bytes are not counted as this one's
    assert sorted(p.name for p in out.iterdir()) == ["config.json", "manifest.json", "thumbs.npz"]


def test_default_outputs_stay_out_of_the_scene_and_the_submission(world: World, capsys, monkeypatch) -> None:
    monkeypatch.chdir(world.tmp)
    sub = world.inputs / "mysub"
    sub.mkdir()
    (sub / "sA.txt").write_text("query/000000 1 0 0 0 0 0 0\n")
    before = {p: checksums(p) for p in (world.data, world.inputs)}
    assert run(["preview", str(world.scene)], capsys)[0] == 0
    assert run(["score", str(sub), "--data", str(world.data)], capsys)[0] == 0
    assert {p: checksums(p) for p in before} == before
    assert (world.tmp / "sA_preview.png").is_file() and (world.tmp / "sA_preview_plan.png").is_file()
    assert (world.tmp / "mysub-scores" / "tables" / "suite.csv").is_file()


def test_a_windows_edited_submission_scores_as_the_clean_one(world: World, capsys) -> None:
    clean = "# name qw qx qy qz tx ty tz\nquery/000000 1 0 0 0 0 0 0\nquery/000001 1 0 0 0 0.5 0 0\n"
    suites = []
    for name, text in (("clean", clean.encode()), ("windows", b"\xef\xbb\xbf" + clean.replace("\n", "\r\n").encode())):
        sub = world.inputs / name
        sub.mkdir()
        (sub / "sA.txt").write_bytes(text)
        assert run(["score", str(sub), "--data", str(world.data), "--out", str(world.tmp / name)], capsys)[0] == 0
        suites.append(pd.read_csv(world.tmp / name / "tables" / "queries.csv")[["query", "t_err_m", "success"]])
    pd.testing.assert_frame_equal(*suites)


def test_an_interrupted_map_build_leaves_nothing_to_mistake_for_a_map(world: World, capsys, monkeypatch) -> None:
    from baselines.nearest_frame import NearestFrame

    def interrupted(self, mapping, map_dir) -> None:
        (map_dir / "thumbs.npz").write_bytes(b"half")
        raise KeyboardInterrupt

    monkeypatch.setattr(NearestFrame, "build_map", interrupted)
    argv = ["map", "--method", "nearest-frame", "--scene", str(world.scene), "--out", str(world.tmp / "m")]
    assert run(argv, capsys)[0] == 130
    assert not (world.tmp / "m").exists()  # the folder the build made is gone with the half map
    monkeypatch.undo()
    assert run(argv, capsys)[0] == 0  # and the next build goes ahead


def test_an_eval_that_cannot_run_generates_no_scene_first(world: World, capsys) -> None:
    suite = world.inputs / "suite.yaml"
    suite.write_text("scenes:\n  - {name: s1, seed: 3, width: 32, height: 24, n_query: 2, max_mapping_frames: 2}\n")
    for methods, config, out in (
        ("nope", [], "res"),
        ("nearest-frame", ["--method-config", f"nearest-frame={suite}"], "res"),
        ("nearest-frame", [], "gen/.."),  # --data inside --out
    ):
        argv = ["eval", "--suite", str(suite), "--methods", methods, "--data", str(world.tmp / "gen"), *config]
        code, _, err = run([*argv, "--out", str(world.tmp / out)], capsys)
        assert code == 2 and "Traceback" not in err, err
        assert not (world.tmp / "gen" / "s1").exists()


TINY_SUITE = "scenes:\n  - {name: s1, seed: 3, width: 64, height: 48, n_query: 2, max_mapping_frames: 12, displaced_share: 0.0, objects_per_room: 12, room_side_min: 4.0, room_side_max: 4.5}\n"  # noqa: E501


def test_regenerating_a_scene_keeps_the_users_files_and_a_failed_run_keeps_the_scene(
    world: World, capsys, monkeypatch
) -> None:
    import generators.generate
    from generators.spec import load_suite

    suite = world.inputs / "suite.yaml"
    suite.write_text(TINY_SUITE)
    out = world.tmp / "gen"
    code, _, err = run(["generate", str(suite), "--out", str(out)], capsys)
    assert code == 0, err
    scene = out / "s1"
    generated = checksums(scene)

    def broken(*args, **kwargs):
        raise RuntimeError("renderer lost")

    monkeypatch.setattr(generators.generate, "measure_difficulty", broken)
    spec = load_suite(suite).scene_specs()[0]
    with pytest.raises(RuntimeError):
        generators.generate.generate_scene(spec, out, progress=False)
    assert checksums(scene) == generated and sorted(p.name for p in out.iterdir()) == ["s1"]
    monkeypatch.undo()

    (scene / "notes.txt").write_text("mine")
    (scene / "mapping" / "color" / "README").write_text("mine too")
    code, _, err = run(["generate", str(suite), "--out", str(out)], capsys)
    one_line_error(code, err, "generate", "holds mapping/color/README and 1 more, which the generator did not write")
    assert (scene / "notes.txt").read_text() == "mine" and (scene / "mapping" / "color" / "README").is_file()
    assert run(["generate", str(suite), "--out", str(out), "--resume"], capsys)[0] == 0  # resuming keeps them too
    (scene / "notes.txt").unlink()
    (scene / "mapping" / "color" / "README").unlink()
    assert run(["generate", str(suite), "--out", str(out)], capsys)[0] == 0
    assert checksums(scene) == generated  # regenerated whole, byte for byte


def test_no_output_lands_inside_another_scene_or_a_map(world: World, capsys) -> None:
    other = world.data / "sB"
    before = {p: checksums(p) for p in (world.data, world.map_dir)}
    for argv, where in (
        (
            ["preview", str(world.scene), "--out", str(other / "query" / "color" / "000000.png")],
            "lies inside the scene",
        ),
        (["show-map", str(world.map_dir), "--out", str(other / "map.png")], "lies inside the scene"),
        (["preview", str(world.scene), "--out", str(world.map_dir / "sub" / "p.png")], "lies inside the map"),
        (
            ["agent", "ActiveReloc-v0", "--scene", str(world.scene), "--out", str(other / "ep.csv")],
            "lies inside the scene",
        ),
        (["agent", "ActiveReloc-v0", "--out", str(world.map_dir / "ep.csv")], "lies inside the map"),
        (["train-encoder", "--out", str(other / "w")], "lies inside the scene"),
        (["train-encoder", "--out", str(world.map_dir)], "is the map"),
        (["train-encoder", "--out", str(other)], "is the scene"),
        (["train-segmenter", "--out", str(world.map_dir)], "is the map"),
        (["train-merger", "--out", str(other / "w")], "lies inside the scene"),
        (
            ["card", str(REPO / "scenes" / "smoke.yaml"), "--data", str(world.tmp / "d"), "--out", str(world.map_dir)],
            "is the map",
        ),
        (
            ["campaign", str(REPO / "leaderboard" / "plan.yaml"), "--data", str(world.data), "--work", str(other)],
            "is the scene",
        ),
        (["diagnose", "--scenes", str(world.scene), "--work", str(world.map_dir)], "is the map"),
    ):
        code, _, err = run(argv, capsys)
        one_line_error(code, err, argv[0], where)
    assert {p: checksums(p) for p in before} == before


def test_a_failed_or_concurrent_import_leaves_no_partial_scene(world: World, capsys, monkeypatch) -> None:
    from openreloc_bench.data import paths
    from openreloc_bench.data.scene import SceneWriter
    from tests.data.test_convert import write_sens_export

    recording = write_sens_export(world.inputs / "rec", n=45, bad_pose=None)
    out = world.tmp / "imported"
    argv = ["import", "scannet", str(recording), "--out", str(out)]
    written = []

    def failing(self, split, i, *args, **kwargs):
        written.append(i)
        if len(written) == 3:
            raise OSError(28, "No space left on device")
        return real(self, split, i, *args, **kwargs)

    real = SceneWriter.write_frame
    monkeypatch.setattr(SceneWriter, "write_frame", failing)
    code, _, err = run(argv, capsys)
    assert code != 0 and "Traceback" not in err, err
    assert not out.exists() and [p.name for p in world.tmp.iterdir() if p.name.startswith(".imported")] == []
    monkeypatch.undo()
    with paths.directory_lock(out, "openreloc-bench import", in_directory=False):
        code, _, err = run(argv, capsys)
        one_line_error(code, err, "import", "another openreloc-bench import is writing here")
    assert run(argv, capsys)[0] == 0 and (out / "scene.json").is_file()
    code, _, err = run(argv, capsys)
    one_line_error(code, err, "import", "is not empty")


def test_a_forged_map_is_one_line(world: World, capsys) -> None:
    from openreloc_bench.data import io, mapfile
    from openreloc_bench.openreloc.map import MAP_FORMAT_NAME, MAP_FORMAT_VERSION
    from tests.openreloc.test_map import make_map

    forged = world.tmp / "forged"
    make_map().save(forged)
    meta = io.read_json(forged / "meta.json")
    meta["landmarks"] = "everything"  # forged, manifest and all: the checksums hold
    payload = {"arrays.npz": (forged / "arrays.npz").read_bytes(), "meta.json": mapfile.json_bytes(meta)}
    mapfile.write_file_set(forged, MAP_FORMAT_NAME, MAP_FORMAT_VERSION, payload)
    code, _, err = run(["show-map", str(forged), "--out", str(world.tmp / "m.png")], capsys)
    one_line_error(code, err, "show-map", "malformed map arrays or metadata")


def test_score_files_a_submission_under_the_track_its_header_records(world: World, capsys) -> None:
    sub = world.inputs / "sub"
    sub.mkdir()
    (sub / "sA.txt").write_text("# method m, track oracle-mask, scene sA\nquery/000000 1 0 0 0 0 0 0\n")
    assert run(["score", str(sub), "--data", str(world.data), "--out", str(world.tmp / "s")], capsys)[0] == 0
    assert set(pd.read_csv(world.tmp / "s" / "tables" / "queries.csv")["track"]) == {"oracle-mask"}


@pytest.mark.parametrize("failure", [KeyboardInterrupt, RuntimeError])
def test_a_failed_map_build_keeps_the_previous_map(world: World, capsys, monkeypatch, failure) -> None:
    from baselines.nearest_frame import NearestFrame

    before = checksums(world.map_dir)

    def failing(self, mapping, map_dir) -> None:
        (map_dir / "thumbs.npz").write_bytes(b"half")
        raise failure("stopped")

    monkeypatch.setattr(NearestFrame, "build_map", failing)
    argv = ["map", "--method", "nearest-frame", "--scene", str(world.scene), "--out", str(world.map_dir)]
    with pytest.raises(RuntimeError) if failure is RuntimeError else contextlib.nullcontext():
        assert run(argv, capsys)[0] == 130
    assert checksums(world.map_dir) == before
    assert [p.name for p in world.map_dir.parent.iterdir() if ".partial-" in p.name] == []
