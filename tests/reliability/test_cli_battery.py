"""The CLI fed a user's mistakes and a hostile environment.

Every case asserts one of two outcomes: a one-line error (exit 2, no traceback) or a counted failure
(exit 1, the run finished and named what failed); and in every case no file of the inputs changed
(sha256 of every file before and after). Each case is a mistake seen or plausible in practice.
"""

from __future__ import annotations

import json
import shutil
import threading
import time
from collections.abc import Callable
from pathlib import Path

import pytest

from openreloc_bench.data import paths
from openreloc_bench.data.results import read_tum_trajectory
from openreloc_bench.harness.leaderboard.rows import BOARD_INPUT_COLUMNS
from tests.data.test_convert import write_tum_sequence
from tests.data.test_sevenscenes import write_7scenes_scene
from tests.data.test_twelvescenes import write_12scenes_scene
from tests.reliability.conftest import PLUGIN, World, checksums, one_line_error, run


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
    "score --splits: the mapping split": (
        "score",
        lambda w: ["score", str(submission(w, "query/000000 1 0 0 0 0 0 0\n")), "--data", str(w.data), "--splits", "mapping", "--out", str(w.tmp / "s")],
        "--splits: 'mapping' built the maps; scoring poses of its own frames measures nothing",
    ),
    "localize --out: inside a file": (
        "localize",
        lambda w: ["localize", "--method", "nearest-frame", "--map", str(w.map_dir), "--scene", str(w.scene), "--out", str(w.inputs / "file.txt" / "p.txt")],
        "cannot write in",
    ),
    "diagnose --swap on the oracle-mask track": (
        "diagnose",
        lambda w: ["diagnose", "--scenes", str(w.scene), "--work", str(w.tmp / "dw"), "--track", "oracle-mask", "--swap"],
        "--swap swaps predicted masks for the dataset's: it needs --track predicted",
    ),
    "diagnose --out: a file": (
        "diagnose",
        lambda w: ["diagnose", "--scenes", str(w.scene), "--work", str(w.tmp / "dw"), "--out", str(w.inputs / "file.txt")],
        "is a file; give a folder",
    ),
    "score: the dataset given as the submission": (
        "score",
        lambda w: ["score", str(w.data), "--data", str(w.data), "--out", str(w.tmp / "s")],
        "is a dataset, not a submission",
    ),
    "score --out: an eval's results folder": (
        "score",
        lambda w: ["score", str(submission(w, "query/000000 1 0 0 0 0 0 0\n")), "--data", str(w.data), "--out", str(eval_results(w))],
        "holds an evaluation's results (runs/)",
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
    # ---- the general rules, applied to every command (numbers checked, paths confined, text decoded)
    "generate: a NaN in the suite": (
        "generate",
        lambda w: ["generate", str(suite_file(w, "fov_y: .nan")), "--out", str(w.tmp / "gen")],
        "'scenes[0].fov_y': expected a finite number, got nan",
    ),
    "generate: a key given twice": (
        "generate",
        lambda w: ["generate", str(suite_file(w, "seed: 4")), "--out", str(w.tmp / "gen")],
        "found duplicate key 'seed'",
    ),
    "generate: a scene of another spec where it would write": (
        "generate",
        lambda w: ["generate", str(suite_file(w, name="sA")), "--out", str(w.data)],
        "was generated from another spec",
    ),
    "generate: the suite file inside the scene folder it replaces": (
        "generate",
        lambda w: ["generate", str(suite_file(w, at="gen/s1/suite.yaml")), "--out", str(w.inputs / "gen")],
        "overlaps the input",
    ),
    "generate: --scenes names nothing": (
        "generate",
        lambda w: ["generate", str(suite_file(w)), "--out", str(w.tmp / "gen"), "--scenes", ","],
        "--scenes names no scene",
    ),
    "map: --out a folder of the user's": (
        "map",
        lambda w: ["map", "--method", "nearest-frame", "--scene", str(w.scene), "--out", str(w.inputs)],
        "holds 'file.txt' that no manifest.json there lists",
    ),
    "map: a config whose key is a number": (
        "map",
        lambda w: ["map", "--method", "nearest-frame", "--scene", str(w.scene), "--out", str(w.tmp / "m"), "--config", str(write_input(w, "c.yaml", b"1: 2"))],
        "key 1 is not a name",
    ),
    "map: a negative learning rate": (
        "map",
        lambda w: ["map", "--method", "openreloc", "--scene", str(w.scene), "--out", str(w.tmp / "m"), "--set", "refinement.lr_rotation=-1"],
        "openreloc.refinement: 'lr_rotation' must be > 0, got -1.0",
    ),
    "map: an unknown encoder option": (
        "map",
        lambda w: ["map", "--method", "openreloc", "--scene", str(w.scene), "--out", str(w.tmp / "m"), "--set", "encoder_options.bogus=1"],
        "encoder 'offline': got an unexpected keyword argument 'bogus'",
    ),
    "map: encoder weights that are not a path": (
        "map",
        lambda w: ["map", "--method", "openreloc", "--scene", str(w.scene), "--out", str(w.tmp / "m"), "--set", "encoder_options.weights=5"],
        "option 'weights' must be a directory path, got 5",
    ),
    "localize: --diagnostics is --out": (
        "localize",
        lambda w: ["localize", "--method", "nearest-frame", "--map", str(w.map_dir), "--scene", str(w.scene), "--out", str(w.tmp / "p.txt"), "--diagnostics", str(w.tmp / "p.txt")],
        "are the same file",
    ),
    "localize: scene.json is a list": (
        "localize",
        lambda w: ["localize", "--method", "nearest-frame", "--map", str(w.map_dir), "--scene", str(damaged(w, "scene.json", b"[1, 2]")), "--out", str(w.tmp / "p.txt")],
        "scene.json: expected a JSON object, got list",
    ),
    "eval: --out the data folder (its clean-up would reach into the scenes)": (
        "eval",
        lambda w: ["eval", "--scenes", "sA", "--methods", "nearest-frame", "--data", str(w.data), "--out", str(w.data)],
        "results folder",
    ),
    "eval: --splits mapping": ("eval", lambda w: eval_argv(w, "--splits", "mapping"), "'mapping' builds the maps"),
    "eval: --splits names nothing": ("eval", lambda w: eval_argv(w, "--splits", ","), "--splits names nothing"),
    "eval: a timeout beyond what the system can wait": (
        "eval",
        lambda w: eval_argv(w, "--timeout", "1e300"),
        "--timeout must be a number of seconds in [0, 1e+07]",
    ),
    "eval: --method-config twice for one method": (
        "eval",
        lambda w: eval_argv(w, "--method-config", f"nearest-frame={write_input(w, 'a.yaml', b'thumb_size: 8')}", "--method-config", f"nearest-frame={write_input(w, 'b.yaml', b'thumb_size: 16')}"),
        "names 'nearest-frame' twice",
    ),
    "eval: a seed beyond 64 bits": (
        "eval",
        lambda w: eval_argv(w, "--seeds", "99999999999999999999", *PLUGIN, methods="test-oracle"),
        "--seeds: 99999999999999999999 is out of range",
    ),
    "score: both layouts for one scene": (
        "score",
        lambda w: ["score", str(submission(w, "query/000000 1 0 0 0 0 0 0\n", also="sA/query.txt")), "--data", str(w.data), "--out", str(w.tmp / "s")],
        "keep one layout",
    ),
    "score: a file naming no scene": (
        "score",
        lambda w: ["score", str(submission(w, "query/000000 1 0 0 0 0 0 0\n", also="sAA.txt")), "--data", str(w.data), "--out", str(w.tmp / "s")],
        "sAA.txt: names no scene under",
    ),
    "score: --out the data folder": (
        "score",
        lambda w: ["score", str(submission(w, "query/000000 1 0 0 0 0 0 0\n")), "--data", str(w.data), "--out", str(w.data)],
        "overlaps the input",
    ),
    "leaderboard: a damaged queries table": (
        "leaderboard",
        lambda w: ["leaderboard", str(results_with(w, b"a,b\n1,2\n")), "--out", str(w.tmp / "lb")],
        "tables/queries.csv: no column",
    ),
    "leaderboard: --out a results folder": (
        "leaderboard",
        lambda w: ["leaderboard", str(results_with(w, HEADER_ONLY)), "--out", str(w.inputs / "results")],
        "overlaps the input",
    ),
    "show-map: --out inside the map": (
        "show-map",
        lambda w: ["show-map", str(w.map_dir), "--out", str(w.map_dir / "map.png")],
        "overlaps the input",
    ),
    "show-map: --out not a PNG": (
        "show-map", lambda w: ["show-map", str(w.map_dir), "--out", str(w.tmp / "map.txt")], "must end in .png"
    ),
    "preview: --out a scene's image": (
        "preview",
        lambda w: ["preview", str(w.scene), "--out", str(w.scene / "query" / "color" / "000000.png")],
        "overlaps the input",
    ),
    "preview: --frames 0": ("preview", lambda w: ["preview", str(w.scene), "--frames", "0"], "--frames must be in [1, 32]"),
    "map: an unknown segmenter": (
        "map",
        lambda w: ["map", "--method", "openreloc", "--scene", str(w.scene), "--out", str(w.tmp / "m"), "--set", "segmenter=bogus"],
        "unknown segmenter 'bogus'",
    ),
    "localize: an option the encoder does not take": (
        "localize",
        lambda w: ["localize", "--method", "goreloc", "--map", str(w.map_dir), "--scene", str(w.scene), "--out", str(w.tmp / "p.txt"), "--set", "encoder_options={size: 3}"],
        "encoder 'offline': got an unexpected keyword argument 'size'",
    ),
    "agent: a negative seed": ("agent", lambda w: ["agent", "ActiveReloc-v0", "--seed", "-1"], "--seed must be at least 0"),
    "agent: --out under a regular file": (
        "agent",
        lambda w: ["agent", "ActiveReloc-v0", "--out", str(w.inputs / "file.txt" / "episodes.csv")],
        "cannot write in",
    ),
    "score: a pose file of another track than --track": (
        "score",
        lambda w: [
            "score", str(submission(w, "# method m, track oracle-mask\n")), "--data", str(w.data),
            "--track", "predicted", "--out", str(w.tmp / "scores"),
        ],
        "records track 'oracle-mask' in its header but --track is predicted",
    ),
    "score: pose files of two tracks": (
        "score",
        lambda w: [
            "score", str(submission(w, "# track predicted\n", also="sB.txt", also_content="# track oracle-mask\n")),
            "--data", str(w.data), "--out", str(w.tmp / "scores"),
        ],
        "its files record different tracks",
    ),
    "import 7scenes: a TUM RGB-D sequence": (
        "import",
        lambda w: ["import", "7scenes", str(write_tum_sequence(w.inputs / "fr1", n=3)), "--out", str(w.tmp / "imp")],
        "it looks like a TUM RGB-D sequence (`import tum`)",
    ),
    "import 7scenes: its sequences still zipped": (
        "import",
        lambda w: ["import", "7scenes", str(zipped_7scenes(w)), "--out", str(w.tmp / "imp")],
        "it holds TestSplit.txt, TrainSplit.txt, seq-01.zip (unpack the .zip files first)",
    ),
    "import 7scenes --protocol splits: TestSplit.txt names a missing sequence": (
        "import",
        lambda w: ["import", "7scenes", str(seven_scenes(w, test_split="sequence9\n")), "--protocol", "splits", "--out", str(w.tmp / "imp")],
        "seq-09: no such sequence; the scene has seq-01, seq-02",
    ),
    "import 12scenes --protocol splits: no split.txt": (
        "import",
        lambda w: ["import", "12scenes", str(twelve_scenes_without_split(w)), "--protocol", "splits", "--out", str(w.tmp / "imp")],
        "split.txt: file not found",
    ),
    "import tum: --max-depth 0": (
        "import",
        lambda w: ["import", "tum", str(write_tum_sequence(w.inputs / "fr1", n=3)), "--max-depth", "0", "--out", str(w.tmp / "imp")],
        "--max-depth must be in (0, 65.534] metres, got 0.0",
    ),
    "diagnose --scenes: one scene twice": (
        "diagnose",
        lambda w: ["diagnose", "--scenes", f"{w.scene},{w.scene}/", "--work", str(w.tmp / "work")],
        "--scenes names sA twice: each scene would count twice in the pooled numbers",
    ),
    "train-encoder: --threads 0": (
        "train-encoder",
        lambda w: ["train-encoder", "--out", str(w.tmp / "enc"), "--threads", "0"],
        "--threads must be >= 1",
    ),
    "train-encoder: --out the scenes of --data": (
        "train-encoder",
        lambda w: ["train-encoder", "--out", str(w.data), "--data", str(w.data)],
        "overlaps the input",
    ),
}  # fmt: skip


