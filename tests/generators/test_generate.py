"""End-to-end generation: format, determinism, ids and depth consistent with objects.json, resume after a kill."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from generators import generate
from generators.generate import generate_scene, generate_suite
from generators.layout import build_layout
from generators.sensor import SensorSpec
from generators.spec import SceneSpec, load_suite, spec_hash
from generators.trajectories import mapping_path, occupancy_grid, sample_walk
from openreloc_bench import config, geometry
from openreloc_bench.data import io
from openreloc_bench.data.scene import DATA_VERSION, DIFFICULTY_COLUMNS, STRUCTURAL_CATEGORIES, Scene
from openreloc_bench.data.splits import QUERY_SPLIT_BY_NAME, QUERY_SPLIT_TABLE, QUERY_SPLITS, SPLITS, WALK
from openreloc_bench.errors import DataError

TINY = dict(
    name="tiny",
    seed=3,
    width=96,
    height=72,
    objects_per_room=12,
    room_side_min=4.0,
    room_side_max=4.5,
    mapping_step_m=0.5,
    mapping_step_deg=30.0,
    max_mapping_frames=12,
    n_query=4,
    displaced_share=0.25,
)
ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def tiny(tmp_path_factory) -> Path:
    return generate_scene(SceneSpec(**TINY), tmp_path_factory.mktemp("a"), progress=False)


@pytest.fixture(scope="module")
def ideal(tmp_path_factory) -> Path:
    """The tiny scene as the noiseless render records it."""
    spec = SceneSpec(**TINY, sensor=SensorSpec(model="ideal"))
    return generate_scene(spec, tmp_path_factory.mktemp("ideal"), progress=False)


def _files(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


def test_layout_on_disk(tiny: Path) -> None:
    scene = Scene(tiny)
    assert scene.splits() == list(SPLITS)
    assert scene.spec_hash == spec_hash(SceneSpec(**TINY))
    assert scene.info["seed"] == 3 and scene.info["rooms"] and scene.info["floors"]
    q = scene.sequence("query")
    assert len(q) == 4 and len(scene.sequence("mapping")) == 12
    assert scene.info["data_version"] == DATA_VERSION
    for split in QUERY_SPLITS:
        seq = scene.sequence(split)
        same = len(seq) == len(q) and np.allclose([r.T_wc for r in seq.records], [r.T_wc for r in q.records])
        assert same == QUERY_SPLIT_BY_NAME[split].shares_query_poses  # query_near and query_walk: their own
        assert np.allclose(seq.K, geometry.intrinsics_from_fov(96, 72, 60.0))
    kinds = sorted(d["kind"] for d in scene.displacements())
    assert len(kinds) == 5 and kinds.count("removed") == 1 and kinds.count("added") == 1  # 3 + 1 + 1 of 12 objects
    assert not list(tiny.rglob("*.tmp"))


def test_structural_flags(tiny: Path) -> None:
    objs = Scene(tiny).objects.values()
    assert all(o.structural == (o.category in STRUCTURAL_CATEGORIES) for o in objs)
    assert sum(not o.structural for o in objs) >= 8
    assert all(o.description for o in objs)


@pytest.mark.parametrize("split", ["mapping", "query", "query_light4", "query_displaced"])
def test_instances_and_depth_match_objects(ideal: Path, split: str) -> None:
    scene = Scene(ideal)
    boxes = {i: o.aabb_array for i, o in scene.objects.items()}
    if split == "query_displaced":
        boxes.update({d["id"]: np.asarray(d["aabb_after"]) for d in scene.displacements()})
    seen = set()
    for frame in scene.sequence(split):
        ids = set(np.unique(frame.instance).tolist()) - {0}
        assert ids <= set(scene.objects), f"unknown instance ids {ids - set(scene.objects)}"
        seen |= ids
        for i in ids:
            pts = geometry.depth_to_points(frame.depth, frame.K, frame.T_wc, frame.instance == i)
            lo, hi = boxes[i]
            inside = np.all((pts >= lo - 0.01) & (pts <= hi + 0.01), axis=1)
            assert inside.mean() > 0.995, (split, frame.name, scene.objects[i].category, inside.mean())
    assert any(not scene.objects[i].structural for i in seen)


def test_query_viewpoints_and_visibility(tiny: Path) -> None:
    scene = Scene(tiny)
    spec = SceneSpec(**TINY)
    mapping = np.array([r.T_wc for r in scene.sequence("mapping").records])
    for rec, info in zip(scene.sequence("query").records, scene.info["query_viewpoints"]):
        d = np.linalg.norm(mapping[:, :3, 3] - rec.T_wc[:3, 3], axis=1)
        assert d.min() >= spec.query_min_distance - 1e-6
        assert abs(d.min() - info["distance_m"]) < 1e-3
        near = d <= 1.0
        if near.any():
            assert geometry.rotation_error(mapping[near], rec.T_wc).min() >= spec.query_min_angle - 1e-6
        assert info["visible_objects"] >= spec.query_min_objects


def test_query_near_lies_on_the_mapping_path(tiny: Path) -> None:
    scene = Scene(tiny)
    mapping = np.array([r.T_wc for r in scene.sequence("mapping").records])
    near = np.array([r.T_wc for r in scene.sequence("query_near").records])
    path, frames = mapping_path(build_layout(SceneSpec(**TINY)), SceneSpec(**TINY))
    assert np.allclose(mapping, path[frames], atol=1e-6)
    assert len(near) == TINY["n_query"]
    assert all(np.abs(path - T).max(axis=(1, 2)).min() < 1e-5 for T in near)  # poses of the camera's path


def test_query_walk_is_a_second_walk_through_the_room(tiny: Path) -> None:
    scene = Scene(tiny)
    spec = SceneSpec(**TINY)
    layout = build_layout(spec)
    walk = scene.sequence("query_walk")
    assert len(walk) == spec.n_query and scene.info["splits"]["query_walk"] == spec.n_query
    assert np.allclose(walk.poses, sample_walk(layout, spec), atol=1e-6)
    assert all(f.color.shape == (72, 96, 3) and f.instance.shape == (72, 96) for f in walk)
    assert scene.info["lighting"]["query_walk"] == scene.info["lighting"]["query"]  # the mapping's lighting
    step = np.linalg.norm(np.diff(walk.poses[:, :3, 3], axis=0), axis=1)
    assert step.max() <= spec.mapping_step_m + 0.03  # one sequence
    occ = occupancy_grid(layout, 0)
    assert (occ.room_index[occ.cell(walk.poses[:, :2, 3])] >= 0).all()


def test_the_walk_leaves_every_other_file_as_it_was(tiny: Path, tmp_path: Path, monkeypatch) -> None:
    """The scene generated without the query_walk row: every other split, objects and displacements are
    the same bytes, scene.json and difficulty.csv the same but for the walk's entries."""
    monkeypatch.setattr(generate, "QUERY_SPLIT_TABLE", tuple(s for s in QUERY_SPLIT_TABLE if s.kind != WALK))
    monkeypatch.setattr(generate, "OWN_POSE_SPLITS", ("query", "query_near"))
    without = generate_scene(SceneSpec(**TINY), tmp_path, progress=False)
    mine = {k: v for k, v in _files(tiny).items() if not k.startswith("query_walk/")}
    theirs = _files(without)
    differ = {k for k in mine.keys() | theirs.keys() if mine.get(k) != theirs.get(k)}
    assert differ == {"scene.json", "difficulty.csv"}
    info, before = io.read_json(tiny / "scene.json"), io.read_json(without / "scene.json")
    for key in ("splits", "lighting"):
        assert info[key].pop("query_walk") and info[key] == before[key]
    assert info == before
    table = pd.read_csv(tiny / "difficulty.csv", dtype={"frame": str})
    assert (
        table[table["split"] != "query_walk"]
        .reset_index(drop=True)
        .equals(pd.read_csv(without / "difficulty.csv", dtype={"frame": str}))
    )


