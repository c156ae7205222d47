"""`mtlc fmt`: canonical formatting of .mtask files that keeps every comment and never changes
what a file means (the formatted file parses to the same AST, spans aside, or it is refused)."""

from __future__ import annotations

import bisect
import dataclasses
import json
from collections import Counter
from dataclasses import dataclass
from typing import Any

from lark import Token

from mtlc.diagnostics import Diagnostic, DiagnosticSink, Severity, Span
from mtlc.fmt.printer import ANCHORS, format_module, nodes
from mtlc.fmt.source import lex, remember
from mtlc.syntax import ast, parse_module, suppressions
from mtlc.syntax.dump import to_data
from mtlc.syntax.gcpause import no_collections
from mtlc.syntax.parser import ItemMemo

__all__ = ["FormatResult", "ast_fingerprint", "format_source", "same_tree"]

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
    with no_collections():
        return _format_source(source, file)


def _format_source(source: str, file: str) -> FormatResult:
    sink = DiagnosticSink()
    # one scan for the parser, the printer, the comments
    tokens, found, item_ends = lex(source, file, sink)
    memo = ItemMemo()
    module = parse_module(source, file, sink, tokens, memo, item_ends)
    if any(d.severity == Severity.ERROR for d in sink.items):
        return FormatResult(None, sink.items)
    remember((source, tokens, found))
    try:
        text, unplaced = format_module(source, module, file)
    except Exception as exc:  # a construct the printer does not know: refuse, never crash
        text, problem = source, f"{type(exc).__name__}: {exc}"
    else:
        if unplaced:
            problem = "a comment was lost"
        elif text == source and not sink.items:
            # already canonical: lexing and parsing the same text again would give the same
            # tokens, tree, comments and suppressions (the original gave no diagnostic either)
            problem = None
        else:
            problem = _why_unsafe(source, found, module, text, file, memo)
    finally:
        remember(None)
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


def _why_unsafe(
    source: str,
    found: list[Token],
    before: ast.Module,
    formatted: str,
    file: str,
    memo: ItemMemo | None = None,
) -> str | None:
    """The real check: the output is lexed and parsed again and compared with the original
    tree. With ``memo`` (what parsing the original recorded), an item of the output whose
    tokens are the very kinds and texts of an original item takes that item's node: the parser
    would build the same tree from them (only the spans would differ, and the comparison
    ignores spans; the suppression check maps the item's positions, token by token)."""
    sink = DiagnosticSink()
    tokens, found_after, item_ends = lex(formatted, file, sink)
    if memo is not None:
        memo.recording = False
    after = parse_module(formatted, file, sink, tokens, memo, item_ends)
    if sink.items:
        return f"it does not parse ({sink.items[0].code}: {sink.items[0].message})"
    if not same_tree(after, before):
        return "its syntax tree is not the same"
    if Counter(_texts(found_after)) != Counter(_texts(found)):
        return "its comments are not the same"
    moved = _moved_suppression(source, before, formatted, after, file, memo)
    if moved:
        return moved
    return None


def _moved_suppression(
    source: str,
    before: ast.Module,
    formatted: str,
    after: ast.Module,
    file: str,
    memo: ItemMemo | None = None,
) -> str | None:
    """Why a `# mtlc: ignore[...]` would cover other statements than it did, if it would."""
    anchors: dict[int, list[ast.Node]] = {}
    was = _coverage(source, before, file, _anchor_lines(before, anchors=anchors))
    if not was:
        return None
    lines = _anchor_lines(after, memo, anchors)
    if lines is None:  # a reused node's part not found among its tokens: look at the real spans
        after = parse_module(formatted, file, DiagnosticSink())
        lines = _anchor_lines(after)
    assert lines is not None
    now = Counter((code, covered) for code, covered, _ in _coverage(formatted, after, file, lines))
    for code, covered, line in was:
        if now[code, covered] == 0:
            return f"{SUPPRESSION_MOVED} on line {line} (`{code}`) would cover other statements"
        now[code, covered] -= 1
    return None


def _anchor_lines(
    module: ast.Module,
    memo: ItemMemo | None = None,
    anchors: dict[int, list[ast.Node]] | None = None,
) -> list[int] | None:
    """The first line of each statement and declaration (ANCHORS), in tree order (that of
    ``nodes``: the uses, then the declarations). A top-level item that ``memo`` reused keeps
    the spans of the original text: the line of each of its parts is that of the token in the
    new text at the same place in the item (None if a part starts at no token). ``anchors``
    keeps each item's ANCHORS by ``id``, so an item reused from the original is walked once."""
    reused = memo.reused if memo is not None else {}
    if anchors is None:
        anchors = {}
    out: list[int] = []
    for top in (*module.uses, *module.decls):
        parts = anchors.get(id(top))
        if parts is None:
            parts = anchors[id(top)] = [n for n in nodes(top) if isinstance(n, ANCHORS)]
        hit = reused.get(id(top))
        if hit is None:
            out.extend([n.span.line for n in parts])
            continue
        _, old, new = hit
        starts = [t.start_pos for t in old]  # in order: an item's tokens are in source order
        for n in parts:
            i = bisect.bisect_left(starts, n.span.start)
            if i == len(starts) or starts[i] != n.span.start:
                return None
            out.append(int(new[i].line))
    return out


