"""Compile with some scene sites moved: what `mtlc serve` does when a site is dragged.

The site's new position must be known while the task expands (MTM times depend on reach and
walk distances), so it is a front-end option (`FrontendOptions.site_overrides`) read by the
expander, not a substitution on the finished timeline.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path

from mtlc.frontend import FrontendOptions, Program, run_frontend

Vec3 = tuple[float, float, float]


def run_frontend_with_sites(
    paths: list[Path], options: FrontendOptions | None, moved: Mapping[str, Vec3]
) -> Program:
    """``run_frontend``, with the named scene sites at the given positions (metres)."""
    base = options or FrontendOptions()
    overrides = {**dict(base.site_overrides), **moved}
    return run_frontend(list(paths), replace(base, site_overrides=tuple(sorted(overrides.items()))))
