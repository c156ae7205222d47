"""Render diagnostics like rustc: header, location arrow, source line, caret under the span."""

from __future__ import annotations

import json
import os
import re
import sys
import traceback
import unicodedata
from collections.abc import Callable, Iterable, Mapping
from typing import IO

from mtlc.diagnostics.codes import Severity
from mtlc.diagnostics.diagnostic import Diagnostic, Span

JSON_FORMAT_VERSION = 1

_COLORS = {
    Severity.ERROR: "\x1b[1;31m",
    Severity.WARNING: "\x1b[1;33m",
    Severity.NOTE: "\x1b[1;36m",
}
_BLUE = "\x1b[1;34m"
_BOLD = "\x1b[1m"
_RESET = "\x1b[0m"
_LINE_BREAK = re.compile(r"\r\n|\n|\r")
# What a terminal would obey or reorder rather than show: C0 and C1 controls (ESC starts colour
# and cursor sequences, \x9b is a one-byte CSI), DEL, the bidirectional embeddings, overrides
# and isolates (U+202E turns "gnp.exe" into "exe.png"), the marks, and the line separators.
_BIDI = r"\u061c\u200e\u200f\u2028\u2029\u202a-\u202e\u2066-\u2069"
_UNSAFE_CHAR = re.compile(r"[\x00-\x1f\x7f-\x9f" + _BIDI + "]")
_UNSAFE_BUT_NEWLINE = re.compile(r"[\x00-\x09\x0b-\x1f\x7f-\x9f" + _BIDI + "]")


def terminal_safe(text: str, *, newlines: bool = False) -> str:
    """``text`` from a task file (a title, a name, a path) made safe to print: every control
    and bidi character becomes its `.mtask` escape, ``\\u{1b}``, so it is seen, not obeyed;
    with ``newlines``, a line break (mtlc's own, in help and notes) is kept."""
    pattern = _UNSAFE_BUT_NEWLINE if newlines else _UNSAFE_CHAR
    return pattern.sub(lambda m: f"\\u{{{ord(m.group()):x}}}", text)


def use_color(stream: IO[str]) -> bool:
    """Colour only on a terminal, and never when NO_COLOR is set (https://no-color.org)."""
    if os.environ.get("NO_COLOR"):
        return False
    if os.environ.get("FORCE_COLOR"):
        return True
    return hasattr(stream, "isatty") and stream.isatty()


def source_lines(text: str) -> list[str]:
    """A source's lines as the tokenizer counts them: ``str.splitlines()`` also breaks at
    \\v, \\f, \\x1c-\\x1e, \\x85, \\u2028 and \\u2029, and its line numbers would then disagree
    with the diagnostics' (line N of a span is ``source_lines(text)[N - 1]``)."""
    return _LINE_BREAK.split(text)


def _source_line(sources: Mapping[str, str], span: Span) -> str | None:
    text = sources.get(span.file)
    if text is None:
        return None
    lines = source_lines(text)
    if not 1 <= span.line <= len(lines):
        return None
    return lines[span.line - 1]


def _printable(line: str) -> tuple[str, list[int]]:
    """Expand tabs and hide control characters; map each character to its display column
    (wide East Asian characters take two), so carets stand under the right text."""
    out: list[str] = []
    cols: list[int] = []
    width = 0
    for ch in line:
        cols.append(width)
        if ch == "\t":
            pad = 4 - width % 4
            out.append(" " * pad)
            width += pad
        elif _UNSAFE_CHAR.match(ch):  # a control or bidi character: one column, shown as �
            out.append("\N{REPLACEMENT CHARACTER}")
            width += 1
        else:
            out.append(ch)
            width += 2 if unicodedata.east_asian_width(ch) in "WF" else 1
    cols.append(width)
    return "".join(out), cols


