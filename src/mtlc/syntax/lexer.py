"""Turn source text into lark tokens, reporting bad characters, bad names and open strings.

Newlines are tokens (they end statements) except inside ( ) and [ ], where they are dropped, so
argument lists may span lines. Runs of characters that start no token become one diagnostic.
Names are Unicode identifiers (XID_Start or `_`, then XID_Continue: str.isidentifier), read in
their NFC form, so two spellings of one name are one name; a word that is not a valid name is
one diagnostic (MT0108) and still a name to the parser. Full-width punctuation (`，` `（`) is
one diagnostic and read as its ASCII form.
"""

from __future__ import annotations

import re
import unicodedata
from collections.abc import Iterator
from functools import cache

from lark import Token

from mtlc.diagnostics import DiagnosticSink, Span
from mtlc.syntax.grammar import lexicon

NEWLINE = "_NL"
MAX_NESTING = 64  # blocks and brackets inside each other (deeper: MT0104, from the parser)
MAX_ERRORS_PER_FILE = 50
_WORD = re.compile(r"\w*")
# Token(...) without its check for a deprecated keyword argument: one per lexeme
_new_token = Token._future_new
_new_str = str.__new__


@cache
def _master_regex() -> re.Pattern[str]:
    lx = lexicon()
    punct = "|".join(re.escape(p) for p in sorted(lx.punctuation, key=len, reverse=True))
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
                # every other character, one at a time: _scan joins runs of them
                r"(?P<BAD>[\s\S])",
            ]
        )
    )


@cache
def _folded_regex() -> re.Pattern[str]:
    """_master_regex with the spaces before a lexeme folded into its match: half as many
    matches on indented code. ``WS`` is left only for spaces that end the text.

    The commonest lexemes are tried first (names, numbers, punctuation: a fifth less time in
    the regex). The order decides nothing else: the alternatives start with different
    characters (a word character, a digit or `.`, punctuation, a line break, `#`, `"`),
    except ``NUMBER`` and the `.` of ``PUNCT`` (a number first, as in _master_regex),
    ``STRING`` and ``BADSTRING``, ``WS`` and ``BAD``, each kept in _master_regex's order."""
    lx = lexicon()
    punct = "|".join(re.escape(p) for p in sorted(lx.punctuation, key=len, reverse=True))
    return re.compile(
        r"[ \t\f\v]*(?:"
        + "|".join(
            [
                f"(?P<NAME>{lx.patterns['NAME']})",
                f"(?P<NUMBER>{lx.patterns['NUMBER']})",
                f"(?P<PUNCT>{punct})",
                r"(?P<NL>\r\n|\n|\r)",
                r"(?P<COMMENT>\#[^\r\n]*)",
                f"(?P<STRING>{lx.patterns['STRING']})",
                r'(?P<BADSTRING>"[^\r\n]*)',
                r"(?P<WS>[ \t\f\v]+)",
                r"(?P<BAD>[\s\S])",
            ]
        )
        + ")"
    )


@cache
def _wide_forms() -> dict[str, str]:
    """Full-width and other look-alike punctuation -> the ASCII token or space it stands for.

    Chinese input methods type `，` `（` `：` and the ideographic space; NFKC maps them to
    `,` `(` `:` and ` `. Each is reported once and then read as what it looks like, so one
    slip gives one diagnostic instead of a cascade of parse errors.
    """
    wanted = set(lexicon().punctuation) | {" "}
    forms = {}
    for code in (*range(0xA0, 0x100), *range(0x2000, 0x2070), *range(0x3000, 0x3020),
                 *range(0xFE50, 0xFE70), *range(0xFF00, 0xFF61)):  # fmt: skip
        ch = chr(code)
        folded = unicodedata.normalize("NFKC", ch)
        if folded in wanted:
            forms[ch] = folded
        elif folded.strip() == "" and ch.isspace() and ch not in "\x85\u2028\u2029":
            forms[ch] = " "
    return forms


