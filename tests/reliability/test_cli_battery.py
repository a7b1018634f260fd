"""The CLI fed a user's mistakes and a hostile environment.

Every case asserts one of two outcomes: a one-line error (exit 2, no traceback) or a counted failure
(exit 1, the run finished and named what failed); and in every case no file of the inputs changed
(sha256 of every file before and after). Each case is a mistake seen or plausible in practice.
"""

from __future__ import annotations

import hashlib
import json
import shutil
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parents[1] / "harness"))  # the test-method plugin, importable by workers
from harness_test_methods import make_scene  # noqa: E402

from openreloc_bench.cli import main  # noqa: E402
from openreloc_bench.data import paths  # noqa: E402
from openreloc_bench.data.results import read_tum_trajectory  # noqa: E402

PLUGIN = ["--plugin", "harness_test_methods"]


def checksums(root: Path) -> dict[str, str]:
    return {
        str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest() for p in root.rglob("*") if p.is_file()
    }


@dataclass
class World:
    """A data folder with two tiny scenes, a nearest-frame map, and folders for the inputs a case writes."""

    data: Path
    map_dir: Path
    inputs: Path
    tmp: Path

    @property
    def scene(self) -> Path:
        return self.data / "sA"


@pytest.fixture
def world(tmp_path: Path) -> World:
    data = tmp_path / "data"
    make_scene(data, "sA", splits=("query", "query_light1"), seed=1)
    make_scene(data, "sB", splits=("query",), seed=2)
    w = World(data, tmp_path / "map", tmp_path / "inputs", tmp_path)
    w.inputs.mkdir()
    assert main(["map", "--method", "nearest-frame", "--scene", str(w.scene), "--out", str(w.map_dir)]) == 0
    return w


def run(argv: list[str], capsys: pytest.CaptureFixture) -> tuple[int, str, str]:
    capsys.readouterr()
    code = main(argv)  # an uncaught exception here is a traceback for the user: the test fails
    out, err = capsys.readouterr()
    return code, out, err


def one_line_error(code: int, err: str, command: str, match: str) -> None:
    lines = [ln for ln in err.splitlines() if ln.startswith(f"openreloc-bench {command}: error:")]
    assert code == 2, err
    assert len(lines) == 1 and match in lines[0], err
    assert "Traceback" not in err


def write_input(w: World, name: str, content: bytes) -> Path:
    p = w.inputs / name
    p.write_bytes(content)
    return p


def eval_argv(w: World, *extra: str, scenes: str = "sA", methods: str = "nearest-frame", out: str = "res") -> list[str]:
    return ["eval", "--scenes", scenes, "--methods", methods, "--data", str(w.data), "--out", str(w.tmp / out), *extra]


