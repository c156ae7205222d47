"""A small Wadler/prettier-style document printer: the formatter says what may break, this
module decides what does, so that a bracket list wraps only when its flat form does not fit.

A document is a ``Text`` (a plain ``str``: the commonest part, so no object per piece), a ``Line`` (a space or nothing when flat, a new line when broken), a
``HardLine``, a ``Group`` (printed flat if it fits, else broken), a ``Nest`` (indents the new
lines inside it), an ``IfBreak`` (text that depends on the enclosing group's mode), a
``LineSuffix`` (a trailing comment, held back until the end of the line) or a list of these.
A group that holds a ``HardLine`` or a ``BreakParent`` anywhere inside it always breaks, even
inside a ``Flat`` (printed flat whatever its width: statements an ignore comment keeps on one
line).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TypeAlias

INDENT = 4


Text = str  # `Text("x")` reads as a document part; it is the string itself


@dataclass(frozen=True, slots=True)
class Line:
    soft: bool = False  # a soft line is nothing when flat; a plain line is a space


@dataclass(frozen=True, slots=True)
class HardLine:
    pass


@dataclass(frozen=True, slots=True)
class BreakParent:
    pass


@dataclass(frozen=True, slots=True)
class Group:
    parts: Doc
    force_break: bool = False


@dataclass(frozen=True, slots=True)
class Flat:
    """Printed flat whatever its width (its groups do not break); a hard line still breaks."""

    parts: Doc


@dataclass(frozen=True, slots=True)
class Nest:
    parts: Doc


@dataclass(frozen=True, slots=True)
class IfBreak:
    broken: str
    flat: str = ""


@dataclass(frozen=True, slots=True)
class LineSuffix:
    text: str


Doc: TypeAlias = (
    Text | Line | HardLine | BreakParent | Group | Flat | Nest | IfBreak | LineSuffix | list["Doc"]
)

SOFTLINE = Line(soft=True)
LINE = Line()
HARDLINE = HardLine()

_FLAT, _BREAK = 0, 1


_EXIT = object()  # in _must_break's stack: the group opened below is done


def _must_break(doc: Doc, broken: set[int]) -> None:
    """Mark (by id) every group that holds a hard line, a BreakParent or a forced group.

    Iterative, so a deeply nested document cannot reach the recursion limit. ``path`` holds
    the groups open around the current part; a mark goes up it and stops at a group already
    marked (whose enclosing groups were marked with it), so each group is marked once.
    """
    path: list[Group] = []
    todo: list[object] = [doc]

    def mark() -> None:
        for group in reversed(path):
            if id(group) in broken:
                return
            broken.add(id(group))

    while todo:
        part = todo.pop()
        kind = type(part)
        if kind is str:
            continue
        if kind is list:
            todo.extend(part)  # type: ignore[arg-type]
        elif part is _EXIT:
            path.pop()
        elif kind is Group:
            path.append(part)  # type: ignore[arg-type]
            todo.append(_EXIT)
            if part.force_break:  # type: ignore[union-attr]
                mark()
            todo.append(part.parts)  # type: ignore[union-attr]
        elif kind is HardLine or kind is BreakParent:
            mark()
        elif kind is Nest or kind is Flat:
            todo.append(part.parts)  # type: ignore[union-attr]


_Command = tuple[int, int, Doc]  # indent, mode, document


def _fits(parts: Doc, rest: list[_Command], width: int, broken: set[int]) -> bool:
    """Whether ``parts``, flat, and what follows it up to the next line break fit in ``width``."""
    todo: list[tuple[int, Doc]] = [(_FLAT, parts)]
    next_rest = len(rest)
    while width >= 0:
        if not todo:
            if next_rest == 0:
                return True
            next_rest -= 1
            todo.append(rest[next_rest][1:])  # type: ignore[arg-type]
            continue
        mode, doc = todo.pop()
        kind = type(doc)
        if kind is str:
            cut = doc.find("\n")  # type: ignore[union-attr]
            if cut >= 0:  # a text of several lines (a block printed as one): its first line
                return width - cut >= 0
            width -= len(doc)  # type: ignore[arg-type]
        elif kind is list:
            todo.extend([(mode, part) for part in reversed(doc)])  # type: ignore[arg-type]
        elif kind is Line:
            if mode == _BREAK:
                return True
            width -= 0 if doc.soft else 1  # type: ignore[union-attr]
        elif kind is Group:
            todo.append((_BREAK if id(doc) in broken else mode, doc.parts))  # type: ignore[union-attr]
        elif kind is Nest:
            todo.append((mode, doc.parts))  # type: ignore[union-attr]
        elif kind is Flat:
            todo.append((_FLAT, doc.parts))  # type: ignore[union-attr]
        elif kind is HardLine:
            return True
        elif kind is IfBreak:
            width -= len(doc.broken if mode == _BREAK else doc.flat)  # type: ignore[union-attr]
    return False


def _flat_pieces(doc: Doc, pieces: list[str], held: list[str]) -> tuple[int, int]:
    """What ``render`` appends for ``doc`` printed flat, for a group that holds nothing that
    breaks (no hard line, BreakParent or broken group: see _must_break): its texts, spaces and
    flat IfBreaks into ``pieces``, its line suffixes into ``held``. Returns the index in
    ``pieces`` of the first non-empty text (where the pending indentation goes; -1: none) and
    the width, as _fits counts it. One walk instead of _fits's and then render's."""
    first_text = -1
    used = 0
    todo: list[object] = [doc]
    while todo:
        part = todo.pop()
        kind = type(part)
        if kind is str:
            if first_text < 0 and part:
                first_text = len(pieces)
            pieces.append(part)  # type: ignore[arg-type]
            used += len(part)  # type: ignore[arg-type]
        elif kind is list:
            todo.extend(reversed(part))  # type: ignore[call-overload]
        elif kind is Line:
            if not part.soft:  # type: ignore[union-attr]
                pieces.append(" ")
                used += 1
        elif kind is Group or kind is Nest or kind is Flat:
            todo.append(part.parts)  # type: ignore[union-attr]
        elif kind is IfBreak:
            pieces.append(part.flat)  # type: ignore[union-attr]
            used += len(part.flat)  # type: ignore[union-attr]
        elif kind is LineSuffix:
            held.append(part.text)  # type: ignore[union-attr]
    return first_text, used


def _spaces(text: str, start: int) -> int:
    """How many spaces ``text`` has from ``start`` on (the indentation of the line there)."""
    end = start
    while end < len(text) and text[end] == " ":
        end += 1
    return end - start


def render(doc: Doc, width: int) -> str:
    """Lay ``doc`` out in lines of at most ``width`` characters where the groups allow it."""
    broken: set[int] = set()
    _must_break(doc, broken)
    out: list[str] = []
    suffixes: list[str] = []
    column = line_indent = 0
    pending_indent: int | None = 0  # indentation is written with a line's first text, so
    stack: list[_Command] = [(0, _BREAK, doc)]  # blank lines carry no trailing spaces

    def flush_suffixes(indent: int) -> None:
        """The line's trailing comment; any other one gets a line of its own after it (two
        comments cannot share a line: the second would become part of the first)."""
        if len(suffixes) > 1 and out and out[-1].endswith(("{", "(", "[")):
            indent = line_indent + INDENT  # the line opened brackets: the comment is inside
        for k, text in enumerate(suffixes):
            out.append(text if k == 0 else "\n" + " " * indent + text.lstrip())
        suffixes.clear()

    def newline(indent: int) -> None:
        nonlocal column, pending_indent, line_indent
        flush_suffixes(indent)
        line_indent = indent
        out.append("\n")
        column, pending_indent = indent, indent

    while stack:
        indent, mode, doc = stack.pop()
        kind = type(doc)
        if kind is str:
            if pending_indent is not None and doc:
                out.append(" " * pending_indent)
                pending_indent = None
            if "\n" not in doc:
                out.append(doc)  # type: ignore[arg-type]
                column += len(doc)  # type: ignore[arg-type]
                continue
            # a text of several lines, with their indentation (a block printed as one text):
            # a comment held to the end of the line goes before its first new line, as at a
            # line break, and the column and indentation are those of its last line
            cut = doc.index("\n")  # type: ignore[union-attr]
            if suffixes:
                out.append(doc[:cut])  # type: ignore[index]
                flush_suffixes(_spaces(doc, cut + 1))  # type: ignore[arg-type]
                out.append(doc[cut:])  # type: ignore[index]
            else:
                out.append(doc)  # type: ignore[arg-type]
            last = doc.rindex("\n") + 1  # type: ignore[union-attr]
            column = len(doc) - last  # type: ignore[arg-type]
            line_indent = _spaces(doc, last)  # type: ignore[arg-type]
        elif kind is list:
            stack.extend([(indent, mode, part) for part in reversed(doc)])  # type: ignore[arg-type]
        elif kind is Line:
            if mode == _FLAT:
                if not doc.soft:  # type: ignore[union-attr]
                    out.append(" ")
                    column += 1
            else:
                newline(indent)
        elif kind is Group:
            if id(doc) in broken:  # a group with a hard line (or comment) breaks
                stack.append((indent, _BREAK, doc.parts))  # type: ignore[union-attr]
                continue
            # nothing inside breaks: its flat pieces are laid out once, then kept if they fit
            pieces: list[str] = []
            held: list[str] = []
            first_text, used = _flat_pieces(doc.parts, pieces, held)  # type: ignore[union-attr]
            room = width - column
            if mode == _FLAT or (used <= room and _fits([], stack, room - used, broken)):
                if pending_indent is not None and first_text >= 0:
                    out.extend(pieces[:first_text])
                    out.append(" " * pending_indent)
                    pending_indent = None
                    out.extend(pieces[first_text:])
                else:
                    out.extend(pieces)
                column += used
                suffixes.extend(held)
            else:
                stack.append((indent, _BREAK, doc.parts))  # type: ignore[union-attr]
        elif kind is Nest:
            stack.append((indent + INDENT, mode, doc.parts))  # type: ignore[union-attr]
        elif kind is Flat:
            stack.append((indent, _FLAT, doc.parts))  # type: ignore[union-attr]
        elif kind is HardLine:
            newline(indent)
        elif kind is IfBreak:
            text = doc.broken if mode == _BREAK else doc.flat  # type: ignore[union-attr]
            out.append(text)
            column += len(text)
        elif kind is LineSuffix:
            suffixes.append(doc.text)  # type: ignore[union-attr]
    flush_suffixes(0)
    return "".join(out)