def test_difficulty_measures_every_query_frame(tiny: Path) -> None:
    scene = Scene(tiny)
    table = scene.difficulty()
    assert tuple(table.columns) == DIFFICULTY_COLUMNS
    for split in QUERY_SPLITS:
        rows = table[table["split"] == split]
        seq = scene.sequence(split)
        assert list(rows["frame"]) == [r.frame_id for r in seq.records]
        assert (rows["light_level"] == scene.info["lighting"][split]["level"]).all()
        mapping = np.array([r.T_wc for r in scene.sequence("mapping").records])
        gaps = [np.linalg.norm(mapping[:, :3, 3] - r.T_wc[:3, 3], axis=1).min() for r in seq.records]
        assert np.allclose(rows["gap_m"], gaps, atol=1e-3)
        structural = {i for i, o in scene.objects.items() if o.structural}
        changes = scene.displacements() if split == "query_displaced" else []
        shown = {d["id"] for d in changes if d["kind"] != "removed"}
        removed = {d["id"] for d in changes if d["kind"] == "removed"}

        def visible(instance: np.ndarray, structural: set[int] = structural) -> set[int]:
            ids, counts = np.unique(instance, return_counts=True)
            big = counts >= 0.005 * instance.size
            return {int(i) for i, b in zip(ids, big) if b and i and int(i) not in structural}

        for (_, row), frame, before in zip(rows.iterrows(), seq, scene.sequence("query")):
            seen = len(visible(frame.instance) & shown) + len(visible(before.instance) & removed)
            assert (row["visible_objects"], row["displaced_in_view"]) == (len(visible(frame.instance)), seen)


