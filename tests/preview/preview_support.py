"""Shared by the preview tests: where things are, and a compiled example.

tests/preview is a package (it has an ``__init__.py``) so that its conftest is
``preview.conftest`` and never shadows the suite's top-level ``conftest`` module.
"""

from __future__ import annotations

import contextlib
import shutil
import tempfile
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mtlc.ir.model import MotionIR

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = sorted((ROOT / "examples").glob("*.mtask"))
CHROMIUM = Path("/usr/bin/chromium")
CHROMEDRIVER = Path("/usr/bin/chromedriver")
# The one line a skipped browser test prints: exactly what to install.
CHROMIUM_MISSING = (
    "Chromium and chromedriver are not installed: run scripts/install_chromium.sh as root "
    "(apt: chromium chromium-driver fonts-dejavu-core)"
)
SELENIUM_MISSING = "selenium is not installed: pip install -e '.[test]'"
CHROMIUM_FLAGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--use-gl=angle",
    "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader",
    "--window-size=1200,800",
]


@dataclass
class Example:
    """One example compiled: its motion, its preview document and the page's path."""

    path: Path
    ir: MotionIR
    document: dict[str, Any]
    page: Path


@contextlib.contextmanager
def headless_chromium() -> Iterator[Any]:
    """A selenium driver on a headless Chromium with a profile of its own, removed afterwards
    (without one, Chromium leaves an ``org.chromium.*`` folder in /tmp per session)."""
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    profile = tempfile.mkdtemp(prefix="mtlc-chromium-")
    options = webdriver.ChromeOptions()
    options.binary_location = str(CHROMIUM)
    for flag in (*CHROMIUM_FLAGS, f"--user-data-dir={profile}"):
        options.add_argument(flag)
    driver = webdriver.Chrome(service=Service(str(CHROMEDRIVER)), options=options)
    try:
        yield driver
    finally:
        driver.quit()
        shutil.rmtree(profile, ignore_errors=True)
