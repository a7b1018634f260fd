"""Write pictures of a generated scene: a contact sheet (RGB / depth / instances of sample frames of
every split) and a top-down floor plan (rooms, objects, mapping trajectory, query poses).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from openreloc_bench.data import paths
from openreloc_bench.errors import ConfigError

NAME = "preview"
HELP = "contact sheet and floor plan PNGs of a generated scene"
ORDER = 11

MAX_FRAMES = 32
"""Most sample frames per split: each adds three columns to the contact sheet."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("scene", type=Path, metavar="SCENE", help="scene directory, e.g. data/smoke-room")
    parser.add_argument(
        "--out",
        type=Path,
        default=None,
        help="contact sheet PNG (default: ./<scene name>_preview.png, never inside the scene); the plan goes "
        "next to it as *_plan.png",
    )
    parser.add_argument("--frames", type=int, default=4, help=f"sample frames per split, 1-{MAX_FRAMES}")


def run(args: argparse.Namespace) -> int:
    from generators.preview import write_previews

    if not 1 <= args.frames <= MAX_FRAMES:
        raise ConfigError(f"--frames must be in [1, {MAX_FRAMES}], got {args.frames}")
    out = args.out or Path(f"{args.scene.resolve().name}_preview.png")
    for path in (out, out.with_name(out.stem + "_plan.png")):
        paths.check_output_file(path, [args.scene], "--out", suffix=".png")
    for path in write_previews(args.scene, out, frames_per_split=args.frames):
        print(path)
    return 0
