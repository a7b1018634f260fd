"""Validate an asset pack (a directory of meshes and its ``manifest.yaml``) and write its gallery.

Prints one line per problem (a missing or unreadable file, a mesh without texture, an absurd size, an
unknown placement...) and exits 1 when there is any; a pack that loads also gets a gallery PNG of every
asset rendered alone. ``--example`` first writes the project's example pack into DIR.
"""

from __future__ import annotations

import argparse
from pathlib import Path

NAME = "assets"
HELP = "validate an asset pack of meshes and write its gallery image"
ORDER = 12


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("pack", type=Path, metavar="PACK", help="asset pack directory (manifest.yaml and its meshes)")
    parser.add_argument(
        "--gallery",
        type=Path,
        default=None,
        help="gallery PNG, never inside the pack (default: ./<pack directory name>_gallery.png)",
    )
    parser.add_argument(
        "--backend",
        choices=["mujoco", "pyrender"],
        default="mujoco",
        help="renderer of the gallery",
    )
    parser.add_argument(
        "--example", action="store_true", help="write the example pack into PACK first (a new directory)"
    )


def run(args: argparse.Namespace) -> int:
    from generators.asset_packs import validate_pack
    from openreloc_bench.data import paths
    from openreloc_bench.errors import ConfigError

    if args.example:
        from generators.example_pack import write_example_pack

        if args.pack.exists() and any(args.pack.iterdir()):
            raise ConfigError(f"{args.pack}: exists and is not empty; --example writes a new pack")
        write_example_pack(args.pack)
    if not args.pack.is_dir():
        raise ConfigError(f"{args.pack}: not a directory")
    gallery = args.gallery or Path(f"{args.pack.resolve().name}_gallery.png")
    paths.check_output_file(gallery, [args.pack], "--gallery", suffix=".png")
    pack, problems = validate_pack(args.pack)
    for line in problems:
        print(line)
    if pack is not None:
        from generators.pack_gallery import write_gallery
        from openreloc_bench.vision.vocabulary import noun

        out = write_gallery(pack, gallery, args.backend)
        print(f"{len(pack.assets)} assets, {len(pack.categories)} categories; gallery: {out}")
        print("describer nouns (describer_options: {extra_nouns: [...]}): " + ", ".join(map(noun, pack.categories)))
    return 1 if problems else 0
