"""Measure OpenReLoc stage by stage on scenes with true poses: where does a track lose?

Per scene and pooled: the map's landmarks (count, points, extent) and the cross-view recall of their
descriptors; unless --no-localize, recall at 50 / 25 cm over every query and the pose stages read
from each query's diagnostics and true pose: segments and matches per query, how often vision and
language agree, the verification's pass rate, the coarse prior's own error, what refinement did to
its start, and the share of wrong poses whose prior was right. Scenes with instance labels (generated
ones) also get query segmentation (mean best IoU, AP50, over- / under-segmentation, boundary F-score
at 2 px), the map's 3D instance precision / recall at IoU 0.5 and 0.25 with every true object's error
(found, split, merged, missed; by size) and the association precision; --swap (predicted track)
localizes again with the dataset's masks on one side, to tell which side costs more. A real recording
(``import``) has no labels: diagnose it on the predicted track. A table goes to stderr, JSON to
stdout; --out also writes diagnose.json, diagnose.md and, with --pictures N, the N queries farthest
from the truth drawn per scene (segments; matched landmarks at the estimated and the true pose).
Maps are built under --work and reused.

  openreloc-bench diagnose --suite scenes/validation.yaml --data data/val --track predicted --work work/diag
  openreloc-bench diagnose --scenes data/real/fr1_rpy --work work/diag --out diag --pictures 4
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from openreloc_bench.commands.options import add_method_config_arguments, add_track_argument, method_overrides
from openreloc_bench.errors import ConfigError
from openreloc_bench.tracks import PREDICTED

NAME = "diagnose"
HELP = "OpenReLoc's losses stage by stage (segmentation, 3D instances, association, poses)"
ORDER = 42


def add_arguments(p: argparse.ArgumentParser) -> None:
    where = p.add_mutually_exclusive_group(required=True)
    where.add_argument(
        "--scenes", help="comma-separated scene directories, or scene names under --data (as eval's --scenes)"
    )
    where.add_argument("--suite", type=Path, help="suite YAML whose scenes lie under --data")
    p.add_argument("--data", type=Path, help="dataset directory of --suite, or of --scenes given by name")
    add_track_argument(p, "predicted: the method's segmenter on map and queries; oracle-mask: the dataset's masks")
    p.add_argument("--splits", default="query", help="comma-separated query splits")
    p.add_argument("--frames", type=int, default=12, help="frames per split whose segmentation is scored")
    p.add_argument("--no-localize", action="store_true", help="segmentation and map only")
    p.add_argument("--swap", action="store_true", help="also localize with the dataset's masks on one side")
    p.add_argument(
        "--pictures",
        type=int,
        default=0,
        help="queries drawn per scene and split, the farthest from the truth first (needs --out)",
    )
    p.add_argument("--work", type=Path, required=True, help="folder for the maps (reused while unchanged)")
    p.add_argument("--out", type=Path, help="folder for diagnose.json and diagnose.md")
    add_method_config_arguments(p)


def run(args: argparse.Namespace) -> int:
    from openreloc_bench import config as cfgmod
    from openreloc_bench.data import io, paths
    from openreloc_bench.harness.diagnose import DiagnoseOptions, diagnose_scene, pool

    scene_dirs = _scene_dirs(args)
    options = cfgmod.from_dict(
        DiagnoseOptions,
        {
            "track": args.track,
            "splits": tuple(s for s in args.splits.split(",") if s),
            "frames": args.frames,
            "localize": not args.no_localize,
            "swap": args.swap,
            "pictures": args.pictures,
        },
        "diagnose",
    )
    if options.frames < 1:
        raise ConfigError(f"--frames must be >= 1, got {options.frames}")
    if options.swap and options.track != PREDICTED:
        raise ConfigError(f"--swap swaps predicted masks for the dataset's: it needs --track {PREDICTED}")
    if options.pictures < 0 or (options.pictures and args.out is None):
        raise ConfigError("--pictures takes a count >= 0 and needs --out (the folder they are written to)")
    for out in (args.work, args.out):
        if out is not None:
            paths.check_output_folder(out, scene_dirs, "output folder")
    overrides = method_overrides(args)
    rows = [diagnose_scene(d, overrides, options, args.work, out_dir=args.out) for d in scene_dirs]
    result = {"track": options.track, "pooled": pool(rows), "scenes": rows}
    result.update(_headline(result["pooled"]))
    text = "\n".join(table(rows, result["pooled"]))
    print(text, file=sys.stderr)
    if args.out is not None:
        args.out.mkdir(parents=True, exist_ok=True)
        io.write_json(args.out / "diagnose.json", result)
        (args.out / "diagnose.md").write_text(f"# diagnose ({options.track})\n\n```\n{text}\n```\n")
    print(json.dumps(result, default=float))
    return 0


def _scene_dirs(args: argparse.Namespace) -> list[Path]:
    if args.suite is not None:
        from openreloc_bench.harness.suites import suite_scene_names

        if args.data is None:
            raise ConfigError("--suite needs --data (the folder holding its generated scenes)")
        dirs = [args.data / n for n in suite_scene_names(args.suite)]
    else:
        # as eval's: a plain name is a scene under --data (where given), anything else a scene's path
        dirs = [
            args.data / s if args.data is not None and Path(s).name == s else Path(s)
            for s in args.scenes.split(",")
            if s
        ]
        seen = [d.resolve() for d in dirs]
        twice = next((d for k, d in enumerate(dirs) if seen[k] in seen[:k]), None)
        if twice is not None:
            raise ConfigError(f"--scenes names {twice.name} twice: each scene would count twice in the pooled numbers")
    missing = [d for d in dirs if not (d / "scene.json").is_file()]
    if missing:
        raise ConfigError(f"no scene at {missing[0]} (generate it first: `openreloc-bench generate SUITE --out DIR`)")
    if not dirs:
        raise ConfigError("no scenes given")
    return dirs


def _headline(pooled: dict[str, Any]) -> dict[str, Any]:
    """The numbers a script reads first: map precision / recall at IoU 0.5, first split's query IoU."""
    m = pooled.get("map", {})
    seg = next(iter(pooled.get("segmentation", {}).values()), {})
    return {
        "map_precision": m.get("precision"),
        "map_recall": m.get("recall"),
        "query_iou": seg.get("mean_best_iou"),
    }


