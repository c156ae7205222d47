"""Lint findings: diagnostics that know which manikins they apply to.

The same problem found for several manikins (the same code and place, the same message up to
its numbers and up to its last ': ', after which come the manikin's own details) is one finding
naming every manikin, with each manikin's own message kept.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field, replace

from mtlc.diagnostics import CODES, Diagnostic, Label, Severity, Span

_NUMBER = re.compile(r"\d+(?:\.\d+)?")


@dataclass(frozen=True)
class Finding:
    code: str
    message: str
    span: Span
    help: str | None = None
    labels: tuple[Label, ...] = ()
    notes: tuple[str, ...] = ()
    # manikin labels (POP:SEX:PCT) and each one's own message; empty when no manikin matters
    manikins: tuple[str, ...] = ()
    details: tuple[str, ...] = field(default=(), compare=False)

    @property
    def severity(self) -> Severity:
        return CODES[self.code].severity

    @property
    def name(self) -> str:
        return CODES[self.code].name

    def merge_key(self) -> tuple[str, Span, str]:
        """What is said before the message's last ': ', numbers masked: the part after it is
        each manikin's own detail ('253 mm short' and '40 mm short' are one finding)."""
        head = self.message.rsplit(": ", 1)[0]
        return (self.code, self.span, _NUMBER.sub("#", head))

    def sort_key(self) -> tuple[str, int, int, str, str]:
        return (self.span.file, self.span.line, self.span.column, self.code, self.message)

    def as_diagnostic(self) -> Diagnostic:
        """For the text renderer: the manikins become a note."""
        notes = self.notes
        if self.manikins:
            notes = (*notes, "for " + "; ".join(self.manikin_lines()))
        return Diagnostic(self.code, self.message, self.span, self.help, self.labels, notes)

    def manikin_lines(self) -> list[str]:
        lines = []
        for label, detail in zip(self.manikins, self.details, strict=True):
            lines.append(label if detail == self.message else f"{label} ({_tail(detail)})")
        return lines


def _tail(message: str) -> str:
    """The part of a per-manikin message after its last ': ' (its numbers), or all of it."""
    return message.rsplit(": ", 1)[-1] if ": " in message else message


def from_diagnostic(d: Diagnostic, manikin: str | None = None) -> Finding:
    manikins = (manikin,) if manikin else ()
    details = (d.message,) if manikin else ()
    return Finding(d.code, d.message, d.span, d.help, d.labels, d.notes, manikins, details)


def merge(findings: list[Finding], order: list[str]) -> list[Finding]:
    """One finding per merge key, naming its manikins in ``order``; sorted by place."""
    rank = {m: i for i, m in enumerate(order)}
    groups: dict[tuple[str, Span, str], list[Finding]] = {}
    for f in findings:
        groups.setdefault(f.merge_key(), []).append(f)
    out = []
    for group in groups.values():
        # each (manikin, detail) once, in the order reported: a set's order is the string
        # hashes', which change from one process to the next (PYTHONHASHSEED), and so did the
        # note of a finding with two details for one manikin
        pairs = sorted(
            dict.fromkeys(p for f in group for p in zip(f.manikins, f.details, strict=True)),
            key=lambda p: (rank.get(p[0], len(rank)), p[0]),
        )
        first = min(group, key=lambda f: rank.get(f.manikins[0], 0) if f.manikins else -1)
        out.append(
            replace(
                first,
                manikins=tuple(m for m, _ in pairs),
                details=tuple(d for _, d in pairs),
            )
        )
    return sorted(out, key=Finding.sort_key)
