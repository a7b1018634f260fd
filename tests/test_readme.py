"""README's "Adding a method" example, run as written: saved as ``hist_nn.py`` and evaluated through the CLI."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pandas as pd
import pytest

from openreloc_bench.cli import main
from tests.conftest import write_tiny_scene

README = Path(__file__).resolve().parents[1] / "README.md"


def example_method() -> str:
    """The first Python block of the README's "Adding a method" section."""
    section = README.read_text().split("\n## Adding a method\n", 1)[1].split("\n## ", 1)[0]
    return re.search(r"```python\n(.*?)```", section, re.S).group(1)


@pytest.fixture
def hist_nn(plugin_sandbox: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """The working folder, holding the README's ``hist_nn.py`` and a tiny scene under ``data/``."""
    (plugin_sandbox / "hist_nn.py").write_text(example_method())
    write_tiny_scene(plugin_sandbox / "data" / "tiny")
    monkeypatch.chdir(plugin_sandbox)
    return plugin_sandbox


def test_the_example_is_a_whole_method_file() -> None:
    code = example_method()
    assert code.startswith("# hist_nn.py") and 'register("hist-nn", HistNN)' in code
    assert "uses_masks = False" in code and "PoseEstimate(" in code and "Failure(" in code


def test_the_example_runs_beside_a_baseline_in_worker_processes(hist_nn: Path, capsys: pytest.CaptureFixture) -> None:
    args = ["eval", "--scenes", "tiny", "--data", "data", "--out", "results", "--plugin", "./hist_nn.py"]
    assert main([*args, "--methods", "hist-nn,nearest-frame", "--workers", "2"]) == 0
    out = " ".join(capsys.readouterr().out.split())
    assert "hist-nn mask-free query" in out and "6 of 6 localized; 0 errors" in out
    q = pd.read_csv(hist_nn / "results" / "tables" / "queries.csv")
    assert set(q.loc[q["method"] == "hist-nn", "track"]) == {"mask-free"}
    done = {p.parts[-4]: json.loads(p.read_text()) for p in (hist_nn / "results" / "runs").glob("*/*/*/*.done.json")}
    assert done["hist-nn"]["method_source"].startswith(f"hist_nn:HistNN in {(hist_nn / 'hist_nn.py').resolve()}")
    assert done["nearest-frame"]["method_source"] == "baselines.nearest_frame:NearestFrame"  # the project's own


def test_the_example_reads_its_settings_and_fails_with_a_reason(hist_nn: Path, capsys: pytest.CaptureFixture) -> None:
    assert main(["config", "hist-nn", "--plugin", "./hist_nn.py"]) == 0
    assert "bins: 8\nmax_distance: 0.5\n" in capsys.readouterr().out
    (hist_nn / "strict.yaml").write_text("max_distance: 0.0\n")
    args = ["eval", "--scenes", "tiny", "--data", "data", "--out", "results", "--plugin", "hist_nn", "--timeout", "0"]
    assert main([*args, "--methods", "hist-nn", "--method-config", "hist-nn=strict.yaml"]) == 0
    q = pd.read_csv(hist_nn / "results" / "tables" / "queries.csv")
    assert not q["success"].any() and q["reason"].str.startswith("closest histogram at ").all()


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["config", "hist-nn", "--set", "bin=8"], r"unknown key 'hist-nn\.bin' \(known: bins, max_distance\)"),
        (["config", "hist-nn", "--set", "bins=abc"], r"'hist-nn\.bins': expected an integer"),
        (["map", "--method", "hist-nn", "--scene", "data/tiny", "--out", "m", "--set", "bin=8"], r"unknown key"),
    ],
)
def test_the_examples_settings_are_checked_before_any_work(
    hist_nn: Path, capsys: pytest.CaptureFixture, argv: list[str], message: str
) -> None:
    assert main([*argv, "--plugin", "./hist_nn.py"]) == 2
    err = capsys.readouterr().err
    assert re.search(message, err) and "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    assert not (hist_nn / "m").exists()


@pytest.mark.parametrize(
    ("bug", "command", "where"),
    [
        ("def __init__(self, **settings):", "config", "its constructor raised at hist_nn.py line"),
        ("def build_map(self, mapping, map_dir):", "map", "build_map raised at hist_nn.py line"),
    ],
)
def test_a_bug_in_the_example_is_one_line_naming_its_file_and_line(
    hist_nn: Path, capsys: pytest.CaptureFixture, bug: str, command: str, where: str
) -> None:
    code = (hist_nn / "hist_nn.py").read_text()
    assert bug in code
    (hist_nn / "hist_nn.py").write_text(code.replace(bug, f"{bug}\n        raise KeyError('oops')", 1))
    line = code.splitlines().index(next(ln for ln in code.splitlines() if bug in ln)) + 2
    argv = ["config", "hist-nn"] if command == "config" else ["map", "--method", "hist-nn", "--scene", "data/tiny"]
    assert (
        main(
            [*argv, "--out", "m", "--plugin", "./hist_nn.py"]
            if command == "map"
            else [*argv, "--plugin", "./hist_nn.py"]
        )
        == 2
    )
    err = capsys.readouterr().err
    assert f"{where} {line}: KeyError: 'oops'" in err and "Traceback" not in err, err
    assert not (hist_nn / "m").exists()  # no empty map folder left behind


def test_the_examples_map_is_rebuilt_into_its_own_folder(hist_nn: Path, capsys: pytest.CaptureFixture) -> None:
    from openreloc_bench.data import mapfile

    argv = ["map", "--method", "hist-nn", "--scene", "data/tiny", "--out", "m", "--plugin", "./hist_nn.py"]
    assert main(argv) == 0 and main(argv) == 0, capsys.readouterr().err
    assert sorted(p.name for p in (hist_nn / "m").iterdir()) == ["manifest.json", "map.npz"]
    assert mapfile.is_intact(hist_nn / "m") and mapfile.recorded_source(hist_nn / "m")["scene"] == "tiny"
