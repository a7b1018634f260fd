"""The benchmark's tracks: which instance masks a method is given, at mapping and at query time.

Maps, result files, markers, tables and boards record these names, so their values never change.
Defined below the data layer, which reads them back from results folders.
"""

from __future__ import annotations

import typing
from typing import Final, Literal

Track = Literal["oracle-mask", "predicted"]
"""A track a run is asked for (``--track``, a config's or a plan's ``track``)."""
RecordedTrack = Literal["oracle-mask", "predicted", "mask-free"]
"""What a map or a result records: its track, or :data:`MASK_FREE`."""

ORACLE_MASK: Final = "oracle-mask"
"""Queries and mapping frames carry the dataset's instance masks (a perfect detector): the upper bound."""
PREDICTED: Final = "predicted"
"""Neither does; a method segments for itself (the paper's setting)."""
MASK_FREE: Final = "mask-free"
"""What stands for the track where it makes no difference: the maps and results of methods that read no
masks (``uses_masks = False``) serve both tracks, and are recorded under this track."""

TRACKS: Final[tuple[Track, ...]] = typing.get_args(Track)
"""The tracks a run can be asked for, in the order of :data:`Track`."""
DEFAULT_TRACK: Final = PREDICTED
"""The track of ``eval``, ``map``, ``localize``, ``score``, ``diagnose`` and the environments unless one is
named: the headline track, the one a deployed method faces (no perfect detector); oracle masks are asked for."""
