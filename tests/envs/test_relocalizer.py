"""The relocalizer in the loop: its map is built and its queries are asked on the environment's track."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from baselines.nearest_frame import NearestFrame
from openreloc_bench.data.scene import Scene
from openreloc_bench.envs.relocalizer import InLoopRelocalizer
from openreloc_bench.harness import cache
from openreloc_bench.methods import QueryFrame, register
from openreloc_bench.tracks import DEFAULT_TRACK, MASK_FREE, ORACLE_MASK, PREDICTED


class Seeing(NearestFrame):
    """nearest-frame reading masks, noting whether its mapping frames and queries carried them."""

    name = "env-seeing"
    uses_masks = True
    mapped_with_masks: list[bool] = []
    asked_with_masks: list[bool] = []

    def build_map(self, mapping, map_dir: Path) -> None:
        Seeing.mapped_with_masks = [f.instance is not None for f in mapping]
        super().build_map(mapping, map_dir)

    def localize(self, query: QueryFrame) -> Any:
        Seeing.asked_with_masks.append(query.instance is not None)
        return super().localize(query)


class Raising(NearestFrame):
    name = "env-raising"

    def localize(self, query: QueryFrame) -> Any:
        raise RuntimeError("boom")


@pytest.fixture(autouse=True)
def methods() -> None:
    register(Seeing.name, Seeing)
    register(Raising.name, Raising)


def ask(reloc: InLoopRelocalizer, scene: Scene):
    f = scene.sequence("query")[0]
    return reloc.localize("agent/000000", f.color, f.K, f.instance)


@pytest.mark.parametrize(("track", "masks"), [(PREDICTED, False), (ORACLE_MASK, True)])
def test_the_map_and_the_queries_follow_the_environments_track(
    tiny_room: Path, tmp_path: Path, track: str, masks: bool
) -> None:
    scene = Scene(tiny_room)
    Seeing.asked_with_masks = []
    reloc = InLoopRelocalizer(Seeing.name, {"thumb_size": 8}, scene, tmp_path, track)
    assert ask(reloc, scene).T_wc is not None
    assert set(Seeing.mapped_with_masks) == {masks} and Seeing.asked_with_masks == [masks]
    assert cache.map_source(reloc.map_dir) == {"scene": scene.name, "spec_hash": scene.spec_hash, "track": track}


def test_maps_of_the_two_tracks_are_cached_apart_and_a_mask_free_method_shares_one(
    tiny_room: Path, tmp_path: Path
) -> None:
    scene = Scene(tiny_room)
    seeing = {t: InLoopRelocalizer(Seeing.name, {}, scene, tmp_path, t).map_dir for t in (PREDICTED, ORACLE_MASK)}
    assert seeing[PREDICTED] != seeing[ORACLE_MASK]
    free = [InLoopRelocalizer("nearest-frame", {}, scene, tmp_path, t) for t in (PREDICTED, ORACLE_MASK)]
    assert free[0].map_dir == free[1].map_dir and {r.track for r in free} == {MASK_FREE}


def test_an_environment_asks_on_its_track_the_predicted_one_by_default(make_env) -> None:
    assert make_env("openreloc/ActiveReloc-v0", method=Seeing.name).unwrapped.relocalizer.track == DEFAULT_TRACK
    oracle = make_env("openreloc/ActiveReloc-v0", method=Seeing.name, track=ORACLE_MASK)
    assert oracle.unwrapped.relocalizer.track == ORACLE_MASK


def test_a_method_that_raises_fails_the_view_with_the_reason(tiny_room: Path, tmp_path: Path) -> None:
    scene = Scene(tiny_room)
    answer = ask(InLoopRelocalizer(Raising.name, {"thumb_size": 8}, scene, tmp_path, PREDICTED), scene)
    assert answer.T_wc is None and answer.matched == 0 and answer.reason == "raised RuntimeError: boom"
