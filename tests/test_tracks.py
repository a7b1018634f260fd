from openreloc_bench.tracks import DEFAULT_TRACK, MASK_FREE, ORACLE_MASK, PREDICTED, TRACKS


def test_the_recorded_names_never_change() -> None:
    """Maps, result files, tables and boards record these strings: results of every version read alike."""
    assert (ORACLE_MASK, PREDICTED, MASK_FREE) == ("oracle-mask", "predicted", "mask-free")
    assert TRACKS == (ORACLE_MASK, PREDICTED) and DEFAULT_TRACK == PREDICTED
