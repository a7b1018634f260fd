"""The shared options: ``--plugin`` on every command that names a method, ``--track``'s one default, and
every option's default in ``--help``."""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

import pytest

from openreloc_bench.cli import build_parser, main
from openreloc_bench.envs.base import EnvConfig
from openreloc_bench.harness.diagnose import DiagnoseOptions
from openreloc_bench.harness.runner import EvalConfig
from openreloc_bench.tracks import DEFAULT_TRACK
from tests.conftest import FREE_PLUGIN, write_tiny_scene

PLUGIN_COMMANDS = {
    "eval": ["--scenes", "s", "--methods", "free-plugin", "--data", "d", "--out", "o"],
    "methods": [],
    "config": ["free-plugin"],
    "map": ["--method", "free-plugin", "--scene", "s", "--out", "o"],
    "localize": ["--method", "free-plugin", "--map", "m", "--scene", "s", "--out", "o"],
    "leaderboard": ["r"],
    "agent": ["ActiveReloc-v0", "--method", "free-plugin"],
    "demo": ["--methods", "free-plugin", "--out", "o"],
    "view": ["m", "--method", "free-plugin", "--out", "v.html"],
}
"""Every command taking ``--plugin``, with the rest of a command line it would run."""


def commands() -> dict[str, argparse.ArgumentParser]:
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    return dict(sub.choices)


def test_every_command_that_names_a_method_takes_plugin() -> None:
    names_methods = {
        name
        for name, p in commands().items()
        if {a.dest for a in p._actions} & {"method", "methods"} and name != "score"  # score's --method is a label
    }
    takes_plugin = {name for name, p in commands().items() if "--plugin" in p._option_string_actions}
    assert names_methods <= takes_plugin and takes_plugin == set(PLUGIN_COMMANDS)


@pytest.fixture
def free_plugin(plugin_sandbox: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """The working folder, holding ``free_plugin.py`` (registers ``free-plugin``) and a tiny scene."""
    (plugin_sandbox / "free_plugin.py").write_text(FREE_PLUGIN)
    write_tiny_scene(plugin_sandbox / "data" / "tiny")
    monkeypatch.chdir(plugin_sandbox)
    return plugin_sandbox


@pytest.mark.parametrize(
    ("argv", "expect"),
    [
        (["methods"], "free-plugin"),
        (["config", "free-plugin"], "thumb_size: 32"),
        (["map", "--method", "free-plugin", "--scene", "data/tiny", "--out", "m"], "map of 6 mapping frames"),
        (["localize", "--method", "free-plugin", "--map", "nf", "--scene", "data/tiny", "--out", "p.txt"], "3/3"),
        (["eval", "--scenes", "tiny", "--methods", "free-plugin", "--data", "data", "--out", "r"], "3 of 3 localized"),
    ],
)
@pytest.mark.parametrize("spec", ["./free_plugin.py", "free_plugin"])
def test_commands_find_a_plugin_by_file_or_module_in_the_working_folder(
    free_plugin: Path, capsys: pytest.CaptureFixture, argv: list[str], expect: str, spec: str
) -> None:
    assert main(["map", "--method", "nearest-frame", "--scene", "data/tiny", "--out", "nf"]) == 0  # same format
    capsys.readouterr()
    assert main([*argv, "--plugin", spec, "--timeout", "0"] if argv[0] == "eval" else [*argv, "--plugin", spec]) == 0
    assert expect in capsys.readouterr().out


@pytest.mark.parametrize("command", sorted(PLUGIN_COMMANDS))
@pytest.mark.parametrize(
    ("plugin", "message"),
    [
        ("./missing.py", "plugin ./missing.py: no such file (paths are relative to the working folder"),
        ("raises.py", "plugin raises.py: raises.py line 1: RuntimeError: no licence server"),
        ("nothing", "plugin nothing: registers no method"),
    ],
)
def test_a_bad_plugin_is_a_one_line_error_of_every_command(
    free_plugin: Path, capsys: pytest.CaptureFixture, command: str, plugin: str, message: str
) -> None:
    (free_plugin / "raises.py").write_text("raise RuntimeError('no licence server')\n")
    (free_plugin / "nothing.py").write_text("x = 1\n")
    assert main([command, *PLUGIN_COMMANDS[command], "--plugin", plugin]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"openreloc-bench {command}: error: {message}") and err.count("\n") == 1


def test_the_console_script_finds_a_module_of_the_working_folder(free_plugin: Path) -> None:
    """The console script, unlike ``python -m``, does not put the working folder on the path."""
    exe = Path(sys.executable).with_name("openreloc-bench")
    done = subprocess.run([exe, "methods", "--plugin", "free_plugin"], capture_output=True, text=True, cwd=free_plugin)
    assert done.returncode == 0, done.stderr
    assert "free-plugin" in done.stdout
    bad = subprocess.run([exe, "methods", "--plugin", "raises"], capture_output=True, text=True, cwd=free_plugin)
    assert bad.returncode == 2 and "Traceback" not in bad.stderr and bad.stderr.count("\n") == 1


@pytest.mark.parametrize("name", sorted(commands()))
def test_help_gives_every_default(name: str) -> None:
    """Each option with a default (not off, empty or None) ends its help with it, or names it itself."""
    parser = commands()[name]
    for action in parser._actions:
        d = action.default
        if action.option_strings and not (d is None or d is False or d == argparse.SUPPRESS or d in ("", [])):
            shown = " ".join(parser._get_formatter()._format_action(action).split())
            assert "(default: " in shown, f"{name} {action.option_strings[0]}: no default in its help: {shown}"


@pytest.mark.parametrize("name", ["eval", "localize", "map", "diagnose"])
def test_track_defaults_to_the_one_default_track_and_help_says_so(name: str) -> None:
    parser = commands()[name]
    assert parser.get_default("track") == DEFAULT_TRACK == "predicted"
    assert f"(default: {DEFAULT_TRACK})" in " ".join(parser.format_help().split())


def test_score_takes_the_track_from_the_pose_files_else_the_default_track() -> None:
    help_text = " ".join(commands()["score"].format_help().split())
    assert f"(default: the track the pose files' headers record, else {DEFAULT_TRACK})" in help_text


def test_the_library_defaults_to_the_same_track() -> None:
    assert EnvConfig().track == EvalConfig(Path(), Path(), [], []).track == DiagnoseOptions().track == DEFAULT_TRACK
