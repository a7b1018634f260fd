"""The analytic box room fused and observed once for the reconstruction tests."""

from __future__ import annotations

import pytest

from openreloc_bench.reconstruction.fusion import FusionConfig, fuse_tsdf
from openreloc_bench.reconstruction.observation import ObservationConfig, observe
from tests.openreloc.boxworld import NoisyMaskSegmenter, boxworld_sequence

VOXEL = 0.05
"""The fusion voxel of the ``room`` fixture (m)."""


@pytest.fixture(scope="session")
def room(tmp_path_factory: pytest.TempPathFactory) -> tuple:
    """(mapping sequence, its reconstruction, its observations with a segmenter's masks, boundaries and colours)."""
    seq = boxworld_sequence(tmp_path_factory.mktemp("room"), n_frames=16, hw=(96, 128))
    rec = fuse_tsdf(seq, FusionConfig(voxel_size=VOXEL), progress=False)
    obs = observe(
        seq,
        rec.points,
        rec.usable,
        ObservationConfig(),
        NoisyMaskSegmenter(split_prob=0.0),
        progress=False,
        boundaries=True,
    )
    return seq, rec, obs
