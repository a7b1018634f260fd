"""COLMAP text models and hloc query lists of a scene, read back by pycolmap."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pycolmap
import pytest

from openreloc_bench import geometry
from openreloc_bench.data import colmap
from openreloc_bench.data.scene import Scene, SceneWriter


def write_wall_scene(root: Path, n_mapping: int = 5, n_query: int = 2) -> Path:
    """Cameras at x = 0 sliding along y, all looking along +x at a wall 1.5 m ahead: a scene whose
    depth agrees between frames, so one 3D point is seen by several of them."""
    K = geometry.intrinsics(20.0, 20.0, 15.5, 11.5)
    writer = SceneWriter(root)
    writer.write_scene_info({"spec_hash": "wall"})
    rng = np.random.default_rng(0)
    for split, n, phase in (("mapping", n_mapping, 0.0), ("query", n_query, 0.5)):
        writer.write_intrinsics(split, K)
        for i in range(n):
            y = 0.1 * (i + phase)
            T = geometry.look_at([0.0, y, 1.0], [1.0, y, 1.0])
            color = rng.integers(0, 255, (24, 32, 3), dtype=np.uint8)
            writer.write_frame(split, i, color, np.full((24, 32), 1.5, np.float32), None, T)
    return root


def test_model_is_read_by_pycolmap_with_our_poses_intrinsics_and_tracks(tmp_path: Path) -> None:
    scene = Scene(write_wall_scene(tmp_path / "wall"))
    mapping = scene.sequence("mapping")
    counts = colmap.write_model(mapping, tmp_path / "sparse", voxel=0.05, pixel_step=4)
    rec = pycolmap.Reconstruction(tmp_path / "sparse")
    assert (rec.num_images(), rec.num_points3D()) == (5, counts["points"]) and counts["points"] > 0
    assert rec.compute_num_observations() == counts["observations"]
    assert rec.compute_mean_track_length() > 1.5  # neighbouring frames see the same part of the wall
    (camera,) = rec.cameras.values()
    np.testing.assert_allclose(camera.params, [20.0, 20.0, 16.0, 12.0])  # principal point + half a pixel
    for image in rec.images.values():
        r = mapping.records[image.image_id - 1]
        assert image.name == f"mapping/color/{r.frame_id}.png"
        np.testing.assert_allclose(image.cam_from_world().matrix(), geometry.invert(r.T_wc)[:3], atol=1e-9)
        for p2 in image.points2D:
            point = rec.points3D[p2.point3D_id]
            uv = camera.img_from_cam(image.cam_from_world() * point.xyz)
            assert np.linalg.norm(uv - p2.xy) <= 0.05 / 1.5 * 20.0 * np.sqrt(3)  # within a voxel's image
            np.testing.assert_allclose(point.xyz[0], 1.5, atol=1e-9)  # on the wall
    assert rec.compute_mean_reprojection_error() < 0.5


def test_query_list_is_hlocs_format(tmp_path: Path) -> None:
    scene = Scene(write_wall_scene(tmp_path / "wall"))
    text = colmap.query_list([scene.sequence("query")])
    assert text.splitlines() == [
        "query/color/000000.png PINHOLE 32 24 20 20 16 12",
        "query/color/000001.png PINHOLE 32 24 20 20 16 12",
    ]


def test_a_split_without_depth_is_refused(tmp_path: Path) -> None:
    scene = Scene(write_wall_scene(tmp_path / "wall"))
    seq = scene.sequence("mapping")
    seq.records[0].depth_path = None
    with pytest.raises(ValueError, match="without depth"):
        colmap.write_model(seq, tmp_path / "sparse")
