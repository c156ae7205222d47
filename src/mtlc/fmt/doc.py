"""A small Wadler/prettier-style document printer: the formatter says what may break, this
module decides what does, so that a bracket list wraps only when its flat form does not fit.

A document is a ``Text``, a ``Line`` (a space or nothing when flat, a new line when broken), a
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


@dataclass(frozen=True, slots=True)
class Text:
    text: str


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


def _must_break(doc: Doc, broken: set[int]) -> bool:
    """Mark every group that holds a hard line; return whether ``doc`` holds one."""
    if isinstance(doc, list):
        found = False
        for part in doc:
            found = _must_break(part, broken) or found
        return found
    if isinstance(doc, HardLine | BreakParent):
        return True
    if isinstance(doc, Group):
        inner = _must_break(doc.parts, broken)
        if inner or doc.force_break:
            broken.add(id(doc))
        return inner or doc.force_break
    if isinstance(doc, Nest | Flat):
        return _must_break(doc.parts, broken)
    return False


_Command = tuple[int, int, Doc]  # indent, mode, document


def _fits(first: _Command, rest: list[_Command], width: int, broken: set[int]) -> bool:
    """Whether ``first``, flat, and what follows it up to the next line break fit in ``width``."""
    todo = [first]
    next_rest = len(rest)
    while width >= 0:
        if not todo:
            if next_rest == 0:
                return True
            next_rest -= 1
            todo.append(rest[next_rest])
            continue
        indent, mode, doc = todo.pop()
        if isinstance(doc, list):
            todo.extend((indent, mode, part) for part in reversed(doc))
        elif isinstance(doc, Text):
            width -= len(doc.text)
        elif isinstance(doc, Nest):
            todo.append((indent, mode, doc.parts))
        elif isinstance(doc, Flat):
            todo.append((indent, _FLAT, doc.parts))
        elif isinstance(doc, Group):
            todo.append((indent, _BREAK if id(doc) in broken else mode, doc.parts))
        elif isinstance(doc, Line):
            if mode == _BREAK:
                return True
            width -= 0 if doc.soft else 1
        elif isinstance(doc, HardLine):
            return True
        elif isinstance(doc, IfBreak):
            width -= len(doc.broken if mode == _BREAK else doc.flat)
    return False


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
        if isinstance(doc, list):
            stack.extend((indent, mode, part) for part in reversed(doc))
        elif isinstance(doc, Text):
            if pending_indent is not None and doc.text:
                out.append(" " * pending_indent)
                pending_indent = None
            out.append(doc.text)
            column += len(doc.text)
        elif isinstance(doc, Nest):
            stack.append((indent + INDENT, mode, doc.parts))
        elif isinstance(doc, Flat):
            stack.append((indent, _FLAT, doc.parts))
        elif isinstance(doc, Group):
            flat = id(doc) not in broken and (  # a group with a hard line (or comment) breaks
                mode == _FLAT or _fits((indent, _FLAT, doc.parts), stack, width - column, broken)
            )
            if flat:
                stack.append((indent, _FLAT, doc.parts))
            else:
                stack.append((indent, _BREAK, doc.parts))
        elif isinstance(doc, Line):
            if mode == _FLAT:
                if not doc.soft:
                    out.append(" ")
                    column += 1
            else:
                newline(indent)
        elif isinstance(doc, HardLine):
            newline(indent)
        elif isinstance(doc, IfBreak):
            text = doc.broken if mode == _BREAK else doc.flat
            out.append(text)
            column += len(text)
        elif isinstance(doc, LineSuffix):
            suffixes.append(doc.text)
    flush_suffixes(0)
    return "".join(out)