def _continues_name(ch: str) -> bool:
    """Can ``ch`` (not ASCII) belong to a word? Letters, digits, marks and XID_Continue.

    The regex's ``\\w`` misses combining marks (a decomposed `é`, Devanagari vowel signs) and
    the few XID_Continue punctuation marks (U+00B7); they are taken here, and whether the
    word is a valid name is decided on its NFC form by str.isidentifier.
    """
    return ch.isalnum() or ("a" + ch).isidentifier() or unicodedata.category(ch)[0] == "M"


_SMART_OPEN = "\u201c\u201e\u201f"  # “ „ ‟
_OPENER = {")": "(", "]": "[", "}": "{"}


def _opened(brackets: list[str], still_open: dict[str, int], opener: str) -> bool:
    """``opener`` pushed on the open brackets; whether they nest at most ``MAX_NESTING``."""
    brackets.append(opener)
    still_open[opener] += 1
    return len(brackets) <= MAX_NESTING


def _closed(brackets: list[str], still_open: dict[str, int], opener: str) -> bool:
    """The innermost open ``opener`` closed, with whatever is open inside it (a `}` also ends
    a `(` left open in its block); whether it was the innermost bracket (plainly nested)."""
    if brackets and brackets[-1] == opener:
        brackets.pop()
        still_open[opener] -= 1
        return True
    if still_open[opener]:
        while (popped := brackets.pop()) != opener:
            still_open[popped] -= 1
        still_open[opener] -= 1
    return False


def _smart_close(text: str, pos: int) -> int:
    """The end of a string in typographic quotes (“...”) opened at ``pos``, or -1."""
    close = text.find("\u201d", pos + 1, pos + 200)  # C speed: a line of “ stays linear
    if close < 0:
        return -1
    body = text[pos + 1 : close]
    return -1 if "\n" in body or "\r" in body or '"' in body else close + 1


def _scan(text: str) -> Iterator[tuple[str, int, int]]:
    """(kind, start, end) for every lexeme of ``text``, covering it without gaps.

    Kinds are the regex's groups plus WIDE (a look-alike of an ASCII token, see _wide_forms).
    A NAME is a whole word, even when it is not a valid name, and a BAD a run of characters
    that start no token: each is one lexeme, so it gets one diagnostic.
    """
    rx = _master_regex()
    wide = _wide_forms()
    matches = rx.finditer(text)
    while (m := next(matches, None)) is not None:
        kind, (pos, end) = m.lastgroup or "BAD", m.span()
        if kind == "NAME" or kind == "BAD":
            kind, end = _widen(text, kind, pos, end, wide)
            if end != m.end():
                matches = rx.finditer(text, end)  # go on after the longer lexeme
        yield kind, pos, end


def _widen(text: str, kind: str, pos: int, end: int, wide: dict[str, str]) -> tuple[str, int]:
    """The lexeme that a NAME or BAD match at ``pos``-``end`` starts: a word going on with
    characters ``\\w`` misses, or a look-alike, typographic string or run of bad characters."""
    n = len(text)
    if kind == "NAME":
        if end < n and not text[end].isascii() and _continues_name(text[end]):
            end = _name_end(text, end)
        return kind, end
    if text[pos] in wide:
        return "WIDE", end
    if text[pos] in _SMART_OPEN and (close := _smart_close(text, pos)) > 0:
        return "SMARTSTRING", close
    if _continues_name(text[pos]):  # a word that starts with a mark
        return "NAME", _name_end(text, end)
    while end < n and (
        _starts_nothing(text[end], wide)
        or (text[end] in _SMART_OPEN and _smart_close(text, end) < 0)
    ):
        end += 1
    return kind, end


def _name_end(text: str, end: int) -> int:
    """The end of the word that goes on at ``end`` past what ``\\w`` matched."""
    n = len(text)
    while end < n and not text[end].isascii() and _continues_name(text[end]):
        end = _WORD.match(text, end + 1).end()  # type: ignore[union-attr]
    return end


def _starts_nothing(ch: str, wide: dict[str, str]) -> bool:
    """``ch`` starts no token and is none of the bad characters _scan treats on their own."""
    if ch.isspace() or ch in wide or ch in _SMART_OPEN:
        return False
    if ch.isascii():
        return _master_regex().match(ch).lastgroup == "BAD"  # type: ignore[union-attr]
    return not _continues_name(ch)


