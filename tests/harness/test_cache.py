"""The one map builder and the map cache: what a map records it was built from, reuse, failed builds."""

from __future__ import annotations

from pathlib import Path

import pytest

from baselines.nearest_frame import NearestFrame
from openreloc_bench.cli import main
from openreloc_bench.data import io, mapfile
from openreloc_bench.data.scene import Scene
from openreloc_bench.errors import ConfigError, PluginError
from openreloc_bench.harness import cache
from openreloc_bench.harness.runner import EvalConfig, MethodRun, evaluate
from openreloc_bench.methods import create_method
from openreloc_bench.plugins import load_plugin
from openreloc_bench.tracks import MASK_FREE, ORACLE_MASK, PREDICTED
from tests.conftest import FREE_PLUGIN, write_tiny_scene


class Masked(NearestFrame):
    """nearest-frame reading the masks it is given: the track decides whether its frames carry them."""

    seen: list[bool] = []

    def build_map(self, mapping, map_dir: Path) -> None:
        Masked.seen = [f.instance is not None for f in mapping]
        super().build_map(mapping, map_dir)


@pytest.mark.parametrize(("track", "masks"), [(ORACLE_MASK, True), (PREDICTED, False)])
def test_a_cached_map_records_what_it_was_built_from_beside_its_files(tmp_path: Path, track: str, masks: bool) -> None:
    scene = Scene(write_tiny_scene(tmp_path / "tiny"))
    map_dir = tmp_path / "maps" / "m" / "key" / scene.name
    rec = cache.cached_map(Masked(thumb_size=8), scene, track, map_dir, {"method": "m"})
    assert Masked.seen == [masks] * 6
    source = {"scene": "tiny", "spec_hash": "tiny-0", "track": track}
    assert rec["built_from"] == io.read_json(cache.map_marker(map_dir))["built_from"] == source
    assert rec["method"] == "m" and rec["n_mapping_frames"] == 6 and rec["map_bytes"] == cache.dir_bytes(map_dir)
    assert mapfile.recorded_source(map_dir) is None  # the method's files are what it wrote
    assert cache.map_source(map_dir) == source
    marker = cache.map_marker(map_dir).stat().st_mtime_ns
    assert cache.cached_map(Masked(thumb_size=8), scene, track, map_dir, {"method": "m"}) == rec  # reused
    assert cache.map_marker(map_dir).stat().st_mtime_ns == marker


class Broken(NearestFrame):
    def build_map(self, mapping, map_dir: Path) -> None:
        (map_dir / "part.bin").write_bytes(b"half a map")
        (map_dir / "sub").mkdir()
        raise RuntimeError("boom")


def test_a_failed_build_leaves_an_empty_folder_and_no_record(tmp_path: Path) -> None:
    scene = Scene(write_tiny_scene(tmp_path / "tiny"))
    map_dir = tmp_path / "maps" / "tiny"
    with pytest.raises(PluginError, match="build_map raised at test_cache.py line .*: RuntimeError: boom"):
        cache.cached_map(Broken(), scene, PREDICTED, map_dir, {})  # a method from outside the package
    assert not any(map_dir.iterdir()) and not cache.map_marker(map_dir).exists()


def test_check_map_source_refuses_a_cached_map_of_another_scene_or_track(tmp_path: Path) -> None:
    mapped = Scene(write_tiny_scene(tmp_path / "a", seed=0))
    other = Scene(write_tiny_scene(tmp_path / "b", seed=1))
    map_dir = tmp_path / "maps" / "a"
    cache.cached_map(Masked(thumb_size=8), mapped, PREDICTED, map_dir, {})
    cache.check_map_source(map_dir, mapped, PREDICTED)
    with pytest.raises(ConfigError, match="map of scene 'a' .*tiny-0.*not of .*tiny-1"):
        cache.check_map_source(map_dir, other)
    with pytest.raises(ConfigError, match="map of the predicted track, not of the oracle-mask track"):
        cache.check_map_source(map_dir, mapped, ORACLE_MASK)


def test_localize_refuses_an_eval_map_of_another_scene(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    data = tmp_path / "data"
    write_tiny_scene(data / "a", seed=0)
    write_tiny_scene(data / "b", seed=1)
    run = MethodRun("nearest-frame", "nearest-frame", {"thumb_size": 8})
    assert evaluate(EvalConfig(data=data, out=tmp_path / "r", scenes=["a"], runs=[run], timeout_s=0)).errors == []
    map_dir = next((tmp_path / "r" / "maps" / "nearest-frame").glob("*/a"))
    assert cache.map_source(map_dir) == {"scene": "a", "spec_hash": "tiny-0", "track": MASK_FREE}
    args = ["localize", "--method", "nearest-frame", "--set", "thumb_size=8", "--map", str(map_dir)]
    out = tmp_path / "poses.txt"
    capsys.readouterr()
    assert main([*args, "--scene", str(data / "b"), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert "map of scene 'a'" in err and "tiny-1" in err and "\n" not in err and not out.exists()
    assert main([*args, "--scene", str(data / "a"), "--out", str(out)]) == 0


def test_the_code_version_is_the_last_commit_that_changed_the_code(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, request: pytest.FixtureRequest
) -> None:
    import subprocess

    request.addfinalizer(cache.git_commit.cache_clear)  # the version of this repository, not the test's

    def git(*args: str) -> str:
        return subprocess.run(["git", *args], cwd=tmp_path, check=True, capture_output=True, text=True).stdout.strip()

    def commit(path: str, text: str) -> str:
        (tmp_path / path).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / path).write_text(text)
        git("add", "-A")
        git("-c", "user.name=t", "-c", "user.email=t@t", "commit", "-qm", path)
        return git("rev-parse", "HEAD")

    def version() -> str:
        cache.git_commit.cache_clear()
        return cache.git_commit()

    git("init", "-q")
    monkeypatch.setattr(cache, "REPO_ROOT", tmp_path)
    code = commit("openreloc_bench/method.py", "a = 1\n")
    assert version() == code
    commit("leaderboard/multi-room/leaderboard.md", "results\n")
    commit("openreloc_bench/harness/leaderboard/pages.py", "drawing = 1\n")  # draws boards: no number changes
    assert version() == code
    (tmp_path / "openreloc_bench/method.py").write_text("a = 2\n")
    assert version() == code + "-dirty"
    changed = commit("openreloc_bench/method.py", "a = 2\n")
    assert version() == changed != code


def test_a_plugins_maps_are_keyed_by_its_code_this_packages_by_config(plugin_sandbox: Path) -> None:
    built_in = create_method("nearest-frame")
    assert cache.foreign_code(built_in) is None  # versioned by the git commit every result records
    plugin = plugin_sandbox / "free_plugin.py"
    plugin.write_text(FREE_PLUGIN)
    load_plugin(str(plugin))
    method = create_method("free-plugin")
    before = cache.map_key(method, MASK_FREE)
    assert cache.foreign_code(method) is not None and cache.map_key(method, MASK_FREE) == before
    plugin.write_text(FREE_PLUGIN + "\n# build_map changed\n")
    assert cache.map_key(method, MASK_FREE) != before  # an edited plugin's maps are rebuilt, not reused
