"""Scene resolution: a directory as given, a suite's scene generated once into the cache."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from openreloc_bench.envs.scenes import resolve_scene
from openreloc_bench.errors import ConfigError
from tests.envs.conftest import TINY


def test_a_scene_directory_is_used_as_it_is(tiny_room: Path, tmp_path: Path) -> None:
    assert resolve_scene(str(tiny_room), "smoke", tmp_path) == tiny_room
    assert not (tmp_path / "scenes").exists()


def test_a_suite_scene_is_generated_once_into_the_cache(tmp_path: Path) -> None:
    suite = tmp_path / "mini.yaml"
    suite.write_text(
        yaml.safe_dump({"name": "mini", "scenes": [{**TINY, "name": "a"}, {**TINY, "name": "b", "seed": 4}]})
    )
    cache = tmp_path / "cache"
    root = resolve_scene("b", str(suite), cache)
    assert root == cache / "scenes" / "mini" / "b" and (root / "scene.json").is_file()
    assert not (cache / "scenes" / "mini" / "a").exists()  # only the scene asked for
    stamp = (root / "scene.json").stat().st_mtime_ns
    assert resolve_scene("b", str(suite), cache) == root
    assert (root / "scene.json").stat().st_mtime_ns == stamp  # complete: not generated again
    with pytest.raises(ConfigError, match=r"unknown scene 'c'.*\(a, b\)"):
        resolve_scene("c", str(suite), cache)


def test_an_unguarded_script_generating_its_scene_does_not_hang(tmp_path: Path) -> None:
    """Top-level code without a ``__main__`` guard (the README's example as a script) on a cold cache."""
    suite = tmp_path / "mini.yaml"
    suite.write_text(yaml.safe_dump({"name": "mini", "scenes": [TINY]}))
    script = tmp_path / "make.py"
    script.write_text(
        "import gymnasium as gym\n"
        "import openreloc_bench.envs\n"
        f"env = gym.make('openreloc/ActiveReloc-v0', suite={str(suite)!r}, cache_dir={str(tmp_path / 'cache')!r},\n"
        "               method='nearest-frame')\n"
        "print(env.unwrapped.scene.name)\n"
    )
    res = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert res.returncode == 0, res.stderr[-2000:]
    assert res.stdout.strip() == "tiny-room"
    assert (tmp_path / "cache" / "scenes" / "mini" / "tiny-room" / "scene.json").is_file()
