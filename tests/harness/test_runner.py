"""The evaluation runner on tiny scenes: outputs, map cache, failures, timeouts, tracks, bad input."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from harness_test_methods import DIFFICULTY, ORACLE_CONFIDENCE, difficulty_scene, make_scene

from openreloc_bench.data import io
from openreloc_bench.data.results import read_results, read_tum_trajectory
from openreloc_bench.data.runs import load_map_records, load_run_queries
from openreloc_bench.data.scene import DATA_VERSION, DIFFICULTY_AXES
from openreloc_bench.errors import ConfigError, DataError
from openreloc_bench.harness import jobs, runner, tables
from openreloc_bench.harness.runner import EvalConfig, MethodRun
from openreloc_bench.methods import uses_masks

PLUGIN = ["harness_test_methods"]


def cfg(data: Path, out: Path, runs: list[MethodRun], **kw) -> EvalConfig:
    kw.setdefault("timeout_s", 0.0)
    kw.setdefault("track", "oracle-mask")  # the tests read the oracle track's folders unless they name one
    return EvalConfig(data=data, out=out, scenes=["sA", "sB"], runs=runs, plugins=PLUGIN, **kw)


def test_eval_writes_poses_tum_tables_and_provenance(data_dir: Path, tmp_path: Path) -> None:
    runs = [
        MethodRun("test-oracle", "test-oracle", {"noise_m": 0.1, "noise_deg": 2.0}),
        MethodRun("nearest-frame", "nearest-frame"),
    ]
    report = runner.evaluate(cfg(data_dir, tmp_path, runs, splits=["query", "query_light1"]))
    assert report.errors == [] and report.maps_built == 4 and report.jobs_run == 8
    assert 0 < report.maps_s < report.wall_s
    d = tmp_path / "runs" / "test-oracle" / "oracle-mask" / "sA"
    poses = read_results(d / "query.txt")
    assert sorted(poses) == [f"query/{i:06d}" for i in range(3)]
    stamps, tum = read_tum_trajectory(d / "query.tum")
    np.testing.assert_allclose(tum, np.stack([poses[n] for n in sorted(poses)]), atol=1e-6)
    marker = io.read_json(d / "query.done.json")
    assert marker["method_config"] == {
        "name": "test-oracle",
        "config": {
            "noise_m": 0.1,
            "noise_deg": 2.0,
            "fail_on": "",
            "raise_on": "",
            "hang_on": "",
            "hang_in": "",
            "delay_s": 0.0,
            "expect_track": "",
            "map_tag": "",
            "seed": 0,
            "odd_diagnostics": False,
            "slow_exit_s": 0.0,
        },
    }
    assert marker["track"] == "oracle-mask" and marker["spec_hash"] == "hash-sA-1" and marker["git_commit"]
    q = load_run_queries(tmp_path, uses_masks)
    assert len(q) == 2 * 2 * 2 * 3
    oracle = q[q["method"] == "test-oracle"]
    np.testing.assert_allclose(oracle["t_err_m"], 0.1, atol=1e-6)
    np.testing.assert_allclose(oracle["r_err_deg"], 2.0, atol=1e-4)
    scenes, suite, seeds = tables.write_tables(tmp_path / "tables", q, load_map_records(tmp_path))
    row = suite[(suite.method == "test-oracle") & (suite.split == "query")].iloc[0]
    assert row.recall_25cm == 100.0 and row.n_scenes == 2 and row.n_queries == 6
    assert row.mte_25cm_m == pytest.approx(0.1) and row.mre_25cm_deg == pytest.approx(2.0, abs=1e-4)
    assert row.map_mb > 0 and row.mapping_time_s >= 0 and row.latency_p90_s >= row.latency_median_s
    for name in ("queries", "scenes", "suite"):
        assert (tmp_path / "tables" / f"{name}.csv").is_file() and (tmp_path / "tables" / f"{name}.json").is_file()
    assert len(scenes) == 8 and seeds.empty and not (tmp_path / "tables" / "seeds.csv").exists()
    robustness = (tmp_path / "tables" / "robustness_test-oracle_oracle-mask.md").read_text()
    assert "| Original | 100 / 100 | 100 / 100 | 0.10 / 0.10 |" in robustness and "Lighting 1" in robustness


def test_maps_are_cached_by_config_and_spec(data_dir: Path, tmp_path: Path) -> None:
    run = MethodRun("test-oracle", "test-oracle", {"noise_m": 0.1})
    assert runner.evaluate(cfg(data_dir, tmp_path, [run])).maps_built == 2
    again = runner.evaluate(cfg(data_dir, tmp_path, [run]))
    assert (again.maps_built, again.maps_cached) == (0, 2)
    # a query-time setting shares the maps; a map-time one (the method's map_config) does not
    query_time = runner.evaluate(cfg(data_dir, tmp_path, [MethodRun("o2", "test-oracle", {"noise_m": 0.2})]))
    assert (query_time.maps_built, query_time.maps_cached) == (0, 2)
    map_time = runner.evaluate(cfg(data_dir, tmp_path, [MethodRun("o3", "test-oracle", {"map_tag": "b"})]))
    assert map_time.maps_built == 2
    assert len(list((tmp_path / "maps" / "test-oracle").iterdir())) == 2  # one folder per map config


def test_maps_of_mask_free_methods_serve_both_tracks(data_dir: Path, tmp_path: Path) -> None:
    free, masked = MethodRun("nearest-frame", "nearest-frame", {}), MethodRun("test-oracle", "test-oracle", {})
    assert runner.evaluate(cfg(data_dir, tmp_path, [free, masked])).maps_built == 4
    predicted = runner.evaluate(cfg(data_dir, tmp_path, [free, masked], track="predicted"))
    assert (predicted.maps_built, predicted.maps_cached) == (2, 2)  # test-oracle reads masks: maps of its own
    assert sorted(p.name for p in (tmp_path / "runs" / "nearest-frame").iterdir()) == ["mask-free"]
    q = load_run_queries(tmp_path, uses_masks)
    runs = q.groupby(["method", "track"])["query"].count().to_dict()
    assert runs == {
        ("nearest-frame", "mask-free"): 6,
        ("test-oracle", "oracle-mask"): 6,
        ("test-oracle", "predicted"): 6,
    }
    assert q.set_index("method")["uses_masks"].groupby(level=0).unique().map(list).to_dict() == {
        "nearest-frame": [False],
        "test-oracle": [True],
    }


@pytest.mark.parametrize("track", ["oracle-mask", "predicted"])
def test_a_method_declaring_no_masks_is_given_none_and_recorded_mask_free(
    data_dir: Path, tmp_path: Path, track: str
) -> None:
    run = MethodRun("free", "test-oracle-mask-free", {"expect_track": "mask-free"})  # raises if given masks
    assert runner.evaluate(cfg(data_dir, tmp_path, [run], track=track)).errors == []
    marker = io.read_json(tmp_path / "runs" / "free" / "mask-free" / "sA" / "query.done.json")
    assert (marker["track"], marker["uses_masks"]) == ("mask-free", False)
    assert "track mask-free" in (tmp_path / "runs" / "free" / "mask-free" / "sA" / "query.txt").read_text()
    q = load_run_queries(tmp_path, uses_masks)
    assert q["success"].all() and set(q["track"]) == {"mask-free"}
    _, suite, _ = tables.write_tables(tmp_path / "tables", q, load_map_records(tmp_path))
    assert "free mask-free query" in " ".join(tables.compact(suite).split())


def _as_legacy(marker: Path, track: str) -> None:
    """``marker`` as a run of ``track`` wrote it before tracks were recorded from the method's declaration."""
    rec = io.read_json(marker)
    del rec["uses_masks"]
    io.write_json(marker, {**rec, "track": track, "finished": "2020-01-01T00:00:00+00:00"})


