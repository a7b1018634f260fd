"""Score pose files produced elsewhere (map-free style), so outside methods can enter the leaderboard.

SUBMISSION_DIR holds one file per scene, ``<scene>.txt`` or map-free's ``pose_<scene>.txt`` (names
``<split>/<frame id>``), or one per split, ``<scene>/<split>.txt``; each line ``name qw qx qy qz tx ty
tz`` with (q, t) of T_cw, optionally followed by map-free's confidence (kept in the query table).
``--names hloc`` reads hloc's image names (``query/color/000012.png``, relative to the scene directory,
as ``export colmap`` lists them). Queries without a line count as failures; duplicate names, NaNs,
non-unit quaternions, names of another style, files naming no scene under --data and a scene given
in two layouts are errors. Tables (CSV + JSON) are written
to --out, in the layout ``eval`` writes, for ``leaderboard``; ``--check`` only validates the files and
counts their poses (map-free's validator), writing nothing.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import pandas as pd

from openreloc_bench.data import paths
from openreloc_bench.data.results import NAME_STYLES
from openreloc_bench.errors import ConfigError
from openreloc_bench.harness import score, tables
from openreloc_bench.harness.suites import suite_scene_names
from openreloc_bench.tracks import DEFAULT_TRACK, MASK_FREE, TRACKS

NAME = "score"
HELP = "score externally produced pose files against a dataset"
ORDER = 45
SUBMISSION_TRACKS = (*TRACKS, MASK_FREE)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "submission", type=Path, metavar="SUBMISSION_DIR", help="a folder of pose files, one per scene (see above)"
    )
    p.add_argument("--data", type=Path, required=True, help="dataset directory (one sub-directory per scene)")
    p.add_argument(
        "--suite", type=Path, help="score every scene of this suite (default: the scenes the submission covers)"
    )
    p.add_argument("--splits", default="query", help="comma-separated query splits to score")
    p.add_argument("--method", help="name in the tables (default: the submission directory's name)")
    p.add_argument(
        "--names",
        default="benchmark",
        choices=NAME_STYLES,
        help="how the files name queries: benchmark (query/000012) or hloc (query/color/000012.png)",
    )
    p.add_argument(
        "--track",
        choices=SUBMISSION_TRACKS,
        help="track the submission was produced in; mask-free: by a method that reads no masks (its rows stand "
        f"in both tracks' tables) (default: the track the pose files' headers record, else {DEFAULT_TRACK})",
    )
    p.add_argument(
        "--out",
        type=Path,
        help="where tables go (default: ./<SUBMISSION_DIR name>-scores; never inside the submission or the data)",
    )
    p.add_argument(
        "--check",
        action="store_true",
        help="only validate the pose files (names, layout, numbers) and count their poses; score and write nothing",
    )


def run(args: argparse.Namespace) -> int:
    if args.submission.resolve() == args.data.resolve() or (args.submission / "scene.json").is_file():
        raise ConfigError(f"{args.submission}: is a dataset, not a submission; give the folder of your pose files")
    if args.suite:
        scenes = suite_scene_names(args.suite)
    else:
        scenes = score.submission_scenes(args.submission, args.data)
    splits = list(dict.fromkeys(s.strip() for s in args.splits.split(",") if s.strip()))
    if not splits:
        raise ConfigError("--splits names no split")
    if "mapping" in splits:
        raise ConfigError("--splits: 'mapping' built the maps; scoring poses of its own frames measures nothing")
    if args.check:
        return _check(args, scenes, splits)
    name = args.submission.resolve().name
    out = args.out or Path(f"{name}-scores")
    paths.check_output(out, [args.submission, *(args.data / s for s in scenes)], "--out")
    if (out / "runs").is_dir():
        raise ConfigError(
            f"--out {out}: holds an evaluation's results (runs/), whose tables this would replace; choose another --out"
        )
    track = score.submission_track(args.submission, scenes, args.track, SUBMISSION_TRACKS)
    queries = score.score_submission(args.submission, args.data, scenes, splits, args.method or name, track, args.names)
    maps = pd.DataFrame(columns=["map_hash", "scene", "map_mb", "mapping_time_s"])
    _, suite, _ = tables.write_tables(out / "tables", queries, maps)
    missing = queries[queries["reason"] == "missing"]
    if len(missing):
        print(f"{len(missing)} of {len(queries)} queries have no estimate (counted as failures)")
    print(tables.compact(suite))
    print(f"tables: {out / 'tables'}")
    return 0


def _check(args: argparse.Namespace, scenes: list[str], splits: list[str]) -> int:
    """``--check``: every file read as scoring would read it, the poses counted; exit 0 when all parse."""
    found = score.check_submission(args.submission, args.data, scenes, splits, args.names)
    for scene, split, poses, queries in found:
        print(f"{scene} {split}: {poses} of {queries} queries have a pose")
    poses, queries = sum(f[2] for f in found), sum(f[3] for f in found)
    missing = f"; the other {queries - poses} count as failures" if poses < queries else ""
    print(f"valid: {poses} poses for {queries} queries in {len(scenes)} scene(s){missing}")
    return 0
