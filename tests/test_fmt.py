"""`mtlc fmt`: canonical, idempotent, meaning-preserving, comment-keeping; and its command line."""

from __future__ import annotations

import io
import re
import shutil
import subprocess
import sys
from collections import Counter
from pathlib import Path

import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

import mtlc.fmt as fmt
from mtlc.diagnostics import DiagnosticSink
from mtlc.fmt import ast_fingerprint, format_source
from mtlc.fmt.__main__ import main as fmt_main
from mtlc.syntax import parse_module
from mtlc.syntax.lexer import comments

# not imported from conftest: another folder's conftest.py may take that module name first
ROOT = Path(__file__).resolve().parent.parent
EXAMPLES = sorted((ROOT / "examples").glob("*.mtask"))
STDLIB = sorted((ROOT / "stdlib").glob("*.mtask"))
MESSY = ROOT / "tests" / "goldens" / "fmt" / "messy.input.mtask"


def _tree(text: str) -> str:
    sink = DiagnosticSink()
    module = parse_module(text, "x.mtask", sink)
    assert sink.items == []
    return ast_fingerprint(module)


def _comment_texts(text: str) -> Counter[str]:
    return Counter(t.value.rstrip() for t in comments(text))


def _formatted(text: str) -> str:
    result = format_source(text, "x.mtask")
    assert result.diagnostics == []
    assert result.text is not None
    return result.text


def _assert_safe_and_idempotent(text: str) -> str:
    once = _formatted(text)
    assert _formatted(once) == once
    assert _tree(once) == _tree(text)
    assert _comment_texts(once) == _comment_texts(text)
    return once


# ---------------------------------------------------------------- the shipped files


@pytest.mark.parametrize("path", EXAMPLES + STDLIB, ids=lambda p: f"{p.parent.name}/{p.name}")
def test_shipped_files_are_canonical(path: Path) -> None:
    text = path.read_text(encoding="utf-8")
    assert _assert_safe_and_idempotent(text) == text


def test_messy_file_golden(golden) -> None:
    text = MESSY.read_text(encoding="utf-8")
    once = _assert_safe_and_idempotent(text)
    golden.check("fmt/messy.mtask", once)


# ---------------------------------------------------------------- style rules


@pytest.mark.parametrize(
    ("source", "expected"),
    [
        # units after a space, spaces around operators and after commas
        (
            "task t {\n budget 1min+30s\n tool f(a,b:2)\n}\n",
            "budget 1 min + 30 s\n    tool f(a, b: 2)",
        ),
        # parentheses the precedence needs are added back; the writer's are kept
        (
            "task t {\n time 1 s-(2 s-3 s)\n time (1 s)\n}\n",
            "time 1 s - (2 s - 3 s)\n    time (1 s)",
        ),
        # a number before `.` stays bracketed (`1.x` would read as `1.` with the unit x)
        ("task t {\n tool (1).x\n}\n", "tool (1).x"),
        # `;` becomes a new line; runs of blank lines become one
        ("task t {\n a(); b()\n\n\n\n c()\n}\n", "    a()\n    b()\n\n    c()\n}"),
        # a trailing comma keeps a list one item per line
        ("task t {\n f(a,)\n}\n", "    f(\n        a,\n    )\n"),
        # trailing comments stay on their line, two spaces from the code
        ("task t {   # t\n a()# c\n}\n", "task t {  # t\n    a()  # c\n}\n"),
        # no blank line after `{` or before `}`; one between top-level items
        (
            "use a\nuse b\ntask t {\n\n a()\n\n}\ntask u {}\n",
            "use a\nuse b\n\ntask t {\n    a()\n}\n\ntask u {}\n",
        ),
        # empty posture arguments go
        ("task t {\n posture stand()\n}\n", "    posture stand\n"),
    ],
)
def test_style(source: str, expected: str) -> None:
    assert expected in _assert_safe_and_idempotent(source)


def test_long_argument_list_wraps_one_per_line() -> None:
    names = ", ".join(f"argument_number_{i}" for i in range(8))
    out = _assert_safe_and_idempotent(f"task t {{\n    f({names})\n}}\n")
    lines = out.splitlines()
    assert lines[1] == "    f("
    assert lines[2] == "        argument_number_0,"
    assert lines[-3] == "        argument_number_7,"
    assert max(len(line) for line in lines) <= 100


