"""Every baseline refuses out-of-range settings with a one-line ConfigError, before any work."""

from __future__ import annotations

import pytest

from openreloc_bench.errors import ConfigError
from openreloc_bench.methods import create_method

BAD = [
    ("sift-pnp", {"ratio": 2.0}),
    ("sift-pnp", {"min_inliers": 3}),
    ("sift-pnp", {"features": {"max_keypoints": 0}}),
    ("sift-pnp", {"pose": {"confidence": 1.0}}),
    ("orb-reloc", {"ransac_iterations": 0}),
    ("orb-reloc", {"vocabulary": {"depth": 99}}),
    ("orb-reloc", {"direct_index_level": 9}),
    ("goreloc", {"candidates": 0}),
    ("goreloc", {"min_frame_nodes": 2}),
    ("goreloc", {"detection": {"min_score": 2.0}}),
    ("goreloc", {"ransac": {"iterations": -1}}),
    ("goreloc", {"mapping": {"ellipsoid_trim": 0.7}}),
    ("retrieval", {"top_k": 0}),
    ("retrieval", {"descriptor": {"grid": 0}}),
    ("posenet", {"steps": 0}),
    ("posenet", {"backbone": "resnet50"}),
]


@pytest.mark.parametrize(("name", "overrides"), BAD, ids=[f"{n}-{next(iter(o))}" for n, o in BAD])
def test_out_of_range_settings_are_one_line_errors(name: str, overrides: dict) -> None:
    with pytest.raises(ConfigError) as err:
        create_method(name, **overrides)
    assert name in str(err.value) and "\n" not in str(err.value)
