"""Turn source text into lark tokens, reporting bad characters and unterminated strings.

Newlines are tokens (they end statements) except inside ( ) and [ ], where they are dropped, so
argument lists may span lines. Runs of characters that start no token become one diagnostic.
"""

from __future__ import annotations

import re
from functools import cache

from lark import Token

from mtlc.diagnostics import DiagnosticSink, Span
from mtlc.syntax.grammar import lexicon

NEWLINE = "_NL"
MAX_ERRORS_PER_FILE = 50


@cache
def _master_regex() -> re.Pattern[str]:
    lx = lexicon()
    punct = "|".join(re.escape(p) for p in sorted(lx.punctuation, key=len, reverse=True))
    starters = re.escape("".join(sorted({p[0] for p in lx.punctuation})))
    return re.compile(
        "|".join(
            [
                r"(?P<NL>\r\n|\n|\r)",
                r"(?P<WS>[ \t\f\v]+)",
                r"(?P<COMMENT>\#[^\r\n]*)",
                f"(?P<NUMBER>{lx.patterns['NUMBER']})",
                f"(?P<NAME>{lx.patterns['NAME']})",
                f"(?P<STRING>{lx.patterns['STRING']})",
                r'(?P<BADSTRING>"[^\r\n]*)',
                f"(?P<PUNCT>{punct})",
                # every other character: the class must exclude exactly what the groups above match
                rf'(?P<BAD>[^ \t\f\v\r\nA-Za-z0-9_"\#{starters}]+)',
            ]
        )
    )


def tokenize(text: str, file: str, sink: DiagnosticSink) -> list[Token]:
    lx = lexicon()
    keywords, punctuation = lx.keywords, lx.punctuation
    tokens: list[Token] = []
    line, line_start = 1, 0
    brackets: list[str] = []  # open ( and [ and {, innermost last
    still_open = {"(": 0, "[": 0, "{": 0}  # how many of each are in ``brackets`` (no search)
    errors = 0
    for m in _master_regex().finditer(text):
        kind = m.lastgroup
        start, end = m.start(), m.end()
        if kind == "WS" or kind == "COMMENT":
            continue
        col = start - line_start + 1
        if kind == "NL":
            if (not brackets or brackets[-1] == "{") and tokens and tokens[-1].type != NEWLINE:
                tokens.append(Token(NEWLINE, "\n", start, line, col, line, col + 1, end))
            line += 1
            line_start = end
            continue
        value = m.group()
        if kind == "NAME":
            ttype = keywords.get(value, "NAME")
        elif kind == "PUNCT":
            ttype = punctuation[value]
            if value in "([{":
                brackets.append(value)
                still_open[value] += 1
            elif value in ")]}" and brackets:
                # a `}` also ends any ( or [ left open inside its block
                opener = {")": "(", "]": "[", "}": "{"}[value]
                if still_open[opener]:
                    while (popped := brackets.pop()) != opener:
                        still_open[popped] -= 1
                    still_open[opener] -= 1
        elif kind in ("NUMBER", "STRING"):
            ttype = kind
        else:
            errors += 1
            if errors == MAX_ERRORS_PER_FILE + 1:
                sink.report(
                    "MT0106",
                    f"more than {MAX_ERRORS_PER_FILE} bad characters; the rest are not reported",
                    Span(file, line, col, line, col + 1, start, start + 1),
                )
            if errors <= MAX_ERRORS_PER_FILE:
                span = Span(file, line, col, line, col + len(value), start, end)
                if kind == "BADSTRING":
                    sink.report(
                        "MT0103",
                        "string is not closed before the end of the line",
                        span,
                        help='close it with `"`; a string cannot span lines (write \\n instead)',
                    )
                else:
                    shown = value if len(value) <= 20 else value[:20] + "…"
                    sink.report(
                        "MT0102",
                        f"unexpected character{'s' if len(value) > 1 else ''} {shown!r}",
                        span,
                    )
            # a bad string still stands for a value, so the statement around it parses
            if kind == "BADSTRING":
                tokens.append(Token("STRING", '""', start, line, col, line, col + len(value), end))
            continue
        tokens.append(Token(ttype, value, start, line, col, line, col + len(value), end))
    return tokens


def comments(text: str) -> list[Token]:
    """Every comment in ``text`` as a COMMENT token with its position (for `mtlc fmt`).

    ``tokenize`` drops comments, so the parser never sees them; this scans with the same
    regex, so a `#` inside a string is never taken for a comment.
    """
    found: list[Token] = []
    line, line_start = 1, 0
    for m in _master_regex().finditer(text):
        kind = m.lastgroup
        if kind == "NL":
            line += 1
            line_start = m.end()
        elif kind == "COMMENT":
            col = m.start() - line_start + 1
            found.append(
                Token(
                    "COMMENT", m.group(), m.start(), line, col, line, col + len(m.group()), m.end()
                )
            )
    return found


_ESCAPES = {"n": "\n", "t": "\t", '"': '"', "\\": "\\"}
_ESCAPE_RE = re.compile(r"\\(u\{[0-9A-Fa-f]{1,6}\}|.)")


def decode_string(token: Token, file: str, sink: DiagnosticSink) -> str:
    """The text of a string literal; unknown escapes are reported and kept literally."""
    body = token.value[1:-1]

    def replace(m: re.Match[str]) -> str:
        esc = m.group(1)
        if esc in _ESCAPES:
            return _ESCAPES[esc]
        if esc.startswith("u{"):
            code = int(esc[2:-1], 16)
            if code <= 0x10FFFF and not 0xD800 <= code <= 0xDFFF:
                return chr(code)
        col = token.column + 1 + m.start()
        start = token.start_pos + 1 + m.start()
        sink.report(
            "MT0107",
            f"unknown escape sequence `{m.group()}`",
            Span(
                file,
                token.line,
                col,
                token.line,
                col + len(m.group()),
                start,
                start + len(m.group()),
            ),
            help='known escapes: \\n \\t \\" \\\\ \\u{XXXX}',
        )
        return m.group()

    return _ESCAPE_RE.sub(replace, body) if "\\" in body else body
