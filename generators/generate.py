"""Scene generation end to end: spec -> layout -> trajectories -> rendered splits and variants on disk.

Everything is a deterministic function of the :class:`~generators.spec.SceneSpec`, so the same spec
gives byte-identical files, and a resumed run (``resume=True``) recomputes the same poses and skips
every frame whose pose file (written last by :class:`~openreloc_bench.data.scene.SceneWriter`) exists.
Suites run scenes in a spawn-context process pool: no GL context exists before a worker starts.
"""

from __future__ import annotations

import logging
import multiprocessing as mp
import os
import shutil
from collections import deque
from concurrent.futures import Future, ProcessPoolExecutor, ThreadPoolExecutor, as_completed
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from generators.difficulty import changes_in_view, measure_difficulty
from generators.layout import Layout, build_layout
from generators.render import Renderer, create_renderer
from generators.sensor import blend_subframes, exposure_poses, sensor_colour, sensor_depth
from generators.spec import GENERATOR_VERSION, SceneSpec, SuiteSpec, spec_hash, spec_record
from generators.trajectories import mapping_path, sample_near_queries, sample_queries, sample_walk, seen_counts
from generators.variants import Lighting, hidden, query_lighting, sample_displacements
from openreloc_bench import config, geometry
from openreloc_bench.data import io, paths
from openreloc_bench.data.scene import DATA_VERSION, SceneWriter, foreign_files, frame_id
from openreloc_bench.data.splits import (
    DISPLACED,
    DISPLACED_SPLIT,
    LIGHT,
    MAPPING_SPLIT,
    NEAR,
    OWN_POSE_SPLITS,
    PLAIN,
    PLAIN_SPLIT,
    QUERY_SPLIT_TABLE,
    SPLITS,
    WALK,
)
from openreloc_bench.errors import ConfigError, DataError
from openreloc_bench.processes import pool_worker, workers_stopped_on_interrupt

log = logging.getLogger(__name__)


def scene_info(spec: SceneSpec, layout: Layout, K: np.ndarray, counts: dict[str, int], extra: dict) -> dict:
    """Content of scene.json (no timestamps or paths: it must be byte-identical across runs)."""
    return {
        "name": spec.name,
        "kind": spec.kind,
        "seed": spec.seed,
        "spec_hash": spec_hash(spec),
        "spec": spec_record(spec),
        "generator_version": GENERATOR_VERSION,
        "data_version": DATA_VERSION,
        "intrinsics": {"K": np.round(K, 9).tolist(), "width": spec.width, "height": spec.height, "fov_y": spec.fov_y},
        "footprint": [round(v, 5) for v in layout.footprint],
        "floors": [
            {"index": f, "z": round(z, 5), "ceiling_height": layout.ceiling_height}
            for f, z in enumerate(layout.floor_z)
        ],
        "rooms": [
            {
                "name": r.name,
                "kind": r.kind,
                "floor": r.floor,
                "rect": [round(v, 5) for v in r.rect],
                "z0": round(r.z0, 5),
            }
            for r in layout.rooms
        ],
        "doors": [
            {"floor": d.floor, "centre": np.round(d.centre, 5).tolist(), "axis": d.axis, "rooms": list(d.rooms)}
            for d in layout.doors
        ],
        "lights": [
            {"index": k, "pos": np.round(li.pos, 5).tolist(), "room": li.room, "floor": li.floor}
            for k, li in enumerate(layout.lights)
        ],
        "splits": counts,
        **extra,
    }


def capture(
    renderer: Renderer, T: np.ndarray, K: np.ndarray, spec: SceneSpec, T_neighbour: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One frame's render, its colour blurred over the motion to ``T_neighbour`` (mapping frames: a
    hand-held sweep) when the spec's sensor blurs."""
    rgb, depth, inst = renderer.render(T, K, spec.width, spec.height)
    sensor = spec.sensor
    if sensor.model != "ideal" and T_neighbour is not None and sensor.blur_subframes > 1:
        poses = exposure_poses(T, T_neighbour, sensor)
        middle = len(poses) // 2 if len(poses) % 2 else -1
        rgb = blend_subframes(
            [
                rgb if k == middle else renderer.render_color(P, K, spec.width, spec.height)[0]
                for k, P in enumerate(poses)
            ]
        )
    return rgb, depth, inst