def tokenize(
    text: str,
    file: str,
    sink: DiagnosticSink,
    comments_out: list[Token] | None = None,
    item_ends_out: list[int] | None = None,
) -> list[Token]:
    """The tokens the parser reads (comments dropped). With ``comments_out``, the comments are
    appended to it as ``comments`` finds them, in the same pass (`mtlc fmt` needs both).

    With ``item_ends_out``, when the brackets are plainly nested (each closer closes the
    innermost opener, none is left open, none nests deeper than MAX_NESTING, no word starts a
    line inside them), the index of each new line outside every bracket, then the number of
    tokens, is appended to it: where the parser's items end, found here in passing instead of
    by the parser's walk over every bracket. Otherwise nothing is (the parser walks them).
    """
    fast = _plain_tokens(text, comments_out is not None)
    if fast is not None:
        tokens, found, item_ends = fast
        if comments_out is not None:
            comments_out += found
        if item_ends_out is not None and item_ends is not None:
            item_ends_out += item_ends
        return tokens
    return _tokenize(text, file, sink, comments_out, item_ends_out)


@cache
def _plain_regex() -> re.Pattern[str]:
    """The spaces before a lexeme, and the lexeme: an ASCII name, a number, punctuation, a new
    line, a comment, a string, or any one other character (which _plain_tokens leaves to
    _tokenize). Two groups, for ``findall``; every alternative takes a character at least, so
    the matches tile the text and each one's offset is the sum of the lengths before it."""
    lx = lexicon()
    punct = "|".join(re.escape(p) for p in sorted(lx.punctuation, key=len, reverse=True))
    uncaptured = [lx.patterns[k].replace("(", "(?:") for k in ("NUMBER", "STRING")]
    return re.compile(
        r"([ \t\f\v]*)("
        + "|".join(
            [
                r"[A-Za-z_][A-Za-z0-9_]*",  # no digit first, as NAME's (?!\d)
                uncaptured[0],
                punct,
                r"\r\n|\n|\r",
                r"\#[^\r\n]*",
                uncaptured[1],
                r"[\s\S]",
            ]
        )
        + ")"
    )


_NAME, _NUMBER, _PUNCT, _OPEN, _CLOSE, _NL, _COMMENT, _STRING = range(8)


@cache
def _first_chars() -> dict[str, int]:
    """What a _plain_regex lexeme is, by its first character (others: not a plain lexeme)."""
    kinds = {ch: _NAME for ch in "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ_"}
    kinds.update({p: _PUNCT for p in lexicon().punctuation})
    kinds.update({p: _OPEN for p in "([{"})
    kinds.update({p: _CLOSE for p in ")]}"})
    kinds.update({ch: _NUMBER for ch in "0123456789."})  # a `.` alone: punctuation
    kinds.update({"\n": _NL, "\r": _NL, "#": _COMMENT, '"': _STRING})
    return kinds


_CHUNK = 1 << 16  # characters of text that _plain_tokens matches at a time (about)