# (command, argv builder, expected text of the one-line error)
MISTAKES: dict[str, tuple[str, Callable[[World], list[str]], str]] = {
    "eval --scenes: an absolute path outside --data": (
        "eval",
        lambda w: eval_argv(w, scenes=str(w.tmp / "elsewhere" / "sA")),
        "is not a scene directory directly under --data",
    ),
    "eval --scenes: a relative path": ("eval", lambda w: eval_argv(w, scenes="../sA"), "not a scene directory"),
    "eval --scenes: a scene that does not exist": ("eval", lambda w: eval_argv(w, scenes="nope"), "not found"),
    "eval --out: a scene directory": (
        "eval",
        lambda w: ["eval", "--scenes", "sA", "--methods", "nearest-frame", "--data", str(w.data), "--out", str(w.scene)],
        "overlaps the input",
    ),
    "eval --out: inside a scene directory": (
        "eval",
        lambda w: eval_argv(w, out="data/sA/results"),
        "overlaps the input",
    ),
    "eval --out: under a regular file": (
        "eval",
        lambda w: eval_argv(w, out="inputs/file.txt/results"),
        "Not a directory",
    ),
    "eval: an unknown method": ("eval", lambda w: eval_argv(w, methods="nope"), "unknown method 'nope'"),
    "eval: an unknown split": ("eval", lambda w: eval_argv(w, "--splits", "qeury"), "no split 'qeury'"),
    "eval: a negative timeout": ("eval", lambda w: eval_argv(w, "--timeout", "-1"), "--timeout must be"),
    "eval: a NaN map timeout": ("eval", lambda w: eval_argv(w, "--map-timeout", "nan"), "--map-timeout must be"),
    "eval: zero workers": ("eval", lambda w: eval_argv(w, "--workers", "0"), "--workers must be >= 1"),
    "eval: seeds that are not numbers": ("eval", lambda w: eval_argv(w, "--seeds", "a,b"), "--seeds expects"),
    "eval: a binary suite file": (
        "eval",
        lambda w: [
            "eval",
            "--suite",
            str(write_input(w, "suite.yaml", bytes(range(256)))),
            "--methods",
            "nearest-frame",
            "--data",
            str(w.data),
            "--out",
            str(w.tmp / "res"),
        ],
        "not a text file",
    ),
    "eval: a method config in Latin-1": (
        "eval",
        lambda w: eval_argv(
            w, "--method-config", f"nearest-frame={write_input(w, 'cfg.yaml', 'thumb_size: 8 # größe'.encode('latin-1'))}"
        ),
        "not UTF-8 text",
    ),
    "eval: an invalid method setting": (
        "eval",
        lambda w: eval_argv(w, "--method-config", f"nearest-frame={write_input(w, 'cfg.yaml', b'thumb_size: -5')}"),
        "thumb_size",
    ),
    "map: --out is the scene": (
        "map",
        lambda w: ["map", "--method", "nearest-frame", "--scene", str(w.scene), "--out", str(w.scene)],
        "overlaps the input",
    ),
    "map: --set thumb_size=-5": (
        "map",
        lambda w: ["map", "--method", "nearest-frame", "--scene", str(w.scene), "--out", str(w.tmp / "m"), "--set", "thumb_size=-5"],
        "'thumb_size' must be in [4, 256]",
    ),
    "localize: --out is a directory": (
        "localize",
        lambda w: ["localize", "--method", "nearest-frame", "--map", str(w.map_dir), "--scene", str(w.scene), "--out", str(w.inputs)],
        "is a directory",
    ),
    "localize: --out inside the map": (
        "localize",
        lambda w: ["localize", "--method", "nearest-frame", "--map", str(w.map_dir), "--scene", str(w.scene), "--out", str(w.map_dir / "p.txt")],
        "overlaps the input",
    ),
    "localize: a map built with other settings": (
        "localize",
        lambda w: ["localize", "--method", "nearest-frame", "--map", str(w.map_dir), "--scene", str(w.scene), "--out", str(w.tmp / "p.txt"), "--set", "thumb_size=8"],
        "map built with",
    ),
    "score: a per-scene file with a mistyped split": (
        "score",
        lambda w: ["score", str(submission(w, "Query/000000 1 0 0 0 0 0 0\n")), "--data", str(w.data), "--out", str(w.tmp / "s")],
        "name no split of scene 'sA', e.g. 'Query/000000'",
    ),
    "score: a binary submission file": (
        "score",
        lambda w: ["score", str(submission(w, bytes(range(256)))), "--data", str(w.data), "--out", str(w.tmp / "s")],
        "not a text file",
    ),
    "score: a NaN pose": (
        "score",
        lambda w: ["score", str(submission(w, "query/000000 nan 0 0 0 0 0 0\n")), "--data", str(w.data), "--out", str(w.tmp / "s")],
        "NaN or inf",
    ),
}  # fmt: skip


def submission(w: World, content: str | bytes) -> Path:
    sub = w.inputs / "submission"
    sub.mkdir(exist_ok=True)
    (sub / "sA.txt").write_bytes(content.encode() if isinstance(content, str) else content)
    return sub


@pytest.mark.parametrize("case", list(MISTAKES))
def test_a_mistake_is_one_line_and_changes_no_input(case: str, world: World, capsys) -> None:
    command, argv, match = MISTAKES[case]
    (world.inputs / "file.txt").write_text("x")
    args = argv(world)
    before = {p: checksums(p) for p in (world.data, world.map_dir, world.inputs)}
    code, _, err = run(args, capsys)
    one_line_error(code, err, command, match)
    assert {p: checksums(p) for p in before} == before


def test_scenes_given_as_absolute_paths_under_data_are_used_not_deleted(world: World, capsys) -> None:
    """The data-loss defect: `eval --scenes /abs/path/to/scene` turned the map cache into the scene itself."""
    before = checksums(world.data)
    code, out, err = run(eval_argv(world, scenes=f"{world.scene.resolve()},sB"), capsys)
    assert code == 0, err
    assert checksums(world.data) == before
    assert sorted(p.name for p in (world.tmp / "res" / "maps" / "nearest-frame").glob("*/*") if p.is_dir()) == [
        "sA",
        "sB",
    ]


def test_resume_recomputes_jobs_run_with_other_settings_or_scenes(world: World, capsys) -> None:
    argv = eval_argv(world, "--resume")
    assert run(argv, capsys)[0] == 0
    marker = world.tmp / "res" / "runs" / "nearest-frame" / "oracle-mask" / "sA" / "query.done.json"
    assert json.loads(marker.read_text())["method_config"]["config"]["thumb_size"] == 32
    code, out, _ = run(argv, capsys)
    assert code == 0 and "1 resumed" in out and "recomputed" not in out
    cfg = write_input(world, "cfg.yaml", b"thumb_size: 8\n")
    code, out, _ = run([*argv, "--method-config", f"nearest-frame={cfg}"], capsys)
    assert code == 0 and "1 finished job(s) were run with other settings or scenes and were recomputed" in out
    assert json.loads(marker.read_text())["method_config"]["config"]["thumb_size"] == 8
    info = json.loads((world.scene / "scene.json").read_text())
    (world.scene / "scene.json").write_text(json.dumps({**info, "spec_hash": "regenerated"}))
    code, out, _ = run([*argv, "--method-config", f"nearest-frame={cfg}"], capsys)
    assert code == 0 and "1 built" in out and "were recomputed" in out
    assert json.loads(marker.read_text())["spec_hash"] == "regenerated"