def record(
    writer: SceneWriter,
    split: str,
    i: int,
    frame: tuple[np.ndarray, np.ndarray, np.ndarray],
    T: np.ndarray,
    K: np.ndarray,
    spec: SceneSpec,
    level: float,
) -> None:
    """Write frame ``i`` of ``split`` as the spec's camera records the render ``frame``: with the sensor's
    colour and depth noise, seeded by (scene seed, split, frame) so that a resumed run redoes it exactly."""
    rgb, depth, inst = frame
    if spec.sensor.model != "ideal":
        rng = np.random.default_rng([spec.seed, SENSOR_STREAM, SPLITS.index(split), i])
        rgb, depth = sensor_colour(rgb, spec.sensor, rng, level), sensor_depth(depth, rgb, K, spec.sensor, rng, level)
    writer.write_frame(split, i, rgb, depth, inst, T)


def render_split(
    renderer: Renderer,
    writer: SceneWriter,
    split: str,
    poses: np.ndarray,
    K: np.ndarray,
    spec: SceneSpec,
    level: float,
    resume: bool,
    bar: tqdm | None,
) -> int:
    """Render and write one split; returns the number of frames reused from a previous run.

    The sensor's noise, PNG encoding and writing of a frame (:func:`record`, twice the rendering's time)
    run on :data:`WRITERS` threads beside the rendering of the next frames (numpy and cv2 release the GIL).
    Each frame is seeded on its own and ends with its pose file, so an interrupted run loses at most the
    frames in flight, which resume redoes.
    """
    writer.write_intrinsics(split, K)
    reused = 0
    pending: deque[Future] = deque()
    blurred = split == "mapping" and len(poses) > 1
    with ThreadPoolExecutor(max_workers=WRITERS) as pool:
        for i, T in enumerate(poses):
            if resume and writer.has_frame(split, i):
                reused += 1
            else:
                frame = capture(renderer, T, K, spec, _sweep_neighbour(poses, i) if blurred else None)
                if len(pending) == WRITERS:
                    pending.popleft().result()
                pending.append(pool.submit(record, writer, split, i, frame, T, K, spec, level))
            if bar is not None:
                bar.update(1)
        while pending:
            pending.popleft().result()
    return reused


WRITERS = 2
"""Frames being written at once (each holds its render in memory)."""


RENDER_ORDER = (PLAIN, NEAR, WALK, LIGHT, DISPLACED)
"""The order the query splits are rendered in, by kind (after the mapping split): the displaced split
last, for it moves objects for good."""
SENSOR_STREAM = 23
"""Seed stream of the sensor noise (the scene's other random draws use other streams)."""
MAX_BLUR_STEP_M = 1.0
"""Consecutive mapping frames farther apart are a cut in the sweep (between floors), not motion to blur."""


def _sweep_neighbour(poses: np.ndarray, i: int) -> np.ndarray | None:
    """The mapping frame the camera moves towards from frame ``i`` (the previous one for the last frame),
    or None across a cut."""
    j = i + 1 if i + 1 < len(poses) else i - 1
    return poses[j] if np.linalg.norm(poses[j][:3, 3] - poses[i][:3, 3]) <= MAX_BLUR_STEP_M else None


def generate_scene(spec: SceneSpec, out_dir: Path | str, resume: bool = False, progress: bool = True) -> Path:
    """Generate ``out_dir/<spec.name>/`` (all splits and variants); returns the scene directory.

    Without ``resume`` an existing generated scene of the same name is regenerated beside it and
    swapped in when complete, so a failed or interrupted run leaves it as it was; with ``resume``,
    finished frames are kept (the spec hash must match). A scene holding files the generator did not
    write is never replaced.
    """
    target = Path(out_dir) / spec.name
    if target.exists():
        check_replaceable(target, spec, resume)
        if not resume:
            with paths.staged(target) as stage:
                write_scene(spec, stage, resume=False, progress=progress)
                replace_directory(stage, target)
            return target
        io.remove_stray_temps(target)
    return write_scene(spec, target, resume, progress)


