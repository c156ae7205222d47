"""The formatter's fast paths give what the reference paths give, byte for byte.

- ``mtlc.fmt.printer``: a statement or scene member that prints on one line is printed without
  a document (``_one_line``), and a block with no comment to place has its statements built
  without placing comments (``_sequence``); with ``FAST_PATHS = False`` every one goes through
  the general code and the layout. Both must give the same text and diagnostics.
- ``mtlc.syntax.lexer.tokenize``: spaces folded into the next lexeme's match, and the common
  lexemes turned into tokens at once; ``_reference_tokenize`` below is the tokenizer as it was
  (one lexeme of ``_scan`` at a time). Both must give the same tokens, comments and diagnostics.

The inputs: the shipped files, the docs' examples, the messy golden, lines around the width
limit at several depths, hypothesis programs (tests/test_fmt.py's) and byte-mutated files
(bench/fuzz.py's), which reach the error paths.
"""

from __future__ import annotations

import importlib.util
import random
import sys
import unicodedata
from collections.abc import Iterator
from contextlib import contextmanager

import pytest
from conftest import EXAMPLES, ROOT, STDLIB
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from lark import Token
from test_fmt import _IGNORES, MESSY, _doc_examples, _program

import mtlc.fmt.printer as printer
from mtlc.diagnostics import DiagnosticSink, Span
from mtlc.fmt import FormatResult, format_source
from mtlc.syntax import lexer, suppressions
from mtlc.syntax.grammar import lexicon

_spec = importlib.util.spec_from_file_location("mtlc_bench_fuzz_paths", ROOT / "bench" / "fuzz.py")
assert _spec is not None and _spec.loader is not None
fuzz = importlib.util.module_from_spec(_spec)
sys.modules[_spec.name] = fuzz
_spec.loader.exec_module(fuzz)


@contextmanager
def _fast_paths(on: bool) -> Iterator[None]:
    saved = printer.FAST_PATHS
    printer.FAST_PATHS = on
    try:
        yield
    finally:
        printer.FAST_PATHS = saved


def _result(result: FormatResult) -> tuple[str | None, list[tuple[str, str, Span]]]:
    return result.text, [(d.code, d.message, d.span) for d in result.diagnostics]


def _assert_same_both_ways(text: str) -> None:
    with _fast_paths(False):
        reference = _result(format_source(text, "x.mtask"))
    with _fast_paths(True):
        fast = _result(format_source(text, "x.mtask"))
    assert fast == reference, text


def _near_the_width() -> list[str]:
    """Statements and sites whose flat text ends just before, at and after column 100, at
    depths 1 to 3, with calls, vectors, lists and sums in them."""
    out = []
    for width in range(88, 106):
        for depth in (1, 2, 3):
            pad = "x" * max(1, width - 4 * depth - 24)
            stmts = [
                f"inspect(bolt, {pad}, 1 s)",
                f"goal right at (1, 2, {pad}) cm approach 3 cm over 1 s",
                f"f(g(a, [b, {pad}]), h: 1 s + 2 s * -3)",
                f"walk to {pad}.site facing (0, 1, 0) over (1 s)",
            ]
            body = "\n".join(stmts)
            for _ in range(depth - 1):
                body = "repeat 2 {\n" + body + "\n}"
            out.append(
                f"scene s {{\n    site {pad} at (0, 0, {pad}) cm\n}}\n\ntask t {{\n{body}\n}}\n"
            )
    return out


@pytest.mark.parametrize("path", [*EXAMPLES, *STDLIB, MESSY], ids=lambda p: p.name)
def test_one_line_path_on_the_shipped_files(path) -> None:  # type: ignore[no-untyped-def]
    _assert_same_both_ways(path.read_text(encoding="utf-8"))