def _plain_tokens(
    text: str, want_comments: bool
) -> tuple[list[Token], list[Token], list[int] | None] | None:
    """``_tokenize``'s tokens, comments and item ends (None: the brackets are not plainly
    nested) for a text made only of ASCII names, numbers, punctuation, new lines, comments,
    strings and the spaces between them; None for any other text (an error, a non-ASCII word,
    spaces that end the text), which ``_tokenize`` reads instead.

    The same tokens as ``_tokenize``'s: its regular expression gives the same lexemes here
    (the alternatives start with different characters, but a number before the `.` of
    punctuation, and a string before a lone `"`, as in _folded_regex; a name is cut short at
    a non-ASCII character, which is then a lexeme of its own and not a plain one), and each
    lexeme is made into a token by _tokenize's own steps for it. ``findall`` and a loop over
    its pairs cost half of ``finditer`` and three method calls per match."""
    lx = lexicon()
    keywords, punctuation = lx.keywords, lx.punctuation
    first = _first_chars()
    opener_of = _OPENER
    tokens: list[Token] = []
    found: list[Token] = []
    item_ends: list[int] = []
    brackets: list[str] = []  # open ( and [ and {, innermost last
    still_open = {"(": 0, "[": 0, "{": 0}
    plain = True
    line, line_start = 1, 0
    last_type = ""
    pos = 0  # where the current match starts
    findall = _plain_regex().findall
    n = len(text)
    new_str, token, append = _new_str, Token, tokens.append
    while pos < n:
        # about 64 KB at a time, up to just after a `\n`, which always ends a lexeme (no
        # lexeme but a new line holds one): the chunks' matches are the whole text's, and no
        # list of all the file's pairs is held at once (40 MB: fresh memory, page faults)
        cut = text.find("\n", pos + _CHUNK)
        for spaces, value in findall(text, pos, n if cut < 0 else cut + 1):
            start = pos + len(spaces) if spaces else pos
            size = len(value)
            pos = end = start + size
            kind = first.get(value[0])
            if kind == _NAME:
                ttype = keywords.get(value, "NAME")
                if start == line_start and brackets:
                    plain = False
            elif kind == _PUNCT:
                ttype = punctuation[value]
            elif kind == _OPEN:
                ttype = punctuation[value]
                if not _opened(brackets, still_open, value):
                    plain = False
            elif kind == _CLOSE:
                ttype = punctuation[value]
                if not _closed(brackets, still_open, opener_of[value]):
                    plain = False
            elif kind == _NUMBER:
                ttype = "NUMBER" if value != "." else "DOT"  # `.5` is a number, `.` punctuation
            elif kind == _NL:
                if (not brackets or brackets[-1] == "{") and tokens and last_type != NEWLINE:
                    if not brackets:
                        item_ends.append(len(tokens))
                    col = start - line_start + 1
                    tok = new_str(token, "\n")
                    tok.type = NEWLINE
                    tok.start_pos = start
                    tok.value = "\n"
                    tok.line = line
                    tok.column = col
                    tok.end_line = line
                    tok.end_column = col + 1
                    tok.end_pos = end
                    append(tok)
                    last_type = NEWLINE
                line += 1
                line_start = end
                continue
            elif kind == _COMMENT:
                if want_comments:
                    col = start - line_start + 1
                    found.append(
                        Token("COMMENT", value, start, line, col, line, col + end - start, end)
                    )
                continue
            elif kind == _STRING and size > 1:
                ttype = "STRING"
            elif kind is None and end == n and value in " \t\f\v":
                continue  # spaces that end the text (the regex keeps their last for [\s\S])
            else:
                return None
            col = start - line_start + 1
            tok = new_str(token, value)
            tok.type = ttype
            tok.start_pos = start
            tok.value = value
            tok.line = line
            tok.column = col
            tok.end_line = line
            tok.end_column = col + size
            tok.end_pos = end
            append(tok)
            last_type = ttype
    ends = None
    if plain and not brackets:
        item_ends.append(len(tokens))
        ends = item_ends
    return tokens, found, ends