def test_markers_from_before_recorded_tracks_read_by_the_method_declaration(data_dir: Path, tmp_path: Path) -> None:
    runs = [MethodRun("nearest-frame", "nearest-frame"), MethodRun("test-oracle", "test-oracle")]
    assert runner.evaluate(cfg(data_dir, tmp_path, runs)).errors == []
    old = tmp_path / "runs" / "nearest-frame" / "predicted"
    (tmp_path / "runs" / "nearest-frame" / "mask-free").rename(old)  # where an older eval put it
    for marker in old.glob("*/*.done.json"):
        _as_legacy(marker, "predicted")
    for marker in (tmp_path / "runs" / "test-oracle").glob("*/*/*.done.json"):
        _as_legacy(marker, "oracle-mask")
    q = load_run_queries(tmp_path, uses_masks)
    tracks = q.groupby("method")[["track", "uses_masks"]].agg(lambda c: sorted(set(c))).to_dict("index")
    assert tracks == {
        "nearest-frame": {"track": ["mask-free"], "uses_masks": [False]},  # registered as reading no masks
        "test-oracle": {"track": ["oracle-mask"], "uses_masks": [True]},
    }
    # the same queries run again, now under the recorded track: the later run's rows, once
    again = MethodRun("nearest-frame", "nearest-frame", {"thumb_size": 8})
    assert runner.evaluate(cfg(data_dir, tmp_path, [again], track="predicted")).errors == []
    new = io.read_json(tmp_path / "runs" / "nearest-frame" / "mask-free" / "sA" / "query.done.json")
    free = load_run_queries(tmp_path, uses_masks).query("method == 'nearest-frame'")
    assert len(free) == 6 and set(free["config_hash"]) == {new["config_hash"]}