def check_replaceable(target: Path, spec: SceneSpec, resume: bool) -> None:
    """ConfigError unless the existing folder ``target`` may be regenerated (or, with ``resume``, resumed)
    as ``spec``'s scene: it must be a generated scene (of this spec, to resume) holding only files the
    generator writes, for a regeneration replaces it whole."""
    if not (target / "scene.json").exists() and any(target.iterdir()):
        raise ConfigError(f"{target}: exists and is not a generated scene; refusing to overwrite")
    if resume and generated_spec_hash(target) not in (None, spec_hash(spec)):
        raise ConfigError(f"{target}: was generated from a different spec; cannot resume (delete it or drop --resume)")
    foreign = [] if resume else foreign_files(target)
    if foreign:
        raise ConfigError(
            f"{target}: holds {foreign[0].relative_to(target)}"
            + (f" and {len(foreign) - 1} more" if len(foreign) > 1 else "")
            + ", which the generator did not write; move them out to regenerate the scene, or use --resume"
        )


def write_scene(spec: SceneSpec, root: Path, resume: bool, progress: bool) -> Path:
    """Render every split and variant of ``spec`` into ``root`` and measure its difficulty."""
    layout = build_layout(spec)
    K = geometry.intrinsics_from_fov(spec.width, spec.height, spec.fov_y)
    writer = SceneWriter(root)
    renderer = create_renderer(layout, spec.backend, spec.width, spec.height)
    try:
        try:
            path, frames = mapping_path(layout, spec)
            mapping = path[frames]
            queries, qinfo = sample_queries(layout, spec, mapping, renderer)
            near = sample_near_queries(layout, spec, path, frames, renderer)
            walk = sample_walk(layout, spec)
        except RuntimeError as e:  # the spec asks for more than its rooms allow: the user's to change
            raise ConfigError(f"scene '{spec.name}': {e}") from None
        seen = seen_counts(layout, spec, renderer, queries)
        displacements = sample_displacements(layout, spec, queries[:, :3, 3], seen)
        lights = query_lighting(spec, len(layout.lights))
        splits: dict[str, tuple[np.ndarray, Lighting]] = {MAPPING_SPLIT: (mapping, Lighting())}
        for s in sorted(QUERY_SPLIT_TABLE, key=lambda s: RENDER_ORDER.index(s.kind)):
            splits[s.name] = ({NEAR: near, WALK: walk}.get(s.kind, queries), lights[s.name])
        counts = {s: len(p) for s, (p, _) in splits.items()}
        extra = {
            "lighting": {s: asdict(li) for s, (_, li) in splits.items()},
            "query_viewpoints": [asdict(q) for q in qinfo],
            "displaced_objects": [d.id for d in displacements],
        }
        root.mkdir(parents=True, exist_ok=True)
        writer.write_scene_info(scene_info(spec, layout, K, counts, extra))
        writer.write_objects(layout.objects())
        writer.write_displacements([asdict(d) for d in displacements])
        reused = 0
        with tqdm(total=sum(counts.values()), desc=spec.name, unit="frame", disable=not progress, leave=False) as bar:
            for d in displacements:
                if not d.shown_in_mapping:
                    renderer.set_instance_pose(d.id, hidden(d.transform_before))
            for split, (poses, lighting) in splits.items():
                renderer.set_lighting(lighting.level, lighting.tint, lighting.lights_off, lighting.headlight)
                if split == DISPLACED_SPLIT:
                    for d in displacements:
                        T = np.asarray(d.transform_after)
                        renderer.set_instance_pose(d.id, T if d.shown_displaced else hidden(T))
                reused += render_split(renderer, writer, split, poses, K, spec, lighting.level, resume, bar)
        if reused:
            log.info("%s: reused %d finished frames", spec.name, reused)
    finally:
        renderer.close()
    if spec.mapping_poses == "odometry":
        info = scene_info(spec, layout, K, counts, extra)
        info["mapping_odometry"] = estimate_mapping_poses(root, writer, mapping, K, progress)
        writer.write_scene_info(info)
    instances = {s: read_instances(root / s, len(splits[s][0])) for s in (*OWN_POSE_SPLITS, DISPLACED_SPLIT)}
    shown = {d.id for d in displacements if d.shown_displaced}
    removed = {d.id for d in displacements if not d.shown_displaced}
    changes = changes_in_view(instances[DISPLACED_SPLIT], instances[PLAIN_SPLIT], shown, removed, layout.objects())
    measured = {  # the lighting variants see what the plain query split sees
        split: (
            poses,
            lighting.level,
            instances[split if split in instances else PLAIN_SPLIT],
            changes if split == DISPLACED_SPLIT else None,
        )
        for split, (poses, lighting) in splits.items()
        if split != MAPPING_SPLIT
    }
    writer.write_difficulty(measure_difficulty(mapping, measured, layout.objects()))
    return root


