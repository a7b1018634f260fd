"""A scene in the formats of COLMAP and hloc, so that their pipelines run on it.

* ``sparse/cameras.txt``, ``images.txt``, ``points3D.txt``: COLMAP's text model of the mapping split
  (known poses, one PINHOLE camera), with a 3D point per voxel of the back-projected depth and its
  track in the frames that sampled it: a reference model for hloc's triangulation or localization;
* ``queries_with_intrinsics.txt``: hloc's query list, ``name PINHOLE width height fx fy cx cy``.

Image names are paths relative to the scene directory (``mapping/color/000000.png``), so the scene
directory is the image directory. COLMAP puts the centre of the top-left pixel at (0.5, 0.5), this
project at (0, 0): principal points and 2D points are shifted by half a pixel on the way out.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from tqdm import tqdm

from openreloc_bench import geometry
from openreloc_bench.data import io
from openreloc_bench.data.types import SceneSequence

PIXEL_CENTRE = 0.5
"""COLMAP's pixel-centre offset relative to the OpenCV convention used here."""


def image_name(split: str, frame_id: str) -> str:
    """The name of a frame's colour image relative to the scene directory (COLMAP / hloc image name)."""
    return f"{split}/color/{frame_id}.png"


def camera_params(K: np.ndarray) -> list[float]:
    """PINHOLE parameters ``fx fy cx cy`` in COLMAP's pixel convention."""
    return [K[0, 0], K[1, 1], K[0, 2] + PIXEL_CENTRE, K[1, 2] + PIXEL_CENTRE]


def query_list(seqs: list[SceneSequence]) -> str:
    """hloc's ``queries_with_intrinsics.txt`` for the frames of ``seqs``."""
    lines = []
    for seq in seqs:
        cam = " ".join(f"{v:.10g}" for v in camera_params(seq.K))
        lines += [f"{image_name(seq.split, r.frame_id)} PINHOLE {seq.width} {seq.height} {cam}" for r in seq.records]
    return "\n".join(lines) + "\n"


def write_model(seq: SceneSequence, out: Path, voxel: float = 0.05, pixel_step: int = 8) -> dict[str, int]:
    """COLMAP's text model of ``seq`` (a split with depth) in ``out``; returns the counts written.

    Every ``pixel_step``-th pixel with depth is lifted to the world; the samples falling in one
    ``voxel`` (metres) become one 3D point (their mean position and colour), observed once per frame
    that sampled it, with its mean reprojection error in pixels.
    """
    if not seq.has_depth:
        raise ValueError(f"split '{seq.split}' has frames without depth")
    obs_image, obs_uv, obs_xyz, obs_rgb = [], [], [], []
    for i, frame in enumerate(tqdm(seq, desc="export", unit="frame", leave=False)):
        d = frame.depth[::pixel_step, ::pixel_step]  # type: ignore[index]
        v, u = np.nonzero(np.isfinite(d) & (d > 0))
        uv = np.stack([u, v], -1) * pixel_step
        obs_xyz.append(geometry.transform_points(frame.T_wc, geometry.unproject(seq.K, uv, d[v, u])))
        obs_uv.append(uv)
        obs_rgb.append(frame.color[uv[:, 1], uv[:, 0]])
        obs_image.append(np.full(len(uv), i))
    image, uv = np.concatenate(obs_image), np.concatenate(obs_uv).astype(np.float64)
    xyz, rgb = np.concatenate(obs_xyz), np.concatenate(obs_rgb).astype(np.float64)
    _, point = np.unique(np.floor(xyz / voxel).astype(np.int64), axis=0, return_inverse=True)
    point = point.ravel()
    # one observation per (point, image): the first sample of the point in that frame
    _, keep = np.unique(point * len(seq) + image, return_index=True)
    image, uv, point = image[keep], uv[keep], point[keep]
    n_points = int(point.max()) + 1 if len(point) else 0
    counts = np.bincount(point, minlength=n_points)[:, None]
    centre = np.stack([np.bincount(point, xyz[keep][:, k], n_points) for k in range(3)], -1) / counts
    colour = np.stack([np.bincount(point, rgb[keep][:, k], n_points) for k in range(3)], -1) / counts
    err = np.zeros(len(point))
    for i in range(len(seq)):
        sel = image == i
        proj, _ = geometry.project(seq.K, seq.records[i].T_wc, centre[point[sel]])
        err[sel] = np.linalg.norm(proj - uv[sel], axis=1)
    mean_err = np.bincount(point, err, n_points) / counts[:, 0]

    fx, fy, cx, cy = camera_params(seq.K)
    io.atomic_write_text(
        out / "cameras.txt",
        "# Camera list with one line of data per camera:\n#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n"
        f"# Number of cameras: 1\n1 PINHOLE {seq.width} {seq.height} {fx:.10g} {fy:.10g} {cx:.10g} {cy:.10g}\n",
    )
    lines = [
        "# Image list with two lines of data per image:",
        "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME",
        "#   POINTS2D[] as (X, Y, POINT3D_ID)",
        f"# Number of images: {len(seq)}",
    ]
    point2d_index = np.zeros(len(point), dtype=np.int64)
    for i, r in enumerate(seq.records):
        q, t = geometry.pose_to_qt(geometry.invert(r.T_wc))
        lines.append(f"{i + 1} " + " ".join(f"{v:.12g}" for v in (*q, *t)) + f" 1 {image_name(seq.split, r.frame_id)}")
        sel = np.flatnonzero(image == i)
        point2d_index[sel] = np.arange(len(sel))
        xy = uv[sel] + PIXEL_CENTRE
        lines.append(" ".join(f"{x:.6g} {y:.6g} {p + 1}" for (x, y), p in zip(xy, point[sel])))
    io.atomic_write_text(out / "images.txt", "\n".join(lines) + "\n")
    order = np.lexsort((image, point))
    starts = np.searchsorted(point[order], np.arange(n_points + 1))
    lines = [
        "# 3D point list with one line of data per point:",
        "#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)",
        f"# Number of points: {n_points}",
    ]
    for p in range(n_points):
        track = order[starts[p] : starts[p + 1]]
        x, y, z = centre[p]
        r, g, b = np.clip(np.round(colour[p]), 0, 255).astype(int)
        pairs = " ".join(f"{image[o] + 1} {point2d_index[o]}" for o in track)
        lines.append(f"{p + 1} {x:.9g} {y:.9g} {z:.9g} {r} {g} {b} {mean_err[p]:.6g} {pairs}")
    io.atomic_write_text(out / "points3D.txt", "\n".join(lines) + "\n")
    return {"images": len(seq), "points": n_points, "observations": len(point)}
