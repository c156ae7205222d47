"""`mtlc fmt`: canonical formatting of .mtask files that keeps every comment and never changes
what a file means (the formatted file parses to the same AST, spans aside, or it is refused)."""

from __future__ import annotations

import json
from collections import Counter
from dataclasses import dataclass
from typing import Any

from mtlc.diagnostics import Diagnostic, DiagnosticSink, Severity, Span
from mtlc.fmt.printer import format_module
from mtlc.syntax import ast, parse_module
from mtlc.syntax.dump import to_data
from mtlc.syntax.lexer import comments

__all__ = ["FormatResult", "ast_fingerprint", "format_source"]


@dataclass(frozen=True, slots=True)
class FormatResult:
    """The formatted text, or (when ``text`` is None) why the file was left as it was."""

    text: str | None
    diagnostics: list[Diagnostic]


def format_source(source: str, file: str) -> FormatResult:
    """Format one file's text; refuse a file with syntax errors, and refuse (MT0900) any output
    that would parse differently or lose a comment."""
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
        bug = DiagnosticSink()
        bug.report(
            "MT0900",
            f"internal error: the formatted file would differ from the original: {problem}",
            Span.whole_file(file),
            help="this is a bug in mtlc fmt; the file is left as it was; please report it",
        )
        return FormatResult(None, bug.items)
    return FormatResult(text, sink.items)


def _why_unsafe(source: str, before: ast.Module, formatted: str, file: str) -> str | None:
    sink = DiagnosticSink()
    after = parse_module(formatted, file, sink)
    if sink.items:
        return f"it does not parse ({sink.items[0].code}: {sink.items[0].message})"
    if ast_fingerprint(after) != ast_fingerprint(before):
        return "its syntax tree is not the same"
    if Counter(_comment_texts(formatted)) != Counter(_comment_texts(source)):
        return "its comments are not the same"
    return None


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
