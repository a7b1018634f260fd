"""Library progress bars, and switching them off while the harness counts the work."""

from __future__ import annotations

from openreloc_bench import bars


def test_bars_draw_unless_quiet(capsys) -> None:
    list(bars.tqdm(range(3), desc="stage"))
    assert "stage: 100%" in capsys.readouterr().err
    with bars.quiet():
        with bars.quiet():
            pass
        list(bars.tqdm(range(3), desc="hidden"))
    list(bars.tqdm(range(3), desc="again", disable=True))
    assert "hidden" not in capsys.readouterr().err
    list(bars.tqdm(range(3), desc="after"))
    assert "after: 100%" in capsys.readouterr().err
