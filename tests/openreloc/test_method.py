"""OpenReLoc end to end on the analytic box room: map, localize a held-out view, diagnostics,
ablation switches, and every bad input answered by a Failure (never an exception)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from threadpoolctl import threadpool_info, threadpool_limits

from openreloc_bench import geometry
from openreloc_bench.data.scene import Scene
from openreloc_bench.errors import ConfigError, DataError
from openreloc_bench.methods import Failure, PoseEstimate, QueryFrame, create_method
from openreloc_bench.openreloc import association as association_module
from openreloc_bench.openreloc import hypotheses as hypotheses_module
from openreloc_bench.openreloc import method as method_module
from openreloc_bench.openreloc import verify as verify_module
from openreloc_bench.openreloc.consistency import LabelRenderer
from openreloc_bench.openreloc.map import ObjectMap
from openreloc_bench.vision.base import register_encoder
from tests.openreloc.boxworld import ROOM, MeanColorEncoder, camera_poses, render, write_boxworld

register_encoder("mean-color")(MeanColorEncoder)
HW = (96, 128)
# the frequency rule alone (the paper's): the shape cue would also drop the walls, leaving this small
# room's views with too few landmarks
MAPPING = {"fusion": {"voxel_size": 0.05}, "filtering": {"shape_filter": False, "max_frequency": 0.9}}


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


def oracle_query(k: int = 3) -> tuple[QueryFrame, np.ndarray]:
    """A held-out view with every instance (walls too): the oracle association needs no encoder."""
    q, T = held_out_query(k)
    _, _, inst = render(ROOM, q.K, T, HW)
    return QueryFrame(q.name, q.color, q.K, inst), T


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


@pytest.mark.xfail(
    reason="not a refinement problem (occlusion is covered by test_refine): this map loses the "
    "table and the box on it (mapping: 8 of 9 instances), so 2 of the view's 3 furniture objects "
    "have no landmark and the mean-colour test encoder matches them to walls"
)
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


@pytest.mark.parametrize(
    "override",
    [
        {"no_coarse": True},
        {"no_scene_graph": True},
        {"retrieval": "visibility"},
        {"no_filtering": True},
        {"verification": {"enabled": False}},
    ],
)
def test_ablation_switches_run(map_dir: Path, override: dict) -> None:
    q, _ = held_out_query()
    res = localizer(map_dir, **override, refinement={"max_iterations": 20}).localize(q)
    assert isinstance(res, (PoseEstimate, Failure))


def test_verification_stage_reports_or_stays_out(map_dir: Path) -> None:
    q, _ = held_out_query()
    on = localizer(map_dir, refinement={"max_iterations": 5}).localize(q)
    assert "verify" in on.diagnostics["timings"] and "inliers" in on.diagnostics["verification"]
    off = localizer(map_dir, refinement={"max_iterations": 5}, verification={"enabled": False}).localize(q)
    assert "verify" not in off.diagnostics["timings"] and "verification" not in off.diagnostics


@pytest.mark.parametrize("keeps_choice", [False, True])
def test_the_place_prior_ranks_the_verification_candidates(map_dir: Path, monkeypatch, keeps_choice: bool) -> None:
    """With ``place_frames``, each kept object's candidates follow the place prior's scores (after the
    association's first candidate with ``place_keeps_choice``), and only valid landmarks compete."""
    seen: dict[str, object] = {}
    associate, verify = association_module.associate, verify_module.verify_matches
    monkeypatch.setattr(association_module, "associate", lambda *a, **k: seen.setdefault("matches", associate(*a, **k)))
    monkeypatch.setattr(
        verify_module,
        "verify_matches",
        lambda evidence, *a, **k: verify(seen.setdefault("evidence", evidence), *a, **k),
    )
    m = localizer(
        map_dir, refinement={"max_iterations": 5}, verification={"place_frames": 2, "place_keeps_choice": keeps_choice}
    )
    ranking = m.verifier.place_scores
    monkeypatch.setattr(m.verifier, "place_scores", lambda *a: seen.setdefault("scores", ranking(*a)))
    m.localize(held_out_query()[0])
    scores, evidence = seen["scores"], seen["evidence"]
    choice = {mt.query: m.ids.index(mt.candidates[0]) for mt in seen["matches"]}
    assert choice and all(not e.candidates for q, e in enumerate(evidence) if q not in choice)
    for q, row in choice.items():
        rows = evidence[q].candidates
        lead = int(keeps_choice)
        assert rows[:lead] == [row][:lead] and np.all(np.isfinite(scores[q, rows]))
        assert np.all(np.diff(scores[q, rows[lead:]]) <= 0)


def test_the_verification_draws_with_the_maps_covisibility(map_dir: Path, monkeypatch) -> None:
    """The RANSAC's guided sampling gets which landmark pairs some reference frame sees together."""
    seen: dict[str, object] = {}
    verify = verify_module.verify_matches
    monkeypatch.setattr(verify_module, "verify_matches", lambda *a, **k: verify(*a, **seen.setdefault("kwargs", k)))
    m = localizer(map_dir, refinement={"max_iterations": 5})
    m.localize(held_out_query()[0])
    covisible, frames = seen["kwargs"]["covisible"], m.verifier.frame_visibility
    assert covisible.shape == (len(m.ids), len(m.ids)) and np.array_equal(covisible, covisible.T)
    a, b = np.nonzero(covisible)
    assert len(a) < covisible.size and all((frames[:, i] & frames[:, j]).any() for i, j in zip(a, b))
    assert all(covisible[i, j] for f in frames for i in np.flatnonzero(f) for j in np.flatnonzero(f))


def test_the_best_explained_hypothesis_wins(map_dir: Path) -> None:
    q, _ = held_out_query()
    on = localizer(map_dir, refinement={"max_iterations": 10}).localize(q)
    hyps = on.diagnostics["hypotheses"]
    assert "compare" in on.diagnostics["timings"] and len(hyps) > 1
    best = max(h["explained"] for h in hyps if h["loss"] is not None)
    chosen = next(h for h in hyps if h["source"] == on.diagnostics["chosen"])
    assert best > 0 and chosen["explained"] >= 0.9 * best  # within the default tie share of the best
    off = localizer(map_dir, refinement={"max_iterations": 10}, consistency={"enabled": False}).localize(q)
    hyps = off.diagnostics["hypotheses"]
    assert "compare" not in off.diagnostics["timings"]
    lowest = min(h["loss"] for h in hyps if h["loss"] is not None)
    assert next(h for h in hyps if h["source"] == off.diagnostics["chosen"])["loss"] == lowest


def test_language_modality_uses_the_describer(map_dir: Path) -> None:
    q, _ = held_out_query()
    m = create_method("openreloc", refinement={"max_iterations": 5})
    m.load_map(map_dir)
    res = m.localize(q)
    assert isinstance(res, PoseEstimate)
    assert all(isinstance(x["phrase"], str) and x["text_sim"] is not None for x in res.diagnostics["matches"])
    # the same view again: its phrases are embedded already, so no text reaches the encoder
    texts: list[str] = []
    inner = m.encoder.encode_texts
    m.encoder.encode_texts = lambda batch: texts.extend(batch) or inner(batch)
    again = m.localize(q)
    assert texts == [] and [x["phrase"] for x in again.diagnostics["matches"]] == [
        x["phrase"] for x in res.diagnostics["matches"]
    ]


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


@pytest.mark.parametrize("frac", [0.002, 0.1])  # 25 px: all three objects; 1229 px: one
def test_the_smallest_object_is_a_share_of_the_image(map_dir: Path, frac: float) -> None:
    m = localizer(map_dir, min_mask_frac=frac)
    q, _ = held_out_query()
    areas = np.bincount(q.instance.ravel())
    assert m.min_mask_area == int(np.ceil(frac * HW[0] * HW[1]))
    kept = int(((areas >= m.min_mask_area) & (np.arange(len(areas)) > 0)).sum())
    r = m.localize(q)
    assert r.diagnostics["detected"] == kept


def test_unknown_config_key_is_a_config_error() -> None:
    with pytest.raises(ConfigError, match="no_such_switch"):
        create_method("openreloc", no_such_switch=True)


@pytest.mark.parametrize("weight", [0.0, -0.5, 1.5])
def test_covisible_weight_outside_its_range_is_a_config_error(weight: float) -> None:
    with pytest.raises(ConfigError, match="covisible_weight must be in"):
        create_method("openreloc", verification={"covisible_weight": weight})


def test_oracle_association_diagnostic_matches_by_instance_id(map_dir: Path) -> None:
    q, _ = oracle_query()
    m = localizer(map_dir, association={"oracle": True}, refinement={"max_iterations": 10})
    res = m.localize(q)
    assert isinstance(res, PoseEstimate), res
    d = res.diagnostics
    assert d["matches"] and all(x["landmark"] == x["query_instance"] and x["how"] == "oracle" for x in d["matches"])
    assert "encode" not in d["timings"] and "describe" not in d["timings"]
    sources = [h["source"] for h in d["hypotheses"]]
    assert d["chosen"] in sources and sum(s.startswith("reference:") for s in sources) == 3
    # the RANSAC runs on the true matches too: the oracle bounds the whole method, not only its coarse stage
    assert "verified" in sources and d["verification"]["changed"] == 0
    best = min(h["loss"] for h in d["hypotheses"] if h["loss"] is not None)
    hop = d["restart"]  # the orbiting restarts of the chosen pose replace it only with a clearly lower loss
    assert hop["before"] == pytest.approx(best)
    assert hop["won"] == (hop["loss"] < 0.9 * best)
    if not hop["won"]:
        assert d["refine"]["loss"] == pytest.approx(best)
    predicted = QueryFrame(q.name, q.color, q.K, None)
    assert "oracle-mask track" in m.localize(predicted).reason


@pytest.mark.parametrize("start", ["truth", "far"])
def test_a_restart_replaces_the_chosen_pose_only_with_a_lower_loss(map_dir: Path, monkeypatch, start: str) -> None:
    q, T_gt = oracle_query()
    oracle = {"oracle": True}
    plain = localizer(map_dir, association=oracle, refinement={"max_iterations": 10, "restart_degrees": 0.0}).localize(
        q
    )
    far = geometry.look_at([3.0, 3.0, 2.5], [6.0, 6.0, 2.5])  # sees none of the matched objects
    monkeypatch.setattr(
        hypotheses_module, "orbit_starts", lambda T, pivot, degrees, up: [T_gt if start == "truth" else far]
    )
    res = localizer(map_dir, association=oracle, refinement={"max_iterations": 10}).localize(q)
    assert isinstance(plain, PoseEstimate) and isinstance(res, PoseEstimate)
    assert "restart" not in plain.diagnostics
    hop = res.diagnostics["restart"]
    if start == "truth":
        assert hop["won"] and hop["loss"] < 0.9 * plain.diagnostics["refine"]["loss"]
        assert not np.allclose(res.T_wc, plain.T_wc) and geometry.pose_errors(T_gt, res.T_wc)[0] < 0.15
    else:
        assert not hop["won"] and hop["loss"] > 0.9 * plain.diagnostics["refine"]["loss"]
        np.testing.assert_array_equal(res.T_wc, plain.T_wc)


def test_no_coarse_refines_only_the_uninformed_start(map_dir: Path) -> None:
    q, _ = held_out_query()
    res = localizer(map_dir, no_coarse=True, refinement={"max_iterations": 5}).localize(q)
    assert isinstance(res, PoseEstimate)
    assert [h["source"] for h in res.diagnostics["hypotheses"]] == ["uninformed"]


def test_paper_literal_coarse_stage_has_one_hypothesis(map_dir: Path) -> None:
    q, _ = held_out_query()
    # the paper has no verification stage, whose pose would be a second hypothesis
    res = localizer(
        map_dir, coarse={"top_frames": 1, "pnp": False}, verification={"enabled": False}, no_refine=True
    ).localize(q)
    assert isinstance(res, PoseEstimate) and "hypotheses" not in res.diagnostics
    assert res.diagnostics["chosen"] == f"reference:{res.diagnostics['reference_frame']['index']}"


@pytest.mark.parametrize("hypothesis", [True, False])
def test_the_verified_pose_is_a_hypothesis_unless_switched_off(map_dir: Path, hypothesis: bool) -> None:
    q, _ = held_out_query()
    # fitted_triples 0: this view's further modes are the raw P3P poses' consensus sets (as below)
    res = localizer(
        map_dir,
        coarse={"top_frames": 1, "pnp": False},
        verification={"hypothesis": hypothesis, "fitted_triples": 0},
        refinement={"max_iterations": 5},
    ).localize(q)
    assert isinstance(res, PoseEstimate), res
    assert res.diagnostics["verification"]["inliers"] >= 3  # verified matches are used either way
    frame = f"reference:{res.diagnostics['reference_frame']['index']}"
    sources = [h["source"] for h in res.diagnostics.get("hypotheses", [{"source": res.diagnostics["chosen"]}])]
    if hypothesis:  # the best mode, then at most refined_modes - 1 further ones (this view has more)
        assert sources[:2] == [frame, "verified"] and len(sources) == 4
        assert all(s.startswith("verified:") for s in sources[2:])
    else:
        assert sources == [frame]
    assert ("modes" in res.diagnostics["verification"]) == hypothesis  # without the pose, no search for further ones


def test_further_verification_modes_compete_with_their_own_matches(map_dir: Path, monkeypatch) -> None:
    q, _ = held_out_query()
    one = localizer(map_dir, verification={"modes": 1}, refinement={"max_iterations": 5}).localize(q)
    assert "modes" not in one.diagnostics["verification"]
    # make the last mode win, as render-and-compare would when it explains the query best
    monkeypatch.setattr(method_module, "choose_hypothesis", lambda losses, explained, tie: len(losses) - 1)
    # this view has three distinct consistent sets of three among the raw P3P poses (a box-fitted pose of
    # one set lies within a metre of another's raw pose and takes its place: fitted_triples 0)
    res = localizer(map_dir, verification={"modes": 3, "fitted_triples": 0}, refinement={"max_iterations": 5}).localize(
        q
    )
    assert isinstance(res, PoseEstimate), res
    modes = res.diagnostics["verification"]["modes"]
    assert modes == 3
    sources = [h["source"] for h in res.diagnostics["hypotheses"]]
    assert sources[-modes:] == ["verified", "verified:2", "verified:3"] and res.diagnostics["chosen"] == "verified:3"
    pairs = lambda r: {(mt["query_instance"], mt["landmark"]) for mt in r.diagnostics["matches"]}  # noqa: E731
    assert pairs(res) != pairs(one)  # the winner's own matches are reported (and placed in the explanation)
    # ... and it was refined against them, in the same batch as the others
    assert set(res.diagnostics["refine"]["object_losses"]) == {str(mt["landmark"]) for mt in res.diagnostics["matches"]}


@pytest.mark.parametrize("render_and_compare", [True, False])
def test_only_the_further_modes_that_render_closest_are_refined(
    map_dir: Path, monkeypatch, render_and_compare: bool
) -> None:
    q, _ = held_out_query()
    # a drawing that prefers later poses: the screen must keep the last mode, not the RANSAC's next best
    monkeypatch.setattr(LabelRenderer, "compare", lambda *_: lambda poses: [float(i) for i in range(len(poses))])
    res = localizer(
        map_dir,
        verification={"modes": 3, "refined_modes": 2, "fitted_triples": 0},  # three modes, as above
        refinement={"max_iterations": 5},
        consistency={"enabled": render_and_compare},
    ).localize(q)
    assert isinstance(res, PoseEstimate), res
    assert res.diagnostics["verification"]["modes"] == 3
    sources = [h["source"] for h in res.diagnostics["hypotheses"]]
    assert sources[-2:] == ["verified", "verified:3" if render_and_compare else "verified:2"]
    assert ("screened" in res.diagnostics["verification"]) == render_and_compare
    if render_and_compare:
        assert list(res.diagnostics["verification"]["screened"]) == ["verified:2", "verified:3"]


def test_text_cache_encodes_each_phrase_once() -> None:
    from openreloc_bench.vision.base import TextCache

    class Counting(MeanColorEncoder):
        calls: list[list[str]] = []

        def encode_texts(self, texts):
            self.calls.append(list(texts))
            return super().encode_texts(texts)

    inner = Counting()
    cache = TextCache(inner)
    a = cache.encode_texts(["a red sofa", "a blue sofa", "a red sofa"])
    b = cache.encode_texts(["a blue sofa"])
    assert inner.calls == [["a red sofa", "a blue sofa"]]
    assert np.allclose(a[1], b[0]) and a.shape == (3, inner.dim) and cache.encode_texts([]).shape == (0, inner.dim)


def test_oracle_association_diagnostic_is_registered_and_keeps_other_overrides() -> None:
    from openreloc_bench.methods import create_method

    m = create_method("openreloc-oracle-association", association={"top_k": 2}, no_refine=True)
    assert m.name == "openreloc-oracle-association"
    assert m.config.association.oracle and m.config.association.top_k == 2 and m.config.no_refine
    assert not create_method("openreloc").config.association.oracle


def test_map_config_ignores_query_time_settings() -> None:
    base = create_method("openreloc").map_config()
    for query_time in (
        {"no_refine": True},
        {"verification": {"enabled": False}},
        {"coarse": {"top_frames": 1}},
    ):
        assert create_method("openreloc", **query_time).map_config() == base
    # the segmenter makes predicted-track maps; maps voted from the dataset masks do not depend on it
    assert create_method("openreloc", segmenter="noisy-gt").map_config() != base
    weights = create_method("openreloc").map_config()["segmenter_weights"]
    assert len(weights) == 12  # predicted maps are rebuilt when the segmenter is retrained
    voted = {"mapping": {"instances_from": "masks"}}
    assert (
        create_method("openreloc", segmenter="noisy-gt", **voted).map_config()
        == create_method("openreloc", **voted).map_config()
    )
    assert create_method("openreloc", mapping={"fusion": {"voxel_size": 0.05}}).map_config() != base
    assert create_method("openreloc", encoder_options={"weights": "elsewhere"}).map_config() != base


class VersionedColorEncoder(MeanColorEncoder):
    """The mean-colour encoder with a settable weights fingerprint (as if retrained)."""

    name = "mean-color-versioned"
    version = "a"

    @classmethod
    def weights_fingerprint(cls, **options) -> str:
        return cls.version


register_encoder("mean-color-versioned")(VersionedColorEncoder)


def test_map_from_other_encoder_weights_is_refused_and_not_reused(tmp_path: Path, monkeypatch) -> None:
    seq = Scene(write_boxworld(tmp_path / "scene", n_frames=16, hw=HW)).sequence("mapping")
    method = create_method("openreloc", encoder="mean-color-versioned", mapping=MAPPING)
    method.build_map(seq, tmp_path / "map")
    before = method.map_config()
    monkeypatch.setattr(VersionedColorEncoder, "version", "b")
    assert create_method("openreloc", encoder="mean-color-versioned", mapping=MAPPING).map_config() != before
    with pytest.raises(DataError, match="rebuild the map"):
        create_method("openreloc", no_language=True).load_map(tmp_path / "map")


def test_map_without_weights_fingerprint_is_refused(tmp_path: Path) -> None:
    """Maps written before fingerprints existed cannot prove which weights made their descriptors."""
    seq = Scene(write_boxworld(tmp_path / "scene", n_frames=16, hw=HW)).sequence("mapping")
    method = create_method("openreloc", encoder="mean-color-versioned", mapping=MAPPING)
    method.build_map(seq, tmp_path / "map")
    old = ObjectMap.load(tmp_path / "map")
    old.encoder.pop("fingerprint")
    old.save(tmp_path / "old")
    create_method("openreloc", no_language=True).load_map(tmp_path / "map")  # the current map loads
    with pytest.raises(DataError, match="fingerprint.*rebuild the map"):
        create_method("openreloc", no_language=True).load_map(tmp_path / "old")


def test_a_query_runs_with_single_threaded_blas_and_restores_it(map_dir: Path, monkeypatch) -> None:
    def blas_threads() -> set[int]:
        return {lib["num_threads"] for lib in threadpool_info() if lib["user_api"] == "blas"}

    m = localizer(map_dir)
    seen: list[set[int]] = []
    inner = m._localize

    def spy(*args):
        seen.append(blas_threads())
        return inner(*args)

    monkeypatch.setattr(m, "_localize", spy)
    with threadpool_limits(limits=2, user_api="blas"):
        assert isinstance(m.localize(held_out_query()[0]), PoseEstimate)
        assert seen == [{1}] and blas_threads() == {2}
