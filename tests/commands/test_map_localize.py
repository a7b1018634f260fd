"""`openreloc-bench map` / `localize`: generic over methods, --set parsing, per-query failures."""

from __future__ import annotations

from pathlib import Path

import pytest

from baselines.nearest_frame import NearestFrame
from openreloc_bench.cli import main
from openreloc_bench.config import parse_overrides
from openreloc_bench.data.results import read_results
from openreloc_bench.errors import ConfigError
from openreloc_bench.methods import Failure, register
from tests.conftest import write_tiny_scene


def test_parse_overrides_nests_dotted_keys_and_parses_yaml() -> None:
    assert parse_overrides(["a.b=1", "a.c=x", "d=true", "e=[1, 2]"]) == {
        "a": {"b": 1, "c": "x"},
        "d": True,
        "e": [1, 2],
    }
    with pytest.raises(ConfigError):
        parse_overrides(["novalue"])


def test_map_then_localize_nearest_frame(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    scene = write_tiny_scene(tmp_path / "tiny")
    assert (
        main(
            [
                "map",
                "--method",
                "nearest-frame",
                "--scene",
                str(scene),
                "--out",
                str(tmp_path / "m"),
                "--set",
                "thumb_size=8",
            ]
        )
        == 0
    )
    assert "MB" in capsys.readouterr().out
    out = tmp_path / "poses.txt"
    assert (
        main(
            [
                "localize",
                "--method",
                "nearest-frame",
                "--set",
                "thumb_size=8",
                "--map",
                str(tmp_path / "m"),
                "--scene",
                str(scene),
                "--out",
                str(out),
                "--diagnostics",
                str(tmp_path / "d.jsonl"),
            ]
        )
        == 0
    )
    text = capsys.readouterr().out
    assert "localized 3/3" in text and "recall@50cm" in text
    assert sorted(read_results(out)) == ["query/000000", "query/000001", "query/000002"]
    assert len((tmp_path / "d.jsonl").read_text().splitlines()) == 3


class Flaky(NearestFrame):
    """Raises on one query and fails another: neither may stop the run."""

    name = "flaky"

    def localize(self, query):  # type: ignore[override]
        if query.name.endswith("0"):
            raise RuntimeError("boom")
        if query.name.endswith("1"):
            return Failure("too few objects")
        return super().localize(query)


def test_per_query_failures_do_not_stop_localize(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    register("flaky", Flaky)
    scene = write_tiny_scene(tmp_path / "tiny")
    assert main(["map", "--method", "flaky", "--scene", str(scene), "--out", str(tmp_path / "m")]) == 0
    out = tmp_path / "poses.txt"
    assert (
        main(
            [
                "localize",
                "--method",
                "flaky",
                "--map",
                str(tmp_path / "m"),
                "--scene",
                str(scene),
                "--out",
                str(out),
                "--track",
                "predicted",
            ]
        )
        == 0
    )
    text = capsys.readouterr().out
    assert "localized 1/3" in text and "raised RuntimeError: boom" in text and "too few objects" in text
    assert list(read_results(out)) == ["query/000002"]


def test_unknown_method_and_bad_set_are_one_line_errors(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    scene = write_tiny_scene(tmp_path / "tiny")
    assert main(["map", "--method", "nope", "--scene", str(scene), "--out", str(tmp_path / "m")]) == 2
    assert (
        main(
            [
                "map",
                "--method",
                "nearest-frame",
                "--scene",
                str(scene),
                "--out",
                str(tmp_path / "m"),
                "--set",
                "bogus=1",
            ]
        )
        == 2
    )
    assert "bogus" in capsys.readouterr().err


def test_a_map_of_another_scene_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    """Poses against another scene's map would be in that scene's frame: refused, naming both."""
    mapped, other = write_tiny_scene(tmp_path / "a", seed=0), write_tiny_scene(tmp_path / "b", seed=1)
    common = ["--method", "nearest-frame", "--set", "thumb_size=8"]
    assert main(["map", *common, "--scene", str(mapped), "--out", str(tmp_path / "m")]) == 0
    out = tmp_path / "poses.txt"
    args = ["localize", *common, "--map", str(tmp_path / "m"), "--out", str(out), "--scene"]
    assert main([*args, str(other)]) == 2
    err = capsys.readouterr().err.strip()
    assert "map of scene 'a'" in err and "tiny-1" in err and "\n" not in err and not out.exists()
    assert main([*args, str(mapped)]) == 0


class Masked(NearestFrame):
    """nearest-frame declaring it reads masks (the default), so that the track decides what it gets."""

    name = "masked"
    uses_masks = True


@pytest.mark.parametrize(("method", "built"), [("nearest-frame", "mask-free"), ("masked", "predicted")])
def test_map_records_its_track_and_localize_refuses_another(
    tmp_path: Path, capsys: pytest.CaptureFixture, method: str, built: str
) -> None:
    register("masked", Masked)
    scene = write_tiny_scene(tmp_path / "tiny")
    assert main(["map", "--method", method, "--scene", str(scene), "--out", str(tmp_path / "m")]) == 0
    assert f"({built} track)" in capsys.readouterr().out  # the default track, unless the method reads no masks
    out = tmp_path / "poses.txt"
    args = ["localize", "--method", method, "--map", str(tmp_path / "m"), "--scene", str(scene), "--out", str(out)]
    assert main([*args, "--track", "oracle-mask"]) == (0 if built == "mask-free" else 2)
    err = capsys.readouterr().err.strip()
    if built != "mask-free":
        assert "is a map of the predicted track, not of the oracle-mask track" in err and "\n" not in err
    assert main(args) == 0
    assert f"# track {built}" in out.read_text()


def test_localize_draws_each_query_it_was_asked_about(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    scene = write_tiny_scene(tmp_path / "tiny")
    assert main(["map", "--method", "nearest-frame", "--scene", str(scene), "--out", str(tmp_path / "m")]) == 0
    argv = ["localize", "--method", "nearest-frame", "--map", str(tmp_path / "m"), "--scene", str(scene)]
    assert main([*argv, "--out", str(tmp_path / "p.txt"), "--draw", str(tmp_path / "seen")]) == 0
    assert "3 pictures of what nearest-frame matched in" in capsys.readouterr().out
    pictures = sorted(p.name for p in (tmp_path / "seen").iterdir())
    assert pictures == ["query_000000.png", "query_000001.png", "query_000002.png"]
    assert main([*argv, "--out", str(tmp_path / "q.txt"), "--draw", str(scene)]) == 2  # never into an input
