"""A tiny analytic scene for mapping tests: axis-aligned boxes rendered by ray casting in numpy.

Depth and instance images are exact (ray/box slab intersection), so the mapping pipeline is tested
on geometrically consistent frames without a renderer. A room has a floor, four walls and a few
coloured 'furniture' boxes; cameras walk a circle inside the room looking outwards and down.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from openreloc_bench import geometry
from openreloc_bench.data.scene import ObjectInfo, Scene, SceneWriter
from openreloc_bench.data.types import SceneSequence
from openreloc_bench.vision.base import ImageTextEncoder, ObjectMask, Segmenter, l2_normalize


@dataclass
class Box:
    id: int
    category: str
    lo: tuple[float, float, float]
    hi: tuple[float, float, float]
    color: tuple[int, int, int]
    structural: bool = False


ROOM = [
    Box(1, "floor", (-3, -3, -0.1), (3, 3, 0.0), (120, 120, 120), True),
    Box(2, "wall", (-3.1, -3, 0), (-3, 3, 2.5), (200, 200, 190), True),
    Box(3, "wall", (3, -3, 0), (3.1, 3, 2.5), (200, 200, 190), True),
    Box(4, "wall", (-3, -3.1, 0), (3, -3, 2.5), (200, 190, 200), True),
    Box(5, "wall", (-3, 3, 0), (3, 3.1, 2.5), (190, 200, 200), True),
    Box(10, "table", (1.5, -0.6, 0), (2.5, 0.6, 0.75), (140, 90, 40)),
    Box(11, "cabinet", (-2.6, -2.6, 0), (-1.8, -1.6, 1.2), (40, 60, 160)),
    Box(12, "sofa", (-2.6, 1.0, 0), (-1.8, 2.6, 0.8), (160, 40, 40)),
    Box(13, "box", (1.8, -0.3, 0.75), (2.2, 0.2, 1.05), (30, 160, 60)),
    Box(14, "bookshelf", (0.0, 2.3, 0), (1.2, 2.9, 1.9), (200, 160, 40)),
]


def render(boxes: list[Box], K: np.ndarray, T_wc: np.ndarray, hw: tuple[int, int]) -> tuple[np.ndarray, ...]:
    """(rgb uint8, depth float32 metres, instance int32) of the boxes seen from ``T_wc``."""
    h, w = hw
    v, u = np.mgrid[0:h, 0:w]
    d_cam = geometry.unproject(K, np.stack([u.ravel(), v.ravel()], -1), np.ones(h * w))
    d_world = d_cam @ T_wc[:3, :3].T
    o = T_wc[:3, 3]
    lo = np.array([b.lo for b in boxes])[:, None, :]
    hi = np.array([b.hi for b in boxes])[:, None, :]
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / d_world[None]
        t0, t1 = (lo - o) * inv, (hi - o) * inv
    tn = np.nanmax(np.minimum(t0, t1), axis=-1)
    tf = np.nanmin(np.maximum(t0, t1), axis=-1)
    hit = (tf >= np.maximum(tn, 0)) & (tn > 0.05)
    t = np.where(hit, tn, np.inf)
    k = np.argmin(t, axis=0)
    tz = t[k, np.arange(h * w)]
    ok = np.isfinite(tz)
    depth = np.where(ok, tz, 0).reshape(h, w).astype(np.float32)  # unit-z rays: t is the z-depth
    ids = np.array([b.id for b in boxes])
    inst = np.where(ok, ids[k], 0).reshape(h, w).astype(np.int32)
    colors = np.array([b.color for b in boxes], np.float64)
    shade = 0.75 + 0.25 * np.cos(3.0 * (u + v) / max(h, w))  # mild texture so crops are not flat
    rgb = (colors[k].reshape(h, w, 3) * shade[..., None]) * ok.reshape(h, w)[..., None]
    return rgb.clip(0, 255).astype(np.uint8), depth, inst


def camera_poses(n: int, radius: float = 1.2, height: float = 1.4) -> list[np.ndarray]:
    """Cameras on a circle in the room, looking outwards and slightly down."""
    poses = []
    for i in range(n):
        a = 2 * np.pi * i / n
        eye = np.array([radius * np.cos(a), radius * np.sin(a), height])
        target = eye + np.array([np.cos(a + 0.6), np.sin(a + 0.6), -0.45])
        poses.append(geometry.look_at(eye, target))
    return poses


def write_boxworld(
    root: Path,
    n_frames: int = 16,
    hw: tuple[int, int] = (48, 64),
    boxes: list[Box] = ROOM,
    objects: list[Box] | None = None,
) -> Path:
    """A boxworld scene; ``objects`` (default: ``boxes``) are the true objects of ``objects.json``, so
    one object can be rendered as several instance ids (parts a segmenter keeps apart)."""
    K = geometry.intrinsics_from_fov(hw[1], hw[0], 70.0)
    writer = SceneWriter(root)
    writer.write_scene_info({"spec_hash": "boxworld", "seed": 0, "width": hw[1], "height": hw[0]})
    writer.write_objects(
        [
            ObjectInfo(id=b.id, category=b.category, structural=b.structural, aabb=[list(b.lo), list(b.hi)])
            for b in (boxes if objects is None else objects)
        ]
    )
    writer.write_intrinsics("mapping", K)
    for i, T in enumerate(camera_poses(n_frames)):
        rgb, depth, inst = render(boxes, K, T, hw)
        writer.write_frame("mapping", i, rgb, depth, inst, T)
    return root


def boxworld_sequence(root: Path, **kw: object) -> SceneSequence:
    return Scene(write_boxworld(root, **kw)).sequence("mapping")  # type: ignore[arg-type]


class MeanColorEncoder(ImageTextEncoder):
    """Test-only encoder: a crop's mean colour and colour spread (deterministic, 6-d)."""

    name = "mean-color"
    dim = 6

    def encode_images(self, crops: list[np.ndarray]) -> np.ndarray:
        feats = [np.concatenate([c.reshape(-1, 3).mean(0), c.reshape(-1, 3).std(0) + 1]) for c in crops]
        return l2_normalize(np.array(feats, np.float32).reshape(-1, self.dim))

    def encode_texts(self, texts: list[str]) -> np.ndarray:
        return l2_normalize(np.ones((len(texts), self.dim), np.float32))


class NoisyMaskSegmenter(Segmenter):
    """Class-agnostic masks from the instance image, eroded / dilated at random and sometimes split:
    the kind of inconsistent per-frame masks view-consensus clustering has to merge."""

    name = "test-noisy"

    def __init__(self, seed: int = 0, split_prob: float = 0.3):
        self.rng = np.random.default_rng(seed)
        self.split_prob = split_prob

    def segment(self, rgb: np.ndarray, instance: np.ndarray | None = None) -> list[ObjectMask]:
        import cv2

        assert instance is not None
        out = []
        for i in np.unique(instance[instance > 0]):
            m = (instance == i).astype(np.uint8)
            op = self.rng.choice([cv2.erode, cv2.dilate, None])
            if op is not None:
                m = op(m, np.ones((3, 3), np.uint8))
            parts = [m.astype(bool)]
            ys, xs = np.nonzero(m)
            if len(xs) > 40 and self.rng.random() < self.split_prob:  # split into left / right halves
                cut = np.median(xs)
                left = m.astype(bool) & (np.arange(m.shape[1])[None, :] < cut)
                parts = [left, m.astype(bool) & ~left]
            for p in parts:
                if p.any():
                    ys, xs = np.nonzero(p)
                    out.append(ObjectMask(p, np.array([xs.min(), ys.min(), xs.max() + 1, ys.max() + 1], np.float32)))
        return out
