"""Harness overhead: wall time of an evaluation outside the methods' own calls.

Runs ``nearest-frame`` (a method whose calls take well under a millisecond, so nearly all time is
harness) on synthetic scenes written with SceneWriter, once with queries in-process (--timeout 0) and
once through the per-query-timeout query server, and reports

    overhead = eval wall time - (mapping + load_map + localize time measured around the method calls)

Usage: python benchmarks/bench_harness.py [--scenes 2] [--queries 50] [--size 160x120] [--workers 1]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from openreloc_bench import geometry
from openreloc_bench.data import io
from openreloc_bench.data.runs import load_map_records
from openreloc_bench.data.scene import SceneWriter
from openreloc_bench.harness import runner


def write_scene(root: Path, name: str, n_map: int, n_query: int, w: int, h: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    sw = SceneWriter(root / name)
    sw.write_scene_info({"name": name, "spec_hash": f"bench-{seed}"})
    K = geometry.intrinsics_from_fov(w, h, 60.0)
    for split, n in (("mapping", n_map), ("query", n_query)):
        sw.write_intrinsics(split, K)
        for i in range(n):
            eye = np.r_[rng.uniform(0, 5, 2), 1.5]
            T = geometry.look_at(eye, eye + np.r_[rng.normal(size=2), 0.0])
            sw.write_frame(
                split,
                i,
                rng.integers(0, 255, (h, w, 3), dtype=np.uint8),
                np.full((h, w), 2.0),
                rng.integers(0, 8, (h, w)),
                T,
            )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenes", type=int, default=2)
    ap.add_argument("--queries", type=int, default=50)
    ap.add_argument("--size", default="160x120")
    ap.add_argument("--workers", type=int, default=1)
    args = ap.parse_args()
    w, h = map(int, args.size.split("x"))
    with tempfile.TemporaryDirectory() as tmp:
        data = Path(tmp) / "data"
        names = [f"bench{i}" for i in range(args.scenes)]
        for i, n in enumerate(names):
            write_scene(data, n, 30, args.queries, w, h, i)
        n_q = args.scenes * args.queries
        print(f"{args.scenes} scenes x {args.queries} queries at {w}x{h}, nearest-frame, {args.workers} worker(s)")
        print(f"{'mode':28s} {'wall s':>8s} {'method s':>9s} {'overhead s':>11s} {'per query ms':>13s}")
        for mode, timeout in (("in-process (--timeout 0)", 0.0), ("query server (--timeout 300)", 300.0)):
            out = Path(tmp) / f"out{timeout:g}"
            cfg = runner.EvalConfig(
                data=data,
                out=out,
                scenes=names,
                runs=[runner.MethodRun("nearest-frame", "nearest-frame")],
                workers=args.workers,
                timeout_s=timeout,
            )
            t0 = time.perf_counter()
            report = runner.evaluate(cfg)
            wall = time.perf_counter() - t0
            assert not report.errors, report.errors
            markers = [io.read_json(p) for p in out.glob("runs/*/*/*/*.done.json")]
            method_s = sum(m["load_map_s"] + m["localize_s"] for m in markers)
            method_s += float(load_map_records(out)["mapping_time_s"].sum())
            over = wall - method_s
            print(f"{mode:28s} {wall:8.2f} {method_s:9.2f} {over:11.2f} {1000 * over / n_q:13.1f}")


if __name__ == "__main__":
    main()