def test_only_the_outer_list_wraps_when_the_inner_fits() -> None:
    inner = ", ".join(f"s{i}" for i in range(5))
    long = "x" * 80
    out = _assert_safe_and_idempotent(f"task t {{\n    f({long}, [{inner}])\n}}\n")
    assert f"        [{inner}],\n" in out


def test_comment_inside_an_expression_moves_above_its_statement() -> None:
    out = _assert_safe_and_idempotent("task t {\n    f(b, (1 min +\n 30 s # why\n + 5 s))\n}\n")
    assert "    # why\n    f(b, (1 min + 30 s + 5 s))\n" in out


def test_comment_on_a_statements_first_line_stays_on_its_first_line() -> None:
    out = _assert_safe_and_idempotent("task t {\n    inspect(b, (1 min # why\n + 30 s))\n}\n")
    assert "    inspect(b, (1 min + 30 s))  # why\n" in out


@pytest.mark.parametrize(
    "source",
    [
        "",
        "# only a comment\n",
        "task t {\r\n    walk to a  # crlf\r\n}\r\n",
        "element walk(to: Site, over: Duration = 2 s) {\n    walk to to over over\n}\n",
        "task t {\n    f(\n        # only a comment\n    )\n    h(  # x\n    )\n}\n",
        "element e(x: Site  # c\n) {\n}\n",
        "task t {\n    grip (1) closed\n    tool -(a).b\n    tool a - -b\n}\n",
    ],
    ids=["empty", "comment-only", "crlf", "soft-keywords", "empty-args", "param-comment", "parens"],
)
def test_edge_cases_are_safe(source: str) -> None:
    _assert_safe_and_idempotent(source)


def test_syntax_error_is_reported_not_formatted() -> None:
    result = format_source("task t {\n    walk to (\n}\n", "bad.mtask")
    assert result.text is None
    assert {d.code for d in result.diagnostics} >= {"MT0105"}


def test_output_that_would_change_meaning_is_refused(monkeypatch: pytest.MonkeyPatch) -> None:
    def careless(text: str, module: object, file: str) -> tuple[str, list[object]]:
        return text.replace("a()", "b()"), []

    monkeypatch.setattr(fmt, "format_module", careless)
    result = format_source("task t {\n    a()\n}\n", "x.mtask")
    assert result.text is None
    assert [d.code for d in result.diagnostics] == ["MT0900"]
    assert "syntax tree" in result.diagnostics[0].message


