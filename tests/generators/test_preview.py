"""Preview pictures of a generated scene (through the CLI) and the floor plan's parts and legend."""

from __future__ import annotations

import shutil
from dataclasses import asdict
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from generators.generate import generate_scene
from generators.preview import draw_floor, floor_index, floor_plan, plan_extent
from generators.spec import SceneSpec
from openreloc_bench.cli import main
from openreloc_bench.data import io
from openreloc_bench.data.scene import ObjectInfo, Scene
from tests.conftest import write_tiny_scene


def test_preview_cli(tmp_path: Path) -> None:
    scene = generate_scene(
        SceneSpec(
            name="p",
            seed=2,
            width=64,
            height=48,
            objects_per_room=8,
            max_mapping_frames=6,
            n_query=2,
            displaced_share=0.2,
            query_min_objects=1,  # few of its 8 objects fill 0.5% of a 64x48 frame seen from the mapping path
        ),
        tmp_path,
        progress=False,
    )
    out = tmp_path / "pics" / "sheet.png"
    assert main(["preview", str(scene), "--out", str(out), "--frames", "2"]) == 0
    for p in (out, out.with_name("sheet_plan.png")):
        img = io.read_rgb(p)
        assert img.shape[0] > 200 and img.shape[1] > 200
        assert np.unique(img.reshape(-1, 3), axis=0).shape[0] > 50  # not blank


def test_preview_missing_scene(tmp_path: Path, capsys) -> None:
    assert main(["preview", str(tmp_path / "nope")]) != 0
    assert "scene directory not found" in capsys.readouterr().err


def write_plan_scene(root: Path) -> Scene:
    """A tiny scene (no rendering) whose scene.json and objects.json hold a plan: two rooms on one floor,
    walls, a door, two objects, one of them moved in query_displaced."""
    write_tiny_scene(root)
    info = io.read_json(root / "scene.json")
    info["floors"] = [{"index": 0, "z": 0.0}]
    info["rooms"] = [
        {"name": "kitchen_0", "kind": "kitchen", "floor": 0, "rect": [-4.0, -4.0, 0.0, 4.0]},
        {"name": "office_0", "kind": "office", "floor": 0, "rect": [0.0, -4.0, 4.0, 4.0]},
    ]
    io.write_json(root / "scene.json", info)
    objects = [
        ObjectInfo(1, "box", aabb=[[-0.5, -0.5, 0.0], [0.5, 0.5, 1.0]]),
        ObjectInfo(2, "chair", aabb=[[2.0, 2.0, 0.0], [2.5, 2.5, 0.9]]),
        ObjectInfo(3, "wall", structural=True, aabb=[[-4.0, 4.0, 0.0], [4.0, 4.1, 2.5]]),
        ObjectInfo(4, "door", structural=True, aabb=[[-0.1, -1.0, 0.0], [0.1, 0.0, 2.0]]),
        ObjectInfo(5, "floor", structural=True, aabb=[[-4.0, -4.0, -0.1], [4.0, 4.0, 0.0]]),
    ]
    io.write_json(root / "objects.json", [asdict(o) for o in objects])
    (root / "query_displaced").mkdir()
    io.write_json(
        root / "query_displaced" / "displacements.json", [{"id": 2, "aabb_after": [[3, 3, 0], [3.5, 3.5, 0.9]]}]
    )
    return Scene(root)


def test_the_floor_plan_legend_names_everything_drawn(tmp_path: Path) -> None:
    scene = write_plan_scene(tmp_path / "plan")
    fig, ax = plt.subplots()
    labels = [h.get_label() for h in draw_floor(ax, scene, 0)]
    assert labels == [
        "room: kitchen",
        "room: office",
        "walls",
        "doors",
        "objects (2)",
        "changed objects, before (1)",
        "changed objects, after (query_displaced)",
    ]
    assert len(ax.patches) == 2 + 1 + 1 + 2 + 1  # rooms, wall, door, objects, the moved one's new place
    _, ax = plt.subplots()
    assert "changed objects, before (1)" not in [h.get_label() for h in draw_floor(ax, scene, 0, displaced=False)]
    plt.close("all")
    lo, hi = plan_extent(scene)
    assert lo.tolist() == [-4.0, -4.0] and hi.tolist() == [4.0, 4.0]
    fig = floor_plan(scene)
    legend = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert legend[:3] == ["room: kitchen", "room: office", "walls"]
    assert legend[-2:] == ["mapping cameras (6)", "query cameras (3)"]
    assert len(fig.axes[0].get_lines()) == 1  # the mapping path
    plt.close(fig)
    shutil.copytree(tmp_path / "plan" / "query", tmp_path / "plan" / "query_walk")
    fig = floor_plan(Scene(tmp_path / "plan"))
    legend = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert legend[-3:] == ["mapping cameras (6)", "query_walk cameras (3)", "query cameras (3)"]
    assert len(fig.axes[0].get_lines()) == 2  # the mapping path and the walk's
    plt.close(fig)


def test_floors_by_height(tmp_path: Path) -> None:
    scene = write_plan_scene(tmp_path / "plan")
    scene.info["floors"] = [{"index": 0, "z": 0.0}, {"index": 1, "z": 3.0}]
    assert floor_index(scene, np.array([-0.5, 1.5, 3.0, 9.0])).tolist() == [0, 0, 1, 1]