def test_an_incomplete_scene_is_refused_by_every_command(world: World, capsys) -> None:
    (world.scene / "query" / "pose" / "000002.txt").unlink()  # as a killed generator leaves a scene
    info = json.loads((world.scene / "scene.json").read_text())
    (world.scene / "scene.json").write_text(json.dumps({**info, "splits": {"mapping": 4, "query": 3}}))
    before = checksums(world.data)
    for command, argv in [
        ("eval", eval_argv(world)),
        ("localize", ["localize", "--method", "nearest-frame", "--map", str(world.map_dir), "--scene", str(world.scene), "--out", str(world.tmp / "p.txt")]),
    ]:  # fmt: skip
        code, _, err = run(argv, capsys)
        one_line_error(code, err, command, "has 2 of the 3 frames scene.json lists: the scene is incomplete")
    assert checksums(world.data) == before


def test_a_corrupted_map_is_one_line(world: World, capsys) -> None:
    blob = (world.map_dir / "thumbs.npz").read_bytes()
    (world.map_dir / "thumbs.npz").write_bytes(blob[:-20])
    argv = ["localize", "--method", "nearest-frame", "--map", str(world.map_dir), "--scene", str(world.scene), "--out", str(world.tmp / "p.txt")]  # fmt: skip
    code, _, err = run(argv, capsys)
    one_line_error(code, err, "localize", "thumbs.npz: checksum mismatch")


def test_tum_export_pairs_each_estimate_with_its_own_ground_truth_after_a_failure(world: World, capsys) -> None:
    cfg = write_input(world, "cfg.yaml", b"fail_on: query/000000\nnoise_m: 0.05\n")
    argv = eval_argv(world, "--method-config", f"test-oracle={cfg}", *PLUGIN, methods="test-oracle")
    assert run(argv, capsys)[0] == 0
    out = world.tmp / "res" / "runs" / "test-oracle" / "oracle-mask" / "sA"
    est_t, est = read_tum_trajectory(out / "query.tum")
    gt_t, gt = read_tum_trajectory(out / "query.gt.tum")
    assert est_t.tolist() == [1.0, 2.0] and gt_t.tolist() == [0.0, 1.0, 2.0]
    for t, T in zip(est_t, est):
        assert abs(float(((T - gt[int(t)])[:3, 3] ** 2).sum()) ** 0.5 - 0.05) < 1e-6  # its own query, 5 cm off


@pytest.mark.parametrize("where", ["build_map", "load_map"])
def test_a_method_hanging_in_its_map_fails_that_map_and_the_run_ends(where: str, world: World, capsys) -> None:
    cfg = write_input(world, "cfg.yaml", f"hang_in: {where}\n".encode())
    argv = eval_argv(
        world, "--method-config", f"test-oracle={cfg}", "--map-timeout", "3", *PLUGIN, methods="test-oracle"
    )
    t0 = time.perf_counter()
    code, out, err = run(argv, capsys)
    assert code == 1 and "timed out after 3 s" in out and "Traceback" not in err
    assert time.perf_counter() - t0 < 60


def test_a_second_eval_on_the_same_results_folder_fails_at_once(world: World, capsys) -> None:
    held, release = threading.Event(), threading.Event()

    def hold() -> None:
        with paths.directory_lock(world.tmp / "res", "openreloc-bench eval"):
            held.set()
            release.wait(30)

    t = threading.Thread(target=hold)
    t.start()
    try:
        held.wait(10)
        code, _, err = run(eval_argv(world), capsys)
        one_line_error(code, err, "eval", "another openreloc-bench eval (pid")
    finally:
        release.set()
        t.join()
    assert run(eval_argv(world), capsys)[0] == 0  # free again once the holder is done


def test_a_truncated_image_is_a_counted_failure_not_a_traceback(world: World, capsys) -> None:
    img = world.scene / "mapping" / "color" / "000001.png"
    img.write_bytes(img.read_bytes()[:40])
    code, out, err = run(eval_argv(world), capsys)
    assert code == 1 and "unreadable image" in out and "Traceback" not in err


def test_the_battery_leaves_no_stray_files(world: World, capsys) -> None:
    shutil.rmtree(world.tmp / "res", ignore_errors=True)
    assert run(eval_argv(world), capsys)[0] == 0
    assert not list((world.tmp / "res").rglob("*.tmp"))
