"""Write pictures of a generated scene: a contact sheet (RGB / depth / instances of sample frames of
every split) and a top-down floor plan (rooms, objects, mapping trajectory, query poses).
"""

from __future__ import annotations

import argparse
from pathlib import Path

NAME = "preview"
HELP = "contact sheet and floor plan PNGs of a generated scene"
ORDER = 11


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("scene", type=Path, help="scene directory, e.g. data/smoke-room")
    parser.add_argument(
        "--out",
        type=Path,
        default=None,
        help="contact sheet PNG (default SCENE/preview.png); the plan goes next to it as *_plan.png",
    )
    parser.add_argument("--frames", type=int, default=4, help="sample frames per split (default 4)")


def run(args: argparse.Namespace) -> int:
    from generators.preview import write_previews

    for path in write_previews(args.scene, args.out, frames_per_split=args.frames):
        print(path)
    return 0