def test_light_variants_darker_and_displaced_differs(tiny: Path) -> None:
    scene = Scene(tiny)
    means = [
        np.mean([f.color.mean() for f in scene.sequence(s)])
        for s in ("query", "query_light1", "query_light2", "query_light3", "query_light4")
    ]
    assert all(a > b for a, b in zip(means, means[1:])), means
    q, d = scene.sequence("query"), scene.sequence("query_displaced")
    moved = {m["id"] for m in scene.displacements()}
    changed = [not np.array_equal(a.instance, b.instance) for a, b in zip(q, d)]
    assert any(changed) or not any(moved & set(np.unique(a.instance)) for a in q)


def test_the_sensor_records_noisy_depth_and_colour_of_the_same_views(tiny: Path, ideal: Path) -> None:
    """Same poses and instances; depth off by millimetres to centimetres with missing returns, colour noisy."""
    for split in ("mapping", "query_light4"):
        for noisy, clean in zip(Scene(tiny).sequence(split), Scene(ideal).sequence(split)):
            assert np.array_equal(noisy.T_wc, clean.T_wc) and np.array_equal(noisy.instance, clean.instance)
            both = (noisy.depth > 0) & (clean.depth > 0)
            lost = (noisy.depth == 0) & (clean.depth > 0)
            assert 0 < lost.mean() < 0.5 and both.mean() > 0.4  # tiny frames: edges are a large share
            err = np.abs(noisy.depth[both] - clean.depth[both])
            assert 0.0005 < np.median(err) < 0.05
            assert not np.array_equal(noisy.color, clean.color)
            assert abs(noisy.color.astype(float).mean() - clean.color.astype(float).mean()) < 15


def test_odometry_mapping_poses_replace_the_truth_which_is_kept(tiny: Path, tmp_path: Path) -> None:
    """With ``mapping_poses: odometry`` the mapping split holds estimated poses near the truth, the truth is
    in ``pose_truth`` and ``scene.json`` records the drift those files show; the images are the same."""
    root = generate_scene(SceneSpec(**TINY, mapping_poses="odometry"), tmp_path, progress=False)
    truth = Scene(tiny).sequence("mapping")
    estimated = Scene(root).sequence("mapping")
    kept = np.array([io.read_matrix(root / "mapping" / "pose_truth" / f"{r.frame_id}.txt") for r in truth.records])
    assert np.allclose(kept, truth.poses, atol=1e-6)
    assert np.array_equal(estimated[0].color, truth[0].color)
    error = np.linalg.norm(estimated.poses[:, :3, 3] - truth.poses[:, :3, 3], axis=1)
    record = Scene(root).info["mapping_odometry"]
    assert record["drift"]["ate_max_m"] == pytest.approx(error.max(), abs=1e-4)
    assert 0 < error.max() < 1.0 and record["segments"] >= 1  # 96 x 72 frames 0.5 m apart: a rough estimate
    assert Scene(root).sequence("query").poses.tolist() == Scene(tiny).sequence("query").poses.tolist()


