"""Suite / scene spec validation: bad specs fail with one line naming the key, before anything is written."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from generators.spec import TRAINING_SEED_MIN, VALIDATION_SEED_MIN, SceneSpec, load_suite, spec_hash
from openreloc_bench import config
from openreloc_bench.errors import ConfigError

SCENES = Path(__file__).resolve().parents[2] / "scenes"


@pytest.mark.parametrize("suite", ["smoke", "single-room", "multi-room", "multi-floor", "validation"])
def test_shipped_suites_load(suite: str) -> None:
    loaded = load_suite(SCENES / f"{suite}.yaml")
    specs = loaded.scene_specs()
    assert specs and loaded.purpose == ("validation" if suite == "validation" else "benchmark")
    if suite == "validation":
        assert all(s.seed >= VALIDATION_SEED_MIN for s in specs)
    else:
        assert all(s.seed < TRAINING_SEED_MIN for s in specs)
    if suite != "smoke":
        assert all((s.width, s.height) == (640, 480) for s in specs)


def _write(tmp_path: Path, scene: dict, defaults: dict | None = None, purpose: str = "benchmark") -> Path:
    p = tmp_path / "suite.yaml"
    p.write_text(yaml.safe_dump({"name": "t", "purpose": purpose, "defaults": defaults or {}, "scenes": [scene]}))
    return p


@pytest.mark.parametrize(
    ("purpose", "seed", "ok"),
    [
        ("benchmark", 5, True),
        ("benchmark", TRAINING_SEED_MIN, False),
        ("benchmark", VALIDATION_SEED_MIN, False),
        ("validation", VALIDATION_SEED_MIN, True),
        ("validation", VALIDATION_SEED_MIN - 1, False),
        ("validation", 5, False),
    ],
)
def test_each_purpose_has_its_own_seed_range(tmp_path: Path, purpose: str, seed: int, ok: bool) -> None:
    """Benchmark, training and validation scenes never share a seed: a model is neither trained nor
    selected on a scene it is scored on."""
    path = _write(tmp_path, {"name": "a", "seed": seed}, purpose=purpose)
    if ok:
        assert load_suite(path).scene_specs()[0].seed == seed
    else:
        with pytest.raises(ConfigError, match="seed"):
            load_suite(path)


def test_unknown_purpose_is_rejected(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="purpose"):
        load_suite(_write(tmp_path, {"name": "a"}, purpose="training"))


@pytest.mark.parametrize(
    "scene, key",
    [
        ({"name": "a", "sed": 1}, "sed"),
        ({"name": "a", "kind": "multi-room", "rooms": 12}, "rooms"),
        ({"name": "a", "kind": "multi-room", "rooms": 2}, "rooms"),
        ({"name": "a", "kind": "multi-floor", "rooms": 3, "floors": 5}, "floors"),
        ({"name": "a", "objects_per_room": 500}, "objects_per_room"),
        ({"name": "a", "width": -640}, "width"),
        ({"name": "a", "room_side_min": -1.0}, "room_side_min"),
        ({"name": "a", "displaced_share": -0.1}, "displaced_share"),
        ({"name": "a", "bare_wall_share": 1.5}, "bare_wall_share"),
        ({"name": "a", "photo_share": -0.2}, "photo_share"),
        ({"name": "a", "room_side_min": 5.0, "room_side_max": 1e6}, "'room_side_max' must be at most 30"),
        ({"name": "a", "removed_share": 1.5}, "removed_share"),
        ({"name": "a", "displaced_share": 0.6, "added_share": 0.6}, "at most 1"),
        ({"name": "a", "kind": "castle"}, "kind"),
        ({"name": "a", "seed": TRAINING_SEED_MIN + 5}, "seed"),
        ({"name": "a", "light_levels": [0.5, 0.4]}, "light_levels"),
    ],
)
def test_bad_spec_names_key(tmp_path: Path, scene: dict, key: str) -> None:
    with pytest.raises(ConfigError) as e:
        load_suite(_write(tmp_path, scene))
    msg = str(e.value)
    assert key in msg and "\n" not in msg


def test_bad_spec_writes_nothing(tmp_path: Path) -> None:
    from openreloc_bench.cli import main

    out = tmp_path / "out"
    rc = main(["generate", str(_write(tmp_path, {"name": "a", "rooms": 0})), "--out", str(out)])
    assert rc != 0 and not out.exists()


def test_defaults_merge_and_hash(tmp_path: Path) -> None:
    suite = load_suite(_write(tmp_path, {"name": "a", "seed": 3}, defaults={"width": 320, "height": 240}))
    (spec,) = suite.scene_specs()
    assert (spec.width, spec.height, spec.seed) == (320, 240, 3)
    same = config.from_dict(SceneSpec, config.to_dict(spec))
    assert spec_hash(same) == spec_hash(spec)
    assert spec_hash(SceneSpec(name="a", seed=4, width=320, height=240)) != spec_hash(spec)


def test_training_seeds_allowed_outside_suites() -> None:
    assert SceneSpec(name="train", seed=TRAINING_SEED_MIN + 1).seed >= TRAINING_SEED_MIN