def test_predicted_track_hides_instances(data_dir: Path, tmp_path: Path) -> None:
    ok = runner.evaluate(
        cfg(data_dir, tmp_path, [MethodRun("p", "test-oracle", {"expect_track": "predicted"})], track="predicted")
    )
    assert ok.errors == []
    q = load_run_queries(tmp_path, uses_masks)
    assert q["success"].all() and set(q["track"]) == {"predicted"}
    runner.evaluate(cfg(data_dir, tmp_path, [MethodRun("m", "test-oracle", {"expect_track": "predicted"})]))
    q = load_run_queries(tmp_path, uses_masks)
    assert q[q.method == "m"]["reason"].str.contains("got a oracle-mask query").all()


def test_local_pool_gives_the_same_results_as_inline(data_dir: Path, tmp_path: Path) -> None:
    runs = [MethodRun("test-oracle", "test-oracle"), MethodRun("nearest-frame", "nearest-frame")]
    frames = []
    for name, workers in [("inline", 1), ("pool", 2)]:
        assert runner.evaluate(cfg(data_dir, tmp_path / name, runs, workers=workers)).errors == []
        frames.append(load_run_queries(tmp_path / name, uses_masks).drop(columns="runtime_s"))
    pd.testing.assert_frame_equal(frames[0], frames[1])


def test_seeds_repeat_seeded_methods_and_share_their_maps(data_dir: Path, tmp_path: Path) -> None:
    runs = [MethodRun("test-oracle", "test-oracle", {"noise_m": 0.2}), MethodRun("nearest-frame", "nearest-frame")]
    report = runner.evaluate(cfg(data_dir, tmp_path, runs, seeds=[0, 1]))
    assert report.errors == [] and report.maps_built == 4 and report.jobs_run == 6  # nearest-frame has no seed
    q = load_run_queries(tmp_path, uses_masks)
    assert sorted(q["method"].unique()) == ["nearest-frame", "test-oracle@seed0", "test-oracle@seed1"]
    seeded = q[q["variant"] == "test-oracle"]
    np.testing.assert_allclose(seeded["t_err_m"], 0.2 + 0.1 * seeded["seed"].to_numpy(dtype=float), atol=1e-6)
    assert q.loc[q["method"] == "nearest-frame", "seed"].isna().all()
    _, suite, seeds = tables.write_tables(tmp_path / "tables", q, load_map_records(tmp_path))
    assert set(suite["method"]) == {"nearest-frame", "test-oracle@seed0", "test-oracle@seed1"}
    row = seeds.set_index("variant").loc["test-oracle"]
    assert (row.n_seeds, row.n_queries) == (2, 6)
    assert (row.recall_25cm_mean, row.recall_25cm_min, row.recall_25cm_max) == (50.0, 0.0, 100.0)
    assert row.recall_25cm_std == pytest.approx(np.std([0, 100], ddof=1))
    assert row.recall_50cm_mean == 100.0 and row.recall_50cm_std == 0.0
    assert row.mte_25cm_m_mean == pytest.approx(0.2)
    assert "test-oracle oracle-mask query, 2 seeds: R@50cm% 100.0 ± 0.0 [100.0, 100.0]" in tables.compact_seeds(seeds)
    pooled = tables.pool_seeds(q)
    assert sorted(pooled["method"].unique()) == ["nearest-frame", "test-oracle"] and len(pooled) == len(q)


def test_a_single_run_of_a_seeded_variant_is_not_pooled_as_one_more_seed(data_dir: Path, tmp_path: Path) -> None:
    run = MethodRun("test-oracle", "test-oracle", {"noise_m": 0.2})
    runner.evaluate(cfg(data_dir, tmp_path, [run], splits=["query", "query_light1"]))
    runner.evaluate(cfg(data_dir, tmp_path, [run], seeds=[1, 2]))
    pooled = tables.pool_seeds(load_run_queries(tmp_path, uses_masks))
    query, light = pooled[pooled["split"] == "query"], pooled[pooled["split"] == "query_light1"]
    assert set(pooled["method"]) == {"test-oracle"} and sorted(query["seed"].unique()) == [1, 2]
    assert len(light) == 6 and light["seed"].isna().all()  # a split run once only stays


