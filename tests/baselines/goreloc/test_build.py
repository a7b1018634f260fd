"""Building GOReloc's map: where its instances come from."""

from __future__ import annotations

from pathlib import Path

import pytest

from baselines.goreloc.build import GORelocMappingConfig, instance_source
from openreloc_bench.data.scene import Scene
from openreloc_bench.errors import ConfigError


@pytest.mark.parametrize(("track", "source"), [("oracle-mask", "masks"), ("predicted", "segmenter"), (None, "masks")])
def test_auto_takes_the_instances_of_the_sequences_track(tiny_scene: Path, track: str | None, source: str) -> None:
    """The builder reads the track the mapping sequence was opened for (without one: the masks it has)."""
    assert instance_source(Scene(tiny_scene).sequence("mapping", track), GORelocMappingConfig()) == source


def test_masks_asked_for_on_the_predicted_track_are_refused(tiny_scene: Path) -> None:
    with pytest.raises(ConfigError, match="no instance masks"):
        instance_source(
            Scene(tiny_scene).sequence("mapping", "predicted"), GORelocMappingConfig(instances_from="masks")
        )
