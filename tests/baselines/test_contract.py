"""The checks every structure-based baseline passes (tests/baselines/contract.py), run for each."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

from openreloc_bench.data.scene import Scene
from tests.baselines import contract

pytestmark = pytest.mark.parametrize("name", ["sift-pnp", "orb-reloc"])


def test_registered(name: str) -> None:
    contract.check_registered(name)


def test_mapping_frames_localize(name: str, built_map: Callable[[str], Path], scenes: tuple[Scene, Scene]) -> None:
    contract.check_mapping_frames_localize(name, built_map(name), scenes[0])


def test_other_scene_fails(name: str, built_map: Callable[[str], Path], scenes: tuple[Scene, Scene]) -> None:
    contract.check_other_scene_fails(name, built_map(name), scenes[1])


def test_ignores_masks(name: str, built_map: Callable[[str], Path], scenes: tuple[Scene, Scene]) -> None:
    contract.check_ignores_masks(name, built_map(name), scenes[0])


def test_damaged_maps(name: str, built_map: Callable[[str], Path], tmp_path: Path) -> None:
    contract.check_damaged_maps(name, built_map(name), tmp_path)