@pytest.mark.parametrize(
    "change, error, match",
    [
        (dict(runs=[MethodRun("x", "no-such-method")]), ConfigError, "unknown method 'no-such-method'"),
        (dict(scenes=["sA", "missing"]), DataError, "scene directory not found"),
        (dict(splits=["query_light4"]), DataError, "no split 'query_light4'"),
        (dict(track="oracle"), ConfigError, "unknown track"),
        (dict(runs=[MethodRun("x", "test-oracle", {"nope": 1})]), ConfigError, "unknown key 'test-oracle.nope'"),
        (dict(seeds=[0, 0]), ConfigError, "seeds repeat"),
        (dict(runs=[MethodRun("x", "test-oracle", {"seed": 3})], seeds=[0, 1]), ConfigError, "sets seed 3"),
    ],
)
def test_bad_input_is_rejected_before_any_work(
    data_dir: Path, tmp_path: Path, change: dict, error: type, match: str
) -> None:
    c = cfg(data_dir, tmp_path, [MethodRun("test-oracle", "test-oracle")])
    for k, v in change.items():
        setattr(c, k, v)
    with pytest.raises(error, match=match):
        runner.evaluate(c)
    assert not (tmp_path / "maps").exists()


def test_query_tables_carry_the_scene_difficulty_and_older_tables_still_load(tmp_path: Path) -> None:
    data, out = tmp_path / "data", tmp_path / "r"
    difficulty_scene(data, "sD", DIFFICULTY)
    make_scene(data, "sP", splits=("query", "query_light1"))  # no difficulty.csv, no data version: imported data
    c = cfg(data, out, [MethodRun("test-oracle", "test-oracle")], splits=["query", "query_light1"])
    c.scenes = ["sD", "sP"]
    assert runner.evaluate(c).errors == []
    runs = out / "runs" / "test-oracle" / "oracle-mask"
    light = pd.read_csv(runs / "sD" / "query_light1.queries.csv")
    np.testing.assert_array_equal(light["gap_deg"], [25.0, np.nan, 90.0])  # frame 000001 has no row
    assert light["data_version"].tolist() == [DATA_VERSION] * 3
    assert light["confidence"].tolist() == [ORACLE_CONFIDENCE] * 3  # what the method said of each pose
    q = load_run_queries(out, uses_masks).set_index(["scene", "query"])
    assert q.loc[("sD", "query/000001"), "visible_objects"] == 2 and q.loc[("sD", "query/000002"), "gap_m"] == 1.5
    plain = q.loc["sP"]
    assert len(plain) == 6 and plain[[*DIFFICULTY_AXES, "data_version"]].isna().all().all()
    # a per-query table written before these columns existed: loads, with no difficulty and data v1
    old = runs / "sD" / "query.queries.csv"
    pd.read_csv(old).drop(columns=[*DIFFICULTY_AXES, "data_version"]).to_csv(old, index=False)
    q = load_run_queries(out, uses_masks).set_index(["scene", "split"])
    assert q.loc[("sD", "query"), "data_version"].tolist() == [1, 1, 1]
    assert q.loc[("sD", "query"), list(DIFFICULTY_AXES)].isna().all().all()
    assert q.loc[("sD", "query_light1"), "light_level"].tolist()[::2] == [0.7, 0.7]


def test_a_broken_difficulty_table_is_rejected_before_any_work(tmp_path: Path) -> None:
    difficulty_scene(tmp_path / "data", "sD", {**DIFFICULTY, "gap_m": ["far", *DIFFICULTY["gap_m"][1:]]})
    c = cfg(tmp_path / "data", tmp_path / "r", [MethodRun("test-oracle", "test-oracle")])
    c.scenes = ["sD"]
    with pytest.raises(DataError, match="difficulty.csv.*column 'gap_m' holds a value that is no number"):
        runner.evaluate(c)
    assert not (tmp_path / "r" / "maps").exists()


@pytest.mark.parametrize(("timeout_s", "workers"), [(0.0, 1), (30.0, 1), (0.0, 2)])
def test_query_bar_ticks_per_query_inline_and_per_job_in_workers(
    data_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, timeout_s: float, workers: int
) -> None:
    steps: list[tuple[str, int]] = []
    update = runner._Bar.update
    monkeypatch.setattr(runner._Bar, "update", lambda bar, n=1: (steps.append((bar.desc, n)), update(bar, n))[1])
    runs = [MethodRun("test-oracle", "test-oracle")]
    report = runner.evaluate(cfg(data_dir, tmp_path, runs, timeout_s=timeout_s, workers=workers))
    assert report.errors == [] and (report.queries, report.queries_localized) == (6, 6)
    queries = [n for desc, n in steps if desc == "queries" and n]
    assert queries == ([1] * 6 if workers == 1 else [3, 3])  # two scenes of three queries
    assert sum(n for desc, n in steps if desc == "maps") == sum(
        len(list((data_dir / s / "mapping" / "pose").iterdir())) for s in ("sA", "sB")
    )
    assert jobs._query_done is None
