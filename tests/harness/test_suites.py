"""Suites on disk: a scene folder that the suite did not generate is never replaced, and the refusal says why."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from openreloc_bench.data.scene import DATA_VERSION
from openreloc_bench.errors import ConfigError
from openreloc_bench.harness.suites import ensure_suite_scenes

SMOKE = Path(__file__).resolve().parents[2] / "scenes" / "smoke.yaml"


@pytest.mark.parametrize(
    ("info", "message"),
    [
        (
            {"generator_version": "0.1.0+gen2"},
            f"generated as benchmark data v1, this openreloc-bench reads v{DATA_VERSION}",
        ),
        ({"generator_version": "0.1.0+gen3", "data_version": DATA_VERSION}, "generated from another spec"),
    ],
)
def test_a_scene_of_another_version_or_spec_is_refused(tmp_path: Path, info: dict, message: str) -> None:
    scene = tmp_path / "smoke-room"
    scene.mkdir()
    (scene / "scene.json").write_text(json.dumps({"spec_hash": "not-this-one", **info}))
    with pytest.raises(ConfigError, match=message):
        ensure_suite_scenes(SMOKE, tmp_path)
    assert json.loads((scene / "scene.json").read_text())["spec_hash"] == "not-this-one"  # left as it was


def test_a_suite_is_a_yaml_or_a_bundled_name(tmp_path: Path, capsys) -> None:
    from openreloc_bench.cli import main
    from openreloc_bench.harness.suites import SUITES_DIR, suite_file

    assert suite_file("smoke") == SUITES_DIR / "smoke.yaml" and suite_file(SUITES_DIR / "demo.yaml").name == "demo.yaml"
    with pytest.raises(ConfigError, match=r"suite 'nope' not found \(a suite YAML, or one of: .*demo.*smoke"):
        suite_file("nope")
    d, r = str(tmp_path / "d"), str(tmp_path / "r")
    for argv in (
        ["eval", "--suite", "nope", "--methods", "nearest-frame", "--data", d, "--out", r],
        ["generate", "nope", "--out", d],
        ["card", "nope", "--data", d, "--out", r],
        ["demo", "--suite", "nope", "--out", r],
    ):
        assert main(argv) == 2 and "suite 'nope' not found" in capsys.readouterr().err, argv[0]