def _coverage(
    text: str, module: ast.Module, file: str, starts: list[int] | None = None
) -> list[tuple[str, frozenset[int], int]]:
    """Each suppression's code, the statements and declarations it covers (by their place in
    the tree, which formatting keeps; lint reports findings on their first lines), its line.
    ``starts``: the ANCHORS' first lines in tree order, when known (``_anchor_lines``)."""
    if starts is None:
        starts = _anchor_lines(module)
        assert starts is not None
    by_line = sorted(range(len(starts)), key=starts.__getitem__)  # found by bisection, not
    lines = [starts[i] for i in by_line]  # by a scan of every start for every suppression
    out = []
    for mark in suppressions.scan(file, text):
        lo = bisect.bisect_left(lines, mark.first_line)
        hi = bisect.bisect_right(lines, mark.last_line)
        out.append((mark.code, frozenset(by_line[lo:hi]), mark.span.line))
    return out


def _texts(found: list[Token]) -> list[str]:
    return [t.value.rstrip() for t in found]


def ast_fingerprint(module: ast.Module) -> str:
    """The AST dump without positions: equal for two files that say the same thing."""
    return json.dumps(_without_spans(to_data(module)), sort_keys=True, ensure_ascii=False)


_COMPARED: dict[type, tuple[str, ...]] = {}  # per node class: the fields the dump keeps


def _compared(cls: type) -> tuple[str, ...]:
    names = _COMPARED.get(cls)
    if names is None:
        names = _COMPARED[cls] = tuple(
            f.name
            for f in dataclasses.fields(cls)
            if f.name not in ("path", "depth") and not f.name.endswith("span")
        )
    return names


def _skipped(value: Any) -> bool:
    """A field value the dump leaves out (as ``to_data`` does)."""
    return value is None or value == () or value == frozenset()


def same_tree(a: Any, b: Any) -> bool:
    """``ast_fingerprint(a) == ast_fingerprint(b)``, by a direct walk that stops at the first
    difference (no JSON: the fingerprints cost as much as a parse on a large file).

    Leaves compare as their JSON would: same type, and floats by ``repr`` (-0.0 is not 0.0,
    NaN is NaN). Iterative, so a deep tree cannot reach the recursion limit.
    """
    stack = [(a, b)]
    while stack:
        x, y = stack.pop()
        if x is y and isinstance(x, ast.Node):  # an item the re-parse reused (ItemMemo)
            continue
        if isinstance(x, ast.Node):
            if type(x) is not type(y):
                return False
            for name in _compared(type(x)):
                vx, vy = getattr(x, name), getattr(y, name)
                if _skipped(vx) or _skipped(vy):
                    if not (_skipped(vx) and _skipped(vy)):
                        return False
                else:
                    stack.append((vx, vy))
        elif isinstance(x, tuple | list) and not isinstance(x, Span):
            if not isinstance(y, tuple | list) or isinstance(y, Span) or len(x) != len(y):
                return False
            stack.extend(zip(x, y, strict=True))
        elif isinstance(x, frozenset):
            if not isinstance(y, frozenset) or sorted(x) != sorted(y):
                return False
        elif not _same_leaf(x, y):
            return False
    return True


def _same_leaf(x: Any, y: Any) -> bool:
    """Whether two leaves would print the same JSON (a str subclass such as a lark Token is
    compared as the str it is)."""
    if isinstance(x, str):
        return isinstance(y, str) and str.__eq__(x, y)
    if isinstance(x, bool) or isinstance(y, bool):
        return type(x) is type(y) and x == y
    if isinstance(x, float):
        return isinstance(y, float) and float.__repr__(x) == float.__repr__(y)
    if isinstance(x, int):
        return isinstance(y, int) and not isinstance(y, float) and int(x) == int(y)
    return type(x) is type(y) and x == y


def _without_spans(data: Any) -> Any:
    if isinstance(data, dict):
        return {k: _without_spans(v) for k, v in data.items() if not k.endswith("span")}
    if isinstance(data, list):
        return [_without_spans(x) for x in data]
    return data
