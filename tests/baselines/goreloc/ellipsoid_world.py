"""A tiny analytic scene whose objects are ellipsoids, ray-cast in numpy and written in the project's
layout: exact depth and instance images, so GOReloc's whole pipeline (fusion, lifting, ellipsoid
fit, graphs, P3P) runs on geometrically consistent frames without a renderer."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from openreloc_bench import geometry
from openreloc_bench.data.scene import ObjectInfo, SceneWriter


@dataclass
class Blob:
    id: int
    category: str
    centre: tuple[float, float, float]
    axes: tuple[float, float, float]
    yaw: float
    colour: tuple[int, int, int]

    @property
    def R(self) -> np.ndarray:
        c, s = np.cos(self.yaw), np.sin(self.yaw)
        return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


BLOBS = [
    Blob(1, "sofa", (-2.0, -1.5, 0.45), (0.8, 0.4, 0.45), 0.3, (170, 40, 40)),
    Blob(2, "potted_plant", (-0.5, -2.2, 0.5), (0.25, 0.25, 0.5), 0.0, (40, 150, 50)),
    Blob(3, "tv", (1.5, -2.0, 1.1), (0.5, 0.08, 0.3), -0.4, (30, 30, 30)),
    Blob(4, "dining_table", (2.2, 0.0, 0.4), (0.6, 0.45, 0.4), 0.8, (140, 90, 40)),
    Blob(5, "clock", (1.2, 2.1, 1.4), (0.2, 0.06, 0.2), 0.2, (220, 220, 60)),
    Blob(6, "bed", (-0.8, 2.0, 0.35), (0.9, 0.6, 0.35), 0.0, (60, 60, 170)),
    Blob(7, "toilet", (-2.3, 0.6, 0.4), (0.25, 0.35, 0.4), 1.2, (230, 230, 230)),
    Blob(8, "vase", (0.4, 0.3, 0.3), (0.15, 0.15, 0.3), 0.0, (160, 60, 160)),
    Blob(9, "fridge", (1.9, -1.2, 0.9), (0.35, 0.35, 0.9), 0.5, (200, 200, 210)),
    Blob(10, "cabinet", (0.0, -0.8, 0.5), (0.3, 0.3, 0.5), 0.0, (120, 100, 80)),  # no COCO class: invisible
]


def render(blobs: list[Blob], K: np.ndarray, T_wc: np.ndarray, hw: tuple[int, int]) -> tuple[np.ndarray, ...]:
    """(rgb uint8, depth float32 metres, instance int32): nearest ray/ellipsoid intersections."""
    h, w = hw
    v, u = np.mgrid[0:h, 0:w]
    rays = geometry.unproject(K, np.stack([u.ravel(), v.ravel()], -1), np.ones(h * w)) @ T_wc[:3, :3].T
    best = np.full(h * w, np.inf)
    ids = np.zeros(h * w, np.int32)
    unit = rays / np.linalg.norm(rays, axis=1, keepdims=True)
    for b in blobs:
        oc = np.array(b.centre) - T_wc[:3, 3]
        near = np.flatnonzero(oc @ oc - (unit @ oc) ** 2 <= max(b.axes) ** 2)  # rays meeting the bounding sphere
        A_inv = np.diag(1.0 / np.array(b.axes)) @ b.R.T  # world -> unit-sphere frame
        o = A_inv @ -oc
        d = rays[near] @ A_inv.T
        qa, qb, qc = np.sum(d * d, 1), 2 * d @ o, o @ o - 1.0
        disc = qb * qb - 4 * qa * qc
        t = np.where(disc >= 0, (-qb - np.sqrt(np.maximum(disc, 0))) / (2 * qa), np.inf)
        t = np.where(t > 0.05, t, np.inf)
        closer = t < best[near]
        best[near[closer]], ids[near[closer]] = t[closer], b.id
    hit = np.isfinite(best)
    depth = np.where(hit, best, 0).reshape(h, w).astype(np.float32)  # rays have unit z: t is the depth
    colours = np.zeros((max(b.id for b in blobs) + 1, 3))
    for b in blobs:
        colours[b.id] = b.colour
    shade = 0.8 + 0.2 * np.cos((u + v) / 7.0)
    rgb = colours[ids].reshape(h, w, 3) * shade[..., None]
    return rgb.clip(0, 255).astype(np.uint8), depth, ids.reshape(h, w)


def ring_poses(n: int, radius: float, height: float, phase: float = 0.0) -> list[np.ndarray]:
    """Cameras on a circle around the room's centre, looking at it."""
    out = []
    for i in range(n):
        a = 2 * np.pi * (i + phase) / n
        eye = np.array([radius * np.cos(a), radius * np.sin(a), height])
        out.append(geometry.look_at(eye, [0.3 * np.cos(a + 2.0), 0.3 * np.sin(a + 2.0), 0.6]))
    return out


def write_ellipsoid_world(root: Path, hw: tuple[int, int] = (240, 320), n_mapping: int = 16, n_query: int = 4) -> Path:
    """The scene with a ring of mapping views and query views between them (farther out, higher)."""
    K = geometry.intrinsics_from_fov(hw[1], hw[0], 60.0)
    writer = SceneWriter(root)
    writer.write_scene_info({"spec_hash": "ellipsoid-world", "seed": 0, "width": hw[1], "height": hw[0]})
    writer.write_objects(
        [
            ObjectInfo(
                id=b.id,
                category=b.category,
                aabb=[(np.array(b.centre) - b.axes).tolist(), (np.array(b.centre) + b.axes).tolist()],
            )
            for b in BLOBS
        ]
    )
    for split, poses in (
        ("mapping", ring_poses(n_mapping, 4.2, 1.6)),
        ("query", ring_poses(n_query, 4.5, 1.8, phase=0.37)),
    ):
        writer.write_intrinsics(split, K)
        for i, T in enumerate(poses):
            rgb, depth, inst = render(BLOBS, K, T, hw)
            writer.write_frame(split, i, rgb, depth, inst, T)
    return root