def render_text(
    diagnostics: Iterable[Diagnostic], sources: Mapping[str, str], *, color: bool = False
) -> str:
    """All diagnostics and a summary line, as one string."""
    diagnostics = list(diagnostics)
    parts = [render_one(d, sources, color=color) for d in diagnostics]
    errors = sum(d.severity is Severity.ERROR for d in diagnostics)
    warnings = sum(d.severity is Severity.WARNING for d in diagnostics)
    if errors or warnings:
        summary = []
        if errors:
            summary.append(f"{errors} error{'s' if errors != 1 else ''}")
        if warnings:
            summary.append(f"{warnings} warning{'s' if warnings != 1 else ''}")
        parts.append(", ".join(summary) + " found\n")
    return "\n".join(parts)


def render_one(d: Diagnostic, sources: Mapping[str, str], *, color: bool = False) -> str:
    sev = d.severity
    c = (lambda s, code: f"{code}{s}{_RESET}") if color else (lambda s, code: s)
    width = len(str(max([d.span.end_line] + [lb.span.line for lb in d.labels])))
    pad = " " * width
    safe = terminal_safe  # messages and paths quote task files: never let them drive the terminal
    message = safe(d.message)
    out = [c(f"{sev.value}[{d.code}]", _COLORS[sev]) + c(f": {message}", _BOLD)]
    out.append(f"{pad}{c('-->', _BLUE)} {safe(d.span.file)}:{d.span.line}:{d.span.column}")
    out.extend(_snippet(d.span, sources, width, "", c, _COLORS[sev]))
    for label in d.labels:
        where = f"{safe(label.span.file)}:{label.span.line}:{label.span.column}"
        out.append(f"{pad}{c('-->', _BLUE)} {where}")
        out.extend(_snippet(label.span, sources, width, safe(label.message), c, _BLUE, mark="-"))
    if d.help or d.notes:
        out.append(f"{pad} {c('|', _BLUE)}")
    for note in d.notes:
        out.append(f"{pad} {c('=', _BLUE)} {c('note', _BOLD)}: {safe(note, newlines=True)}")
    if d.help:
        out.append(f"{pad} {c('=', _BLUE)} {c('help', _BOLD)}: {safe(d.help, newlines=True)}")
    return "\n".join(out) + "\n"


def _snippet(
    span: Span,
    sources: Mapping[str, str],
    width: int,
    message: str,
    c: Callable[[str, str], str],
    caret_color: str,
    mark: str = "^",
) -> list[str]:
    line = _source_line(sources, span)
    if line is None:
        return []
    shown, cols = _printable(line)
    start = cols[min(span.column - 1, len(cols) - 1)]
    if span.end_line == span.line:
        end = cols[min(max(span.end_column - 1, span.column), len(cols) - 1)]
    else:
        end = cols[-1]
    carets = mark * max(1, end - start)
    bar = c("|", _BLUE)
    tail = f" {message}" if message else ""
    return [
        f"{' ' * width} {bar}",
        f"{c(str(span.line).rjust(width), _BLUE)} {bar} {shown}",
        f"{' ' * width} {bar} {' ' * start}{c(carets + tail, caret_color)}",
    ]


def render_json(diagnostics: Iterable[Diagnostic]) -> str:
    """Versioned machine-readable diagnostics (documented in docs/diagnostics.md)."""
    items = [d.as_dict() for d in diagnostics]
    doc = {
        "format": "mtlc-diagnostics",
        "version": JSON_FORMAT_VERSION,
        "diagnostics": items,
        "summary": {
            "errors": sum(1 for d in items if d["severity"] == "error"),
            "warnings": sum(1 for d in items if d["severity"] == "warning"),
        },
    }
    return json.dumps(doc, indent=2, ensure_ascii=False, sort_keys=False) + "\n"


def report_internal_error(command: str, exc: BaseException) -> None:
    """A bug as one line on stderr (MT0900), never a bare traceback; MTLC_DEBUG=1 shows it."""
    if os.environ.get("MTLC_DEBUG"):
        traceback.print_exception(exc)
    sys.stderr.write(
        f"mtlc {command}: internal error: {type(exc).__name__}: {exc} (MT0900; "
        "rerun with MTLC_DEBUG=1 for the trace and report it)\n"
    )
