"""The board's HTML page in a real headless browser: its columns sort, and it can be photographed."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest

from openreloc_bench.harness import browser
from openreloc_bench.harness.leaderboard import to_html

pytestmark = pytest.mark.skipif(not browser.available(), reason=browser.MISSING)


def board_page(tmp_path: Path) -> Path:
    b = pd.DataFrame(
        {
            "method": ["a", "b", "c", "d"],
            "track": ["predicted", "predicted", "predicted", "mask-free"],
            "split": ["query"] * 4,
            "recall_50cm": [60.0, 90.0, 75.0, 5.0],
            "recall_25cm": [50.0, 80.0, 70.0, 1.0],
            "latency_median_s": [1200.0, float("nan"), 3.5, 0.4],
        }
    )
    path = tmp_path / "index.html"
    path.write_text(to_html(b, []))
    return path


def test_clicking_a_header_sorts_its_column_both_ways(tmp_path: Path) -> None:
    with browser.page(board_page(tmp_path)) as driver:
        table = driver.find_element("css selector", "table.sortable")

        def names() -> list[str]:
            return [r.find_elements("tag name", "td")[0].text for r in table.find_elements("css selector", "tbody tr")]

        assert names() == ["b", "c", "a", "d"]  # the board's own order: best R@25cm first
        header = table.find_element("xpath", ".//th[text()='R@50cm [%]']")
        header.click()
        assert names() == ["d", "a", "c", "b"]  # ascending
        header.click()
        assert names() == ["b", "c", "a", "d"]  # descending
        table.find_element("xpath", ".//th[text()='Latency med [ms]']").click()
        assert names() == ["d", "c", "a", "b"]  # numbers as numbers (3.5 < 1200), the missing value last


def test_screenshot_is_a_png_of_the_page(tmp_path: Path) -> None:
    browser.screenshot(board_page(tmp_path), tmp_path / "shot.png", width=800)
    assert (tmp_path / "shot.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
