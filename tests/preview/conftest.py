"""Fixtures for the preview tests: compiled examples, a real headless Chromium, a live server.

Chromium comes from Debian (`scripts/install_chromium.sh` installs it when missing); the tests
skip, with the reason, only when it cannot be installed (no root, no apt, no network).
"""

from __future__ import annotations

import shutil
import subprocess
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from conftest import compiled_example

from mtlc.frontend import FrontendOptions
from mtlc.passes import MotionOptions
from mtlc.preview.html import render_page
from mtlc.preview.server import MotionHub, PreviewServer

from .preview_support import (
    CHROMEDRIVER,
    CHROMIUM,
    CHROMIUM_MISSING,
    EXAMPLES,
    ROOT,
    SELENIUM_MISSING,
    Example,
    headless_chromium,
)


@pytest.fixture(scope="session")
def examples(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Example]:
    """Every example compiled once per session, with its preview page written."""
    out = tmp_path_factory.mktemp("previews")
    result: dict[str, Example] = {}
    for path in EXAMPLES:
        compiled = compiled_example(path)
        assert compiled.ok, compiled.program.diagnostics
        ir, doc = compiled.motions[0], compiled.documents()[0]
        page = out / f"{path.stem}.html"
        page.write_text(render_page(doc), encoding="utf-8")
        result[path.stem] = Example(path, ir, doc, page)
    return result


def _ensure_chromium() -> str | None:
    """None when Chromium and its driver are there (installing them if we can), else one line
    naming what to install (the script's own reason after it)."""
    if not CHROMIUM.exists() or not CHROMEDRIVER.exists():
        script = ROOT / "scripts" / "install_chromium.sh"
        run = subprocess.run(["sh", str(script)], capture_output=True, text=True, timeout=900)
        if run.returncode != 0:
            why = " ".join((run.stderr or run.stdout).split())[-200:]
            return f"{CHROMIUM_MISSING} [{why}]"
    if not CHROMIUM.exists() or not CHROMEDRIVER.exists():
        return CHROMIUM_MISSING
    return None


@pytest.fixture(scope="session")
def browser() -> Iterator[Any]:
    """A headless Chromium driven by selenium through Debian's chromedriver."""
    pytest.importorskip("selenium.webdriver", reason=SELENIUM_MISSING)

    reason = _ensure_chromium()
    if reason is not None:
        pytest.skip(reason)
    with headless_chromium() as driver:
        driver.set_script_timeout(30)
        yield driver


@pytest.fixture
def served(tmp_path: Path) -> Iterator[tuple[PreviewServer, Path]]:
    """A server on a free loopback port over a copy of an example (so saves can be tested)."""
    task = tmp_path / "remove_access_panel.mtask"
    shutil.copy(ROOT / "examples" / "remove_access_panel.mtask", task)
    hub = MotionHub([task], FrontendOptions(), MotionOptions())
    server = PreviewServer(hub, port=0, poll=0.1)
    server.start()
    try:
        yield server, task
    finally:
        server.stop()