def _tokenize(
    text: str,
    file: str,
    sink: DiagnosticSink,
    comments_out: list[Token] | None,
    item_ends_out: list[int] | None,
) -> list[Token]:
    """``tokenize`` for any text: every lexeme, diagnostics for the bad ones."""
    lx = lexicon()
    keywords, punctuation = lx.keywords, lx.punctuation
    wide = _wide_forms()
    new = _new_token
    tokens: list[Token] = []
    line, line_start = 1, 0
    brackets: list[str] = []  # open ( and [ and {, innermost last
    still_open = {"(": 0, "[": 0, "{": 0}  # how many of each are in ``brackets`` (no search)
    errors = 0
    item_ends: list[int] = []  # new lines outside every bracket (see item_ends_out)
    plain = True  # the brackets are plainly nested so far

    def error(code: str, message: str, help: str | None = None) -> None:
        """Report the current lexeme (at most MAX_ERRORS_PER_FILE of them)."""
        nonlocal errors
        errors += 1
        if errors > MAX_ERRORS_PER_FILE + 1:
            return
        span = Span(file, line, col, line, col + (end - start), start, end)
        if errors == MAX_ERRORS_PER_FILE + 1:
            sink.report(
                "MT0106",
                f"more than {MAX_ERRORS_PER_FILE} bad characters or names; the rest are not "
                "reported",
                span,
            )
        if errors <= MAX_ERRORS_PER_FILE:
            sink.report(code, message, span, help=help)

    rx = _folded_regex()
    n = len(text)
    last_type = ""  # that of tokens[-1]
    pos = 0
    restart = -1  # a lexeme ran past its match (a longer word, a run of bad characters)
    while True:
        for m in rx.finditer(text, pos):
            if restart >= 0:  # the match after it: scan again from its end instead
                break
            # the same lexemes as _scan, spaces folded into the next one's match (_folded_regex),
            # and the commonest ones (ASCII names, punctuation, numbers) turned into tokens at once
            kind = m.lastgroup
            end = m.end()
            start = m.start(kind)  # type: ignore[arg-type]
            col = start - line_start + 1
            if kind == "PUNCT":
                value = text[start:end]
                ttype = punctuation[value]
                if value in "([{":
                    if not _opened(brackets, still_open, value):
                        plain = False
                elif value in ")]}" and not _closed(brackets, still_open, _OPENER[value]):
                    plain = False
            elif (
                kind == "NAME"
                and (end == n or text[end].isascii())  # else the word may go on (_name_end)
                and (value := text[start:end]).isascii()
            ):
                ttype = keywords.get(value, "NAME")
                if col == 1 and brackets:
                    plain = False
            elif kind == "NUMBER":
                value, ttype = text[start:end], kind
            elif kind == "NL":
                if (not brackets or brackets[-1] == "{") and tokens and last_type != NEWLINE:
                    if not brackets:
                        item_ends.append(len(tokens))
                    # Token(NEWLINE, "\n", ...) made as below: a new line per line of code
                    tok = _new_str(Token, "\n")
                    tok.type = NEWLINE
                    tok.start_pos = start
                    tok.value = "\n"
                    tok.line = line
                    tok.column = col
                    tok.end_line = line
                    tok.end_column = col + 1
                    tok.end_pos = end
                    tokens.append(tok)
                    last_type = NEWLINE
                line += 1
                line_start = end
                continue
            elif kind == "WS":
                continue
            else:
                if kind == "NAME":
                    if end < n and not text[end].isascii() and _continues_name(text[end]):
                        end = _name_end(text, end)
                        restart = end  # go on after the longer word
                elif kind == "BAD":
                    kind, end = _widen(text, kind, start, end, wide)  # type: ignore[arg-type]
                    if end != m.end():
                        restart = end
                if kind == "COMMENT":
                    if comments_out is not None:
                        comments_out.append(
                            Token(
                                "COMMENT",
                                text[start:end],
                                start,
                                line,
                                col,
                                line,
                                col + end - start,
                                end,
                            )
                        )
                    continue
                if kind == "NL":
                    if (not brackets or brackets[-1] == "{") and tokens and last_type != NEWLINE:
                        if not brackets:
                            item_ends.append(len(tokens))
                        tokens.append(new(NEWLINE, "\n", start, line, col, line, col + 1, end))
                        last_type = NEWLINE
                    line += 1
                    line_start = end
                    continue
                value = text[start:end]
                if kind == "WIDE":
                    ascii_form = wide[value]
                    shown = "a space" if ascii_form == " " else f"`{ascii_form}`"
                    if errors <= MAX_ERRORS_PER_FILE:  # past it, skip building the message
                        error(
                            "MT0102",
                            f"unexpected character {_describe_char(value)}",
                            help=f"write {shown} instead (mtlc reads it as one here)",
                        )
                    if ascii_form == " ":
                        continue
                    value, kind = ascii_form, "PUNCT"
                if (
                    kind == "NAME" and value.isdecimal()
                ):  # non-ASCII digits: ASCII ones are a NUMBER
                    digits = "".join(str(unicodedata.decimal(ch)) for ch in value)
                    error(
                        "MT0102",
                        f"unexpected digits `{value}`",
                        help=f"write numbers with the digits 0-9: `{digits}` (mtlc reads it so here)",
                    )
                    value, kind = digits, "NUMBER"
                if kind == "NAME":
                    if not value.isascii():
                        value = unicodedata.normalize("NFC", value)
                        if not value.isidentifier():
                            error(
                                "MT0108", f"`{value}` is not a valid name", help=_name_help(value)
                            )
                    ttype = keywords.get(value, "NAME")
                    if col == 1 and brackets:
                        plain = False
                elif kind == "PUNCT":
                    ttype = punctuation[value]
                    plain = False  # a look-alike (reported): the parser walks the brackets
                    if value in "([{":
                        _opened(brackets, still_open, value)
                    elif value in ")]}" and brackets:
                        # a `}` also ends any ( or [ left open inside its block
                        _closed(brackets, still_open, _OPENER[value])
                elif kind in ("NUMBER", "STRING"):
                    ttype = kind
                elif kind == "SMARTSTRING":
                    error(
                        "MT0102",
                        "a string in typographic quotes",
                        help=f'strings use the straight quote `"`: write "{value[1:-1]}" '
                        "(mtlc reads it as one here)",
                    )
                    body = value[1:-1]
                    literal = f'"{body}"' if "\\" not in body else '""'
                    tokens.append(
                        Token("STRING", literal, start, line, col, line, col + len(value), end)
                    )
                    last_type = "STRING"
                    continue
                elif kind == "BADSTRING":
                    error(
                        "MT0103",
                        "string is not closed before the end of the line",
                        help='close it with `"`; a string cannot span lines (write \\n instead)',
                    )
                    # a bad string still stands for a value, so the statement around it parses
                    tokens.append(
                        Token("STRING", '""', start, line, col, line, col + len(value), end)
                    )
                    last_type = "STRING"
                    continue
                elif errors <= MAX_ERRORS_PER_FILE:
                    shown = value if len(value) <= 20 else value[:20] + "…"
                    error(
                        "MT0102",
                        f"unexpected character{'s' if len(value) > 1 else ''} {shown!r}",
                        help=_bad_help(value),
                    )
                    continue
                else:
                    continue
            # Token(...) as lark's Token._future_new makes it, without its call: one per token
            tok = _new_str(Token, value)
            tok.type = ttype
            tok.start_pos = start
            tok.value = value
            tok.line = line
            tok.column = col
            tok.end_line = line
            tok.end_column = col + (end - start)
            tok.end_pos = end
            tokens.append(tok)
            last_type = ttype
        else:
            if restart < 0 or restart >= n:
                break
        pos, restart = restart, -1
    if item_ends_out is not None and plain and not brackets:
        item_ends_out += item_ends
        item_ends_out.append(len(tokens))
    return tokens


