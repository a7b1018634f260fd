from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from baselines.global_descriptors import GlobalDescriptor, GlobalDescriptorConfig, grid_pool
from baselines.image_retrieval import MAP_FORMAT, MAP_VERSION, ImageRetrieval, interpolate_poses
from openreloc_bench import geometry
from openreloc_bench.data import mapfile
from openreloc_bench.data.scene import Scene
from openreloc_bench.errors import ConfigError, DataError
from openreloc_bench.methods import create_method
from tests.baselines import contract

NAME = "retrieval"


def pose(yaw_deg: float, centre: tuple[float, float, float]) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("z", yaw_deg, degrees=True).as_matrix()
    T[:3, 3] = centre
    return T


def test_interpolation_is_a_weighted_mean() -> None:
    poses = np.stack([pose(0, (0, 0, 0)), pose(40, (1, 0, 0))])
    mid = interpolate_poses(poses, np.array([1.0, 1.0]))
    assert np.allclose(mid[:3, 3], [0.5, 0, 0]) and np.isclose(
        Rotation.from_matrix(mid[:3, :3]).as_euler("zyx", degrees=True)[0], 20
    )
    assert np.allclose(interpolate_poses(poses, np.array([1.0, 0.0])), poses[0])
    near_first = interpolate_poses(poses, np.array([3.0, 1.0]))
    assert np.allclose(near_first[:3, 3], [0.25, 0, 0])


@pytest.mark.parametrize("kind", ["encoder-grid", "encoder-vlad", "sift-vlad"])
def test_each_descriptor_finds_the_frame_itself(kind: str, scenes: tuple[Scene, Scene], tmp_path: Path) -> None:
    mapping = scenes[0].sequence("mapping").subset(range(0, 16, 2))
    cfg = {"descriptor": {"kind": kind, "vlad": {"clusters": 4, "training_descriptors": 2000}}, "top_k": 1}
    method = ImageRetrieval(**cfg)
    method.build_map(mapping, tmp_path)
    method.load_map(tmp_path)
    for i, frame in enumerate(mapping):
        est = method.localize(contract.query_of(scenes[0], "mapping", 2 * i)[0])
        assert est.diagnostics["retrieved"] == [i] and np.array_equal(est.T_wc, frame.T_wc)


def test_interpolation_keeps_a_mapping_frame_at_its_pose(
    built_map: Callable[[str], Path], scenes: tuple[Scene, Scene]
) -> None:
    """Shepard's weights: a query identical to a mapping frame outweighs the other retrieved frames."""
    method = contract.loaded(NAME, built_map(NAME))
    for i in (2, 7):
        query, T = contract.query_of(scenes[0], "mapping", i)
        est = method.localize(query)
        assert len(est.diagnostics["interpolated"]) == method.config.top_k > 1
        t_err, r_err = geometry.pose_errors(T, est.T_wc)
        assert t_err < 1e-3 and r_err < 0.05, (t_err, r_err)


def test_top_k_interpolates_only_near_the_best(built_map: Callable[[str], Path], scenes: tuple[Scene, Scene]) -> None:
    query, _ = contract.query_of(scenes[0], "query", 0)
    poses = scenes[0].sequence("mapping").poses
    far = contract.loaded(NAME, built_map(NAME), top_k=5, interpolation_radius_m=0.0).localize(query)
    assert (
        len(far.diagnostics["retrieved"]) == 5 and far.diagnostics["interpolated"] == far.diagnostics["retrieved"][:1]
    )
    everywhere = contract.loaded(NAME, built_map(NAME), top_k=5, interpolation_radius_m=100.0).localize(query)
    used = everywhere.diagnostics["interpolated"]
    assert used == everywhere.diagnostics["retrieved"]
    assert geometry.translation_error(everywhere.T_wc, poses[used[0]]) > 0  # an average, not the best frame
    box = poses[used, :3, 3]
    assert ((everywhere.T_wc[:3, 3] >= box.min(0) - 1e-9) & (everywhere.T_wc[:3, 3] <= box.max(0) + 1e-9)).all()


def test_map_round_trip_and_mismatch(built_map: Callable[[str], Path], scenes: tuple[Scene, Scene]) -> None:
    arrays, meta = mapfile.read_arrays(built_map(NAME), MAP_FORMAT, MAP_VERSION)
    assert arrays["descriptors"].shape[0] == len(scenes[0].sequence("mapping")) == meta["frames"]
    assert ImageRetrieval(top_k=3).map_config() == ImageRetrieval().map_config()
    with pytest.raises(DataError, match="meta.json: map built with"):
        contract.loaded(NAME, built_map(NAME), descriptor={"vlad": {"clusters": 8}})


def test_grid_pooling_is_unit_norm_per_layout() -> None:
    import torch

    fmap = torch.rand(8, 5, 7)
    d = grid_pool(fmap, 2)
    assert d.shape == (32,) and np.isclose(np.linalg.norm(d), 1)
    describer = GlobalDescriptor(GlobalDescriptorConfig(kind="encoder-grid", image_width=64, grid=1))
    assert describer.describe(np.zeros((48, 64, 3), np.uint8)).shape == (256,)


@pytest.mark.parametrize(
    "overrides", [{"top_k": 0}, {"interpolation_radius_m": -1}, {"descriptor": {"kind": "netvlad"}}]
)
def test_config_validation(overrides: dict) -> None:
    with pytest.raises(ConfigError, match=NAME):
        create_method(NAME, **overrides)


def test_malformed_arrays_are_one_line_errors(built_map: Callable[[str], Path], tmp_path: Path) -> None:
    arrays, meta = mapfile.read_arrays(built_map(NAME), MAP_FORMAT, MAP_VERSION)
    meta = {k: v for k, v in meta.items() if k not in ("format", "version")}
    for name, damaged in (
        ("poses", {**arrays, "poses": arrays["poses"][1:]}),
        ("centres", {**arrays, "vlad_centres": arrays["vlad_centres"][1:]}),
    ):
        mapfile.write_arrays(tmp_path / name, MAP_FORMAT, MAP_VERSION, damaged, meta)
        with pytest.raises(DataError, match="arrays.npz: malformed map arrays") as err:
            contract.loaded(NAME, tmp_path / name)
        assert "\n" not in str(err.value)