def estimate_mapping_poses(root: Path, writer: SceneWriter, truth: np.ndarray, K: np.ndarray, progress: bool) -> dict:
    """Replace the mapping split's poses by those RGB-D odometry estimates from its recorded frames,
    aligned to the true world frame part by part (a jump between floors splits the sweep); the truth goes
    to ``mapping/pose_truth``. Returns the record for ``scene.json``: the drift and the pose graph."""
    from generators.odometry import align_to, drift, estimate_trajectory  # torch and open3d: only when asked

    frames = [root / "mapping" / k for k in ("color", "depth")]
    names = [f"{frame_id(i)}.png" for i in range(len(truth))]
    rgbs = [io.read_rgb(frames[0] / n) for n in names]
    depths = [io.read_depth(frames[1] / n) for n in names]
    trajectory = estimate_trajectory(rgbs, depths, K, truth[0], progress=progress)
    aligned = align_to(trajectory.poses, truth, trajectory.segments)
    writer.write_poses("mapping", truth, "pose_truth")
    writer.write_poses("mapping", aligned)
    error = drift(aligned, truth, trajectory.segments)
    return {
        "drift": {k: round(v, 5) for k, v in asdict(error).items()},
        "segments": int(trajectory.segments.max(initial=-1) + 1),
        "loop_closures": trajectory.loop_closures,
        "failed_pairs": trajectory.failed_pairs,
    }


def replace_directory(new: Path, target: Path) -> None:
    """Put the complete folder ``new`` in place of ``target``: the old one is set aside first and
    removed only once the new one stands in its place."""
    old = target.parent / f".{target.name}.replaced"
    shutil.rmtree(old, ignore_errors=True)
    os.rename(target, old)
    os.rename(new, target)
    shutil.rmtree(old)


def read_instances(split_dir: Path, n: int) -> list[np.ndarray]:
    """The instance images of a rendered split, in frame order."""
    return [io.read_instance(split_dir / "instance" / f"{frame_id(i)}.png") for i in range(n)]


def generated_spec_hash(root: Path) -> str | None:
    """The spec hash ``root/scene.json`` records, or None when there is no scene.json."""
    info_path = Path(root) / "scene.json"
    if not info_path.exists():
        return None
    info = io.read_json(info_path)
    if not isinstance(info, dict):
        raise DataError(info_path, f"expected a JSON object, got {type(info).__name__}")
    return str(info.get("spec_hash"))


def _worker(spec_dict: dict, out_dir: str, resume: bool) -> str:
    spec = config.from_dict(SceneSpec, spec_dict)
    return str(generate_scene(spec, out_dir, resume=resume, progress=False))