def test_one_line_path_on_the_docs_examples_and_around_the_width(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    texts = [*_doc_examples(), *_near_the_width()]
    for text in texts:
        _assert_same_both_ways(text)
    # the width cases take both ways: some lines fit in one, others need the document
    taken: list[bool] = []
    original = printer._Printer._one_line

    def counted(self, node, line):  # type: ignore[no-untyped-def]
        text = original(self, node, line)
        taken.append(text is not None)
        return text

    monkeypatch.setattr(printer._Printer, "_one_line", counted)
    for text in _near_the_width():
        format_source(text, "x.mtask")
    assert any(taken) and not all(taken)


def test_quiet_block_path_would_be_caught(monkeypatch: pytest.MonkeyPatch) -> None:
    """A block taken for one without comments when a comment after its `}` is on an entry's
    line (the entry hosts it) would lose or move that comment: the comparison sees it."""
    text = "task t {\n    repeat 2 {\n        a(1, 2) }  # c\n}\n"
    _assert_same_both_ways(text)
    monkeypatch.setattr(printer.CommentPool, "quiet", lambda self, start, end, end_line: True)
    with _fast_paths(False):
        reference = _result(format_source(text, "x.mtask"))
    with _fast_paths(True):
        fast = _result(format_source(text, "x.mtask"))
    assert fast != reference


def test_one_line_path_is_taken_and_would_be_caught(monkeypatch: pytest.MonkeyPatch) -> None:
    """The comparison above can fail: a one-line path that spaced a list differently would
    give another text than the document does."""
    text = EXAMPLES[0].read_text(encoding="utf-8")
    original = printer._Printer._line_list

    def tighter(self, open_index, close_index, items):  # type: ignore[no-untyped-def]
        return original(self, open_index, close_index, items).replace(", ", ",")

    monkeypatch.setattr(printer._Printer, "_line_list", tighter)
    with _fast_paths(False):
        reference = format_source(text, "x.mtask").text
    with _fast_paths(True):
        fast = format_source(text, "x.mtask").text
    assert reference == text and fast != reference


@settings(
    max_examples=150,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much],
)
@given(_program())
def test_one_line_path_on_random_programs(text: str) -> None:
    _assert_same_both_ways(text)


@pytest.mark.parametrize("index", range(40))
def test_one_line_path_on_mutated_files(index: int) -> None:
    rng = random.Random(f"paths:{index}")
    sources = fuzz.example_sources()
    for _ in range(5):
        data = fuzz.mutate(rng, sources)
        _assert_same_both_ways(data.decode("utf-8", "replace"))


# ------------------------------------------------ blocks as one text, repeated lines, parameters

# statements drawn from a few, so that the same line comes back at other depths (the flat
# text is made once per source text: _one_line's memo), some with the writer's parentheses
_LINES = [
    "reach(hand, bolt)",
    "inspect(bolt, (1 min + 30 s))",
    "inspect(bolt, ((2 s)))",
    "f((1).x, g((a)), -(b))",
    "goal hand at (0, 1, 2) cm approach 3 cm over 1 s",
    "posture stand()",
    "turn(hand, -90 deg, 0.2 kg)",
]
_COMMENTS = ["", "  # c", "  # mtlc: ignore[MT0501]", "  # mtlc: ignore[MT0501] a longer reason"]


@st.composite
def _blocks(draw: st.DrawFn, depth: int = 1) -> str:
    """A block's lines: statements (some joined by `;`, some with a trailing comment, one
    padded towards the width), nested `repeat` and `parallel` blocks, blank lines."""
    out = []
    for _ in range(draw(st.integers(1, 4))):
        choice = draw(st.integers(0, 5))
        comment = draw(st.sampled_from(_COMMENTS))
        if choice == 0 and depth < 4:
            head = draw(st.sampled_from(["repeat 2 {", "parallel {", "for v in [1, 2] {"]))
            inner = draw(_blocks(depth + 1))
            tail = draw(st.sampled_from(["}", "}; reach(hand, bolt)"]))
            out.append(f"{head}{comment}\n{inner}\n{tail}")
        elif choice == 1:
            pad = "x" * draw(st.integers(60, 100 - 4 * depth))
            out.append(f"inspect({pad}, 1 s){comment}")
        elif choice == 2:
            out.append(
                draw(st.sampled_from(_LINES)) + "; " + draw(st.sampled_from(_LINES)) + comment
            )
        else:
            out.append(draw(st.sampled_from(_LINES)) + comment)
        if draw(st.booleans()):
            out.append("")
    return "\n".join(out)


@st.composite
def _definitions(draw: st.DrawFn) -> str:
    """An action whose parameter list ends around column 100, and a task of blocks."""
    names = draw(st.lists(st.sampled_from(["hand", "bolt", "a_long_parameter_name"]), max_size=5))
    params = ", ".join(f"{n}{k}: Site" for k, n in enumerate(names))
    extra = draw(st.sampled_from(["", ", turns: Int = 2", ", at: Vector = (0, 0, 1) cm", ","]))
    pad = "y" * draw(st.integers(1, 40))
    body = draw(_blocks())
    comment = draw(st.sampled_from(["", "  # c"]))
    return (
        f"action a{pad}({params}{extra}) {{{comment}\n{body}\n}}\n\n"
        f"task t {{\n{draw(_blocks())}\n}}\n"
    )


