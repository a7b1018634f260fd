"""The board's HTML page in a real headless browser: its columns sort, and it is photographed whole.

The screenshot's sizing is tested without a browser; the tests that open a page skip where headless
Chromium is not installed."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from PIL import Image

from openreloc_bench.harness import browser
from openreloc_bench.harness.leaderboard.pages import to_html

needs_browser = pytest.mark.skipif(not browser.available(), reason=browser.MISSING)


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


def test_a_page_is_widened_only_for_content_wider_than_asked() -> None:
    assert browser.page_width(1600, 1600) == 1600  # fits: laid out at the width asked for
    assert browser.page_width(1600, 2400) == 2400 + browser.MARGIN_PX  # a wide table: all of it, and a margin


def test_full_page_size_measures_again_after_widening() -> None:
    widths = []

    def measure(w: int) -> tuple[int, int]:
        """A page holding a 2000 px wide table, whose text takes less height the wider it is laid out."""
        widths.append(w)
        return max(w, 2000), 3_000_000 // w

    assert browser.full_page_size(measure, 1600) == (2032, 3_000_000 // 2032)  # the height at the final width
    assert widths == [1600, 2032]
    widths.clear()
    assert browser.full_page_size(lambda w: (widths.append(w) or w, 900), 1600) == (1600, 900)
    assert widths == [1600]  # it fits: measured once


def test_a_page_longer_than_a_screenshot_can_be_is_scaled_to_fit() -> None:
    assert browser.shot_scale((1600, 9000)) == 1.0
    scale = browser.shot_scale((2000, 4 * browser.MAX_SIDE_PX))
    assert scale == 0.25 and round(4 * browser.MAX_SIDE_PX * scale) == browser.MAX_SIDE_PX


@needs_browser
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


@needs_browser
def test_screenshot_is_a_png_of_the_page(tmp_path: Path) -> None:
    size = browser.screenshot(board_page(tmp_path), tmp_path / "shot.png", width=800)
    assert (tmp_path / "shot.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert Image.open(tmp_path / "shot.png").size == size and size[0] == 800


@needs_browser
def test_screenshot_holds_the_whole_page_past_the_right_edge_and_the_window(tmp_path: Path) -> None:
    """A table scrolling sideways (as the boards' do) ends in a red cell; a blue box ends the tall page."""
    cells = "".join(f"<td>column {i:02d}</td>" for i in range(60))
    page = tmp_path / "wide.html"
    page.write_text(
        '<!doctype html><html><body style="margin: 20px">'
        f'<div style="overflow-x: auto"><table><tr>{cells}<td style="background: #f00">end</td></tr></table></div>'
        '<div style="height: 3000px"></div><div style="background: #00f; width: 40px; height: 20px"></div>'
        "</body></html>"
    )
    size = browser.screenshot(page, tmp_path / "shot.png", width=800)
    shot = np.asarray(Image.open(tmp_path / "shot.png").convert("RGB")).astype(int)
    assert shot.shape[:2] == (size[1], size[0]) and size[0] > 800 and size[1] > 3000
    red = np.argwhere((shot[..., 0] > 200) & (shot[..., 1] < 50) & (shot[..., 2] < 50))
    blue = np.argwhere((shot[..., 2] > 200) & (shot[..., 0] < 50) & (shot[..., 1] < 50))
    assert len(red) and red[:, 1].max() < size[0] - 1  # the table's last cell, whole
    assert len(blue) and blue[:, 0].max() < size[1] - 1  # the page's last box, whole
