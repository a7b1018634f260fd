"""Render a contact sheet of every asset category (one sampled instance each) for a visual check.

Each asset is drawn with matplotlib's ``plot_trisurf``-style polygons from a fixed 3/4 front view,
faces coloured by their part's colour and shaded by a directional light, and titled with its
category, triangle count and description. Also prints triangle-count statistics.

Usage: python benchmarks/asset_gallery.py --out gallery.png [--seed 0] [--cols 10]
"""

from __future__ import annotations

import argparse
import textwrap
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from mpl_toolkits.mplot3d.art3d import Poly3DCollection  # noqa: E402
from tqdm import tqdm  # noqa: E402

from generators.assets import CATEGORIES, Asset, sample_asset  # noqa: E402

LIGHT = np.array([0.4, 0.7, 0.6]) / np.linalg.norm([0.4, 0.7, 0.6])


def draw(ax, asset: Asset) -> None:
    """Draw the asset's faces, Lambert-shaded, in an equal-aspect 3D axis seen from the front-right."""
    polys, colours = [], []
    for part in asset.parts:
        m = part.mesh
        shade = 0.45 + 0.55 * np.clip(m.face_normals @ LIGHT, 0, 1)
        polys.append(m.vertices[m.faces])
        colours.append(np.clip(np.asarray(part.rgb)[None, :] * shade[:, None], 0, 1))
    ax.add_collection3d(Poly3DCollection(np.concatenate(polys), facecolors=np.concatenate(colours), linewidths=0))
    half = asset.extent.max() / 2
    centre = np.array([0, 0, asset.extent[2] / 2])
    for setter, c in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), centre):
        setter(c - half, c + half)
    ax.set_box_aspect((1, 1, 1))
    ax.view_init(elev=20, azim=65)  # camera in front (+y) and to the right (+x)
    ax.set_axis_off()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True, help="PNG file to write")
    parser.add_argument("--seed", type=int, default=0, help="rng seed of the sampled instances")
    parser.add_argument("--cols", type=int, default=10, help="gallery columns")
    args = parser.parse_args()
    names = sorted(CATEGORIES)
    rows = -(-len(names) // args.cols)
    fig = plt.figure(figsize=(args.cols * 2.0, rows * 2.3), dpi=80)
    tris = []
    for i, name in enumerate(tqdm(names, desc="assets")):
        asset = sample_asset(name, np.random.default_rng(args.seed))
        tris.append(len(asset.to_trimesh().faces))
        ax = fig.add_subplot(rows, args.cols, i + 1, projection="3d")
        draw(ax, asset)
        ax.set_title(f"{name} ({tris[-1]})\n" + "\n".join(textwrap.wrap(asset.description, 30)[:2]), fontsize=6.5)
    fig.subplots_adjust(left=0, right=1, bottom=0, top=0.97, wspace=0, hspace=0.35)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out)
    print(
        f"{len(names)} categories -> {args.out}; triangles mean {np.mean(tris):.0f}, median {np.median(tris):.0f}, max {max(tris)} ({names[int(np.argmax(tris))]})"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