@settings(
    max_examples=200,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much],
)
@given(_definitions())
def test_block_text_and_repeated_lines_on_random_programs(text: str) -> None:
    """Blocks made one text, lines made once per source text, flat parameter lists: the same
    output and diagnostics as the general code and the layout (the property), on the text and
    on its formatted form (already canonical: the case the paths are for)."""
    _assert_same_both_ways(text)
    formatted = format_source(text, "x.mtask").text
    if formatted is not None:
        _assert_same_both_ways(formatted)


def test_block_text_paths_are_taken_and_would_be_caught(monkeypatch: pytest.MonkeyPatch) -> None:
    """The comparison sees a block text that put a held comment after the block instead of
    after its `{` line, and a parameter list kept flat past the width."""
    hosted = "task t {\n    repeat 2 {  # c\n        a()\n    }\n    b()\n}\n"
    _assert_same_both_ways(hosted)

    def at_end(element):  # type: ignore[no-untyped-def]
        first, second = element
        if type(first) is printer.LineSuffix and type(second) is str:
            return second + first.text
        return original_suffix(element)

    original_suffix = printer._with_suffix
    monkeypatch.setattr(printer, "_with_suffix", at_end)
    with _fast_paths(False):
        reference = _result(format_source(hosted, "x.mtask"))
    with _fast_paths(True):
        fast = _result(format_source(hosted, "x.mtask"))
    assert reference[0] == hosted and fast != reference
    monkeypatch.undo()

    long = "action a(" + ", ".join(f"p{k}: Site" for k in range(12)) + ") {\n    b()\n}\n"
    assert long.index(" {") > 100  # the list breaks
    _assert_same_both_ways(long)
    original_params = printer._Printer._flat_params

    def wider(self, definition, open_index, close_index):  # type: ignore[no-untyped-def]
        monkeypatch.setattr(printer, "LINE_LENGTH", 200)  # for the flat test only
        try:
            return original_params(self, definition, open_index, close_index)
        finally:
            monkeypatch.setattr(printer, "LINE_LENGTH", 100)

    monkeypatch.setattr(printer._Printer, "_flat_params", wider)
    with _fast_paths(False):
        reference = _result(format_source(long, "x.mtask"))
    with _fast_paths(True):
        fast = _result(format_source(long, "x.mtask"))
    assert fast != reference


def test_a_repeated_line_is_made_once(monkeypatch: pytest.MonkeyPatch) -> None:
    """The same statement text, written at several depths (one past the width), is flattened
    once, and kept flat only where it fits."""
    line = "inspect(bolt, " + "x" * 76 + ", 1 s)"  # 96 characters
    text = f"task t {{\n    {line}\n    repeat 2 {{\n        {line}\n    }}\n    {line}\n}}\n"
    _assert_same_both_ways(text)
    made: list[str] = []
    original = printer._Printer._line_stmt

    def counted(self, stmt):  # type: ignore[no-untyped-def]
        made.append(original(self, stmt))
        return made[-1]

    monkeypatch.setattr(printer._Printer, "_line_stmt", counted)
    out = format_source(text, "x.mtask").text
    assert made == [line] and out is not None and f"        {line}" not in out


# ---------------------------------------------------------------- the tokenizer


