from collections.abc import Callable, Iterator
from importlib.metadata import EntryPoint
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from baselines.nearest_frame import NearestFrame
from openreloc_bench import methods
from openreloc_bench.data.types import Frame
from openreloc_bench.errors import ConfigError
from openreloc_bench.methods import (
    BUILTIN_METHODS,
    ENTRY_POINT_GROUP,
    Failure,
    PoseEstimate,
    QueryFrame,
    Relocalizer,
    available_methods,
    create_method,
    localize_safely,
    recorded_track,
    register,
    uses_masks,
)
from openreloc_bench.tracks import MASK_FREE, ORACLE_MASK, PREDICTED, TRACKS


@pytest.mark.parametrize("name", sorted(BUILTIN_METHODS))
def test_every_built_in_method_loads_as_a_relocalizer_of_its_name(name: str) -> None:
    m = create_method(name)
    assert isinstance(m, Relocalizer) and m.name == name
    assert available_methods()[name].__doc__ == f"built-in {BUILTIN_METHODS[name]}"


def test_the_built_in_methods_are_not_entry_points_of_this_project() -> None:
    """One table names them: the project's own pyproject declares no method."""
    assert ENTRY_POINT_GROUP not in (Path(__file__).parents[1] / "pyproject.toml").read_text()


@pytest.fixture
def installed(monkeypatch: pytest.MonkeyPatch) -> Iterator[Callable[..., None]]:
    """``installed(name=value, ...)``: these entry points stand for the environment's, until the test ends."""

    def install(**found: str) -> None:
        eps = [EntryPoint(name, value, ENTRY_POINT_GROUP) for name, value in found.items()]
        monkeypatch.setattr(methods, "entry_points", lambda group: eps if group == ENTRY_POINT_GROUP else [])
        methods._named_methods.cache_clear()

    yield install
    methods._named_methods.cache_clear()  # read again from the environment


def test_a_stale_entry_point_of_a_built_in_is_dropped_silently(installed, caplog: pytest.LogCaptureFixture) -> None:
    """An install of this project from when its methods were entry points names the same classes."""
    installed(**{"nearest-frame": BUILTIN_METHODS["nearest-frame"], "outside": "baselines.nearest_frame:NearestFrame"})
    found = available_methods()
    assert list(found).count("nearest-frame") == 1 and found["nearest-frame"].__doc__.startswith("built-in ")
    assert found["outside"].__doc__ == "entry point baselines.nearest_frame:NearestFrame"
    assert not uses_masks("outside") and not caplog.records
    with pytest.raises(ConfigError, match="method name 'outside' is taken by baselines.nearest_frame:NearestFrame"):
        register("outside", NearestFrame)


def test_an_entry_point_cannot_take_a_built_in_name(installed, caplog: pytest.LogCaptureFixture) -> None:
    """It is ignored with one warning line (per process), and the name stays the built-in's."""
    installed(**{"nearest-frame": "my_package.methods:Mine"})
    for _ in range(2):
        assert available_methods()["nearest-frame"].__doc__ == f"built-in {BUILTIN_METHODS['nearest-frame']}"
    assert isinstance(create_method("nearest-frame"), NearestFrame)
    assert [r.getMessage() for r in caplog.records if r.levelname == "WARNING"] == [
        "entry point nearest-frame = my_package.methods:Mine ignored: 'nearest-frame' is the built-in method "
        "baselines.nearest_frame:NearestFrame; declare yours under another name"
    ]


def test_unknown_method_lists_known_ones():
    with pytest.raises(ConfigError, match="unknown method 'nope'.*nearest-frame"):
        create_method("nope")


def test_unknown_config_key():
    with pytest.raises(ConfigError, match="thumbsize"):
        NearestFrame(thumbsize=8)


def test_in_process_registration():
    register("test-identity", NearestFrame)
    assert isinstance(create_method("test-identity"), NearestFrame)


def test_a_method_without_a_name_is_a_one_line_error(monkeypatch) -> None:
    class Nameless:
        def build_map(self, mapping, map_dir) -> None: ...

        def load_map(self, map_dir) -> None: ...

        def localize(self, query) -> None: ...

    monkeypatch.setitem(methods._REGISTRY, "nameless", Nameless)  # gone after the test
    with pytest.raises(ConfigError, match="method 'nameless': its Nameless has no 'name'; a method needs name, "):
        create_method("nameless")


def test_methods_read_masks_unless_they_say_otherwise() -> None:
    assert uses_masks("openreloc") and uses_masks("no-such-method")
    assert not uses_masks("nearest-frame")


