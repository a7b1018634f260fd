"""The checks of tests/baselines/contract.py, run for each baseline they apply to."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

from openreloc_bench.data.scene import Scene
from tests.baselines import contract

STRUCTURE_BASED = ["sift-pnp", "orb-reloc"]
"""Methods that verify their answer: a mapping frame comes back at its own pose, another room fails."""
ALL = [*STRUCTURE_BASED, "retrieval", "posenet"]
"""Retrieval returns a mapping frame's own pose too; posenet regresses poses, and neither can fail."""

each = pytest.mark.parametrize("name", ALL)


@each
def test_registered(name: str) -> None:
    contract.check_registered(name)


@pytest.mark.parametrize("name", [*STRUCTURE_BASED, "retrieval"])
def test_mapping_frames_localize(name: str, built_map: Callable[[str], Path], scenes: tuple[Scene, Scene]) -> None:
    contract.check_mapping_frames_localize(name, built_map(name), scenes[0])


@pytest.mark.parametrize("name", STRUCTURE_BASED)
def test_confidence_is_the_inlier_count(
    name: str, built_map: Callable[[str], Path], scenes: tuple[Scene, Scene]
) -> None:
    contract.check_confidence_is_inliers(name, built_map(name), scenes[0])


@pytest.mark.parametrize("name", STRUCTURE_BASED)
def test_other_scene_fails(name: str, built_map: Callable[[str], Path], scenes: tuple[Scene, Scene]) -> None:
    contract.check_other_scene_fails(name, built_map(name), scenes[1])


@each
def test_ignores_masks(name: str, built_map: Callable[[str], Path], scenes: tuple[Scene, Scene]) -> None:
    contract.check_ignores_masks(name, built_map(name), scenes[0])


@each
def test_damaged_maps(name: str, built_map: Callable[[str], Path], tmp_path: Path) -> None:
    contract.check_damaged_maps(name, built_map(name), tmp_path)
