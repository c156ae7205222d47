"""`# mtlc: ignore[MT0501, MT0605]`: where suppressions are and what lines they cover.

A comment on a line that opens a block (`task t {`, `for b in [...] {`) covers the whole block
up to its closing `}`; anywhere else it covers its own line. Comments are read from the source
text directly (a `#` outside a string starts one, as the tokenizer has it), so suppressions work
in files that do not parse too. Here, below the commands, because `mtlc lint` applies them and
`mtlc fmt` keeps them covering the same statements (and must not load the lint engine for that).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Protocol

from mtlc.diagnostics import CODES, Span


class _Finding(Protocol):
    """What a suppression is matched with (a lint finding)."""

    @property
    def code(self) -> str: ...

    @property
    def span(self) -> Span: ...


_IGNORE = re.compile(r"mtlc:\s*ignore\[([^\]]*)\]")
_LINE_BREAK = re.compile(r"\r\n|\n|\r")


@dataclass
class Suppression:
    code: str  # a code, or the name of one, as written
    span: Span  # the code inside the brackets
    first_line: int
    last_line: int
    used: bool = field(default=False)

    def covers(self, f: _Finding) -> bool:
        return (
            f.span.file == self.span.file
            and self.first_line <= f.span.line <= self.last_line
            and resolve(self.code) == f.code
        )


def resolve(word: str) -> str | None:
    """The code a suppression names (a code or a rule's name, as written), or None."""
    word = word.strip()
    if word.upper() in CODES:
        return word.upper()
    return next((c.code for c in CODES.values() if c.name == word), None)


def _comment_start(line: str) -> int | None:
    """Index of the `#` that starts this line's comment, skipping strings."""
    if '"' not in line:  # no string to skip: the first `#` (found at C speed)
        cut = line.find("#")
        return cut if cut >= 0 else None
    in_string = escaped = False
    for i, ch in enumerate(line):
        if in_string:
            if escaped:
                escaped = False
            elif ch == "\\":
                escaped = True
            elif ch == '"':
                in_string = False
        elif ch == '"':
            in_string = True
        elif ch == "#":
            return i
    return None


def _block_end(lines: list[str], start_line: int) -> int:
    """The line of the `}` closing the block opened at the end of ``start_line`` (0-based)."""
    depth = 0
    for n in range(start_line, len(lines)):
        line = lines[n]
        cut = _comment_start(line)
        code = _strip_strings(line if cut is None else line[:cut])
        for ch in code:
            if ch == "{":
                depth += 1
            elif ch == "}":
                depth -= 1
                if depth == 0:
                    return n
    return len(lines) - 1  # unclosed: to the end of the file


def _strip_strings(code: str) -> str:
    return re.sub(r'"([^"\\]|\\.)*"?', "", code)


def scan(file: str, text: str) -> list[Suppression]:
    if "mtlc:" not in text:  # no suppression anywhere (most files: no split into lines)
        return []
    # with no `\r`, the line breaks are the `\n`s alone: str.split, a fifth of the regex's time
    lines = text.split("\n") if "\r" not in text else _LINE_BREAK.split(text)
    out: list[Suppression] = []
    for n, line in enumerate(lines):
        if "mtlc:" not in line:  # no suppression can be on it (most lines: no loop below)
            continue
        cut = _comment_start(line)
        if cut is None:
            continue
        opens_block = _strip_strings(line[:cut]).rstrip().endswith("{")
        last = _block_end(lines, n) if opens_block else n
        for m in _IGNORE.finditer(line, cut):
            inner = m.start(1)
            for word in re.finditer(r"[^,\s]+", m.group(1)):
                col = inner + word.start() + 1
                span = Span(file, n + 1, col, n + 1, col + len(word.group()))
                out.append(Suppression(word.group(), span, n + 1, last + 1))
    return out