SUITE_SCENE = "  - {{name: {name}, seed: 3, width: 32, height: 24, n_query: 2, max_mapping_frames: 2, displaced_share: 0.0, objects_per_room: 4{extra}}}\n"


def seven_scenes(w: World, test_split: str) -> Path:
    """A 7-Scenes scene of two short sequences whose ``TestSplit.txt`` holds ``test_split``."""
    root = write_7scenes_scene(w.inputs / "chess", n_sequences=2, n=3)
    (root / "TestSplit.txt").write_text(test_split)
    return root


def zipped_7scenes(w: World) -> Path:
    """A 7-Scenes scene as its download unpacks: the split files and one zip per sequence."""
    root = w.inputs / "chess"
    root.mkdir()
    for name, text in (("TrainSplit.txt", "sequence1\n"), ("TestSplit.txt", "sequence1\n"), ("seq-01.zip", "PK")):
        (root / name).write_text(text)
    return root


def twelve_scenes_without_split(w: World) -> Path:
    root = write_12scenes_scene(w.inputs / "apt1_kitchen", n=3, n_test=1)
    (root / "split.txt").unlink()
    return root


def suite_file(w: World, extra: str = "", name: str = "s1", at: str = "suite.yaml") -> Path:
    """A one-scene suite (``extra``: one more key of the scene, given inline)."""
    p = w.inputs / at
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_text("scenes:\n" + SUITE_SCENE.format(name=name, extra=f", {extra}" if extra else ""))
    return p


