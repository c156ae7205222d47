"""Shared fixtures: golden files (refresh with `pytest --update-goldens`) and helpers."""

from __future__ import annotations

import difflib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
GOLDENS = Path(__file__).resolve().parent / "goldens"
EXAMPLES = sorted((ROOT / "examples").glob("*.mtask"))
STDLIB = sorted((ROOT / "stdlib").glob("*.mtask"))


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption(
        "--update-goldens",
        action="store_true",
        default=False,
        help="rewrite golden files from the current output instead of comparing",
    )


class Golden:
    def __init__(self, update: bool) -> None:
        self.update = update

    def check(self, relpath: str, actual: str) -> None:
        path = GOLDENS / relpath
        if self.update:
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(actual, encoding="utf-8")
            return
        if not path.exists():
            pytest.fail(f"golden file {relpath} is missing: run pytest --update-goldens")
        expected = path.read_text(encoding="utf-8")
        if actual != expected:
            diff = "".join(
                list(
                    difflib.unified_diff(
                        expected.splitlines(True), actual.splitlines(True), "golden", "actual"
                    )
                )[:80]
            )
            pytest.fail(f"{relpath} differs from its golden file:\n{diff}")


@pytest.fixture
def golden(request: pytest.FixtureRequest) -> Golden:
    return Golden(request.config.getoption("--update-goldens"))


@pytest.fixture(autouse=True)
def _run_in_repo(monkeypatch: pytest.MonkeyPatch) -> None:
    """Display paths are relative to the cwd: run every test from the checkout's root."""
    monkeypatch.chdir(ROOT)
    monkeypatch.setenv("NO_COLOR", "1")
