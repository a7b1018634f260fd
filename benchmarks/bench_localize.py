"""Per-stage latency and recall of a method on scene splits, one query at a time (the paper's efficiency
table). ``--map`` and ``--scene`` may repeat, in pairs: the table then pools every scene's queries.

  .venv/bin/python benchmarks/bench_localize.py --map MAPDIR --scene DIR/<scene> [--map ... --scene ...]
      [--split query] [--method openreloc] [--track predicted|oracle-mask] [--set key=value ...] [--threads 1]
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

import numpy as np
import torch

from openreloc_bench.commands.localize import localize_split, summary
from openreloc_bench.config import parse_overrides
from openreloc_bench.data.scene import Scene
from openreloc_bench.methods import create_method
from openreloc_bench.openreloc.method import STAGES
from openreloc_bench.tracks import DEFAULT_TRACK, TRACKS


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--map", type=Path, action="append", required=True, help="a scene's map (repeat with --scene)")
    p.add_argument("--scene", type=Path, action="append", required=True, help="the scene the map is of")
    p.add_argument("--split", default="query")
    p.add_argument("--method", default="openreloc")
    p.add_argument("--track", default=DEFAULT_TRACK, choices=TRACKS)
    p.add_argument("--set", dest="overrides", action="append", default=[])
    p.add_argument("--threads", type=int, default=1, help="torch threads (the 2-core target machine: 1)")
    args = p.parse_args()
    if len(args.map) != len(args.scene):
        p.error(f"--map and --scene come in pairs: got {len(args.map)} maps and {len(args.scene)} scenes")
    torch.set_num_threads(args.threads)
    method = create_method(args.method, **parse_overrides(args.overrides))
    records, gt = [], {}
    for map_dir, scene in zip(args.map, args.scene):
        seq = Scene(scene).sequence(args.split)
        method.load_map(map_dir)
        # query names repeat across scenes: prefix them with the scene's
        records += [
            dataclasses.replace(r, name=f"{scene.name}/{r.name}") for r in localize_split(method, seq, args.track)
        ]
        gt.update({f"{scene.name}/{n}": T for n, T in zip(seq.names, seq.poses)})
    scenes = ", ".join(s.name for s in args.scene)
    print(f"{args.method} on {scenes} / {args.split} ({args.track}, {len(records)} queries, one at a time)")
    print(f"{'stage':<10} {'median s':>9} {'mean s':>9}")
    for stage in (*STAGES, "total"):
        vals = [r.diagnostics.get("timings", {}).get(stage) for r in records]
        vals = [v for v in vals if v is not None]
        if vals:
            print(f"{stage:<10} {np.median(vals):9.4f} {np.mean(vals):9.4f}")
    matches = [mt for r in records for mt in r.diagnostics.get("matches", [])]
    scored = [mt for mt in matches if mt.get("query_instance") is not None]
    if scored:  # the oracle instance ids score the association; the method never uses them
        correct = sum(mt["landmark"] == mt["query_instance"] for mt in scored)
        print(f"association precision {correct / len(scored):.1%} ({correct}/{len(scored)} accepted matches correct)")
    hyps = [r.diagnostics.get("chosen") for r in records if r.diagnostics.get("chosen")]
    if hyps:
        kinds = [h.split(":")[0] for h in hyps]
        print("chosen hypothesis: " + ", ".join(f"{k} x{kinds.count(k)}" for k in sorted(set(kinds))))
    for line in summary(records, gt):
        print(line)


if __name__ == "__main__":
    main()