def damaged(w: World, name: str, content: bytes) -> Path:
    """A copy of scene sA under the inputs with one file replaced."""
    copy = w.inputs / "data" / "sA"
    shutil.copytree(w.scene, copy)
    (copy / name).write_bytes(content)
    return copy


HEADER_ONLY = ",".join(BOARD_INPUT_COLUMNS).encode() + b"\n"
"""A well-formed per-query table of no query."""


def results_with(w: World, queries_csv: bytes) -> Path:
    """A results folder whose tables/queries.csv holds ``queries_csv``."""
    r = w.inputs / "results"
    (r / "tables").mkdir(parents=True, exist_ok=True)
    (r / "tables" / "queries.csv").write_bytes(queries_csv)
    return r


def eval_results(w: World) -> Path:
    """A folder laid out as an evaluation's results: finished runs and their tables."""
    r = results_with(w, HEADER_ONLY)
    (r / "runs").mkdir(exist_ok=True)
    return r


def submission(w: World, content: str | bytes, also: str = "", also_content: str | bytes | None = None) -> Path:
    """A submission folder with ``sA.txt`` (and ``also``) holding ``content`` (``also_content`` for ``also``)."""
    sub = w.inputs / "submission"
    sub.mkdir(exist_ok=True)
    for name, text in (("sA.txt", content), (also, content if also_content is None else also_content)):
        if name:
            (sub / name).parent.mkdir(parents=True, exist_ok=True)
            (sub / name).write_bytes(text.encode() if isinstance(text, str) else text)
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
    marker = world.tmp / "res" / "runs" / "nearest-frame" / "mask-free" / "sA" / "query.done.json"
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


