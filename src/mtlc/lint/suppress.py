"""`# mtlc: ignore[MT0501, MT0605]`: applying suppressions to lint's findings.

Where they are and what they cover is found by ``mtlc.syntax.suppressions`` (``scan``, re-exported
here), which `mtlc fmt` uses too without loading the lint engine.
"""

from __future__ import annotations

from collections.abc import Callable

from mtlc.diagnostics import CODES, RETIRED
from mtlc.lint.findings import Finding
from mtlc.syntax.suppressions import Suppression, resolve, scan

__all__ = ["Suppression", "apply", "scan"]


def apply(
    findings: list[Finding],
    suppressions: list[Suppression],
    *,
    report_unused: bool,
    checked: Callable[[str], bool] = lambda code: True,
) -> list[Finding]:
    """Drop suppressed findings; an unknown or unused suppression is itself a finding, unless
    its code was not checked in this run (``checked``), so it could not have been used."""
    kept = []
    for f in findings:
        hits = [s for s in suppressions if s.covers(f)]
        for s in hits:
            s.used = True
        if not hits:
            kept.append(f)
    if report_unused:
        # an unknown code is always reported; a known one only if its check ran; a retired
        # code's never runs (an old ignore comment for it is not a new warning)
        live = tuple(c for c in CODES if c not in RETIRED and checked(c))
        relevant = [s for s in suppressions if resolve(s.code) in (None, *live)]
        kept.extend(_unused(relevant))
    return kept


def _unused(suppressions: list[Suppression]) -> list[Finding]:
    out = []
    for s in suppressions:
        if resolve(s.code) is None:
            out.append(
                Finding(
                    "MT0606",
                    f"`{s.code}` is not a diagnostic code or rule name",
                    s.span,
                    help="write a code such as MT0501 or a rule name such as unreachable-site",
                )
            )
        elif not s.used:
            out.append(
                Finding(
                    "MT0606",
                    f"nothing here is reported as {resolve(s.code)}; the suppression hides nothing",
                    s.span,
                    help="remove it, or move it to the line or block the finding is on",
                )
            )
    return out
