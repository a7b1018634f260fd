"""Tiny synthetic scenes for vision tests: coloured shapes with categories, colours and materials.

Each object keeps its shape, colour and a texture stripe across frames but moves and scales, so
'views' of one instance differ the way rendered views do (position, size, lighting).
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from openreloc_bench import geometry
from openreloc_bench.data.scene import ObjectInfo, SceneWriter

COLOURS = {"red": (200, 30, 30), "blue": (30, 60, 200), "green": (40, 160, 50), "yellow": (230, 210, 40)}
SHAPES = ("box", "ball", "bottle")


def draw_object(
    img: np.ndarray, inst: np.ndarray, oid: int, shape: str, rgb: tuple[int, int, int], cx: int, cy: int, r: int
) -> None:
    layer = np.zeros(inst.shape, np.uint8)
    if shape == "box":
        cv2.rectangle(layer, (cx - r, cy - r), (cx + r, cy + r), 1, -1)
    elif shape == "ball":
        cv2.circle(layer, (cx, cy), r, 1, -1)
    else:
        cv2.rectangle(layer, (cx - r // 3, cy - r), (cx + r // 3, cy + r), 1, -1)
    m = layer.astype(bool)
    img[m] = rgb
    inst[m] = oid


def write_shapes_scene(
    root: Path, seed: int, n_objects: int = 4, frames: int = 3, hw: tuple[int, int] = (96, 128)
) -> Path:
    rng = np.random.default_rng(seed)
    h, w = hw
    K = geometry.intrinsics_from_fov(w, h, 60.0)
    writer = SceneWriter(root)
    writer.write_scene_info({"spec_hash": f"shapes-{seed}", "seed": seed, "width": w, "height": h})
    objs = []
    for i in range(n_objects):
        shape = SHAPES[int(rng.integers(len(SHAPES)))]
        colour = list(COLOURS)[int(rng.integers(len(COLOURS)))]
        objs.append(
            ObjectInfo(
                id=i + 1,
                category=shape,
                description=f"a {colour} {shape}",
                attributes={"colour": colour, "material": "plastic", "size": "small"},
                aabb=[[0.0, 0.0, 0.0], [0.1, 0.1, 0.1]],
            )
        )
    objs.append(ObjectInfo(id=99, category="wall", structural=True))
    writer.write_objects(objs)
    for split, gain in (("mapping", 1.0), ("query", 1.0), ("query_light1", 0.6)):
        writer.write_intrinsics(split, K)
        for f in range(frames):
            img = np.full((h, w, 3), 90, np.uint8)
            img[: h // 3] = 150  # 'wall'
            inst = np.zeros((h, w), np.int32)
            inst[: h // 3] = 99
            cols = np.linspace(20, w - 20, n_objects).astype(int)
            for o, cx in zip(objs[:-1], cols):
                r = int(rng.integers(8, 14))
                draw_object(
                    img,
                    inst,
                    o.id,
                    o.category,
                    COLOURS[o.attributes["colour"]],
                    int(cx + rng.integers(-4, 5)),
                    int(h * 0.6 + rng.integers(-6, 7)),
                    r,
                )
            img = np.clip(img * gain, 0, 255).astype(np.uint8)
            writer.write_frame(
                split, f, img, np.full((h, w), 2.0, np.float32), inst, geometry.look_at([2, 0, 1], [0, 0, 0.5])
            )
    return root