def test_added_objects_only_in_the_displaced_split_and_removed_ones_not_there(tiny: Path) -> None:
    scene = Scene(tiny)
    kind = {d["id"]: d["kind"] for d in scene.displacements()}
    for split in SPLITS:
        drawn = set().union(*(set(np.unique(f.instance).tolist()) for f in scene.sequence(split)))
        absent = {i for i, k in kind.items() if k == ("removed" if split == "query_displaced" else "added")}
        assert not drawn & absent, split


def test_byte_identical_and_seed_dependent(tiny: Path, tmp_path: Path) -> None:
    again = generate_scene(SceneSpec(**TINY), tmp_path / "b", progress=False)
    assert _files(again) == _files(tiny)
    other = generate_scene(SceneSpec(**{**TINY, "seed": 4}), tmp_path / "c", progress=False)
    assert (other / "objects.json").read_bytes() != (tiny / "objects.json").read_bytes()


def test_suite_with_process_pool(tmp_path: Path, tiny: Path) -> None:
    small = {**TINY, "max_mapping_frames": 4, "n_query": 2, "displaced_share": 0.2}
    suite_yaml = tmp_path / "s.yaml"
    suite_yaml.write_text(
        yaml.safe_dump({"name": "s", "defaults": small, "scenes": [{"name": "x", "seed": 3}, {"name": "y", "seed": 5}]})
    )
    out = generate_suite(load_suite(suite_yaml), tmp_path / "out", workers=2)
    assert [p.name for p in out] == ["x", "y"]
    assert Scene(out[0]).info["spec_hash"] != Scene(out[1]).info["spec_hash"]
    # the pool worker renders exactly what an in-process run renders
    ref = generate_scene(
        config.from_dict(SceneSpec, {**small, "name": "x", "seed": 3}), tmp_path / "ref", progress=False
    )
    assert _files(ref) == _files(out[0])


def test_resume_after_kill(tmp_path: Path) -> None:
    spec = {**TINY, "max_mapping_frames": 40, "mapping_step_m": 0.25, "mapping_step_deg": 15.0}
    suite_yaml = tmp_path / "s.yaml"
    suite_yaml.write_text(yaml.safe_dump({"name": "s", "scenes": [spec]}))
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "openreloc_bench.cli", "generate", str(suite_yaml), "--out", str(out)]
    proc = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    pose_dir = out / "tiny" / "mapping" / "pose"
    deadline = time.time() + 120
    while time.time() < deadline and len(list(pose_dir.glob("*.txt"))) < 5:
        time.sleep(0.05)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    done = sorted(pose_dir.glob("*.txt"))
    assert 5 <= len(done) < 40, "the kill should land mid-generation"
    mtimes = {p.name: p.stat().st_mtime_ns for p in done}
    rc = subprocess.run(cmd + ["--resume"], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert rc.returncode == 0, rc.stderr
    scene = Scene(out / "tiny")
    assert len(scene.sequence("mapping")) == 40 and len(scene.sequence("query_displaced")) == 4
    assert all((pose_dir / n).stat().st_mtime_ns == t for n, t in mtimes.items())  # finished frames reused
    assert not [p for p in (out / "tiny").rglob("*") if p.name.endswith(".tmp")]
    fresh = generate_scene(SceneSpec(**spec), tmp_path / "fresh", progress=False)
    assert _files(fresh) == _files(out / "tiny")  # resumed output equals an uninterrupted run


def test_resume_redoes_truncated_and_missing_images(tmp_path: Path, tiny: Path) -> None:
    copy = tmp_path / "tiny"
    shutil.copytree(tiny, copy)
    color, depth = copy / "mapping" / "color" / "000002.png", copy / "query" / "depth" / "000001.png"
    color.write_bytes(color.read_bytes()[:-100])
    depth.unlink()
    generate_scene(SceneSpec(**TINY), tmp_path, resume=True, progress=False)
    assert _files(copy) == _files(tiny)


def test_an_incomplete_scene_is_refused_with_one_line(tmp_path: Path, tiny: Path) -> None:
    copy = tmp_path / "tiny"
    shutil.copytree(tiny, copy)
    (copy / "query" / "pose" / "000003.txt").unlink()  # as a killed `generate` leaves it
    with pytest.raises(DataError, match="has 3 of the 4 frames scene.json lists: the scene is incomplete"):
        Scene(copy).sequence("query")
