"""Convert a real recording into the scene layout, so that ``eval --scenes`` runs on it.

  scannet SRC   a ScanNet export made by ScanNet's SensReader from the ``.sens`` file (``color/``,
                ``depth/``, ``pose/``, ``intrinsic/``; ``instance-filt/`` from the 2D instance zip when
                present). Colour is resized to the depth size; ``<scene>.aggregation.json`` in SRC or
                next to it (or --aggregation) gives the instances' labels in ``objects.json``.
  tum SRC       a TUM RGB-D sequence (``rgb.txt``, ``depth.txt``, ``groundtruth.txt``): each colour frame
                associated with the nearest depth and ground-truth stamps within --max-dt; depth
                converted from 5000 units per metre to millimetres.
  7scenes SRC   a 7-Scenes scene (``seq-XX/frame-XXXXXX.{color.png,depth.png,pose.txt}``, ``TrainSplit.txt``,
                ``TestSplit.txt``), seen by the colour camera: depth re-projected into it and poses moved
                onto it with the calibration DSAC* and ACE use (f = 525 colour, 585 depth, the depth-to-colour
                transform ACE applies); colour and depth stay a few pixels apart.
  12scenes SRC  a 12-Scenes scene (``info.txt``, ``split.txt``, ``data/frame-XXXXXX.*``): colour resized to
                the depth size, as for ScanNet.

The split is the paper's protocol on one sequence: mapping frames 0, 20, 40..., query frames 10, 30,
50... (--stride, --offset; 7scenes: of --sequence). For 7scenes and 12scenes, --protocol splits maps
from the dataset's training frames and queries its test frames, taking frames 0, 20, 40... of the
training sequences and 10, 30, 50... of the test ones (--stride 1 --offset 0: every frame). Depth
readings beyond --max-depth count as missing. Only ScanNet has instance masks: evaluate the others with
--track predicted. How to get each dataset, its licence and its world frame: docs/real-data.md.

Example:
  openreloc-bench import scannet scans/scene0000_00 --out data/scannet/scene0000_00
  openreloc-bench import 7scenes 7scenes/chess --protocol splits --out data/7scenes/chess
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
HELP = "convert a ScanNet export, a TUM RGB-D sequence or a 7-Scenes / 12-Scenes scene into a scene"
ORDER = 15
FORMAT_OPTIONS = {
    "aggregation": ("scannet",),
    "intrinsics": ("tum", "7scenes"),
    "sequence": ("7scenes",),
}
"""The options only some formats take."""


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("format", choices=convert.FORMATS, help="the recording's format")
    p.add_argument("src", type=Path, metavar="SRC", help="the export / sequence / scene directory")
    p.add_argument("--out", type=Path, required=True, help="the new scene directory, DATA/<scene>")
    p.add_argument(
        "--protocol",
        choices=convert.PROTOCOLS,
        default="stride",
        help="stride: the paper's split of one sequence; splits (7scenes, 12scenes): the dataset's training "
        "frames map, its test frames query",
    )
    p.add_argument("--stride", type=int, default=20, help="frames between two mapping frames (and two query frames)")
    p.add_argument("--offset", type=int, default=10, help="first query frame (query frames are offset + k * stride)")
    p.add_argument(
        "--max-depth",
        type=float,
        default=convert.MAX_DEPTH_M,
        help="depth beyond this many metres is written as missing (past an indoor sensor's range)",
    )
    p.add_argument("--aggregation", type=Path, help="scannet: the aggregation JSON with the instances' labels")
    p.add_argument(
        "--intrinsics",
        metavar="FX,FY,CX,CY",
        help="tum, 7scenes: the colour camera's intrinsics (default: tum, the ROS defaults the TUM benchmark "
        "recommends; 7scenes, f = 525 at the image centre)",
    )
    p.add_argument("--sequence", metavar="seq-XX", help="7scenes, stride protocol: the sequence (default: the first)")
    p.add_argument("--max-dt", type=float, default=0.02, help="tum: largest colour-depth / ground-truth gap (s)")


def _intrinsics(text: str) -> np.ndarray:
    try:
        fx, fy, cx, cy = (float(v) for v in text.split(","))
    except ValueError:
        raise ConfigError(f"--intrinsics expects FX,FY,CX,CY, got '{text}'") from None
    return geometry.intrinsics(fx, fy, cx, cy)


def run(args: argparse.Namespace) -> int:
    for option, formats in FORMAT_OPTIONS.items():
        if getattr(args, option) and args.format not in formats:
            raise ConfigError(f"--{option} is for {' and '.join(formats)}")
    if args.protocol == "splits" and args.format not in convert.SPLIT_FORMATS:
        raise ConfigError(f"--protocol splits is for {' and '.join(convert.SPLIT_FORMATS)}: {args.format} has no split")
    K = _intrinsics(args.intrinsics) if args.intrinsics else None
    frames = {"stride": args.stride, "offset": args.offset, "max_depth": args.max_depth}
    if args.format == "scannet":
        report = convert.import_scannet(args.src, args.out, aggregation=args.aggregation, **frames)
    elif args.format == "tum":
        if not 0 < args.max_dt < 1:
            raise ConfigError(f"--max-dt must be in (0, 1) seconds, got {args.max_dt}")
        report = convert.import_tum(args.src, args.out, K=K, max_dt=args.max_dt, **frames)
    elif args.format == "7scenes":
        split_by = {"protocol": args.protocol, "sequence": args.sequence}
        report = convert.import_7scenes(args.src, args.out, K=K, **split_by, **frames)
    else:
        report = convert.import_12scenes(args.src, args.out, protocol=args.protocol, **frames)
    counts = ", ".join(f"{n} {split}" for split, n in report.frames.items())
    objects = f", {report.objects} objects" if report.objects else ""
    skipped = f" ({len(report.skipped)} frame(s) skipped: no valid pose or depth)" if report.skipped else ""
    print(f"{report.scene}: {counts} frames{objects}{skipped}")
    return 0
