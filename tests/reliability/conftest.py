"""What the reliability tests share: a world of tiny scenes and a map, and the checks every case makes."""

from __future__ import annotations

import hashlib
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parents[1] / "harness"))  # the test-method plugin, importable by workers
from harness_test_methods import make_scene  # noqa: E402

from openreloc_bench.cli import main  # noqa: E402

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
