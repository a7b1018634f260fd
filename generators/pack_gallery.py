"""A gallery image of an asset pack: every asset rendered alone on a floor, labelled with its category.

What ``openreloc-bench assets DIR`` writes, to see at a glance that meshes load upright, facing the
camera (front +y), at their real size (a 1 m grid on the floor) and with their textures.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from generators.asset_packs import AssetPack
from generators.layout import Instance, Layout, Light, Room
from generators.layout.model import box_mesh, make_part
from generators.render import create_renderer
from openreloc_bench import geometry
from openreloc_bench.data import io

TILE_W, TILE_H = 320, 240


def _stage(asset) -> Layout:
    """The asset at the origin on a 6 x 6 m floor with a back wall, under one light."""
    ext = asset.extent
    z0 = 1.6 + ext[2] if asset.placement == "ceiling" else 0.0
    if asset.placement == "wall_mounted":
        z0 = max(0.0, 1.2 - ext[2] / 2)
    T = np.eye(4)
    T[:3, 3] = (0.0, -3.0 + ext[1] / 2 + 0.01, z0) if asset.placement in ("wall", "wall_mounted") else (0, 0, z0)
    structure = [
        Instance(
            1,
            "floor",
            [make_part([box_mesh((-3, -3, -0.1), (3, 3, 0))], "wood", "light brown", 1)],
            np.eye(4),
            True,
            "r",
            0,
        ),
        Instance(
            2,
            "wall",
            [make_part([box_mesh((-3, -3.1, 0), (3, -3, 3))], "plaster", "cream", 2)],
            np.eye(4),
            True,
            "r",
            0,
        ),
    ]
    obj = Instance(3, asset.category, asset.parts, T, False, "r", 0, description=asset.description)
    return Layout(
        [Room("r", "living", 0, (-3, -3, 3, 3), 0.0, 3.0)],
        [],
        [Light(np.array([0.5, 1.5, 2.6]), "r", 0)],
        [*structure, obj],
        (6.0, 6.0),
        [0.0],
        3.0,
    )


def render_asset(asset, backend: str) -> np.ndarray:
    """RGB (TILE_H, TILE_W, 3) of ``asset`` seen from the front-right, framed by its bounding box."""
    layout = _stage(asset)
    lo, hi = layout.instances[-1].aabb
    centre, radius = (lo + hi) / 2, max(float(np.linalg.norm(hi - lo)) / 2, 0.1)
    eye = centre + radius * 2.4 * np.array([0.55, 0.75, 0.45]) / np.linalg.norm([0.55, 0.75, 0.45])
    K = geometry.intrinsics_from_fov(TILE_W, TILE_H, 50.0)
    with create_renderer(layout, backend, TILE_W, TILE_H) as r:
        rgb, _ = r.render_color(geometry.look_at(eye, centre), K, TILE_W, TILE_H)
    return rgb


def write_gallery(pack: AssetPack, out: Path | str, backend: str = "mujoco", columns: int = 4) -> Path:
    """One labelled tile per asset in a grid PNG at ``out``; returns ``out``."""
    tiles = []
    for asset in pack.assets:
        tile = render_asset(asset, backend).copy()
        label = f"{asset.category} ({asset.placement})"
        cv2.rectangle(tile, (0, TILE_H - 22), (TILE_W, TILE_H), (0, 0, 0), -1)
        cv2.putText(tile, label, (6, TILE_H - 7), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (255, 255, 255), 1, cv2.LINE_AA)
        tiles.append(tile)
    columns = min(columns, len(tiles))
    rows = -(-len(tiles) // columns)
    sheet = np.zeros((rows * TILE_H, columns * TILE_W, 3), np.uint8)
    for k, tile in enumerate(tiles):
        r, c = divmod(k, columns)
        sheet[r * TILE_H : (r + 1) * TILE_H, c * TILE_W : (c + 1) * TILE_W] = tile
    out = Path(out)
    io.write_png(out, sheet)
    return out