def test_runs_with_other_settings_are_never_pooled_into_one_row(world: World, capsys) -> None:
    assert run(eval_argv(world, scenes="sA"), capsys)[0] == 0
    cfg = write_input(world, "cfg.yaml", b"thumb_size: 8\n")
    other = ["--method-config", f"nearest-frame={cfg}"]
    for extra in ([], ["--resume"]):
        code, _, err = run(eval_argv(world, *other, *extra, scenes="sB"), capsys)
        one_line_error(
            code, err, "eval", "holds a run of 'nearest-frame' (mask-free) on sA/query made with other settings"
        )
    assert run(eval_argv(world, *other, "--resume", scenes="sA,sB"), capsys)[0] == 0  # redoing sA pools nothing


def test_a_relative_out_redoing_the_same_scene_with_other_settings_is_not_refused(
    world: World, capsys, monkeypatch
) -> None:
    """Retuning a method and rerunning the same scene into a relative --out redoes the run (the finished
    run's marker and the planned one are the same file, however --out is spelled)."""
    monkeypatch.chdir(world.tmp)
    argv = ["eval", "--scenes", "sA", "--methods", "nearest-frame", "--data", str(world.data), "--out", "res"]
    assert run(argv, capsys)[0] == 0
    cfg = write_input(world, "cfg.yaml", b"thumb_size: 8\n")
    code, out, _ = run([*argv, "--method-config", f"nearest-frame={cfg}"], capsys)
    assert code == 0 and "jobs: 1 run" in out, out


