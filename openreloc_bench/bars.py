"""Progress bars of library code that can be switched off while the harness draws its own.

Map building draws a bar per stage (TSDF fusion, crops, features...). Run by ``map`` they show the
work; run by ``eval``, which counts the mapping frames of all maps in one bar, they would draw a
second and third bar over the same frames, from worker processes too. Library code builds its bars
with :func:`tqdm` here; the harness builds maps inside :func:`quiet`.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

from tqdm import tqdm as _tqdm

_quiet = False


def tqdm(*args: Any, disable: bool = False, **kwargs: Any) -> _tqdm:
    """``tqdm.tqdm``, disabled inside :func:`quiet`."""
    return _tqdm(*args, disable=disable or _quiet, **kwargs)


@contextmanager
def quiet() -> Iterator[None]:
    """No bars from :func:`tqdm` in this process while the block runs."""
    global _quiet
    before, _quiet = _quiet, True
    try:
        yield
    finally:
        _quiet = before
