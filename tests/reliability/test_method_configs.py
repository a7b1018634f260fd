"""Every number of a method's config, read from a user's YAML or ``--set``, is checked: NaN,
infinities, negatives and out-of-range shares are one-line ConfigErrors naming the key, before any
map is built or query run (they used to reach open3d, numpy or torch as tracebacks or silent garbage)."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterator
from typing import Any

import pytest

from openreloc_bench.errors import ConfigError
from openreloc_bench.methods import create_method
from openreloc_bench.openreloc.method import OpenReLocConfig


def numeric_fields(cls: type, prefix: tuple[str, ...] = ()) -> Iterator[tuple[tuple[str, ...], Any]]:
    for f in dataclasses.fields(cls):
        default = f.default if f.default is not dataclasses.MISSING else f.default_factory()  # type: ignore[misc]
        if dataclasses.is_dataclass(default):
            yield from numeric_fields(type(default), (*prefix, f.name))
        elif isinstance(default, (int, float)) and not isinstance(default, bool):
            yield (*prefix, f.name), default


def nested(path: tuple[str, ...], value: Any) -> dict[str, Any]:
    out: Any = value
    for key in reversed(path):
        out = {key: out}
    return out


FIELDS = list(numeric_fields(OpenReLocConfig))


def test_the_walk_sees_every_section() -> None:
    sections = {p[0] for p, _ in FIELDS if len(p) > 1}
    assert {"association", "verification", "coarse", "refinement", "consistency", "mapping"} <= sections
    assert len(FIELDS) > 90


@pytest.mark.parametrize("path", [p for p, _ in FIELDS], ids=[".".join(p) for p, _ in FIELDS])
def test_nan_infinity_and_negative_values_are_refused_naming_the_key(path: tuple[str, ...]) -> None:
    default = dict(FIELDS)[path]
    bad = [-1] if isinstance(default, int) else [math.nan, math.inf, -math.inf, -1.0]
    for value in bad:
        with pytest.raises(ConfigError) as e:
            create_method("openreloc", **nested(path, value))
        message = str(e.value)
        assert path[-1] in message and "\n" not in message, message
    create_method("openreloc", **nested(path, default))  # the default itself is in range


@pytest.mark.parametrize(
    "overrides, message",
    [
        ({"min_mask_frac": 2.0}, "'min_mask_frac' must be in [0, 1]"),
        ({"refinement": {"lr_rotation": 0.0}}, "openreloc.refinement: 'lr_rotation' must be > 0"),
        ({"verification": {"samples": 0}}, "openreloc.verification: 'samples' must be >= 1"),
        ({"mapping": {"fusion": {"voxel_size": 0.0}}}, "openreloc.mapping.fusion: 'voxel_size' must be > 0"),
        ({"mapping": {"fusion": {"max_fusion_width": 1}}}, "'max_fusion_width' must be 0 (full resolution) or >= 16"),
        ({"mapping": {"descriptors": {"top_k": 0}}}, "'top_k' must be >= 1"),
        ({"mapping": {"instances": {"clustering": {"observer_percentiles": [101.0]}}}}, "percentiles in [0, 100]"),
        ({"consistency": {"stride": 0}}, "'stride' must be >= 1"),
        ({"refinement": {"max_iterations": 2**64}}, "out of range (a 64-bit integer)"),
    ],
)
def test_zero_and_out_of_range_values_where_they_mean_nothing(overrides: dict, message: str) -> None:
    with pytest.raises(ConfigError) as e:
        create_method("openreloc", **overrides)
    assert message in str(e.value)