def generate_scenes(
    specs: list[SceneSpec], out_dir: Path | str, resume: bool = False, workers: int = 1, desc: str = "scenes"
) -> list[Path]:
    """Generate ``specs`` into ``out_dir`` in ``workers`` spawned processes; returns the scene dirs in order.

    Always out of process, even with one worker: the caller (a trainer, an environment) never holds a
    GL context, which torch and forked workers do not survive.
    """
    done: dict[str, Path] = {}
    ctx = mp.get_context("spawn")
    with (
        ProcessPoolExecutor(
            max_workers=max(1, workers), mp_context=ctx, initializer=pool_worker, initargs=(os.getpid(),)
        ) as pool,
        workers_stopped_on_interrupt(pool),
    ):
        futures = {pool.submit(_worker, config.to_dict(s), str(out_dir), resume): s.name for s in specs}
        for fut in tqdm(as_completed(futures), total=len(futures), desc=desc, unit="scene"):
            done[futures[fut]] = Path(fut.result())
    return [done[s.name] for s in specs]


def generate_suite(
    suite: SuiteSpec, out_dir: Path | str, resume: bool = False, workers: int = 1, only: list[str] | None = None
) -> list[Path]:
    """Generate every scene of ``suite`` (or the named ones) into ``out_dir``; returns the scene dirs.

    ``out_dir`` is locked meanwhile (a second generation into it fails at once), and a scene of the
    same name generated from another spec is never replaced, with or without ``resume``: it may be
    the user's data (delete it first to regenerate it).
    """
    specs = suite.scene_specs()
    if only is not None:
        unknown = sorted(set(only) - {s.name for s in specs})
        if unknown or not only:
            raise ConfigError(
                (f"unknown scene '{unknown[0]}' in --scenes" if unknown else "--scenes names no scene")
                + f" (suite has: {', '.join(s.name for s in specs)})"
            )
        specs = [s for s in specs if s.name in only]
    out_dir = Path(out_dir)
    with paths.directory_lock(out_dir, "openreloc-bench generate", in_directory=False):
        for s in specs:
            if generated_spec_hash(out_dir / s.name) not in (None, spec_hash(s)):
                raise ConfigError(
                    f"{out_dir / s.name}: was generated from another spec (or generator version) than "
                    f"{suite.name}'s scene '{s.name}'; delete it to regenerate it, or choose another --out"
                )
            if (out_dir / s.name).exists():
                check_replaceable(out_dir / s.name, s, resume)
        if workers <= 1 or len(specs) == 1:
            return [
                generate_scene(s, out_dir, resume=resume, progress=True)
                for s in tqdm(specs, desc=suite.name, unit="scene")
            ]
        return generate_scenes(specs, out_dir, resume, workers, suite.name)


def training_specs(
    prefix: str, seeds: list[int], width: int, height: int, with_floors: bool = False, **overrides: Any
) -> list[SceneSpec]:
    """Specs of scenes for training models, one per seed of the reserved training range: two single-room
    scenes for each three-room one; with ``with_floors``, every fifth a two-floor house (stairs, landings).
    ``overrides``: further :class:`SceneSpec` fields for every scene."""
    from generators.spec import TRAINING_SEED_MIN, VALIDATION_SEED_MIN

    specs = []
    for i, seed in enumerate(seeds):
        if not TRAINING_SEED_MIN <= seed < VALIDATION_SEED_MIN:
            raise ConfigError(
                f"training scene seed {seed} is outside the training range [{TRAINING_SEED_MIN}, "
                f"{VALIDATION_SEED_MIN}): lower --seed or the number of scenes"
            )
        kind, rooms, floors = ("multi-room", 3, 1) if i % 3 == 2 else ("single-room", 1, 1)
        if with_floors and i % 5 == 4:
            kind, rooms, floors = "multi-floor", 4, 2
        spec = dict(
            name=f"{prefix}-{seed}", kind=kind, seed=seed, rooms=rooms, floors=floors, width=width, height=height
        )
        specs.append(config.from_dict(SceneSpec, {**spec, **overrides}))
    return specs
