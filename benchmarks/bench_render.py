"""Rendering speed of the scene generator (prints numbers; not a test).

    python benchmarks/bench_render.py [--suite scenes/multi-room.yaml] [--scene sc4] [--frames 200] [--full]
                                      [--backends mujoco,pyrender]

Reports, for one multi-room scene at the suite's resolution (640x480): layout / model build time,
RGB + depth + instance frames per second over the first ``--frames`` mapping poses (render only,
and render + PNG encoding + atomic writes), the projected time for 1000 frames, and with ``--full``
the wall time of generating the whole scene (all splits and variants) with ``generate_scene``.
``--backends`` adds one render-only line per named backend (pyrender needs its extra).
Targets (issue 3): >= 15 frames/s and a 1000-frame multi-room scene in <= 3 minutes.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from generators.generate import generate_scene, render_split  # noqa: E402
from generators.layout import build_layout  # noqa: E402
from generators.render import create_renderer  # noqa: E402  (sets MUJOCO_GL before mujoco loads)
from generators.spec import load_suite  # noqa: E402
from generators.trajectories import mapping_trajectory  # noqa: E402
from openreloc_bench import geometry  # noqa: E402
from openreloc_bench.data.scene import SceneWriter  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--suite", type=Path, default=Path(__file__).resolve().parents[1] / "scenes" / "multi-room.yaml")
    ap.add_argument("--scene", default="sc4")
    ap.add_argument("--frames", type=int, default=200)
    ap.add_argument("--full", action="store_true", help="also generate the whole scene and report its wall time")
    ap.add_argument("--backends", default="", help="comma-separated backends for one render-only fps line each")
    args = ap.parse_args()
    spec = next(s for s in load_suite(args.suite).scene_specs() if s.name == args.scene)
    print(
        f"scene {spec.name}: {spec.kind}, {spec.rooms} rooms x {spec.floors} floors, {spec.width}x{spec.height}, "
        f"MUJOCO_GL={os.environ.get('MUJOCO_GL')}, load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs"
    )
    t = time.perf_counter()
    layout = build_layout(spec)
    t_layout = time.perf_counter() - t
    n_obj = sum(not i.structural for i in layout.instances)
    print(f"layout: {t_layout:.1f} s, {len(layout.instances)} instances ({n_obj} objects), {len(layout.lights)} lights")
    mapping = mapping_trajectory(layout, spec)
    K = geometry.intrinsics_from_fov(spec.width, spec.height, spec.fov_y)
    poses = mapping[: args.frames]
    for backend in [b for b in args.backends.split(",") if b]:
        with create_renderer(layout, backend, spec.width, spec.height) as r:
            print(f"{backend}: " + _render_fps(r, poses, K, spec.width, spec.height))
    t = time.perf_counter()
    renderer = create_renderer(layout, spec.backend, spec.width, spec.height)
    print(f"model ({spec.backend}): {time.perf_counter() - t:.1f} s, {len(mapping)} mapping poses")
    print(_render_fps(renderer, poses, K, spec.width, spec.height))
    with tempfile.TemporaryDirectory() as tmp:
        t = time.perf_counter()
        render_split(renderer, SceneWriter(tmp), "mapping", poses, K, spec, 1.0, resume=False, bar=None)
        dt = time.perf_counter() - t
    fps = len(poses) / dt
    print(f"render + write PNGs: {fps:.1f} frames/s -> 1000 frames in {1000 / fps:.0f} s (+ {t_layout:.0f} s layout)")
    renderer.close()
    if args.full:
        with tempfile.TemporaryDirectory() as tmp:
            t = time.perf_counter()
            root = generate_scene(spec, tmp, progress=False)
            wall = time.perf_counter() - t
            n = sum(1 for _ in root.rglob("pose/*.txt"))
        print(f"full scene: {n} frames (all splits) in {wall:.0f} s wall ({n / wall:.1f} frames/s overall)")


def _render_fps(renderer, poses, K, width: int, height: int) -> str:
    """One line: RGB + depth + instances frames per second over ``poses`` (after a warm-up frame)."""
    renderer.render(poses[0], K, width, height)  # GL context creation, texture upload
    times = []
    cpu0 = time.process_time()
    for T in poses:
        t = time.perf_counter()
        renderer.render(T, K, width, height)
        times.append(time.perf_counter() - t)
    cpu = (time.process_time() - cpu0) / len(poses)
    times = np.array(times)
    return (
        f"render RGB+depth+instances at {width}x{height}: {1 / times.mean():.1f} frames/s mean, "
        f"{1 / np.median(times):.1f} median over {len(times)} frames; {1000 * cpu:.0f} ms CPU per frame "
        f"(all threads; on an idle machine at most {os.cpu_count() / cpu:.0f} frames/s)"
    )


if __name__ == "__main__":
    main()
