"""``openreloc-paper``: every stage beyond the paper is off, and what remains localizes a view of an
analytic box room from the single DIoU reference frame."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from openreloc_bench import geometry
from openreloc_bench.data.scene import Scene
from openreloc_bench.methods import PoseEstimate, QueryFrame, create_method
from openreloc_bench.openreloc import consistency as consistency_module
from openreloc_bench.openreloc import hypotheses as hypotheses_module
from openreloc_bench.openreloc import verify as verify_module
from openreloc_bench.openreloc.filtering import reference_frequency
from openreloc_bench.openreloc.map import ObjectMap
from openreloc_bench.openreloc.method import OpenReLocConfig
from openreloc_bench.openreloc.refine import RefineConfig
from openreloc_bench.vision.base import register_encoder
from tests.openreloc.boxworld import Box, MeanColorEncoder, camera_poses, render, write_boxworld

register_encoder("mean-color")(MeanColorEncoder)
HW = (96, 128)
# every box a colour of its own, so that the mean-colour test encoder can associate walls and furniture
ROOM = [
    Box(1, "floor", (-3, -3, -0.1), (3, 3, 0.0), (120, 120, 120), True),
    Box(2, "wall", (-3.1, -3, 0), (-3, 3, 2.5), (230, 90, 90), True),
    Box(3, "wall", (3, -3, 0), (3.1, 3, 2.5), (90, 230, 90), True),
    Box(4, "wall", (-3, -3.1, 0), (3, -3, 2.5), (90, 90, 230), True),
    Box(5, "wall", (-3, 3, 0), (3, 3.1, 2.5), (230, 230, 90), True),
    Box(10, "table", (1.5, -0.6, 0), (2.5, 0.6, 0.75), (140, 60, 20)),
    Box(11, "cabinet", (-2.6, -2.6, 0), (-1.8, -1.6, 1.2), (20, 40, 120)),
    Box(12, "sofa", (-2.6, 1.0, 0), (-1.8, 2.6, 0.8), (120, 20, 20)),
    Box(14, "bookshelf", (0.0, 2.3, 0), (1.2, 2.9, 1.9), (200, 160, 40)),
    Box(15, "fridge", (1.6, -2.9, 0), (2.4, -2.3, 1.9), (90, 230, 230)),
    Box(16, "bed", (-1.0, -2.9, 0), (0.6, -1.6, 0.6), (200, 60, 200)),
    Box(17, "chest", (2.4, 1.5, 0), (2.9, 2.5, 1.0), (40, 120, 40)),
    Box(18, "desk", (-2.9, -0.8, 0), (-2.3, 0.5, 0.8), (250, 250, 250)),
]


def held_out_query(k: int) -> tuple[QueryFrame, np.ndarray]:
    """The view half a step after mapping view ``k`` (with every instance mask)."""
    T = camera_poses(32)[2 * k + 1]
    K = geometry.intrinsics_from_fov(HW[1], HW[0], 70.0)
    rgb, _, inst = render(ROOM, K, T, HW)
    return QueryFrame(f"query/{k:06d}", rgb, K, inst), T


@pytest.fixture(scope="module")
def paper_map(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("room")
    seq = Scene(write_boxworld(root / "scene", n_frames=16, hw=HW, boxes=ROOM)).sequence("mapping")
    create_method("openreloc-paper", encoder="mean-color", mapping={"fusion": {"voxel_size": 0.05}}).build_map(
        seq, root / "map"
    )
    return root / "map"


def test_every_addition_beyond_the_paper_is_off() -> None:
    cfg: OpenReLocConfig = create_method("openreloc-paper").config
    filtering = cfg.mapping.filtering
    assert filtering.enabled and not filtering.shape_filter and filtering.scope == "global"
    assert filtering.max_frequency == 0.5
    v = cfg.verification
    assert not v.enabled and v.place_frames == 0 and v.covisible_weight == 1.0 and v.modes == 1
    assert not v.hypothesis
    assert cfg.coarse.top_frames == 1 and not cfg.coarse.pnp and cfg.retrieval == "diou"
    assert not cfg.consistency.enabled and cfg.refinement.restart_degrees == 0.0
    # the paper's own stages stay on, with its settings
    assert not (cfg.no_refine or cfg.no_coarse or cfg.no_scene_graph or cfg.no_language or cfg.no_filtering)
    assert cfg.association.top_k == 3 and cfg.association.hops == 1 and cfg.mapping.descriptors.top_k == 5
    assert (cfg.refinement.lr_rotation, cfg.refinement.lr_translation, cfg.refinement.huber_delta) == (
        0.025,
        0.025,
        10.0,
    )
    assert cfg.refinement.outlier_factor == 5.0


def test_overrides_apply_on_top_of_the_preset() -> None:
    cfg = create_method("openreloc-paper", refinement={"max_iterations": 7}, seed=3).config
    assert cfg.refinement.max_iterations == 7 and cfg.refinement.restart_degrees == 0.0 and cfg.seed == 3
    assert cfg.refinement.huber_delta == RefineConfig().huber_delta
    # one addition switched back on, the others stay off
    cfg = create_method("openreloc-paper", verification={"enabled": True}).config
    assert cfg.verification.enabled and cfg.verification.place_frames == 0 and not cfg.consistency.enabled


def test_the_map_filters_by_global_frequency_alone(paper_map: Path) -> None:
    m = ObjectMap.load(paper_map)
    ids = sorted(m.landmarks)
    freq = reference_frequency(m.reference_frames, ids, "global")
    assert {i for i in ids if not m.landmarks[i].valid} == {i for i in ids if freq[i] > 0.5}
    # the floor is in every view; the walls, large thin slabs that the project's shape cue drops, are not
    assert not m.landmarks[1].valid and all(m.landmarks[i].valid for i in (2, 3, 4, 5))


def test_localizes_from_the_single_diou_prior_without_any_addition(paper_map: Path, monkeypatch) -> None:
    def forbidden(*_a, **_k):
        raise AssertionError("a stage beyond the paper ran")

    for module, stage in (
        (verify_module, "verify_matches"),
        (verify_module, "place_landmarks"),
        (consistency_module, "consistency"),
        (hypotheses_module, "pnp_prior"),
        (hypotheses_module, "orbit_starts"),
    ):
        monkeypatch.setattr(module, stage, forbidden)
    m = create_method("openreloc-paper", no_language=True)
    m.load_map(paper_map)
    q, T_gt = held_out_query(12)
    res = m.localize(q)
    assert isinstance(res, PoseEstimate), res
    d = res.diagnostics
    assert [h["source"] for h in d["hypotheses"]] == [f"reference:{d['reference_frame']['index']}"]
    assert d["reference_frame"]["ranking"] == "diou"
    assert "restart" not in d and "verification" not in d and "compare" not in d["timings"]
    te, re = geometry.pose_errors(T_gt, res.T_wc)
    _, prior_re = geometry.pose_errors(T_gt, np.array(d["prior_T_wc"]))
    assert te < 0.25 and re < 6.0 and re < prior_re  # the 2D ICP turns the camera towards the truth
