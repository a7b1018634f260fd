"""Sightings (visibility + 2D boxes) and the 'new landmark or 2x visibility' reference-frame rule."""

from __future__ import annotations

import numpy as np

from openreloc_bench.openreloc.reference_frames import (
    ReferenceFrameConfig,
    Sightings,
    landmark_sightings,
    select_reference_frames,
)
from openreloc_bench.reconstruction.observation import FrameObservation

CFG = ReferenceFrameConfig(min_visibility=0.0, min_points=1)


def sightings(rows: list[tuple[int, int, float]]) -> Sightings:
    f, i, v = (np.array(x) for x in zip(*rows))
    return Sightings(f, i, v.astype(float), np.full(len(f), 10), np.tile(np.float32([0, 0, 4, 4]), (len(f), 1)))


def test_visibility_and_box_of_seen_points() -> None:
    labels = np.array([0, 1, 1, 1, 1, 2, 2])
    obs = [FrameObservation(3, np.array([1, 2, 5, 0], np.int32), np.array([[4, 5], [10, 7], [1, 1], [0, 0]], np.int16))]
    s = landmark_sightings(obs, labels, CFG)
    assert list(s.frame) == [3, 3] and list(s.landmark) == [1, 2]
    np.testing.assert_allclose(s.visibility, [0.5, 0.5])
    np.testing.assert_allclose(s.box[0], [4, 5, 11, 8])  # exclusive right/bottom
    np.testing.assert_allclose(s.box[1], [1, 1, 2, 2])


def test_frames_kept_for_new_landmarks_and_doubled_visibility() -> None:
    s = sightings(
        [
            (0, 1, 0.2),  # new landmark 1 -> keep
            (1, 1, 0.3),  # 1.5x -> skip
            (2, 1, 0.45),  # 2.25x of 0.2 -> keep
            (3, 1, 0.5),
            (3, 2, 0.1),  # new landmark 2 -> keep, records both boxes
            (4, 2, 0.15),  # 1.5x -> skip
        ]
    )
    poses = np.tile(np.eye(4), (5, 1, 1))
    rfs = select_reference_frames(s, poses, ReferenceFrameConfig())
    assert [rf.index for rf in rfs] == [0, 2, 3]
    assert set(rfs[2].boxes) == {1, 2} and rfs[2].visibility[2] == 0.1


def test_min_visibility_drops_glimpses() -> None:
    labels = np.array([1] * 100)
    obs = [FrameObservation(0, np.arange(3, dtype=np.int32), np.zeros((3, 2), np.int16))]
    assert len(landmark_sightings(obs, labels, ReferenceFrameConfig(min_visibility=0.05)).frame) == 0