def test_lost_comment_is_refused(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(fmt, "format_module", lambda text, module, file: ("task t {}\n", []))
    result = format_source("task t {}  # keep me\n", "x.mtask")
    assert result.text is None
    assert "comments" in result.diagnostics[0].message


# ---------------------------------------------------------------- random programs

_NAMES = st.sampled_from(["a", "b", "right", "hand", "bolt_1", "x", "_t", "mtm"])
_UNITS = st.sampled_from([None, "cm", "s", "deg", "kg", "m"])
_NUMBERS = st.sampled_from(["0", "12", "1.5", ".5", "2.", "1e-3", "90"])
_COMMENTS = st.sampled_from(["# c", "#tight", "# two  spaces  ", "# a # in a comment", '# "q"'])


@st.composite
def _space(draw: st.DrawFn) -> str:
    return draw(st.sampled_from(["", " ", " ", "  ", "\t"]))


@st.composite
def _bracket_gap(draw: st.DrawFn) -> str:
    """Whitespace inside ( ) or [ ]: may hold new lines and comments."""
    kind = draw(st.integers(0, 5))
    if kind == 0:
        return "\n    "
    if kind == 1:
        return f"  {draw(_COMMENTS)}\n        "
    return draw(_space())


@st.composite
def _comma_list(draw: st.DrawFn, items: st.SearchStrategy[str], lo: int, hi: int) -> str:
    parts = draw(st.lists(items, min_size=lo, max_size=hi))
    out = draw(_bracket_gap())
    for i, part in enumerate(parts):
        out += part
        if i < len(parts) - 1 or draw(st.booleans()):  # a trailing comma, sometimes
            out += "," + draw(_bracket_gap())
    return out + draw(_bracket_gap())


def _exprs() -> st.SearchStrategy[str]:
    @st.composite
    def number(draw: st.DrawFn) -> str:
        unit = draw(_UNITS)
        return draw(_NUMBERS) + ("" if unit is None else draw(st.sampled_from([" ", ""])) + unit)

    leaves = st.one_of(number(), _NAMES, st.sampled_from(['"s"', '"a \\"q\\""', '"#x"']))

    def extend(inner: st.SearchStrategy[str]) -> st.SearchStrategy[str]:
        @st.composite
        def compound(draw: st.DrawFn) -> str:
            kind = draw(st.integers(0, 6))
            sp = draw(_space())
            if kind == 0:
                op = draw(st.sampled_from(["+", "-", "*", "/"]))
                return f"{draw(inner)}{sp}{op}{sp}{draw(inner)}"
            if kind == 1:
                return f"-{sp}{draw(inner)}"
            if kind == 2:
                return f"({draw(inner)})"
            if kind == 3:
                return f"{draw(_NAMES)}.{draw(_NAMES)}({draw(_comma_list(inner, 0, 3))})"
            if kind == 4:
                unit = draw(st.sampled_from(["", " cm", " deg"]))
                items = ",".join(draw(st.lists(inner, min_size=3, max_size=3)))
                return f"({items}){unit}"
            if kind == 5:
                return f"[{draw(_comma_list(inner, 0, 3))}]"
            return f"{draw(_NAMES)}{sp}.{sp}{draw(_NAMES)}"

        return compound()

    return st.recursive(leaves, extend, max_leaves=6)


_EXPR = _exprs()


@st.composite
def _args(draw: st.DrawFn) -> str:
    @st.composite
    def arg(draw: st.DrawFn) -> str:
        value = draw(_EXPR)
        return f"{draw(_NAMES)}:{draw(_space())}{value}" if draw(st.booleans()) else value

    return draw(_comma_list(arg(), 0, 4))


@st.composite
def _simple_stmt(draw: st.DrawFn) -> str:
    e = _EXPR
    over = f" over {draw(e)}" if draw(st.booleans()) else ""
    kind = draw(st.integers(0, 11))
    return [
        lambda: f"{draw(_NAMES)}({draw(_args())})",
        lambda: f"manikin {draw(_NAMES)} {draw(_NAMES)} p5",
        lambda: f"scene {draw(_NAMES)}",
        lambda: f"tool {draw(e)}",
        lambda: f"budget {draw(e)}",
        lambda: f"time {draw(e)}",
        lambda: f"goal {draw(e)} at {draw(e)} approach {draw(e)} orient{over}",
        lambda: f"posture {draw(_NAMES)}({draw(_args())}){over}",
        lambda: f"walk {draw(st.sampled_from(['to', 'by']))} {draw(e)} facing {draw(e)}{over}",
        lambda: f"grip {draw(_NAMES)} closed{over}",
        lambda: f"gaze at {draw(e)}{over}",
        lambda: f"still over {draw(e)}",
    ][kind]()


@st.composite
def _block(draw: st.DrawFn, depth: int) -> str:
    stmts = draw(st.lists(_stmt(depth), max_size=4))
    out = "{" + draw(st.sampled_from(["\n", " ", f"  {draw(_COMMENTS)}\n"]))
    for stmt in stmts:
        out += draw(_space()) + stmt
        out += draw(st.sampled_from(["\n", ";", "\n\n\n", f"  {draw(_COMMENTS)}\n"]))
        if draw(st.integers(0, 4)) == 0:
            out += f"{draw(_space())}{draw(_COMMENTS)}\n"
    return out + draw(_space()) + "}"


def _stmt(depth: int) -> st.SearchStrategy[str]:
    if depth >= 2:
        return _simple_stmt()

    @st.composite
    def compound(draw: st.DrawFn) -> str:
        body = draw(_block(depth + 1))
        return draw(
            st.sampled_from(
                [
                    f"repeat {draw(_EXPR)} {body}",
                    f"for {draw(_NAMES)} in {draw(_EXPR)} {body}",
                    f"parallel {body}",
                    body,
                ]
            )
        )

    return st.one_of(_simple_stmt(), _simple_stmt(), compound())


@st.composite
def _top_item(draw: st.DrawFn) -> str:
    kind = draw(st.integers(0, 4))
    if kind == 0:
        return f"use {draw(_NAMES)}.{draw(_NAMES)}"
    if kind == 1:
        site = f"site {draw(_NAMES)} at {draw(_EXPR)} normal {draw(_EXPR)}"
        members = draw(st.permutations([f"ground {draw(_EXPR)}", site, f"site s at {draw(_EXPR)}"]))
        sep = draw(st.sampled_from(["\n", ";", f"  {draw(_COMMENTS)}\n"]))
        return "scene bay {\n" + sep.join(members) + "\n}"
    if kind == 2:
        return f"tool w {{\n length {draw(_EXPR)}\n mass {draw(_EXPR)}\n}}"
    if kind == 3:

        @st.composite
        def param(draw: st.DrawFn) -> str:
            default = f" = {draw(_EXPR)}" if draw(st.booleans()) else ""
            return f"{draw(_NAMES)}: {draw(_NAMES)}{default}"

        keyword = draw(st.sampled_from(["element", "action"]))
        params = draw(_comma_list(param(), 0, 3))
        return f"{keyword} e({params}) {draw(_block(0))}"
    title = draw(st.sampled_from(["", ' "Title"', ' "with \\"quotes\\""']))
    return f"task t{title} {draw(_block(0))}"


@st.composite
def _program(draw: st.DrawFn) -> str:
    out = ""
    for item in draw(st.lists(_top_item(), min_size=1, max_size=3)):
        if draw(st.booleans()):
            out += f"{draw(_COMMENTS)}\n"
        out += item + draw(st.sampled_from(["\n", "\n\n", "\n\n\n", f"  {draw(_COMMENTS)}\n"]))
    return out


@settings(
    max_examples=150,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much],
)
@given(_program())
def test_random_programs_format_safely(text: str) -> None:
    sink = DiagnosticSink()
    parse_module(text, "x.mtask", sink)
    assume(sink.items == [])
    _assert_safe_and_idempotent(text)


