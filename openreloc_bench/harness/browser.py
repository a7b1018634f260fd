"""The boards' HTML page in a real headless browser: Debian's Chromium driven by Selenium.

Used to screenshot each board and, in the tests, to check that its columns sort. Nothing is
downloaded: the browser and its driver are the system's (``apt-get install chromium chromium-driver``,
which ``scripts/setup.sh`` does), and Selenium is told where they are.
"""

from __future__ import annotations

import shutil
from collections.abc import Iterator
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


def screenshot(html_file: Path, png: Path, width: int = 1600, height: int | None = 1400) -> None:
    """A PNG of the top ``height`` pixels of the page at ``width`` pixels (None: the whole page)."""
    with page(html_file, width) as driver:
        if height is None:
            height = int(driver.execute_script("return document.documentElement.scrollHeight")) + 40
        driver.set_window_size(width, min(height, 12000))
        png.parent.mkdir(parents=True, exist_ok=True)
        driver.save_screenshot(str(png))
