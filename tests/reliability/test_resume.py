"""A resumed or repeated run reuses only what it can verify: damaged records of finished jobs and
maps are recomputed, never trusted, and a results folder with a damaged record is a one-line error."""

from __future__ import annotations

import shutil

from tests.reliability.conftest import World, one_line_error, run


def eval_argv(w: World, *extra: str) -> list[str]:
    return ["eval", "--scenes", "sA", "--methods", "nearest-frame", "--data", str(w.data), "--out", str(w.tmp / "res"), *extra]  # fmt: skip


def test_a_damaged_job_marker_is_recomputed_on_resume(world: World, capsys) -> None:
    assert run(eval_argv(world), capsys)[0] == 0
    marker = world.tmp / "res" / "runs" / "nearest-frame" / "mask-free" / "sA" / "query.done.json"
    marker.write_text("{")  # as a full disk or an editor leaves it
    code, out, err = run(eval_argv(world, "--resume"), capsys)
    assert code == 0 and "jobs: 1 run, 0 resumed" in out, err
    assert marker.read_text().startswith("{\n")


def test_a_damaged_map_record_rebuilds_the_map(world: World, capsys) -> None:
    assert run(eval_argv(world), capsys)[0] == 0
    (record,) = (world.tmp / "res" / "maps").glob("*/*/sA.done.json")
    record.write_text("[]")
    code, out, err = run(eval_argv(world, "--resume"), capsys)
    assert code == 0 and "maps: 1 built, 0 cached" in out, err


def test_a_results_folder_with_a_damaged_map_record_is_one_line_for_the_leaderboard(world: World, capsys) -> None:
    assert run(eval_argv(world), capsys)[0] == 0
    results = world.inputs / "res"
    shutil.copytree(world.tmp / "res", results)
    (record,) = results.glob("maps/*/*/sA.done.json")
    record.write_text("{}")
    code, _, err = run(["leaderboard", str(results), "--out", str(world.tmp / "lb")], capsys)
    one_line_error(code, err, "leaderboard", "sA.done.json: not a finished map's record")


def test_a_damaged_per_query_table_is_one_line_for_the_leaderboard(world: World, capsys) -> None:
    assert run(eval_argv(world), capsys)[0] == 0
    table = world.tmp / "res" / "tables" / "queries.csv"
    table.write_text(table.read_text().replace("True", "maybe"))
    code, _, err = run(["leaderboard", str(world.tmp / "res"), "--out", str(world.tmp / "lb")], capsys)
    one_line_error(code, err, "leaderboard", "queries.csv: column 'success' holds values of the wrong type")


def test_a_damaged_cached_map_is_rebuilt_not_failed_query_by_query(world: World, capsys) -> None:
    assert run(eval_argv(world), capsys)[0] == 0
    (thumbs,) = (world.tmp / "res" / "maps").glob("*/*/sA/thumbs.npz")
    thumbs.write_bytes(thumbs.read_bytes()[:-10])
    code, out, err = run(eval_argv(world), capsys)
    assert code == 0 and "maps: 1 built, 0 cached" in out, out + err


def test_a_plugin_that_fails_as_it_is_imported_is_one_line(world: World, capsys, monkeypatch) -> None:
    (world.inputs / "broken_plugin.py").write_text("raise RuntimeError('no licence server')\n")
    monkeypatch.syspath_prepend(str(world.inputs))
    code, _, err = run(eval_argv(world, "--plugin", "broken_plugin"), capsys)
    one_line_error(code, err, "eval", "plugin broken_plugin: broken_plugin.py line 1: RuntimeError: no licence server")
