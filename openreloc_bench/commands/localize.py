"""Localize every frame of a query split against a method's map and write a result file.

The result file is the benchmark format (``name qw qx qy qz tx ty tz`` of T_cw). A query the method
cannot place (a failure, or an exception inside the method) is left out of the file and counted in
the summary; it never stops the run. ``--diagnostics`` writes one JSON line per query (the method's
diagnostics: matches, timings, explanation...); ``--draw DIR`` one picture per query of what the method
matched (its keypoints, kept or rejected by the pose, and its objects: :mod:`openreloc_bench.matchview`,
like hloc's ``visualize_loc``). When the split has ground-truth poses the summary
also prints recall@50/25 cm; the method never sees them. The file's header names the track: --track,
or mask-free for a method that declares it reads no masks (it is given none).

  openreloc-bench localize --method openreloc --map maps/smoke --scene data/smoke-room \\
      --split query --out poses.txt [--draw matches/]
"""

from __future__ import annotations

import argparse
import json
import math
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from openreloc_bench import geometry
from openreloc_bench.commands.options import TRACK_HELP, add_method_arguments, add_track_argument, method_overrides
from openreloc_bench.data import io, paths
from openreloc_bench.data.results import write_results
from openreloc_bench.data.scene import Scene
from openreloc_bench.data.splits import QUERY_SPLITS
from openreloc_bench.data.types import SceneSequence
from openreloc_bench.errors import ConfigError
from openreloc_bench.harness.cache import check_map_source
from openreloc_bench.methods import Answer, QueryFrame, Relocalizer, create_method, localize_safely, recorded_track
from openreloc_bench.tracks import RecordedTrack

NAME = "localize"
HELP = "localize a query split against a map and write poses"
ORDER = 30


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_method_arguments(p)
    p.add_argument("--map", type=Path, required=True, help="map directory (from `openreloc-bench map`)")
    p.add_argument("--scene", type=Path, required=True, help="scene directory")
    p.add_argument("--split", default="query", choices=QUERY_SPLITS, help="query split")
    p.add_argument("--out", type=Path, required=True, help="result file to write")
    add_track_argument(p, TRACK_HELP)
    p.add_argument("--diagnostics", type=Path, help="also write per-query diagnostics as JSON lines")
    p.add_argument("--draw", type=Path, metavar="DIR", help="also draw what the method matched in each query (PNGs)")


def localize_split(
    method: Relocalizer, seq: SceneSequence, track: RecordedTrack, progress: bool = True
) -> list[Answer]:
    """Localize every frame of ``seq``; failures and method exceptions are answers with a reason."""
    return [
        localize_safely(method, QueryFrame.from_frame(f, track))
        for f in tqdm(seq, desc=f"localize {seq.split}", disable=not progress, leave=False)
    ]


def summary(records: list[Answer], gt: dict[str, np.ndarray] | None = None) -> list[str]:
    """Printable lines: localized share, failure reasons, latency, and recall when ground truth exists."""
    n = len(records)
    ok = [r for r in records if r.T_wc is not None]
    lines = [
        f"localized {len(ok)}/{n} queries; median latency {np.median([r.seconds for r in records]) if n else 0:.3f} s"
    ]
    for reason, count in Counter(r.reason for r in records if r.T_wc is None).most_common():
        lines.append(f"  failed x{count}: {reason}")
    if gt and n:
        te = np.array(
            [geometry.translation_error(gt[r.name], r.T_wc) if r.T_wc is not None else np.inf for r in records]
        )
        re = np.array([geometry.rotation_error(gt[r.name], r.T_wc) if r.T_wc is not None else np.inf for r in records])
        lines.append(
            f"vs ground truth: recall@50cm {np.mean(te < 0.5):.1%}, @25cm {np.mean(te < 0.25):.1%}, "
            f"(25cm, 5deg) {np.mean((te < 0.25) & (re < 5)):.1%}; median error "
            f"{np.median(te) * 100:.1f} cm / {np.median(re):.2f} deg"
        )
    return lines


def _json_safe(v: Any) -> Any:
    """A method's diagnostics as standard JSON holds them: NaN as null, infinities as "inf" / "-inf",
    sets as sorted lists, numpy values as Python ones, anything else as its text."""
    if isinstance(v, dict):
        return {str(k): _json_safe(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_json_safe(x) for x in v]
    if isinstance(v, (set, frozenset)):
        return sorted((_json_safe(x) for x in v), key=repr)
    if isinstance(v, (np.ndarray, np.generic)):
        return _json_safe(v.tolist())
    if isinstance(v, float) and not math.isfinite(v):
        return None if math.isnan(v) else ("inf" if v > 0 else "-inf")
    if v is None or isinstance(v, (bool, int, float, str)):
        return v
    return str(v)


def run(args: argparse.Namespace) -> int:
    for flag, out in (("--out", args.out), ("--diagnostics", args.diagnostics)):
        if out is not None:
            paths.check_output_file(out, [args.scene, args.map], flag)
    if args.diagnostics is not None and args.diagnostics.resolve() == args.out.resolve():
        raise ConfigError(f"--diagnostics and --out are the same file {args.out}; give two paths")
    if args.draw is not None:
        paths.check_output_folder(args.draw, [args.scene, args.map], "--draw")
    method = create_method(args.method, **method_overrides(args))
    scene = Scene(args.scene)
    track = recorded_track(method, args.track)
    seq = scene.sequence(args.split, track)
    check_map_source(args.map, scene, track)
    method.load_map(args.map)
    records = localize_split(method, seq, track)
    poses = {r.name: r.T_wc for r in records if r.T_wc is not None}
    write_results(
        args.out,
        poses,
        [
            f"method {args.method}",
            f"track {track}",
            f"split {args.split}",
            f"localized {len(poses)}/{len(records)}",
        ],
    )
    if args.diagnostics:
        lines = [
            json.dumps(
                _json_safe(
                    {
                        "name": r.name,
                        "ok": r.T_wc is not None,
                        "reason": r.reason or None,
                        "seconds": round(r.seconds, 4),
                        "diagnostics": r.diagnostics,
                    }
                ),
                sort_keys=True,
                allow_nan=False,
            )
            for r in records
        ]
        io.atomic_write_text(args.diagnostics, "\n".join(lines) + "\n")
    gt = dict(zip(seq.names, seq.poses))
    if args.draw is not None:
        from openreloc_bench.matchview import draw_query

        args.draw.mkdir(parents=True, exist_ok=True)
        for frame, r in zip(seq, records):
            draw_query(frame.color, r, gt.get(r.name), args.method, args.draw / f"{r.name.replace('/', '_')}.png")
        print(f"{len(records)} pictures of what {args.method} matched in {args.draw}")
    for line in summary(records, gt):
        print(line)
    print(f"poses written to {args.out}")
    return 0
