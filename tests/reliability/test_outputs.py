"""Outputs never land in or around an input: default output paths sit beside the command's inputs,
never inside them, and a map directory holds one map (a previous one is replaced, not mixed in)."""

from __future__ import annotations

import pandas as pd

from openreloc_bench.data import mapfile
from tests.reliability.conftest import World, checksums, run


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
    assert list((world.tmp / "m").iterdir()) == []
    monkeypatch.undo()
    assert run(argv, capsys)[0] == 0  # and the next build goes ahead


def test_an_eval_that_cannot_run_generates_no_scene_first(world: World, capsys) -> None:
    suite = world.inputs / "suite.yaml"
    suite.write_text("scenes:\n  - {name: s1, seed: 3, width: 32, height: 24, n_query: 2, max_mapping_frames: 2}\n")
    for methods, config in (("nope", []), ("nearest-frame", ["--method-config", f"nearest-frame={suite}"])):
        argv = ["eval", "--suite", str(suite), "--methods", methods, "--data", str(world.tmp / "gen"), *config]
        code, _, err = run([*argv, "--out", str(world.tmp / "res")], capsys)
        assert code == 2 and "Traceback" not in err, err
        assert not (world.tmp / "gen" / "s1").exists()
