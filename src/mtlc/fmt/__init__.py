"""`mtlc fmt`: canonical formatting of .mtask files that keeps every comment and never changes
what a file means (the formatted file parses to the same AST, spans aside, or it is refused)."""

from __future__ import annotations

import bisect
import json
from collections import Counter
from dataclasses import dataclass
from typing import Any

from mtlc.diagnostics import Diagnostic, DiagnosticSink, Severity, Span
from mtlc.fmt.printer import ANCHORS, format_module, nodes
from mtlc.lint import suppress
from mtlc.syntax import ast, parse_module
from mtlc.syntax.dump import to_data
from mtlc.syntax.lexer import comments

__all__ = ["FormatResult", "ast_fingerprint", "format_source"]

SUPPRESSION_MOVED = "the `# mtlc: ignore`"


@dataclass(frozen=True, slots=True)
class FormatResult:
    """The formatted text, or (when ``text`` is None) why the file was left as it was."""

    text: str | None
    diagnostics: list[Diagnostic]


def format_source(source: str, file: str) -> FormatResult:
    """Format one file's text; refuse a file with syntax errors, a suppression the style cannot
    keep covering the same statements (MT0109), and (MT0900) any output that would parse
    differently or lose a comment."""
    sink = DiagnosticSink()
    module = parse_module(source, file, sink)
    if any(d.severity == Severity.ERROR for d in sink.items):
        return FormatResult(None, sink.items)
    try:
        text, unplaced = format_module(source, module, file)
    except Exception as exc:  # a construct the printer does not know: refuse, never crash
        text, problem = source, f"{type(exc).__name__}: {exc}"
    else:
        problem = _why_unsafe(source, module, text, file) if not unplaced else "a comment was lost"
    if problem:
        return FormatResult(None, _refusal(problem, file))
    return FormatResult(text, sink.items)


def _refusal(problem: str, file: str) -> list[Diagnostic]:
    sink = DiagnosticSink()
    if problem.startswith(SUPPRESSION_MOVED):  # a layout the style cannot keep, not a bug
        sink.report(
            "MT0109",
            f"fmt cannot keep this layout: {problem}",
            Span.whole_file(file),
            help=(
                "the file is left as it was; put the comment on the first line of the statement "
                "it is for, with nothing else starting on that line, then format again"
            ),
        )
        return sink.items
    sink.report(
        "MT0900",
        f"internal error: the formatted file would differ from the original: {problem}",
        Span.whole_file(file),
        help="this is a bug in mtlc fmt; the file is left as it was; please report it",
    )
    return sink.items


def _why_unsafe(source: str, before: ast.Module, formatted: str, file: str) -> str | None:
    sink = DiagnosticSink()
    after = parse_module(formatted, file, sink)
    if sink.items:
        return f"it does not parse ({sink.items[0].code}: {sink.items[0].message})"
    if ast_fingerprint(after) != ast_fingerprint(before):
        return "its syntax tree is not the same"
    if Counter(_comment_texts(formatted)) != Counter(_comment_texts(source)):
        return "its comments are not the same"
    moved = _moved_suppression(source, before, formatted, after, file)
    if moved:
        return moved
    return None


def _moved_suppression(
    source: str, before: ast.Module, formatted: str, after: ast.Module, file: str
) -> str | None:
    """Why a `# mtlc: ignore[...]` would cover other statements than it did, if it would."""
    was = _coverage(source, before, file)
    now = Counter((code, covered) for code, covered, _ in _coverage(formatted, after, file))
    for code, covered, line in was:
        if now[code, covered] == 0:
            return f"{SUPPRESSION_MOVED} on line {line} (`{code}`) would cover other statements"
        now[code, covered] -= 1
    return None


def _coverage(text: str, module: ast.Module, file: str) -> list[tuple[str, frozenset[int], int]]:
    """Each suppression's code, the statements and declarations it covers (by their place in
    the tree, which formatting keeps; lint reports findings on their first lines), its line."""
    starts = [n.span.line for n in nodes(module) if isinstance(n, ANCHORS)]
    by_line = sorted(range(len(starts)), key=starts.__getitem__)  # found by bisection, not
    lines = [starts[i] for i in by_line]  # by a scan of every start for every suppression
    out = []
    for mark in suppress.scan(file, text):
        lo = bisect.bisect_left(lines, mark.first_line)
        hi = bisect.bisect_right(lines, mark.last_line)
        out.append((mark.code, frozenset(by_line[lo:hi]), mark.span.line))
    return out


def _comment_texts(text: str) -> list[str]:
    return [t.value.rstrip() for t in comments(text)]


def ast_fingerprint(module: ast.Module) -> str:
    """The AST dump without positions: equal for two files that say the same thing."""
    return json.dumps(_without_spans(to_data(module)), sort_keys=True, ensure_ascii=False)


def _without_spans(data: Any) -> Any:
    if isinstance(data, dict):
        return {k: _without_spans(v) for k, v in data.items() if not k.endswith("span")}
    if isinstance(data, list):
        return [_without_spans(x) for x in data]
    return data