def _reference_tokenize(
    text: str, file: str, sink: DiagnosticSink, comments_out: list[Token] | None = None
) -> list[Token]:
    """The tokenizer before spaces were folded into the regex: one ``_scan`` lexeme at a time."""
    lx = lexicon()
    keywords, punctuation = lx.keywords, lx.punctuation
    wide = lexer._wide_forms()
    tokens: list[Token] = []
    line, line_start = 1, 0
    brackets: list[str] = []
    still_open = {"(": 0, "[": 0, "{": 0}
    errors = 0
    limit = lexer.MAX_ERRORS_PER_FILE

    def error(code: str, message: str, help: str | None = None) -> None:
        nonlocal errors
        errors += 1
        if errors > limit + 1:
            return
        span = Span(file, line, col, line, col + (end - start), start, end)
        if errors == limit + 1:
            sink.report(
                "MT0106",
                f"more than {limit} bad characters or names; the rest are not reported",
                span,
            )
        if errors <= limit:
            sink.report(code, message, span, help=help)

    for kind, start, end in lexer._scan(text):
        if kind == "WS":
            continue
        col = start - line_start + 1
        if kind == "COMMENT":
            if comments_out is not None:
                comments_out.append(
                    Token(
                        "COMMENT", text[start:end], start, line, col, line, col + end - start, end
                    )
                )
            continue
        if kind == "NL":
            if (not brackets or brackets[-1] == "{") and tokens and tokens[-1].type != "_NL":
                tokens.append(Token("_NL", "\n", start, line, col, line, col + 1, end))
            line += 1
            line_start = end
            continue
        value = text[start:end]
        if kind == "WIDE":
            ascii_form = wide[value]
            shown = "a space" if ascii_form == " " else f"`{ascii_form}`"
            if errors <= limit:
                error(
                    "MT0102",
                    f"unexpected character {lexer._describe_char(value)}",
                    help=f"write {shown} instead (mtlc reads it as one here)",
                )
            if ascii_form == " ":
                continue
            value, kind = ascii_form, "PUNCT"
        if kind == "NAME" and value.isdecimal():
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
                    error("MT0108", f"`{value}` is not a valid name", help=lexer._name_help(value))
            ttype = keywords.get(value, "NAME")
        elif kind == "PUNCT":
            ttype = punctuation[value]
            if value in "([{":
                brackets.append(value)
                still_open[value] += 1
            elif value in ")]}" and brackets:
                opener = {")": "(", "]": "[", "}": "{"}[value]
                if still_open[opener]:
                    while (popped := brackets.pop()) != opener:
                        still_open[popped] -= 1
                    still_open[opener] -= 1
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
            tokens.append(Token("STRING", literal, start, line, col, line, col + len(value), end))
            continue
        elif kind == "BADSTRING":
            error(
                "MT0103",
                "string is not closed before the end of the line",
                help='close it with `"`; a string cannot span lines (write \\n instead)',
            )
            tokens.append(Token("STRING", '""', start, line, col, line, col + len(value), end))
            continue
        elif errors <= limit:
            shown = value if len(value) <= 20 else value[:20] + "…"
            error(
                "MT0102",
                f"unexpected character{'s' if len(value) > 1 else ''} {shown!r}",
                help=lexer._bad_help(value),
            )
            continue
        else:
            continue
        tokens.append(Token(ttype, value, start, line, col, line, col + (end - start), end))
    return tokens


def _lexed(tokenize, text: str):  # type: ignore[no-untyped-def]
    sink = DiagnosticSink()
    found: list[Token] = []
    tokens = tokenize(text, "x.mtask", sink, found)

    def fields(t: Token) -> tuple[object, ...]:
        return (t.type, t.value, t.start_pos, t.line, t.column, t.end_line, t.end_column, t.end_pos)

    return (
        [fields(t) for t in tokens],
        [fields(t) for t in found],
        [(d.code, d.message, d.span, d.help) for d in sink.items],
    )


def _assert_same_tokens(text: str) -> None:
    assert _lexed(lexer.tokenize, text) == _lexed(_reference_tokenize, text), repr(text)


_ODD = list(" \t\f\v\n\r#\"\\()[]{},.;:=+-*/e_19é\u0301·一，（：\u3000“”„\u00a0\u2028\x85\x1c$@'")


@settings(max_examples=300, deadline=None)
@given(st.lists(st.sampled_from([*_ODD, "abc", "12.5e3", "  ", "# c", "\r\n", "1x"]), max_size=40))
def test_tokenize_equals_the_reference_on_odd_text(parts: list[str]) -> None:
    _assert_same_tokens("".join(parts))


@pytest.mark.parametrize("index", range(40))
def test_tokenize_equals_the_reference_on_mutated_files(index: int) -> None:
    rng = random.Random(f"lex:{index}")
    sources = fuzz.example_sources()
    for _ in range(5):
        _assert_same_tokens(fuzz.mutate(rng, sources).decode("utf-8", "replace"))


def test_tokenize_equals_the_reference_on_the_shipped_files() -> None:
    for path in [*EXAMPLES, *STDLIB, MESSY]:
        _assert_same_tokens(path.read_text(encoding="utf-8"))
    # and on text with more bad characters than are reported, with spaces at the end
    _assert_same_tokens("task t {\n" + "$ " * 80 + "}\n   ")


def test_tokenize_comparison_can_fail(monkeypatch: pytest.MonkeyPatch) -> None:
    """A tokenizer that matched `)` with the wrong opener (so kept a new line inside the
    brackets, or dropped one after them) differs from the reference."""
    text = "task t {\n    a(1,\n      2)\n    b()\n}\n"
    assert _lexed(lexer.tokenize, text) == _lexed(_reference_tokenize, text)
    monkeypatch.setattr(lexer, "_OPENER", {")": "[", "]": "(", "}": "{"})
    assert _lexed(lexer.tokenize, text) != _lexed(_reference_tokenize, text)


# ---------------------------------------------------------------- the plain-text tokenizer


