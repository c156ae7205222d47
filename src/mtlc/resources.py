"""Locate the files that ship with mtlc (grammar, stdlib, diagnostic pages).

In a built wheel they live in ``mtlc/_resources``; in a source checkout (editable install, tests)
they are the top-level folders of the repository. Both layouts are looked up here and nowhere else.
"""

from __future__ import annotations

from functools import cache
from pathlib import Path

_PACKAGE_DIR = Path(__file__).resolve().parent
_CHECKOUT_DIR = _PACKAGE_DIR.parent.parent

# name in the wheel -> folder in the checkout
_LAYOUT = {
    "grammar": Path("grammar"),
    "stdlib": Path("stdlib"),
    "diagnostics": Path("docs") / "diagnostics",
}


@cache
def resource_dir(name: str) -> Path:
    """The folder holding the named resource, whichever layout is installed."""
    installed = _PACKAGE_DIR / "_resources" / name
    if installed.is_dir():
        return installed
    checkout = _CHECKOUT_DIR / _LAYOUT[name]
    if checkout.is_dir():
        return checkout
    raise FileNotFoundError(f"mtlc resource folder {name!r} is missing from this installation")


def grammar_path() -> Path:
    return resource_dir("grammar") / "mtask.lark"


def stdlib_dir() -> Path:
    return resource_dir("stdlib")


def data_path(*parts: str) -> Path:
    """A data table carried inside the package (``mtlc/data``)."""
    return _PACKAGE_DIR.joinpath("data", *parts)
