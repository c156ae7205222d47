"""The diagnostic record and the sink that passes collect them into."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, NamedTuple

from mtlc.diagnostics.codes import CODES, Severity


class Span(NamedTuple):
    """A region of a source file: 1-based lines and columns, end exclusive; offsets into the text.

    A NamedTuple rather than a frozen dataclass: the parser makes one per token and node, and a
    tuple is several times cheaper to build, while staying immutable, hashable and ordered.
    """

    file: str
    line: int
    column: int
    end_line: int
    end_column: int
    start: int = 0
    end: int = 0

    @staticmethod
    def whole_file(file: str) -> Span:
        return Span(file, 1, 1, 1, 1, 0, 0)

    def to(self, other: Span) -> Span:
        """The span from the start of this one to the end of ``other``."""
        return Span(
            self.file,
            self.line,
            self.column,
            other.end_line,
            other.end_column,
            self.start,
            other.end,
        )

    def as_dict(self) -> dict[str, Any]:
        return {
            "file": self.file,
            "line": self.line,
            "column": self.column,
            "end_line": self.end_line,
            "end_column": self.end_column,
        }


@dataclass(frozen=True, slots=True)
class Label:
    """A secondary span with a short message (``note: first defined here``)."""

    span: Span
    message: str


@dataclass(frozen=True, slots=True)
class Diagnostic:
    code: str
    message: str
    span: Span
    help: str | None = None
    labels: tuple[Label, ...] = ()
    notes: tuple[str, ...] = ()

    @property
    def severity(self) -> Severity:
        return CODES[self.code].severity

    def sort_key(self) -> tuple[str, int, int, str, str]:
        return (self.span.file, self.span.line, self.span.column, self.code, self.message)

    def as_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "code": self.code,
            "name": CODES[self.code].name,
            "severity": self.severity.value,
            "message": self.message,
            "span": self.span.as_dict(),
        }
        if self.help:
            out["help"] = self.help
        if self.labels:
            out["labels"] = [
                {"message": lb.message, "span": lb.span.as_dict()} for lb in self.labels
            ]
        if self.notes:
            out["notes"] = list(self.notes)
        return out


@dataclass
class DiagnosticSink:
    """Collects diagnostics; passes report into it and keep going."""

    items: list[Diagnostic] = field(default_factory=list)

    def report(
        self,
        code: str,
        message: str,
        span: Span,
        *,
        help: str | None = None,
        labels: tuple[Label, ...] = (),
        notes: tuple[str, ...] = (),
    ) -> None:
        if code not in CODES:  # a programming error, caught by the tests
            raise KeyError(f"undeclared diagnostic code {code}")
        self.items.append(Diagnostic(code, message, span, help, labels, notes))

    @property
    def has_errors(self) -> bool:
        return any(d.severity is Severity.ERROR for d in self.items)

    def sorted(self) -> list[Diagnostic]:
        """Diagnostics in source order, duplicates removed (deterministic output)."""
        seen: set[tuple[str, str, Span]] = set()
        out = []
        for d in sorted(self.items, key=Diagnostic.sort_key):
            key = (d.code, d.message, d.span)
            if key not in seen:
                seen.add(key)
                out.append(d)
        return out
