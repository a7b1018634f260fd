"""Write a scene in the formats of the field's tools, so that their pipelines run on it.

  colmap SCENE  COLMAP's text model of the mapping split (``sparse/cameras.txt``, ``images.txt``,
                ``points3D.txt``: known poses, points from depth with their tracks) and hloc's query
                list with intrinsics (``queries_with_intrinsics.txt``) for the query splits.

Image names are relative to SCENE, so SCENE is the image directory of the COLMAP / hloc pipeline;
``score --names hloc`` reads the pose files such a pipeline writes. (``eval`` already writes the
ground truth of every localized split as ``<split>.gt.tum`` next to the estimates' ``<split>.tum``.)

Example:
  openreloc-bench export colmap data/multi-room/sc1 --out exports/sc1
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from openreloc_bench.data import colmap, io, paths
from openreloc_bench.data.scene import Scene
from openreloc_bench.errors import ConfigError, DataError

NAME = "export"
HELP = "write a scene as a COLMAP model and an hloc query list"
ORDER = 16


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("format", choices=("colmap",), help="the tools' format")
    p.add_argument("scene", type=Path, metavar="SCENE", help="scene directory")
    p.add_argument("--out", type=Path, required=True, help="a new directory for the export")
    p.add_argument("--splits", default="query", help="comma-separated query splits listed for hloc")
    p.add_argument("--voxel", type=float, default=0.05, help="size of the voxel one 3D point stands for (m)")
    p.add_argument("--pixel-step", type=int, default=8, help="every n-th pixel (in x and y) is lifted to 3D")


def run(args: argparse.Namespace) -> int:
    if not (math.isfinite(args.voxel) and args.voxel > 0) or args.pixel_step < 1:
        raise ConfigError("--voxel must be > 0 metres and --pixel-step >= 1")
    splits = list(dict.fromkeys(s.strip() for s in args.splits.split(",") if s.strip()))
    if not splits or "mapping" in splits:
        raise ConfigError("--splits names the query splits to list (the mapping split is the model)")
    scene = Scene(args.scene)
    out = paths.check_output(args.out, [scene.root], "--out")
    mapping = scene.sequence("mapping")
    if not mapping.has_depth:
        raise DataError(scene.root / "mapping" / "depth", "mapping frames without depth: no 3D points to export")
    queries = []
    for split in splits:
        if split not in scene.splits():
            raise DataError(scene.root, f"scene has no split '{split}' (available: {', '.join(scene.splits())})")
        queries.append(scene.sequence(split))
    not_empty = f"--out {args.out} is not empty; exporting writes a new directory"
    with paths.new_directory(out, "openreloc-bench export", not_empty) as stage:
        counts = colmap.write_model(mapping, stage / "sparse", args.voxel, args.pixel_step)
        io.atomic_write_text(stage / "queries_with_intrinsics.txt", colmap.query_list(queries))
    query_file = out / "queries_with_intrinsics.txt"
    print(
        f"{out / 'sparse'}: {counts['images']} images, {counts['points']} points, {counts['observations']} "
        f"observations; {query_file}: {sum(len(q) for q in queries)} queries (image directory: {scene.root})"
    )
    return 0
