"""Speed of every method, map building and queries, per stage, one query at a time on one core.

For each method (and track: mask-free methods run once, their map serves both), on each scene: build
the map (timed; its per-stage times where the method records them), then localize every query of the
split one at a time with one torch and one BLAS thread, timing each query and its stages. Writes, under
``--work``:

- ``maps/<method>/<map track>/<scene>/``: the maps (``--reuse-maps`` keeps those already there);
- ``poses/<method>/<track>/<scene>.txt``: the estimates, in the benchmark's result format;
- ``speed.json``: every number printed below;
- with ``--profile``: ``profiles/<method>-<track>-{map,query}.txt``, pyinstrument call trees (the ``dev`` extra).

``--reference OTHER_WORK`` compares the poses with those of an earlier run of this benchmark (e.g. at the
previous commit, from a checkout of it): a pure speed-up leaves every pose within 1 mm and 0.01 deg.

    .venv/bin/python benchmarks/bench_speed.py --data DATA/validation --scenes val1,val2,val3 \\
        --methods openreloc,sift-pnp,orb-reloc --tracks oracle-mask,predicted --work WORK [--profile]

The targets it checks, meant for the validation suite's multi-room scenes: openreloc at most 0.5 s median
per query with oracle masks and 0.8 s predicted, ``sift-pnp`` and ``orb-reloc`` 0.5 s, an openreloc map in
60 s, the learned segmenter 100 ms per frame (``docs/speed.md`` has the measured table).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

import numpy as np
import torch
from threadpoolctl import threadpool_limits

from openreloc_bench import geometry
from openreloc_bench.commands.localize import localize_split
from openreloc_bench.data.results import read_results, write_results
from openreloc_bench.data.scene import Scene
from openreloc_bench.methods import create_method, uses_masks
from openreloc_bench.tracks import MASK_FREE, ORACLE_MASK, PREDICTED
from openreloc_bench.vision import create_segmenter

TARGETS_S = {  # (method, track) -> median seconds per query
    ("openreloc", ORACLE_MASK): 0.5,
    ("openreloc", PREDICTED): 0.8,
    ("sift-pnp", MASK_FREE): 0.5,
    ("orb-reloc", MASK_FREE): 0.5,
}
MAP_TARGET_S = {"openreloc": 60.0}
SEGMENTER_TARGET_MS = 100.0


def _stage_times(diagnostics: dict[str, Any]) -> dict[str, float]:
    """A query's per-stage seconds, under whichever key its method records them."""
    for key in ("timings", "timing_s"):
        if isinstance(diagnostics.get(key), dict):
            return {k: float(v) for k, v in diagnostics[key].items() if k != "total"}
    return {}


def _profiler(enabled: bool) -> Any:
    if not enabled:
        return None
    from pyinstrument import Profiler  # a benchmark extra, not a dependency of the package

    return Profiler(interval=0.002)


def _save_profile(profiler: Any, path: Path) -> None:
    """Write the call tree, if anything was profiled (reused maps are not)."""
    if profiler is not None and profiler.last_session is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(profiler.output_text(unicode=False, color=False))


def build_maps(method_name: str, map_track: str, scenes: list[Scene], work: Path, reuse: bool, profile: bool) -> dict:
    """Build (or reuse) the method's map of every scene; seconds and per-stage seconds per scene."""
    out = {}
    profiler = _profiler(profile)
    for scene in scenes:
        map_dir = work / "maps" / method_name / map_track / scene.name
        record = map_dir.with_name(scene.name + ".json")
        if reuse and record.is_file():
            out[scene.name] = json.loads(record.read_text())
            continue
        seq = scene.sequence("mapping", map_track)
        map_dir.mkdir(parents=True, exist_ok=True)
        method = create_method(method_name)
        if profiler is not None:
            profiler.start()
        t0 = time.perf_counter()
        method.build_map(seq, map_dir)
        seconds = time.perf_counter() - t0
        if profiler is not None:
            profiler.stop()
        stats_file = map_dir / "meta.json"
        stages = {}
        if stats_file.is_file():  # OpenReLoc's map records its stage times
            stages = json.loads(stats_file.read_text()).get("stats", {}).get("timings_s", {})
        out[scene.name] = {"seconds": seconds, "frames": len(seq), "stages": stages}
        record.write_text(json.dumps(out[scene.name]))
    _save_profile(profiler, work / "profiles" / f"{method_name}-{map_track}-map.txt")
    return out