def _both_loops(text: str) -> tuple[object, object, bool]:
    """(tokens, comments, item ends, diagnostics) by ``tokenize`` and by its general loop
    ``_tokenize`` alone, and whether ``tokenize`` took its plain-text path."""

    def run(tokenize) -> tuple[object, ...]:  # type: ignore[no-untyped-def]
        sink = DiagnosticSink()
        found: list[Token] = []
        ends: list[int] = []
        tokens = tokenize(text, "x.mtask", sink, found, ends)

        def fields(t: Token) -> tuple[object, ...]:
            return (type(t), t.type, t.value, t.start_pos, t.line, t.column, t.end_line,
                    t.end_column, t.end_pos)  # fmt: skip

        diags = [(d.code, d.message, d.span, d.help) for d in sink.items]
        return [fields(t) for t in tokens], [fields(t) for t in found], ends, diags

    return run(lexer.tokenize), run(lexer._tokenize), lexer._plain_tokens(text, True) is not None


_PLAIN = [*" \t\f\v\n\r#\"()[]{},.;:=+-*/e_19", "abc", "use", "site", "12.5e3", ".5", "1.",
          "  ", "# c", "# é", '"é"', "\r\n", "1x", "x1", "é", "$", "\u3000", "“"]  # fmt: skip


@settings(max_examples=400, deadline=None)
@given(st.lists(st.sampled_from(_PLAIN), max_size=50))
def test_plain_tokens_equal_the_general_loop(parts: list[str]) -> None:
    fast, general, _ = _both_loops("".join(parts))
    assert fast == general


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(_program())
def test_plain_tokens_equal_the_general_loop_on_programs(text: str) -> None:
    fast, general, plain = _both_loops(text)
    assert fast == general
    assert plain or not text.isascii() or '"' in text or text[-1:].isspace()


@pytest.mark.parametrize("chunk", [1, 7, 1 << 16])
def test_plain_tokens_on_the_shipped_and_mutated_files(
    chunk: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(lexer, "_CHUNK", chunk)  # chunks of the text cut after a new line
    taken = 0
    texts = [p.read_text(encoding="utf-8") for p in [*EXAMPLES, *STDLIB, MESSY]]
    rng = random.Random("plain")
    sources = fuzz.example_sources()
    texts += [fuzz.mutate(rng, sources).decode("utf-8", "replace") for _ in range(200)]
    for text in texts:
        fast, general, plain = _both_loops(text)
        assert fast == general
        taken += plain
    assert taken >= len(EXAMPLES) + len(STDLIB)  # the path is taken, not just skipped


def test_plain_tokens_comparison_can_fail(monkeypatch: pytest.MonkeyPatch) -> None:
    """A plain path that read a lexeme starting with `.` as a name differs."""
    text = "task t {\n    a(.5, b.c)\n}\n"
    fast, general, plain = _both_loops(text)
    assert plain and fast == general
    wrong = {**lexer._first_chars(), ".": lexer._NAME}
    monkeypatch.setattr(lexer, "_first_chars", lambda: wrong)
    fast, general, plain = _both_loops(text)
    assert plain and fast != general


# ---------------------------------------------------------------- suppressions, by lines


def _marks(text: str) -> list[tuple[object, ...]]:
    return [(m.code, m.span, m.first_line, m.last_line) for m in suppressions.scan("f", text)]


def _assert_same_marks_any_breaks(text: str) -> None:
    """``scan`` splits a text without `\r` with str.split, any other with the regex: lines and
    columns do not depend on how the lines are broken, so both ways find the same marks."""
    plain = text.replace("\r\n", "\n").replace("\r", "\n")
    expected = _marks(plain)
    assert _marks(plain.replace("\n", "\r\n")) == expected
    assert _marks(plain.replace("\n", "\r")) == expected
    assert _marks(plain + "\r") == expected  # a lone `\r` at the end: the regex's way


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.data())
def test_suppressions_scan_the_same_with_any_line_breaks(data: st.DataObject) -> None:
    text = data.draw(_program()).replace("# c", data.draw(_IGNORES))
    _assert_same_marks_any_breaks(text)


def test_suppressions_scan_the_shipped_files_with_any_line_breaks() -> None:
    found = 0
    for path in [*EXAMPLES, *STDLIB, MESSY]:
        text = path.read_text(encoding="utf-8")
        _assert_same_marks_any_breaks(text)
        found += len(_marks(text))
    text = "task t {  # mtlc: ignore[MT0501]\n    a()\n}\nb()  # mtlc: ignore[MT0601]\n"
    _assert_same_marks_any_breaks(text)
    assert [(m[2], m[3]) for m in _marks(text)] == [(1, 3), (4, 4)]
    assert _marks("task t {\n}\n") == []  # no `mtlc:`: no split at all
