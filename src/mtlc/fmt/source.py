"""What the AST does not keep but the formatter must: the tokens as written (number and string
spellings, parentheses, trailing commas) and the comments, each handed out once."""

from __future__ import annotations

import bisect
from dataclasses import dataclass

from lark import Token

from mtlc.diagnostics import DiagnosticSink, Span
from mtlc.syntax.lexer import comments, tokenize

_PAIRS = {"LPAR": "RPAR", "LSQB": "RSQB", "LBRACE": "RBRACE"}

# the text being formatted and its tokens and comments: `format_source` lexes the file once and
# the printer's SourceTokens and CommentPool take them from here instead of scanning it again
_lexed: tuple[str, list[Token], list[Token]] | None = None


def lex(text: str, file: str, sink: DiagnosticSink) -> tuple[list[Token], list[Token]]:
    """The tokens (diagnostics into ``sink``) and the comments of ``text``, in one scan."""
    found: list[Token] = []
    return tokenize(text, file, sink, found), found


def remember(lexed: tuple[str, list[Token], list[Token]] | None) -> None:
    """Hand (text, tokens, comments) to the printer's SourceTokens and CommentPool (None: forget)."""
    global _lexed
    _lexed = lexed


def _known(text: str, file: str) -> tuple[list[Token], list[Token]]:
    if _lexed is not None and _lexed[0] is text:
        return _lexed[1], _lexed[2]
    return lex(text, file, DiagnosticSink())


@dataclass(frozen=True, slots=True)
class Comment:
    start: int  # offset in the source
    line: int
    text: str  # from `#`, trailing spaces removed


class SourceTokens:
    """The file's tokens, found by offset, with their matching brackets."""

    def __init__(self, text: str, file: str) -> None:
        self.tokens: list[Token] = _known(text, file)[0]
        self._by_start = {t.start_pos: i for i, t in enumerate(self.tokens)}
        self._by_end = {t.end_pos: i for i, t in enumerate(self.tokens)}
        self.match = _match_brackets(self.tokens)

    def starting_at(self, offset: int) -> int:
        return self._by_start[offset]

    def ending_at(self, offset: int) -> int:
        return self._by_end[offset]

    def line_of(self, end: int) -> int:
        """The line on which the token ending at offset ``end`` ends."""
        return int(self.tokens[self._by_end[end]].end_line)

    def kind(self, index: int) -> str:
        if 0 <= index < len(self.tokens):
            return str(self.tokens[index].type)
        return ""

    def text(self, index: int) -> str:
        return str(self.tokens[index].value)

    def at(self, index: int) -> Token:
        return self.tokens[index]

    def wrapped_in_parens(self, span: Span, structural: set[int]) -> bool:
        """Whether the code in ``span`` was written inside parentheses of its own (not a call's)."""
        first, last = self._by_start.get(span.start), self._by_end.get(span.end)
        if first is None or last is None:
            return False
        before, after = first - 1, last + 1
        return (
            self.kind(before) == "LPAR"
            and self.match.get(before) == after
            and before not in structural
        )

    def comma_before(self, closer: int) -> bool:
        """Whether the bracket list that ``closer`` ends has a trailing comma."""
        return self.kind(closer - 1) == "COMMA"


def _match_brackets(tokens: list[Token]) -> dict[int, int]:
    match: dict[int, int] = {}
    open_: list[int] = []
    for i, tok in enumerate(tokens):
        if tok.type in _PAIRS:
            open_.append(i)
        elif tok.type in _PAIRS.values() and open_ and _PAIRS[tokens[open_[-1]].type] == tok.type:
            j = open_.pop()
            match[j], match[i] = i, j
    return match


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
        hi = bisect.bisect_left(self._starts, end)
        found = []
        for i in range(lo, hi):
            if not self._taken[i]:
                self._taken[i] = True
                found.append(self._items[i])
        return found

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