@pytest.mark.parametrize("track", TRACKS)
def test_the_recorded_track_follows_the_method_declaration(track: str) -> None:
    assert recorded_track(create_method("nearest-frame"), track) == MASK_FREE  # uses_masks = False
    assert recorded_track(object(), track) == track  # says nothing: reads masks


def test_a_query_frame_carries_the_dataset_masks_on_the_oracle_mask_track_only_and_its_track() -> None:
    frame = Frame("query/000001", np.eye(4), np.eye(3), np.zeros((4, 4, 3), np.uint8), instance=np.ones((4, 4), int))
    assert QueryFrame.from_frame(frame, ORACLE_MASK).track == ORACLE_MASK
    assert QueryFrame.from_frame(frame, ORACLE_MASK).instance is frame.instance
    for track in (PREDICTED, MASK_FREE):
        assert QueryFrame.from_frame(frame, track).instance is None
        assert QueryFrame.from_frame(frame, track).track == track


def test_a_query_frame_made_without_a_track_is_taken_for_the_one_its_masks_say() -> None:
    img = np.zeros((4, 4, 3), np.uint8)
    assert QueryFrame("q/1", img, np.eye(3)).track == PREDICTED
    assert QueryFrame("q/1", img, np.eye(3), np.ones((4, 4), int)).track == ORACLE_MASK
    assert QueryFrame("q/1", img, np.eye(3), None, MASK_FREE).track == MASK_FREE


class Answering:
    """A method whose ``localize`` answers ``answer`` (raises it when it is an exception)."""

    name = "answering"

    def __init__(self, answer: Any):
        self.answer = answer

    def localize(self, query: QueryFrame) -> Any:
        if isinstance(self.answer, BaseException):
            raise self.answer
        return self.answer


POSE = np.eye(4)
POSE[:3, 3] = (1.0, 2.0, 3.0)
SHEARED = POSE.copy()
SHEARED[0, 1] = 0.5
NAN_POSE = POSE.copy()
NAN_POSE[0, 3] = np.nan


@pytest.mark.parametrize(
    ("answer", "reason"),
    [
        (RuntimeError("boom"), "raised RuntimeError: boom"),
        (ValueError("x" * 400), "raised ValueError: " + "x" * 281),  # cut at 300 characters
        (SystemExit(0), "called sys.exit(0)"),  # a plugin's exit fails its query, not the run with exit 0
        (None, "no estimate"),
        (Failure("too few objects", {"matches": [1]}), "too few objects"),
        (Failure(""), "failure"),
        ((POSE, 1.0), "invalid return type tuple"),
        (PoseEstimate(SHEARED), "invalid pose (not a finite rigid 4x4 transform)"),
        (PoseEstimate(NAN_POSE), "invalid pose (not a finite rigid 4x4 transform)"),
        (PoseEstimate(np.stack([POSE, POSE])), "invalid pose (not a finite rigid 4x4 transform)"),
        (PoseEstimate("not a pose"), "invalid pose (not a finite rigid 4x4 transform)"),  # type: ignore[arg-type]
    ],
)
def test_every_answer_but_a_rigid_pose_is_a_failure_with_its_reason(answer: Any, reason: str) -> None:
    query = QueryFrame("query/000003", np.zeros((4, 4, 3), np.uint8), np.eye(3))
    got = localize_safely(Answering(answer), query)  # type: ignore[arg-type]
    assert (got.name, got.T_wc, got.reason) == ("query/000003", None, reason) and got.seconds >= 0
    assert got.diagnostics == (answer.diagnostics if isinstance(answer, (Failure, PoseEstimate)) else {})


def test_a_rigid_pose_is_the_answer_with_its_diagnostics() -> None:
    query = QueryFrame("query/000003", np.zeros((4, 4, 3), np.uint8), np.eye(3))
    got = localize_safely(Answering(PoseEstimate(POSE.tolist(), {"matches": [1, 2]})), query)  # type: ignore[arg-type]
    assert got.reason == "" and got.diagnostics == {"matches": [1, 2]}
    assert got.T_wc is not None and got.T_wc.dtype == np.float64 and np.array_equal(got.T_wc, POSE)
    assert np.isnan(got.confidence)  # the method did not say


@pytest.mark.parametrize(
    ("confidence", "recorded"), [(42, 42.0), (np.float32(0.5), 0.5), ("high", np.nan), (None, np.nan)]
)
def test_a_pose_carries_the_methods_confidence_a_non_number_none(confidence: Any, recorded: float) -> None:
    query = QueryFrame("query/000003", np.zeros((4, 4, 3), np.uint8), np.eye(3))
    got = localize_safely(Answering(PoseEstimate(POSE, confidence=confidence)), query)  # type: ignore[arg-type]
    assert got.reason == "" and np.array_equal([got.confidence], [recorded], equal_nan=True)
