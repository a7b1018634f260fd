"""The dataset card (``openreloc-bench card``) of a suite of two tiny generated rooms.

Every expectation is counted from the scenes' own files (pose files, ``objects.json``, ``difficulty.csv``),
not from the card's code.
"""

from __future__ import annotations

import argparse
import json
import re
import shutil
from collections import Counter
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml
from PIL import Image

from generators.generate import generate_scene
from generators.spec import load_suite
from openreloc_bench.cli import main
from openreloc_bench.commands import card as card_command
from openreloc_bench.data.scene import DATA_VERSION
from openreloc_bench.errors import ConfigError, DataError, OpenRelocError

TINY = dict(
    width=64,
    height=48,
    objects_per_room=8,
    room_side_min=3.5,
    room_side_max=4.0,
    mapping_step_m=0.5,
    mapping_step_deg=30.0,
    max_mapping_frames=8,
    n_query=2,
    displaced_share=0.2,
    query_min_objects=2,
)
SCENES = ("tiny-a", "tiny-b")


@pytest.fixture(scope="module")
def suite(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """(suite YAML, data directory holding its two generated scenes)."""
    root = tmp_path_factory.mktemp("card")
    path = root / "tiny.yaml"
    path.write_text(
        yaml.safe_dump(
            {
                "name": "tiny",
                "description": "two tiny rooms for the card's tests",
                "defaults": TINY,
                "scenes": [{"name": n, "seed": s} for n, s in zip(SCENES, (5, 9))],
            }
        )
    )
    for spec in load_suite(path).scene_specs():
        generate_scene(spec, root / "data", progress=False)
    return path, root / "data"


def card(argv: list[str]) -> int:
    """The command as the CLI runs it (its own parser; the CLI prints an OpenRelocError as one line)."""
    parser = argparse.ArgumentParser()
    card_command.add_arguments(parser)
    return card_command.run(parser.parse_args(argv))


@pytest.fixture(scope="module")
def written(suite: tuple[Path, Path], tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    """(output directory, the card's text)."""
    path, data = suite
    out = tmp_path_factory.mktemp("cards")
    assert card([str(path), "--data", str(data), "--out", str(out)]) == 0
    return out, (out / "tiny.md").read_text()


def md_table(text: str, first: str) -> pd.DataFrame:
    """The markdown table whose header starts with column ``first``, as text cells."""
    lines = text.splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith(f"| {first} |"))
    rows = []
    for line in lines[start:]:
        if not line.startswith("|"):
            break
        rows.append([c.strip() for c in re.split(r"(?<!\\)\|", line)[1:-1]])
    return pd.DataFrame(rows[2:], columns=rows[0])


def objects(data: Path, scene: str) -> list[dict]:
    return [o for o in json.loads((data / scene / "objects.json").read_text()) if not o["structural"]]


def test_card_names_the_data_version_and_the_suite(written, suite):
    _, text = written
    version = {json.loads((suite[1] / s / "scene.json").read_text())["data_version"] for s in SCENES}
    assert version == {DATA_VERSION}
    assert f"| Data version | v{DATA_VERSION} |" in text
    assert "| Image size | 64x48 |" in text and "| Purpose | benchmark |" in text
    assert text.startswith("# Dataset card: tiny\n") and "two tiny rooms for the card's tests" in text


def test_scene_table_counts_frames_and_objects_on_disk(written, suite):
    table = md_table(written[1], "scene").set_index("scene")
    assert list(table.index) == [*SCENES, "**total**"]
    splits = ["mapping", "query", "query_near", "query_light1", "query_light2", "query_light3"]
    splits += ["query_light4", "query_displaced", "query_walk"]
    for scene in SCENES:
        for split in splits:
            assert int(table.loc[scene, split]) == len(list((suite[1] / scene / split / "pose").glob("*.txt")))
        objs = objects(suite[1], scene)
        assert int(table.loc[scene, "objects"]) == len(objs)
        assert int(table.loc[scene, "categories"]) == len({o["category"] for o in objs})
    assert int(table.loc["**total**", "mapping"]) == sum(int(table.loc[s, "mapping"]) for s in SCENES)


def test_categories_are_counted_over_the_suite_most_first(written, suite):
    table = md_table(written[1], "category")
    expected = Counter(o["category"] for s in SCENES for o in objects(suite[1], s))
    assert dict(zip(table["category"], table["instances"].astype(int))) == dict(expected)
    counts = table["instances"].astype(int).tolist()
    assert counts == sorted(counts, reverse=True)
    in_scenes = {c: sum(any(o["category"] == c for o in objects(suite[1], s)) for s in SCENES) for c in expected}
    assert dict(zip(table["category"], table["scenes"].astype(int))) == in_scenes


def test_lookalike_groups_are_the_twins_of_each_scene(written, suite):
    twins: Counter[tuple] = Counter()  # (category, description, attributes, scene) -> instances, when > 1
    for s in SCENES:
        attrs = (", ".join(f"{k}={v}" for k, v in sorted(o["attributes"].items())) for o in objects(suite[1], s))
        models = Counter((o["category"], o["description"], a) for o, a in zip(objects(suite[1], s), attrs))
        twins.update({(*m, s): n for m, n in models.items() if n > 1})
    assert twins, "the tiny rooms should hold a twin for this test to mean something"
    table = md_table(written[1].split("## Look-alike groups")[1], "category")
    assert table["instances"].astype(int).sum() == sum(twins.values())
    for (cat, desc, attrs, scene), n in twins.items():
        row = table[(table["category"] == cat) & (table["description"] == desc) & (table["attributes"] == attrs)]
        assert f"{scene} ({n})" in row["scenes"].iloc[0]


def test_difficulty_percentiles_come_from_the_csv(written, suite):
    table = md_table(written[1], "axis")
    csv = pd.concat(pd.read_csv(suite[1] / s / "difficulty.csv") for s in SCENES)
    axes = (
        ("gap_m", "query"),
        ("gap_deg", "query_near"),
        ("gap_m", "query_walk"),
        ("displaced_in_view", "query_displaced"),
    )
    for axis, split in axes:
        row = table[(table["axis"] == axis) & (table["split"] == split)].iloc[0]
        values = csv.loc[csv["split"] == split, axis]
        assert int(row["frames"]) == len(values)
        assert float(row["median"]) == pytest.approx(np.median(values), rel=5e-3, abs=1e-9)
        assert float(row["max"]) == pytest.approx(values.max(), rel=5e-3)
    assert set(table.loc[table["axis"] == "light_level", "split"]) == set(csv["split"])


def test_card_writes_every_picture_it_links_and_nothing_else(written):
    out, text = written
    links = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", text)
    assert {f"tiny/{s}_{kind}.png" for s in SCENES for kind in ("frames", "plan")} | {"tiny/difficulty.png"} == set(
        links
    )
    for link in links:
        with Image.open(out / link) as im:
            assert im.format == "PNG" and im.width >= 64
    assert {p.relative_to(out).as_posix() for p in (out / "tiny").iterdir()} == set(links)
    assert sum((out / link).stat().st_size for link in links) < 1_500_000


def test_same_data_gives_the_same_bytes(written, suite, tmp_path):
    out, _ = written
    assert card([str(suite[0]), "--data", str(suite[1]), "--out", str(tmp_path)]) == 0
    files = sorted(p.relative_to(out) for p in out.rglob("*") if p.is_file())
    assert files == sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*") if p.is_file())
    for f in files:
        assert (out / f).read_bytes() == (tmp_path / f).read_bytes(), f


def copy_data(suite: tuple[Path, Path], tmp_path: Path) -> Path:
    data = tmp_path / "data"
    shutil.copytree(suite[1], data)
    return data


def set_version(scene: Path, version: int) -> None:
    info = json.loads((scene / "scene.json").read_text())
    info["data_version"] = version
    (scene / "scene.json").write_text(json.dumps(info))


def refusal(argv: list[str], kind: type[OpenRelocError] = DataError) -> str:
    """The one-line message the command refuses ``argv`` with; nothing is written."""
    with pytest.raises(kind) as e:
        card(argv)
    assert "\n" not in str(e.value)
    return str(e.value)


def test_refuses_scenes_of_mixed_data_versions(suite, tmp_path):
    data = copy_data(suite, tmp_path)
    set_version(data / "tiny-b", 1)
    msg = refusal([str(suite[0]), "--data", str(data), "--out", str(tmp_path / "out")])
    assert "mixed" in msg and "v1: tiny-b" in msg and f"v{DATA_VERSION}: tiny-a" in msg
    assert not (tmp_path / "out").exists()


def test_refuses_an_older_data_version(suite, tmp_path):
    data = copy_data(suite, tmp_path)
    for s in SCENES:
        set_version(data / s, 1)
    assert "benchmark data v1" in refusal([str(suite[0]), "--data", str(data), "--out", str(tmp_path / "out")])


def test_refuses_a_missing_scene(suite, tmp_path):
    data = copy_data(suite, tmp_path)
    shutil.rmtree(data / "tiny-b")
    msg = refusal([str(suite[0]), "--data", str(data), "--out", str(tmp_path / "out")])
    assert "tiny-b" in msg and "not generated" in msg
    assert not (tmp_path / "out").exists()


def test_refuses_an_incomplete_scene(suite, tmp_path):
    data = copy_data(suite, tmp_path)
    next((data / "tiny-a" / "query" / "pose").glob("*.txt")).unlink()
    assert "incomplete" in refusal([str(suite[0]), "--data", str(data), "--out", str(tmp_path / "out")])


def test_refuses_bad_paths(suite, tmp_path):
    out = str(tmp_path / "out")
    assert "nope.yaml' not found" in refusal(
        [str(tmp_path / "nope.yaml"), "--data", str(suite[1]), "--out", out], ConfigError
    )
    assert "data directory not found" in refusal([str(suite[0]), "--data", str(tmp_path / "nodata"), "--out", out])
    inside = str(suite[1] / "cards")
    assert "overlaps the input" in refusal([str(suite[0]), "--data", str(suite[1]), "--out", inside], ConfigError)


def test_cli_refuses_in_one_line_without_traceback(suite, tmp_path, capsys):
    data = copy_data(suite, tmp_path)
    shutil.rmtree(data / "tiny-a")
    assert main(["card", str(suite[0]), "--data", str(data), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("openreloc-bench card: error: ") and "tiny-a" in err and err.count("\n") == 1
