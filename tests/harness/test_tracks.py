"""What each track gives a method: the predicted track never hands over an instance image."""

from __future__ import annotations

from pathlib import Path

import pytest

from openreloc_bench.harness import jobs, runner
from openreloc_bench.harness.runner import EvalConfig, MethodRun
from openreloc_bench.methods import available_methods
from tests.baselines.conftest import CHEAP


@pytest.mark.parametrize("name", sorted(n for n in available_methods() if not n.startswith("test-")))
def test_the_predicted_track_gives_no_method_an_instance_image(
    name: str, data_dir: Path, tmp_path: Path, monkeypatch
) -> None:
    seen: dict[str, list[bool]] = {"mapping": [], "queries": []}
    create = jobs.create_method

    def spy(method: str, **overrides):
        m = create(method, **overrides)
        build, localize = m.build_map, m.localize

        def build_map(mapping, map_dir):
            seen["mapping"] += [mapping.has_instances] + [mapping[i].instance is not None for i in range(len(mapping))]
            return build(mapping, map_dir)

        def localize_spy(query):
            seen["queries"].append(query.instance is not None)
            return localize(query)

        m.build_map, m.localize = build_map, localize_spy
        return m

    monkeypatch.setattr(jobs, "create_method", spy)
    cfg = EvalConfig(
        data=data_dir, out=tmp_path, scenes=["sA"], runs=[MethodRun(name, name, CHEAP.get(name, {}))], track="predicted",
        timeout_s=0, map_timeout_s=0,
    )  # fmt: skip
    runner.evaluate(cfg)
    assert seen["mapping"] and not any(seen["mapping"])
    assert not any(seen["queries"])


@pytest.mark.parametrize(("name", "given"), [("test-oracle", True), ("nearest-frame", False)])
def test_the_oracle_track_gives_the_dataset_masks_to_methods_that_read_them(
    name: str, given: bool, data_dir: Path, tmp_path: Path, monkeypatch
) -> None:
    """A method declaring ``uses_masks = False`` gets none: its results are recorded for both tracks."""
    seen: list[bool] = []
    create = jobs.create_method

    def spy(method: str, **overrides):
        m = create(method, **overrides)
        build, localize = m.build_map, m.localize
        m.build_map = lambda mapping, d: (seen.append(mapping.has_instances), build(mapping, d))[1]
        m.localize = lambda q: (seen.append(q.instance is not None), localize(q))[1]
        return m

    monkeypatch.setattr(jobs, "create_method", spy)
    run = MethodRun(name, name)
    runner.evaluate(
        EvalConfig(
            data=data_dir, out=tmp_path, scenes=["sA"], runs=[run], track="oracle-mask", timeout_s=0, map_timeout_s=0
        )
    )
    assert len(seen) == 4 and set(seen) == {given}  # the map, then three queries