def table(rows: list[dict[str, Any]], pooled: dict[str, Any]) -> list[str]:
    """Printable lines: one per scene and a pooled one, per stage."""
    from openreloc_bench.reconstruction.instance_eval import OBJECT_ERRORS, SIZES

    lines = [
        f"{'scene':<10} {'map P/R@.5':>11} {'P/R@.25':>10} {'pred':>5} {'gt':>4}  objects found/split/merged/missed"
    ]
    for name, m in [(r["scene"], r["map"]) for r in rows] + [("pooled", pooled.get("map", {}))]:
        if "objects" in m:
            o = m["objects"]
            counts = "/".join(str(sum(o[e].values())) for e in ("found", "split", "merged", "missed"))
            lines.append(
                f"{name:<10} {m['precision']:5.2f}/{m['recall']:<5.2f} {m['precision_25']:4.2f}/{m['recall_25']:<5.2f}"
                f" {m['n_pred']:5d} {m['n_gt']:4d}  {counts}"
            )
    o = pooled.get("map", {}).get("objects")
    if o:
        lines.append(
            "pooled errors by size (small/medium/large): "
            + "; ".join(f"{e} {[o[e][s] for s in SIZES]}" for e in OBJECT_ERRORS)
        )
    for split, s in pooled.get("segmentation", {}).items():
        lines.append(
            f"segmentation {split}: mean best IoU {s['mean_best_iou']:.3f}, AP50 {s['ap50']:.3f}, boundary F@2px "
            f"{s['boundary_f']:.3f}, over {s['over_segmentation']:.3f}, under {s['under_segmentation']:.3f} ({s['objects']} objects)"
        )
    for label, block in [("localization", pooled.get("localization", {}))] + list(pooled.get("swap", {}).items()):
        for split, s in block.items():
            precision = s["association_precision"]
            lines.append(
                f"{label} {split}: R@50 {s['recall_50cm']:.1f}, R@25 {s['recall_25cm']:.1f}, association precision "
                + ("- (no instance labels)" if precision is None else f"{precision:.3f}")
                + f" ({s['accepted_matches']} matches, {s['queries']} queries)"
            )
    for split, s in pooled.get("localization", {}).items():
        if "stages" in s:
            lines += stage_lines(split, s["stages"])
    return lines


def stage_lines(split: str, st: dict[str, Any]) -> list[str]:
    """The pose stages of one split (:mod:`openreloc_bench.harness.pose_stages`), a line per stage."""

    def num(v: float | None, fmt: str = ".1f") -> str:
        return "-" if v is None else format(v, fmt)

    def recall(r: dict[str, Any]) -> str:
        return (
            f"R@50 {num(r['recall_50cm'])}, R@25 {num(r['recall_25cm'])}, (25cm, 5deg) {num(r['recall_25cm_5deg'])},"
            f" median {num(r['median_te_m'], '.2f')} m / {num(r['median_re_deg'])} deg"
        )

    how = ", ".join(f"{k} {num(v)}%" for k, v in st["matches_by_how"].items())
    return [
        f"stages {split} ({st['queries']} queries):",
        f"  segments {num(st['segments_per_query'])} and unique objects {num(st['unique_per_query'])} per query"
        f" (medians); matches {num(st['matches_per_query'])} per query ({how})",
        f"  vision and language agree on {num(st['modalities_agree'])}% of associated matches; verification"
        f" finds a pose for {num(st['verification_pass_rate'])}% of the queries it sees",
        f"  poses from keypoints ({num(st['keypoint_pose']['share'])}%): {recall(st['keypoint_pose'])}",
        f"  poses from objects ({num(st['object_pose']['share'])}%):   {recall(st['object_pose'])}",
        f"  coarse prior (first reference frame): {recall(st['coarse_prior'])}",
        f"  best reference start (object poses):  {recall(st['best_reference_start'])}",
        f"  refinement start (chosen):           {recall(st['refinement_start'])}",
        f"  final:                               {recall(st['final'])}",
        f"  refinement (object poses): {num(st['refinement_worse'])}% worse, {num(st['refinement_better'])}% better than its start"
        f" (by > 5 cm), median change {num(st['refinement_median_change_m'], '+.2f')} m; wrong final poses"
        f" (>= 25 cm) with a right prior: {num(st['wrong_with_right_prior'])}%, with a right reference start:"
        f" {num(st['wrong_with_right_reference'])}%",
        f"  failures: {st['failures'] or 'none'}",
    ]
