import pytest

from baselines.nearest_frame import NearestFrame
from openreloc_bench.errors import ConfigError
from openreloc_bench.methods import (
    MASK_FREE,
    TRACKS,
    Relocalizer,
    available_methods,
    create_method,
    recorded_track,
    register,
    uses_masks,
)


def test_nearest_frame_is_registered_through_entry_points():
    assert "nearest-frame" in available_methods()
    m = create_method("nearest-frame")
    assert isinstance(m, Relocalizer) and m.name == "nearest-frame"


def test_unknown_method_lists_known_ones():
    with pytest.raises(ConfigError, match="unknown method 'nope'.*nearest-frame"):
        create_method("nope")


def test_unknown_config_key():
    with pytest.raises(ConfigError, match="thumbsize"):
        NearestFrame(thumbsize=8)


def test_in_process_registration():
    register("test-identity", NearestFrame)
    assert isinstance(create_method("test-identity"), NearestFrame)


def test_methods_read_masks_unless_they_say_otherwise() -> None:
    assert uses_masks("openreloc") and uses_masks("no-such-method")
    assert not uses_masks("nearest-frame")


@pytest.mark.parametrize("track", TRACKS)
def test_the_recorded_track_follows_the_method_declaration(track: str) -> None:
    assert recorded_track(create_method("nearest-frame"), track) == MASK_FREE  # uses_masks = False
    assert recorded_track(object(), track) == track  # says nothing: reads masks