def localize_all(
    method_name: str, map_track: str, track: str, scenes: list[Scene], split: str, work: Path, profile: bool
) -> tuple[list[float], dict[str, list[float]], dict[str, np.ndarray], dict[str, np.ndarray]]:
    """Localize every query; (seconds per query, per-stage seconds, estimates by name, truth by name)."""
    seconds, stages, estimates, truth = [], {}, {}, {}
    profiler = _profiler(profile)
    method = create_method(method_name)
    for scene in scenes:
        method.load_map(work / "maps" / method_name / map_track / scene.name)
        seq = scene.sequence(split)
        if profiler is not None:
            profiler.start()
        records = localize_split(method, seq, track, progress=False)
        if profiler is not None:
            profiler.stop()
        poses = {r.name: r.T_wc for r in records if r.T_wc is not None}
        write_results(work / "poses" / method_name / track / f"{scene.name}.txt", poses, [f"method {method_name}"])
        for r in records:
            seconds.append(r.seconds)
            for k, v in _stage_times(r.diagnostics).items():
                stages.setdefault(k, []).append(v)
        estimates.update({f"{scene.name}/{n}": T for n, T in poses.items()})
        truth.update({f"{scene.name}/{n}": T for n, T in zip(seq.names, seq.poses)})
    _save_profile(profiler, work / "profiles" / f"{method_name}-{track}-query.txt")
    return seconds, stages, estimates, truth


def compare_poses(work: Path, reference: Path, method_name: str, track: str, scenes: list[Scene]) -> dict[str, Any]:
    """How many estimates agree with the reference run's (within 1 mm and 0.01 deg), and the worst gap."""
    same = differ = 0
    worst_t = worst_r = 0.0
    for scene in scenes:
        ref_file = reference / "poses" / method_name / track / f"{scene.name}.txt"
        if not ref_file.is_file():
            return {"reference": "absent"}
        new = read_results(work / "poses" / method_name / track / f"{scene.name}.txt")
        old = read_results(ref_file)
        for name in set(new) | set(old):
            if name not in new or name not in old:
                differ += 1  # localized by one run only
                continue
            dt = geometry.translation_error(old[name], new[name])
            dr = geometry.rotation_error(old[name], new[name])
            worst_t, worst_r = max(worst_t, dt), max(worst_r, dr)
            if dt <= 1e-3 and dr <= 0.01:
                same += 1
            else:
                differ += 1
    return {"same": same, "differ": differ, "max_dt_m": worst_t, "max_dr_deg": worst_r}


def segmenter_ms(scenes: list[Scene], frames: int) -> float:
    """Median milliseconds of the learned segmenter per query frame, one thread."""
    segmenter = create_segmenter("learned", threads=1)
    times = []
    for scene in scenes:
        seq = scene.sequence("query")
        for i in np.linspace(0, len(seq) - 1, min(frames, len(seq))).round().astype(int):
            rgb = seq[int(i)].color
            t0 = time.perf_counter()
            segmenter.segment(rgb)
            times.append(time.perf_counter() - t0)
    return 1000 * float(np.median(times))


