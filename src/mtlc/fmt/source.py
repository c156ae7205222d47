"""What the AST does not keep but the formatter must: the tokens as written (number and string
spellings, parentheses, trailing commas) and the comments, each handed out once."""

from __future__ import annotations

import bisect
from dataclasses import dataclass

from lark import Token

from mtlc.diagnostics import DiagnosticSink
from mtlc.syntax.lexer import comments, tokenize

_PAIRS = {"LPAR": "RPAR", "LSQB": "RSQB", "LBRACE": "RBRACE"}
_OPENERS = {"RPAR": "LPAR", "RSQB": "LSQB"}

# the text being formatted and its tokens and comments: `format_source` lexes the file once and
# the printer's SourceTokens and CommentPool take them from here instead of scanning it again
_lexed: tuple[str, list[Token], list[Token]] | None = None


def lex(text: str, file: str, sink: DiagnosticSink) -> tuple[list[Token], list[Token], list[int]]:
    """The tokens (diagnostics into ``sink``), the comments of ``text`` and where its items
    end (``tokenize``'s ``item_ends_out``, for ``parse_module``), in one scan."""
    found: list[Token] = []
    item_ends: list[int] = []
    return tokenize(text, file, sink, found, item_ends), found, item_ends


def remember(lexed: tuple[str, list[Token], list[Token]] | None) -> None:
    """Hand (text, tokens, comments) to the printer's SourceTokens and CommentPool (None: forget)."""
    global _lexed
    _lexed = lexed


def _known(text: str, file: str) -> tuple[list[Token], list[Token]]:
    if _lexed is not None and _lexed[0] is text:
        return _lexed[1], _lexed[2]
    return lex(text, file, DiagnosticSink())[:2]


@dataclass(frozen=True, slots=True)
class Comment:
    start: int  # offset in the source
    line: int
    text: str  # from `#`, trailing spaces removed


class SourceTokens:
    """The file's tokens, found by offset, with their matching brackets."""

    def __init__(self, text: str, file: str) -> None:
        self.tokens: list[Token] = _known(text, file)[0]
        self.types: list[str] = [t.type for t in self.tokens]
        # a token by the offset where it starts: found by bisection (the printer looks up a few
        # tens of thousands in a large file; a list as long as the text, -1 where no token
        # starts, cost more to fill than they cost)
        self._starts = [t.start_pos for t in self.tokens]
        self.match = _Partners(self.types)

    def starting_at(self, offset: int) -> int:
        """The index of the token that starts at ``offset`` (KeyError: none does)."""
        i = self.index_at(offset)
        if i < 0:
            raise KeyError(offset)
        return i

    def index_at(self, offset: int) -> int:
        """The index of the token that starts at ``offset``, or -1."""
        starts = self._starts
        i = bisect.bisect_left(starts, offset)
        return i if i < len(starts) and starts[i] == offset else -1

    def ending_at(self, offset: int) -> int:
        """The index of the token that ends at ``offset`` (KeyError: none does)."""
        i = bisect.bisect_left(self._starts, offset) - 1  # the last token starting before
        if i < 0 or self.tokens[i].end_pos != offset:
            raise KeyError(offset)
        return i

    def line_of(self, end: int) -> int:
        """The line on which the token ending at offset ``end`` ends."""
        return int(self.tokens[self.ending_at(end)].end_line)

    def kind(self, index: int) -> str:
        if 0 <= index < len(self.types):
            return self.types[index]
        return ""

    def text(self, index: int) -> str:
        return str(self.tokens[index].value)

    def at(self, index: int) -> Token:
        return self.tokens[index]

    def text_at(self, offset: int) -> str:
        """The text of the token that starts at ``offset``."""
        return str(self.tokens[self.starting_at(offset)].value)

    def comma_before(self, closer: int) -> bool:
        """Whether the bracket list that ``closer`` ends has a trailing comma."""
        return self.kind(closer - 1) == "COMMA"


class _Partners(dict[int, int]):
    """The index of the bracket that matches the ``(`` ``)`` ``[`` or ``]`` at an index, found
    when first asked for (the printer asks for a few of them: the calls, lists and vectors it
    builds, and the parentheses before an expression), by a scan to it that counts that kind
    of bracket only. Right for the text of a parse without errors, where the grammar nested
    every bracket in its pair (pairing them all up front, by a walk with a stack over every
    bracket of the file, cost more than the look-ups)."""

    def __init__(self, types: list[str]) -> None:
        super().__init__()
        self.types = types

    def __missing__(self, index: int) -> int:
        types = self.types
        if not 0 <= index < len(types):
            raise KeyError(index)
        kind = types[index]
        closer = _PAIRS.get(kind)
        if closer is not None:  # scan forward to the closer at depth 0
            depth, step, other = 0, 1, closer
        else:
            opener = _OPENERS[kind]  # KeyError: not a bracket that pairs
            depth, step, other = 0, -1, opener
        i = index + step
        while 0 <= i < len(types):
            found = types[i]
            if found == kind:
                depth += 1
            elif found == other:
                if depth == 0:
                    self[index] = i
                    self[i] = index
                    return i
                depth -= 1
            i += step
        raise KeyError(index)

    def get(self, index: int, default: int | None = None) -> int | None:  # type: ignore[override]
        try:
            return self[index]
        except (KeyError, IndexError):
            return default


class CommentPool:
    """The file's comments in order; each is taken by exactly one place in the output."""

    def __init__(self, text: str) -> None:
        found = _lexed[2] if _lexed is not None and _lexed[0] is text else comments(text)
        self._items = [Comment(t.start_pos, t.line, t.value.rstrip()) for t in found]
        self._starts = [c.start for c in self._items]
        self._taken = [False] * len(self._items)

    def take(self, start: int, end: int) -> list[Comment]:
        """The comments not yet taken that start in [start, end), in source order."""
        lo = bisect.bisect_left(self._starts, start)
        if lo == len(self._starts) or self._starts[lo] >= end:
            return []  # the usual answer, without a second bisection
        hi = bisect.bisect_left(self._starts, end, lo)
        found = []
        for i in range(lo, hi):
            if not self._taken[i]:
                self._taken[i] = True
                found.append(self._items[i])
        return found

    def any_in(self, start: int, end: int) -> bool:
        """Whether a comment (taken or not) starts in [start, end)."""
        i = bisect.bisect_left(self._starts, start)
        return i < len(self._starts) and self._starts[i] < end

    def quiet(self, start: int, end: int, end_line: int) -> bool:
        """Whether no comment (taken or not) starts in [start, end) or after it on ``end_line``."""
        i = bisect.bisect_left(self._starts, start)
        return i == len(self._items) or (
            self._items[i].start >= end and self._items[i].line > end_line
        )

    def next_after(self, offset: int) -> Comment | None:
        """The first comment at or after ``offset``, if it is not taken yet."""
        i = bisect.bisect_left(self._starts, offset)
        if i < len(self._items) and not self._taken[i]:
            return self._items[i]
        return None

    def claim(self, comment: Comment) -> None:
        self._taken[bisect.bisect_left(self._starts, comment.start)] = True

    def all(self) -> list[Comment]:
        return list(self._items)

    def left(self) -> list[Comment]:
        return [c for c, taken in zip(self._items, self._taken, strict=True) if not taken]

    def all_texts(self) -> list[str]:
        return [c.text for c in self._items]
