"""Convert a real recording into the scene layout, so that ``eval --scenes`` runs on it.

  scannet SRC  a ScanNet export made by ScanNet's SensReader from the ``.sens`` file (``color/``,
               ``depth/``, ``pose/``, ``intrinsic/``; ``instance-filt/`` from the 2D instance zip when
               present). Colour is resized to the depth size; ``<scene>.aggregation.json`` in SRC or
               next to it (or --aggregation) gives the instances' labels in ``objects.json``.
  tum SRC      a TUM RGB-D sequence (``rgb.txt``, ``depth.txt``, ``groundtruth.txt``): each colour frame
               associated with the nearest depth and ground-truth stamps within --max-dt; depth
               converted from 5000 units per metre to millimetres.

Both are split by the paper's protocol: mapping frames 0, 20, 40..., query frames 10, 30, 50...
(--stride, --offset). TUM sequences have no instance masks: evaluate them with --track predicted.

Example:
  openreloc-bench import scannet scans/scene0000_00 --out data/scannet/scene0000_00
  openreloc-bench eval --scenes scene0000_00 --data data/scannet --methods openreloc --out results
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from openreloc_bench import geometry
from openreloc_bench.data import convert
from openreloc_bench.errors import ConfigError

NAME = "import"
HELP = "convert a ScanNet export or a TUM RGB-D sequence into a scene"
ORDER = 15


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("format", choices=convert.FORMATS, help="the recording's format")
    p.add_argument("src", type=Path, metavar="SRC", help="the export / sequence directory")
    p.add_argument("--out", type=Path, required=True, help="the new scene directory, DATA/<scene>")
    p.add_argument("--stride", type=int, default=20, help="frames between two mapping frames")
    p.add_argument("--offset", type=int, default=10, help="first query frame (query frames are offset + k * stride)")
    p.add_argument("--aggregation", type=Path, help="scannet: the aggregation JSON with the instances' labels")
    p.add_argument(
        "--intrinsics",
        metavar="FX,FY,CX,CY",
        help="tum: the colour camera's intrinsics (default: the ROS defaults the TUM benchmark recommends)",
    )
    p.add_argument("--max-dt", type=float, default=0.02, help="tum: largest colour-depth / ground-truth gap (s)")


def _intrinsics(text: str) -> np.ndarray:
    try:
        fx, fy, cx, cy = (float(v) for v in text.split(","))
    except ValueError:
        raise ConfigError(f"--intrinsics expects FX,FY,CX,CY, got '{text}'") from None
    return geometry.intrinsics(fx, fy, cx, cy)


def run(args: argparse.Namespace) -> int:
    if args.format == "scannet":
        if args.intrinsics:
            raise ConfigError("--intrinsics is for tum: a ScanNet export has its own intrinsic/ folder")
        report = convert.import_scannet(args.src, args.out, args.stride, args.offset, args.aggregation)
    else:
        if args.aggregation:
            raise ConfigError("--aggregation is for scannet")
        if not 0 < args.max_dt < 1:
            raise ConfigError(f"--max-dt must be in (0, 1) seconds, got {args.max_dt}")
        K = _intrinsics(args.intrinsics) if args.intrinsics else None
        report = convert.import_tum(args.src, args.out, args.stride, args.offset, K, args.max_dt)
    counts = ", ".join(f"{n} {split}" for split, n in report.frames.items())
    objects = f", {report.objects} objects" if report.objects else ""
    skipped = f" ({len(report.skipped)} frame(s) skipped: no valid pose or depth)" if report.skipped else ""
    print(f"{report.scene}: {counts} frames{objects}{skipped}")
    return 0
