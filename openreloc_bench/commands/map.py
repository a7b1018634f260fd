"""Build a method's map from the ``mapping`` split of one scene.

Works for every registered method (``openreloc-bench methods`` lists them). Method settings come from
``--config`` (a YAML mapping of the method's config fields) and ``--set key=value`` (repeatable; dotted
keys reach nested sections, values are parsed as YAML), e.g.::

  openreloc-bench map --method openreloc --scene data/smoke-room --out maps/smoke \\
      --set mapping.landmark_voxel=0.03 --set encoder=clip

The mapping frames carry the dataset's instance masks on the oracle-mask track only (never for a method
that declares it reads no masks); the map records its track, and ``localize`` refuses another.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from openreloc_bench.commands.options import TRACK_HELP, add_method_arguments, add_track_argument, method_overrides
from openreloc_bench.data import mapfile, paths
from openreloc_bench.data.scene import Scene
from openreloc_bench.harness.cache import build_map, dir_bytes
from openreloc_bench.methods import create_method, recorded_track

NAME = "map"
HELP = "build a method's map from a scene's mapping split"
ORDER = 20


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_method_arguments(p)
    p.add_argument("--scene", type=Path, required=True, help="scene directory (with a mapping split)")
    p.add_argument("--out", type=Path, required=True, help="map directory to write")
    add_track_argument(p, TRACK_HELP)


def run(args: argparse.Namespace) -> int:
    paths.check_output(args.out, [args.scene], "--out")
    method = create_method(args.method, **method_overrides(args))
    scene = Scene(args.scene)
    track = recorded_track(method, args.track)
    scene.sequence("mapping", track)  # refused before any work, as the build would refuse it
    # the directory holds the map alone (its size is the map's): a previous map there is replaced once
    # the new one is complete (built beside it), anything else is refused; no other build writes there
    with paths.directory_lock(args.out, "openreloc-bench map", in_directory=False):
        mapfile.replaceable_files(args.out)
        with paths.staged(args.out) as stage:
            built = build_map(method, scene, track, stage)
            # what the map is of: `localize` refuses to pair it with another scene
            mapfile.record_source(stage, built[mapfile.SOURCE_KEY])
            mapfile.clear_file_set(args.out)
            for part in sorted(stage.iterdir(), key=lambda f: f.name == mapfile.MANIFEST):  # the manifest last
                os.rename(part, args.out / part.name)
            stage.rmdir()
    size = dir_bytes(args.out)
    print(
        f"{args.method}: map of {built['n_mapping_frames']} mapping frames ({track} track) written to {args.out} "
        f"({size / 1e6:.3f} MB, {built['mapping_time_s']:.1f} s)"
    )
    return 0
