"""Write a method's map in 3D as one self-contained HTML file (plotly, opens offline in a browser).

It shows what the map keeps in 3D, as its method describes it (``map_points``): OpenReLoc's landmarks
(points coloured per landmark, hover: id and category; the ones filtered as invalid objects in grey) and
reference frames, the keypoints' world points of ``sift-pnp`` and ``orb-reloc`` (coloured by the mapping
frame that saw them) and their mapping frames, GOReloc's ellipsoids. The method is the one whose format
the map's manifest names (``<method>-map``), or --method; the title names it. A method that keeps no
points (``nearest-frame``, ``posenet``...) is drawn with --scene's mapping path only. With --scene (the scene the map was
built from): the mapping path and a few of its cameras. With --results (a pose file, or an ``eval``
run folder ``RESULTS/runs/<method>/<track>/<scene>/``, whose ``<split>.txt`` is read): every query of
--split at its true camera, and each estimate joined to it by a line, green within 50 cm and red
beyond; estimates far outside the scene are drawn at the view's edge and counted in the legend.
Map points are subsampled to --max-points. Nothing is written inside the inputs.

  openreloc-bench view maps/smoke --scene data/smoke-room --results poses.txt --out smoke.html
  openreloc-bench view RESULTS/maps/sift-pnp/HASH/smoke-room --scene data/smoke-room --out sift.html
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

import numpy as np

from openreloc_bench import view3d
from openreloc_bench.commands.options import add_plugin_argument
from openreloc_bench.data import io, mapfile, paths
from openreloc_bench.data.results import read_submission
from openreloc_bench.data.scene import Scene
from openreloc_bench.data.splits import QUERY_SPLITS
from openreloc_bench.errors import ConfigError, DataError
from openreloc_bench.harness.cache import check_map_source
from openreloc_bench.methods import MapPoints, available_methods, create_method

NAME = "view"
HELP = "3D HTML view of any method's map: its points, mapping path, estimated and true query cameras"
ORDER = 46


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "map_dir", type=Path, metavar="MAPDIR", help="map directory written by `openreloc-bench map` or `eval`"
    )
    parser.add_argument("--method", help="the method that built MAPDIR (default: the one its manifest's format names)")
    add_plugin_argument(parser)
    parser.add_argument("--scene", type=Path, help="the scene the map was built from: draws the mapping path")
    parser.add_argument(
        "--results",
        type=Path,
        metavar="RUN_OR_POSE_FILE",
        help="a pose file (`localize --out`, `name qw qx qy qz tx ty tz`) or an eval run folder; needs --scene",
    )
    parser.add_argument("--split", default="query", choices=QUERY_SPLITS, help="the query split of --results drawn")
    parser.add_argument("--max-points", type=int, default=view3d.DEFAULT_MAX_POINTS, help="map points drawn at most")
    parser.add_argument("--out", type=Path, required=True, help="HTML file to write")


def map_method(map_dir: Path, method: str | None) -> str:
    """The registered method whose map ``map_dir`` is: ``method``, else the one the manifest's format
    names (``<method>-map``); ConfigError when neither is known."""
    known = available_methods()
    if method is not None:
        if method not in known:
            raise ConfigError(f"unknown method '{method}' (known: {', '.join(sorted(known))})")
        return method
    doc = io.read_json(map_dir / mapfile.MANIFEST) if (map_dir / mapfile.MANIFEST).is_file() else None
    if not isinstance(doc, dict):
        raise DataError(map_dir, "no map manifest here: give a map directory written by `map` or `eval`")
    fmt = str(doc.get("format", ""))
    name = fmt.removesuffix("-map")
    if name not in known:
        raise ConfigError(f"{map_dir}: no method is registered for map format '{fmt}': give it with --method")
    return name


def map_points(name: str, map_dir: Path, scene: Scene | None) -> MapPoints:
    """What method ``name`` draws of its map, its name first in the summary; a method that declares no
    points gives the mapping camera of ``scene`` and no points (ConfigError without a scene)."""
    method = create_method(name)
    draw = getattr(method, "map_points", None)
    if draw is not None:
        mp = draw(map_dir)
        return dataclasses.replace(mp, summary=f"{name}: {mp.summary}")
    if scene is None:
        raise ConfigError(
            f"method '{name}' keeps no 3D points it can draw (no map_points): give --scene to draw the "
            "mapping path and queries"
        )
    seq = scene.sequence("mapping")
    return MapPoints(
        np.zeros((0, 3)),
        np.zeros(0, np.int64),
        {},
        seq.K,
        (seq.width, seq.height),
        summary=f"{name}: keeps no 3D points",
    )


def pose_file(results: Path, split: str) -> Path:
    """The pose file of ``results``: itself, or the ``<split>.txt`` of a run folder."""
    if not results.is_dir():
        return results
    path = results / f"{split}.txt"
    if not path.is_file():
        raise DataError(
            results, f"no {split}.txt here: give a pose file or an eval run folder (runs/<method>/<track>/<scene>)"
        )
    return path


def check_run_scene(results: Path, split: str, scene: Scene) -> None:
    """ConfigError when an eval run folder's done marker names another scene spec than ``scene``'s."""
    marker = results / f"{split}.done.json"
    if not (results.is_dir() and marker.is_file()):
        return
    doc = io.read_json(marker)
    spec = doc.get("spec_hash") if isinstance(doc, dict) else None
    if spec is not None and spec != scene.spec_hash:
        raise ConfigError(
            f"{results} is a run on scene '{doc.get('scene')}' (spec {spec}), not on {scene.root} "
            f"(spec {scene.spec_hash}): give the scene it ran on"
        )


def query_poses(path: Path, scene: Scene, split: str) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """(true T_wc of every query of ``split``, estimated T_wc of those the file gives); DataError for a
    file that does not parse or names frames the scene lacks."""
    estimates, _ = read_submission(path)
    seq = scene.sequence(split)
    true = dict(zip(seq.names, seq.poses))
    mine = {n: T for n, T in estimates.items() if n.startswith(f"{split}/")}
    if estimates and not mine:
        raise ConfigError(
            f"{path} names no query of split '{split}' (e.g. '{next(iter(estimates))}'): choose its split with --split"
        )
    unknown = sorted(set(mine) - set(true))
    if unknown:
        raise DataError(path, f"names '{unknown[0]}', which {scene.root} has no frame of")
    return true, mine


def run(args: argparse.Namespace) -> int:
    inputs = [p for p in (args.map_dir, args.scene, args.results) if p is not None]
    out = paths.check_output_file(args.out, inputs, "--out", suffix=".html")
    if args.results is not None and args.scene is None:
        raise ConfigError("--results needs --scene: the true query cameras come from the scene's ground truth")
    if args.max_points < 1:
        raise ConfigError(f"--max-points must be >= 1, got {args.max_points}")
    name = map_method(args.map_dir, args.method)
    scene = mapping = true = estimates = None
    if args.scene is not None:
        scene = Scene(args.scene)
        check_map_source(args.map_dir, scene)
        mapping = np.asarray(scene.sequence("mapping").poses)
        if args.results is not None:
            check_run_scene(args.results, args.split, scene)
            true, estimates = query_poses(pose_file(args.results, args.split), scene, args.split)
    fig = view3d.map_figure(map_points(name, args.map_dir, scene), mapping, true, estimates, max_points=args.max_points)
    out.parent.mkdir(parents=True, exist_ok=True)
    io.atomic_write_text(out, fig.to_html(include_plotlyjs=True, full_html=True))
    print(fig.layout.title.text)
    print(out)
    return 0