def _recall(estimates: dict[str, np.ndarray], truth: dict[str, np.ndarray]) -> tuple[float, float]:
    err = np.array(
        [geometry.translation_error(T, estimates[n]) if n in estimates else np.inf for n, T in truth.items()]
    )
    return float(np.mean(err < 0.5)), float(np.mean(err < 0.25))


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--data", type=Path, required=True, help="folder holding the scenes")
    p.add_argument("--scenes", required=True, help="comma-separated scene names")
    p.add_argument("--methods", default="openreloc,sift-pnp,orb-reloc")
    p.add_argument("--tracks", default="oracle-mask,predicted")
    p.add_argument("--split", default="query")
    p.add_argument("--work", type=Path, required=True, help="maps, poses, profiles and speed.json go here")
    p.add_argument("--reuse-maps", action="store_true", help="keep maps an earlier run built in --work")
    p.add_argument("--reference", type=Path, help="an earlier run's --work: compare poses with it")
    p.add_argument("--profile", action="store_true", help="write pyinstrument call trees to WORK/profiles")
    p.add_argument("--segmenter-frames", type=int, default=10, help="query frames per scene timed (0: skip)")
    args = p.parse_args()
    torch.set_num_threads(1)
    scenes = [Scene(args.data / s) for s in args.scenes.split(",")]
    report: dict[str, Any] = {"scenes": [s.name for s in scenes], "split": args.split, "runs": []}
    met: list[str] = []
    with threadpool_limits(limits=1):
        for method_name in args.methods.split(","):
            tracks = [MASK_FREE] if not uses_masks(method_name) else args.tracks.split(",")
            for track in tracks:
                map_track = track
                maps = build_maps(method_name, map_track, scenes, args.work, args.reuse_maps, args.profile)
                query_track = PREDICTED if track == MASK_FREE else track
                seconds, stages, est, truth = localize_all(
                    method_name, map_track, query_track, scenes, args.split, args.work, args.profile
                )
                r50, r25 = _recall(est, truth)
                run = {
                    "method": method_name,
                    "track": track,
                    "queries": len(seconds),
                    "median_s": float(np.median(seconds)),
                    "mean_s": float(np.mean(seconds)),
                    "stages_median_s": {k: float(np.median(v)) for k, v in stages.items()},
                    "stages_mean_s": {k: float(np.mean(v)) for k, v in stages.items()},
                    "recall50": r50,
                    "recall25": r25,
                    "maps": maps,
                }
                if args.reference:
                    run["agreement"] = compare_poses(args.work, args.reference, method_name, query_track, scenes)
                report["runs"].append(run)
                _print_run(run)
                if (method_name, track) in TARGETS_S:
                    target = TARGETS_S[method_name, track]
                    met.append(_verdict(f"{method_name} ({track}) median query", run["median_s"], target, "s"))
                if method_name in MAP_TARGET_S:
                    worst = max(m["seconds"] for m in maps.values())
                    met.append(_verdict(f"{method_name} ({track}) slowest map", worst, MAP_TARGET_S[method_name], "s"))
    if args.segmenter_frames:
        ms = segmenter_ms(scenes, args.segmenter_frames)
        report["segmenter_ms"] = ms
        met.append(_verdict("learned segmenter per frame", ms, SEGMENTER_TARGET_MS, "ms"))
    print("\ntargets:")
    for line in met:
        print("  " + line)
    args.work.mkdir(parents=True, exist_ok=True)
    (args.work / "speed.json").write_text(json.dumps(report, indent=1))


def _verdict(what: str, value: float, target: float, unit: str) -> str:
    word = "met" if value <= target else f"MISSED by {value - target:.2f} {unit}"
    return f"{what}: {value:.2f} {unit} (target {target:g} {unit}) {word}"


def _print_run(run: dict[str, Any]) -> None:
    print(
        f"\n{run['method']} ({run['track']}): {run['queries']} queries, median {run['median_s']:.3f} s, "
        f"mean {run['mean_s']:.3f} s; R@50 {run['recall50']:.1%}, R@25 {run['recall25']:.1%}"
    )
    for stage, v in run["stages_median_s"].items():
        print(f"  {stage:<18} median {v:.4f} s  mean {run['stages_mean_s'][stage]:.4f} s")
    for scene, m in run["maps"].items():
        stages = ", ".join(f"{k} {v:.1f}" for k, v in m.get("stages", {}).items() if k != "total")
        print(f"  map {scene}: {m['seconds']:.1f} s for {m['frames']} frames" + (f" ({stages})" if stages else ""))
    if "agreement" in run:
        a = run["agreement"]
        if "same" in a:
            print(
                f"  vs reference: {a['same']} poses agree, {a['differ']} differ (worst {a['max_dt_m'] * 1000:.2f} mm, "
                f"{a['max_dr_deg']:.4f} deg)"
            )
        else:
            print("  vs reference: no reference poses")


if __name__ == "__main__":
    main()