def _describe_char(ch: str) -> str:
    name = unicodedata.name(ch, "")
    return f"`{ch}` (U+{ord(ch):04X} {name})" if name else f"U+{ord(ch):04X}"


def _name_help(word: str) -> str:
    """Which character of ``word`` spoils it, and the rule (one help line for the whole word)."""
    if not word[0].isidentifier():
        first = f"it cannot start with {_describe_char(word[0])}"
    else:
        bad = next((ch for ch in word if not ("_" + ch).isidentifier()), word[0])
        first = f"{_describe_char(bad)} cannot be part of a name"
    return f"{first}: a name is letters (any script), digits and `_`, and starts with no digit"


def _bad_help(value: str) -> str | None:
    if value[0] in "\u201c\u201d\u201e\u201f\u2033":
        return 'strings use the straight quote `"`'
    return None


def comments(text: str) -> list[Token]:
    """Every comment in ``text`` as a COMMENT token with its position (for `mtlc fmt`).

    ``tokenize`` drops comments, so the parser never sees them; this scans with the same
    scanner, so a `#` inside a string is never taken for a comment.
    """
    found: list[Token] = []
    line, line_start = 1, 0
    for kind, start, end in _scan(text):
        if kind == "NL":
            line += 1
            line_start = end
        elif kind == "COMMENT":
            col = start - line_start + 1
            found.append(
                Token("COMMENT", text[start:end], start, line, col, line, col + end - start, end)
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
