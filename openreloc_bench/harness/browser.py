"""The boards' HTML page in a real headless browser: Debian's Chromium driven by Selenium.

Used to screenshot each board (the whole page) and, in the tests, to check that its columns sort. Nothing is
downloaded: the browser and its driver are the system's (``apt-get install chromium chromium-driver``,
which ``scripts/setup.sh`` does), and Selenium is told where they are.
"""

from __future__ import annotations

import base64
import shutil
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

BROWSER = "chromium"
DRIVER = "chromedriver"
MISSING = "headless Chromium is not installed (apt-get install chromium chromium-driver; pip install selenium)"

FLAGS = (
    "--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage", "--no-first-run",
    "--disable-background-networking", "--disable-component-update", "--disable-sync", "--hide-scrollbars",
)  # fmt: skip
"""Headless, and quiet on a machine without a network (no background connections to refuse)."""


def available() -> bool:
    """Whether Chromium, its driver and Selenium are installed."""
    try:
        import selenium  # noqa: F401
    except ImportError:
        return False
    return shutil.which(BROWSER) is not None and shutil.which(DRIVER) is not None


@contextmanager
def page(html_file: Path, width: int = 1600, height: int = 1000) -> Iterator[Any]:
    """A Selenium driver with ``html_file`` open in headless Chromium (quit on exit)."""
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = shutil.which(BROWSER) or BROWSER
    for flag in (*FLAGS, f"--window-size={width},{height}"):
        options.add_argument(flag)
    driver = webdriver.Chrome(service=Service(executable_path=shutil.which(DRIVER)), options=options)
    try:
        driver.get(Path(html_file).resolve().as_uri())
        yield driver
    finally:
        driver.quit()


MAX_SIDE_PX = 16384
"""The longest side of a screenshot Chromium makes: a page longer than this is photographed whole at a
smaller scale."""
MARGIN_PX = 32
"""Room left right of content wider than the window (the page's own margin is on its left only)."""

UNCLIP_JS = """
for (const e of document.querySelectorAll('*')) {
  const s = getComputedStyle(e);
  if (['auto', 'scroll'].includes(s.overflowX)) e.style.overflow = 'visible';
}
"""
"""Shows in full what scrolls sideways (the boards' wide tables), so that the page grows to hold it."""
SIZE_JS = "const d = document.documentElement; return [d.scrollWidth, d.scrollHeight];"
"""The page's size in CSS pixels: at least the viewport's, more where its content reaches further."""


def page_width(viewport_width: int, content_width: int) -> int:
    """The width of a viewport that holds content ``content_width`` wide, measured in one
    ``viewport_width`` wide: the same where the content fits (the page keeps the width asked for), else
    the content's width and :data:`MARGIN_PX`."""
    return viewport_width if content_width <= viewport_width else content_width + MARGIN_PX


def shot_scale(size: tuple[int, int], max_side: int = MAX_SIDE_PX) -> float:
    """The scale at which a page of ``size`` fits a screenshot: 1, or less for a page longer than ``max_side``."""
    return min(1.0, max_side / max(size))


def full_page_size(measure: Callable[[int], tuple[int, int]], width: int, rounds: int = 4) -> tuple[int, int]:
    """The viewport (width, height) that shows the whole page, laid out at least ``width`` wide.
    ``measure(w)`` lays the page out in a viewport ``w`` wide and one pixel tall (so that the height
    measured is the page's, not the window's) and returns its content's size; the page is measured
    again after each widening, since a wider page wraps and scales its content anew (``rounds`` at most)."""
    w = width
    for _ in range(rounds):
        content_w, content_h = measure(w)
        wider = page_width(w, content_w)
        if wider == w:
            return w, max(1, content_h)
        w = wider
    return w, max(1, measure(w)[1])


def screenshot(html_file: Path, png: Path, width: int = 1600) -> tuple[int, int]:
    """A PNG of the whole page laid out at ``width`` CSS pixels (wider where its content is wider, e.g. a
    table that scrolls sideways in a browser), its full height, scaled down only where a side would
    pass :data:`MAX_SIDE_PX`. Returns the page's size in CSS pixels."""
    with page(html_file, width) as driver:
        driver.execute_script(UNCLIP_JS)

        def measure(w: int) -> tuple[int, int]:
            _set_viewport(driver, (w, 1))
            content_w, content_h = driver.execute_script(SIZE_JS)
            return int(content_w), int(content_h)

        size = full_page_size(measure, width)
        _set_viewport(driver, size)
        clip = {"x": 0, "y": 0, "width": size[0], "height": size[1], "scale": shot_scale(size)}
        shot = driver.execute_cdp_cmd("Page.captureScreenshot", {"format": "png", "clip": clip})
    png.parent.mkdir(parents=True, exist_ok=True)
    png.write_bytes(base64.b64decode(shot["data"]))
    return size


def _set_viewport(driver: Any, size: tuple[int, int]) -> None:
    """The page's viewport in CSS pixels, exactly (a window's size in headless Chromium is not its viewport's)."""
    metrics = {"width": size[0], "height": size[1], "deviceScaleFactor": 1, "mobile": False}
    driver.execute_cdp_cmd("Emulation.setDeviceMetricsOverride", metrics)