# ---------------------------------------------------------------- command line


def _write(path: Path, text: str) -> Path:
    path.write_text(text, encoding="utf-8")
    return path


UGLY = "task t {\n  a( 1 ,2)\n}\n"
PRETTY = "task t {\n    a(1, 2)\n}\n"


def test_cli_formats_in_place(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = _write(tmp_path / "a.mtask", UGLY)
    assert fmt_main([str(path)]) == 0
    assert path.read_text(encoding="utf-8") == PRETTY
    assert "reformatted" in capsys.readouterr().err
    assert fmt_main([str(path)]) == 0  # already canonical: nothing to do


def test_cli_check_lists_files_and_writes_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    ugly = _write(tmp_path / "b.mtask", UGLY)
    _write(tmp_path / "a.mtask", PRETTY)
    (tmp_path / "sub").mkdir()
    _write(tmp_path / "sub" / "c.mtask", UGLY)
    assert fmt_main(["--check", str(tmp_path)]) == 1
    out = capsys.readouterr().out.splitlines()
    assert out == [(tmp_path / "b.mtask").as_posix(), (tmp_path / "sub" / "c.mtask").as_posix()]
    assert ugly.read_text(encoding="utf-8") == UGLY
    assert fmt_main(["--check", str(tmp_path / "a.mtask")]) == 0


def test_cli_diff_prints_a_unified_diff(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = _write(tmp_path / "a.mtask", UGLY)
    assert fmt_main(["--diff", str(path)]) == 1
    out = capsys.readouterr().out
    assert "-  a( 1 ,2)\n+    a(1, 2)\n" in out
    assert out.startswith(f"--- {path.as_posix()}\n+++ {path.as_posix()}\n")  # absolute: no a/
    assert path.read_text(encoding="utf-8") == UGLY


def test_cli_stdin_to_stdout(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setattr(sys, "stdin", io.StringIO(UGLY))
    assert fmt_main(["-"]) == 0
    assert capsys.readouterr().out == PRETTY
    monkeypatch.setattr(sys, "stdin", io.StringIO(UGLY))
    assert fmt_main(["--check", "-"]) == 1
    assert capsys.readouterr().out == "<stdin>\n"


def test_cli_syntax_error_leaves_the_file_alone(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bad = _write(tmp_path / "bad.mtask", "task t {\n  walk to (\n}\n")
    good = _write(tmp_path / "good.mtask", UGLY)
    assert fmt_main([str(bad), str(good)]) == 1
    err = capsys.readouterr().err
    assert "error[MT0105]" in err and "bad.mtask:2:" in err
    assert bad.read_text(encoding="utf-8") == "task t {\n  walk to (\n}\n"
    assert good.read_text(encoding="utf-8") == PRETTY  # the other files are still formatted


def test_cli_internal_error_exits_2_and_writes_nothing(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setattr(fmt, "format_module", lambda text, module, file: ("task u {}\n", []))
    path = _write(tmp_path / "a.mtask", UGLY)
    assert fmt_main([str(path)]) == 2
    assert "MT0900" in capsys.readouterr().err
    assert path.read_text(encoding="utf-8") == UGLY


def test_cli_missing_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert fmt_main([str(tmp_path / "none.mtask")]) == 1
    assert "MT0001" in capsys.readouterr().err


def test_python_m_mtlc_fmt_checks_the_shipped_files() -> None:
    run = subprocess.run(
        [sys.executable, "-m", "mtlc.fmt", "--check", "examples", "stdlib"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        check=False,
    )
    assert run.returncode == 0, run.stdout + run.stderr
    assert run.stdout == ""


def _doc_examples() -> list[str]:
    block = re.compile(r"^```mtask\n(.*?)^```", re.M | re.S)
    found = []
    refused = {"MT0109.md"}  # its example is a layout fmt refuses, on purpose
    for page in sorted((ROOT / "docs").rglob("*.md")):
        if page.name in refused:
            continue
        for text in block.findall(page.read_text(encoding="utf-8")):
            sink = DiagnosticSink()
            parse_module(text, "x.mtask", sink)
            if not sink.items:
                found.append(text)
    return found


def test_every_docs_example_formats_safely() -> None:
    examples = _doc_examples()
    assert len(examples) >= 10
    for text in examples:
        _assert_safe_and_idempotent(text)


# ---------------------------------------------------------------- comments and `mtlc: ignore`

_SUP_SCENE = "scene s {\n    site a at (0, 0, 1) m\n}\n\n"


def _coverage(text: str) -> Counter[tuple[str, frozenset[int]]]:
    """Each suppression's code and the statements (by their place in the tree) it covers."""
    return Counter((code, covered) for code, covered, _ in fmt._coverage(text, _parsed(text), "x"))


def _parsed(text: str):  # type: ignore[no-untyped-def]
    sink = DiagnosticSink()
    module = parse_module(text, "x", sink)
    assert sink.items == []
    return module


@pytest.mark.parametrize(
    ("body", "expected"),
    [
        (
            "parallel { a(); b() } # mtlc: ignore[MT0501]",
            "    parallel {  # mtlc: ignore[MT0501]\n        a()\n        b()\n    }\n",
        ),
        (
            "press(right, # mtlc: ignore[MT0501]\n far)",
            "    press(right, far)  # mtlc: ignore[MT0501]\n",
        ),
        ("a(); b() # mtlc: ignore[MT0501]", "    a(); b()  # mtlc: ignore[MT0501]\n"),
        ("repeat 2 { x() } # mtlc: ignore[MT0501]", "    repeat 2 {  # mtlc: ignore[MT0501]\n"),
        ("a(); b() # plain", "    a()\n    b()  # plain\n"),
    ],
)
def test_a_trailing_comment_keeps_covering_the_same_statements(body: str, expected: str) -> None:
    text = f"{_SUP_SCENE}task t {{\n    {body}\n    c()\n}}\n"
    out = _assert_safe_and_idempotent(text)
    assert expected in out
    assert _coverage(out) == _coverage(text)


_LONG = (
    "inspect(b, 1 min + 30 s + 1 min + 30 s + 1 min + 30 s + 1 min + 30 s + 1 min + 30 s + 20 s)"
)


@pytest.mark.parametrize(
    "body",
    [
        f"a(); {_LONG} # mtlc: ignore[MT0501]",  # issue 17: the call's brackets break
        f"a();{_LONG} # mtlc: ignore[MT0501]",
        "repeat 2 { x() }; a() # mtlc: ignore[MT0501]",  # the `{` line covers to `}; a()`
        "parallel { a(); b() } # mtlc: ignore[MT0501]",  # the comment moves after the `{`
    ],
)
def test_a_long_joined_line_with_an_ignore_formats_idempotently(body: str) -> None:
    """Statements an ignore keeps on one line stay together when that line breaks, and
    formatting the result again changes nothing (it was refused, or moved, before)."""
    text = f"{_SUP_SCENE}task t {{\n    {body}\n    c()\n}}\n"
    out = _assert_safe_and_idempotent(text)
    assert _coverage(out) == _coverage(text)


def test_the_review_file_lints_the_same_after_formatting() -> None:
    text = (
        "task t {\n    press(right, a)\n"
        "    parallel { press(right, far); press(left, a) } # mtlc: ignore[MT0501]\n"
        "    press(right, # mtlc: ignore[MT0501]\n        far)\n}\n"
    )
    out = _assert_safe_and_idempotent(text)
    assert _coverage(out) == _coverage(text)
    assert sum(len(covered) for _, covered in _coverage(text)) == 4  # parallel, 2 presses, press


def test_an_ignore_that_the_layout_cannot_keep_is_refused() -> None:
    """`hand` and the element start on one line: no canonical layout keeps both covered."""
    text = "element e(hand: Hand, # mtlc: ignore[MT0602]\n    other: Hand,\n) {\n    still over 1 s\n}\n"
    result = format_source(text, "x.mtask")
    assert result.text is None
    (diag,) = result.diagnostics
    assert "mtlc: ignore" in diag.message and "line 1" in diag.message
    assert "bug" not in (diag.help or "")


_IGNORES = st.sampled_from(["# mtlc: ignore[MT0501]", "# mtlc: ignore[MT0601, MT0605]", "# c"])


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.data())
def test_random_ignores_cover_the_same_statements_or_are_refused(data: st.DataObject) -> None:
    text = data.draw(_program()).replace("# c", data.draw(_IGNORES))
    sink = DiagnosticSink()
    parse_module(text, "x.mtask", sink)
    assume(sink.items == [])
    result = format_source(text, "x.mtask")
    if result.text is None:
        assert [d.code for d in result.diagnostics] == ["MT0109"]
        assert "mtlc: ignore" in result.diagnostics[0].message
        return
    assert _coverage(result.text) == _coverage(text)
    assert _formatted(result.text) == result.text


# ---------------------------------------------------------------- files: modes and symlinks


def test_formatting_keeps_the_mode_and_writes_through_a_symlink(tmp_path: Path) -> None:
    private = _write(tmp_path / "priv.mtask", UGLY)
    private.chmod(0o600)
    target = _write(tmp_path / "target.mtask", UGLY)
    link = tmp_path / "link.mtask"
    link.symlink_to("target.mtask")
    assert fmt_main([str(private), str(link), str(target)]) == 0
    assert (private.stat().st_mode & 0o777) == 0o600
    assert link.is_symlink() and target.read_text(encoding="utf-8") == PRETTY
    assert private.read_text(encoding="utf-8") == PRETTY


# ---------------------------------------------------------------- --diff is a patch that applies


@pytest.mark.skipif(shutil.which("patch") is None, reason="needs patch(1)")
@pytest.mark.parametrize(
    "text",
    [
        "task t {\n  a( 1 ,2)\n}",  # no final new line
        "task t {\r\n  a( 1 ,2)\r\n}\r\n",
        "task t {\r  a( 1 ,2)\r}\r",
        "task t { # form\x0cfeed \u2028 sep\n  a( 1 ,2)\n}\n",
    ],
    ids=["no-final-newline", "crlf", "cr", "ff-and-u2028"],
)
def test_diff_applies_with_patch(text: str, tmp_path: Path) -> None:
    from mtlc.fmt.command import unified_diff

    path = tmp_path / "x.mtask"
    path.write_bytes(text.encode("utf-8"))
    expected = _formatted(text)
    diff = unified_diff(text, expected, path.as_posix())
    assert diff.startswith(f"--- {path.as_posix()}\n+++ {path.as_posix()}\n")
    done = subprocess.run(
        ["patch", "-p0", "-s", "-i", "-"],
        input=diff.encode("utf-8"),
        cwd="/",
        capture_output=True,
        timeout=30,
    )
    assert done.returncode == 0, done.stderr + done.stdout
    assert path.read_bytes() == expected.encode("utf-8")


def test_ignore_after_a_closing_brace_is_refused_as_input_not_as_a_bug(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A comment no layout can keep covering the same (no) statements is the file's problem:
    MT0109, exit 1, the file untouched; MT0900 and exit 2 are for formatter bugs."""
    text = 'task t "Hold" {\n    repeat 3 {\n    }  # mtlc: ignore[MT0402]\n}\n'
    result = format_source(text, "x.mtask")
    assert result.text is None
    assert [d.code for d in result.diagnostics] == ["MT0109"]
    assert "line 3" in result.diagnostics[0].message
    path = _write(tmp_path / "a.mtask", text)
    assert fmt_main([str(path)]) == 1
    assert "error[MT0109]" in capsys.readouterr().err
    assert path.read_text(encoding="utf-8") == text


# ---------------------------------------------------------------- the tree comparison


def _module(text: str) -> object:
    sink = DiagnosticSink()
    module = parse_module(text, "x.mtask", sink)
    assert sink.items == []
    return module


_VARIANTS = [
    "task t {\n    wait(1 s)\n}\n",
    "task t {\n    wait(1.0 s)\n}\n",
    "task t {\n    wait(-0.0 s)\n}\n",
    "task t {\n    wait(0.0 s)\n}\n",
    "task t {\n    wait(1 ms)\n}\n",
    "task t {\n    wait((1 s))\n}\n",
    "task t {\n  wait( 1 s )  # moved\n}\n",
    'task t "a" {\n    wait(1 s)\n}\n',
    'task t "b" {\n    wait(1 s)\n}\n',
    "task t {\n    wait(1 s)\n    wait(1 s)\n}\n",
    "task u {\n    wait(1 s)\n}\n",
    "task t {\n    wait(x: 1 s)\n}\n",
]


def test_same_tree_agrees_with_the_fingerprints() -> None:
    """fmt's safety check walks the trees instead of comparing JSON fingerprints: it must say
    "same" exactly when the fingerprints are equal (positions aside)."""
    texts = [p.read_text(encoding="utf-8") for p in EXAMPLES + STDLIB] + _VARIANTS
    modules = [_module(t) for t in texts]
    prints = [ast_fingerprint(m) for m in modules]
    same = 0
    for i, a in enumerate(modules):
        for j, b in enumerate(modules):
            assert fmt.same_tree(a, b) == (prints[i] == prints[j]), (texts[i], texts[j])
            same += i != j and prints[i] == prints[j]
    assert same > 0  # the variants hold trees equal apart from layout, so both answers occur


@pytest.mark.parametrize("path", [*EXAMPLES, MESSY], ids=lambda p: p.name)
def test_reused_items_keep_their_new_lines(path: Path) -> None:
    """The re-parse of fmt's output reuses the nodes of items with unchanged tokens (ItemMemo);
    the suppression check must then see each statement on its line in the output, as a full
    parse of the output gives it."""
    from mtlc.syntax.parser import ItemMemo

    text = path.read_text(encoding="utf-8")
    memo = ItemMemo()
    parse_module(text, "x.mtask", DiagnosticSink(), memo=memo)
    once = _formatted(text)
    memo.recording = False
    after = parse_module(once, "x.mtask", DiagnosticSink(), memo=memo)
    assert memo.reused  # the check above has something to check
    plain = parse_module(once, "x.mtask", DiagnosticSink())
    assert fmt._anchor_lines(after, memo) == fmt._anchor_lines(plain)
    assert fmt.same_tree(after, plain)