def test_the_oracle_mask_track_refuses_frames_without_instance_images(world: World, capsys) -> None:
    """A missing instance image was a method's failure (query) or an unmasked frame (mapping), exit 0."""
    (world.scene / "mapping" / "instance" / "000001.png").unlink()
    (world.scene / "query" / "instance" / "000002.png").unlink()
    cases = [
        ("map", ["map", "--method", "openreloc", "--scene", str(world.scene), "--out", str(world.tmp / "m"), "--track", "oracle-mask"], "mapping"),
        ("eval", eval_argv(world, "--track", "oracle-mask", methods="openreloc"), "mapping"),
        ("localize", ["localize", "--method", "openreloc", "--map", str(world.map_dir), "--scene", str(world.scene), "--out", str(world.tmp / "p.txt"), "--track", "oracle-mask"], "query"),
    ]  # fmt: skip
    for command, argv, split in cases:
        code, _, err = run(argv, capsys)
        one_line_error(code, err, command, f"{split}: 1 of ")
        assert "have no instance image" in err and "use --track predicted" in err
    assert run(eval_argv(world, "--track", "oracle-mask"), capsys)[0] == 0  # nearest-frame reads no masks


def test_a_mask_free_map_for_a_method_reading_masks_advises_no_track_localize_lacks(world: World, capsys) -> None:
    argv = ["localize", "--method", "openreloc", "--map", str(world.map_dir), "--scene", str(world.scene)]
    code, _, err = run([*argv, "--out", str(world.tmp / "p.txt"), "--track", "oracle-mask"], capsys)
    one_line_error(code, err, "localize", "is a map of the mask-free track, not of the oracle-mask track: build a map")
    assert "--track mask-free" not in err


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
    out = world.tmp / "res" / "runs" / "test-oracle" / "predicted" / "sA"  # the default track
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


def test_diagnostics_that_json_cannot_hold_are_written_as_standard_json(world: World, capsys) -> None:
    oracle_map, diag = world.tmp / "oracle-map", world.tmp / "diag.jsonl"
    assert (
        run(["map", "--method", "test-oracle", *PLUGIN, "--scene", str(world.scene), "--out", str(oracle_map)], capsys)[
            0
        ]
        == 0
    )
    argv = ["localize", "--method", "test-oracle", *PLUGIN, "--set", "odd_diagnostics=true", "--map", str(oracle_map)]
    argv += ["--scene", str(world.scene), "--out", str(world.tmp / "poses.txt"), "--diagnostics", str(diag)]
    assert run(argv, capsys)[0] == 0

    def refuse(constant: str) -> None:
        raise AssertionError(f"{constant} is not JSON")

    lines = [json.loads(line, parse_constant=refuse) for line in diag.read_text().splitlines()]
    assert lines and all(
        ln["diagnostics"] == {"nan": None, "inf": "inf", "set": [1, 2], "array": [None, 1.0]} for ln in lines
    )


@pytest.mark.parametrize("timeout", ["300", "0"])  # the query in a worker process, or in the eval's own
def test_an_unreadable_query_image_is_an_error_of_the_run_not_a_failure(world: World, capsys, timeout: str) -> None:
    img = world.scene / "query" / "color" / "000001.png"
    good = img.read_bytes()
    img.write_bytes(good[:40])
    code, out, err = run(eval_argv(world, "--timeout", timeout, "--resume"), capsys)
    assert code == 1 and "Traceback" not in err, err
    assert "000001.png: unreadable image" in out and "1 errors" in out
    assert not (world.tmp / "res" / "runs" / "nearest-frame" / "mask-free" / "sA" / "query.done.json").exists()
    img.write_bytes(good)
    code, out, _ = run(eval_argv(world, "--timeout", timeout, "--resume"), capsys)
    assert code == 0 and "3 of 3 localized" in out  # resumed: the job runs again, whole


def test_the_battery_leaves_no_stray_files(world: World, capsys) -> None:
    shutil.rmtree(world.tmp / "res", ignore_errors=True)
    assert run(eval_argv(world), capsys)[0] == 0
    assert not list((world.tmp / "res").rglob("*.tmp"))
