from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from baselines.posenet import MAP_FORMAT, MAP_VERSION, PoseNet, pose_targets
from openreloc_bench import geometry
from openreloc_bench.data import mapfile
from openreloc_bench.data.scene import Scene
from openreloc_bench.errors import ConfigError, DataError
from openreloc_bench.methods import QueryFrame, create_method
from tests.baselines import contract
from tests.baselines.conftest import CHEAP

NAME = "posenet"
SMALL = CHEAP[NAME]


def test_fits_a_handful_of_frames(scenes: tuple[Scene, Scene], tmp_path: Path) -> None:
    """Trained without augmentation on 5 frames, the regressor returns their poses closely."""
    mapping = scenes[0].sequence("mapping").subset(range(0, 15, 3))
    no_augmentation = {"crop_margin": 0.0, "brightness": 0.0, "contrast": 0.0, "saturation": 0.0, "dropout": 0.0}
    cfg = {**SMALL, **no_augmentation, "steps": 200, "batch_size": 5, "hidden": 128, "lr": 3e-3, "lr_decay_at": [0.9]}
    method = PoseNet(**cfg)
    method.build_map(mapping, tmp_path)
    method.load_map(tmp_path)
    centres = mapping.poses[:, :3, 3]
    spread = np.linalg.norm(centres - centres.mean(axis=0), axis=1).mean()  # the error of always answering the mean
    errors = np.array(
        [geometry.pose_errors(f.T_wc, method.localize(QueryFrame(f.name, f.color, f.K)).T_wc) for f in mapping]
    )
    assert errors[:, 0].mean() < 0.25 * spread and errors[:, 1].max() < 10, (errors, spread)


def test_map_round_trip_and_determinism(
    built_map: Callable[[str], Path], scenes: tuple[Scene, Scene], tmp_path: Path
) -> None:
    """The same scene and seed give the same weights; a loaded map answers like the trained one."""
    mapping = scenes[0].sequence("mapping")
    PoseNet(**SMALL).build_map(mapping, tmp_path / "again")
    a, _ = mapfile.read_arrays(built_map(NAME), MAP_FORMAT, MAP_VERSION)
    b, meta = mapfile.read_arrays(tmp_path / "again", MAP_FORMAT, MAP_VERSION)
    assert a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a)
    assert meta["frames"] == len(mapping) and set(meta["final"]) == {"loss", "l_x", "l_q", "s_x", "s_q"}
    assert (built_map(NAME) / "meta.json").read_bytes() == (tmp_path / "again" / "meta.json").read_bytes()
    query, _ = contract.query_of(scenes[0], "query", 0)
    first, second = contract.loaded(NAME, built_map(NAME)), contract.loaded(NAME, tmp_path / "again")
    T = first.localize(query).T_wc
    assert np.array_equal(T, second.localize(query).T_wc)
    assert np.allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-5)
    other = PoseNet(**{**SMALL, "seed": 1})
    other.build_map(mapping, tmp_path / "seed1")
    other.load_map(tmp_path / "seed1")
    assert not np.array_equal(other.localize(query).T_wc, T)


def test_weights_that_do_not_fit_are_one_line_errors(built_map: Callable[[str], Path], tmp_path: Path) -> None:
    arrays, meta = mapfile.read_arrays(built_map(NAME), MAP_FORMAT, MAP_VERSION)
    meta = {k: v for k, v in meta.items() if k not in ("format", "version")}
    wrong = {**arrays, "net.t.weight": arrays["net.t.weight"][:, :-1]}
    mapfile.write_arrays(tmp_path / "shape", MAP_FORMAT, MAP_VERSION, wrong, meta)
    with pytest.raises(DataError, match="arrays.npz: weights do not fit the network") as err:
        contract.loaded(NAME, tmp_path / "shape")
    assert "\n" not in str(err.value)
    mapfile.write_arrays(
        tmp_path / "norm", MAP_FORMAT, MAP_VERSION, {**arrays, "t_scale": np.zeros(1, np.float32)}, meta
    )
    with pytest.raises(DataError, match="translation normalisation"):
        contract.loaded(NAME, tmp_path / "norm")
    with pytest.raises(DataError, match="meta.json: map built with"):
        contract.loaded(NAME, built_map(NAME), seed=3)
    contract.loaded(NAME, built_map(NAME), threads=2)  # where it trained is not part of the network


def test_targets_keep_one_quaternion_hemisphere() -> None:
    poses = np.tile(np.eye(4), (2, 1, 1))
    poses[1, :3, :3] = Rotation.from_euler("z", 350, degrees=True).as_matrix()
    centres, quats = pose_targets(poses)
    assert (quats[:, 3] >= 0).all() and np.allclose(np.linalg.norm(quats, axis=1), 1)
    assert np.allclose(Rotation.from_quat(quats).as_matrix(), poses[:, :3, :3], atol=1e-6)


@pytest.mark.parametrize(
    "overrides",
    [{"backbone": "resnet"}, {"steps": 0}, {"dropout": 1.5}, {"lr_decay_at": [2.0]}, {"device": "tpu"}, {"lr": 0}],
)
def test_config_validation(overrides: dict) -> None:
    with pytest.raises(ConfigError, match=NAME):
        create_method(NAME, **overrides)
