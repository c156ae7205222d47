"""Text from a task file cannot drive a terminal, reorder a line, run as a spreadsheet formula
or become markup: report (terminal, HTML, CSV), diagnostics and lint text, the preview page."""

from __future__ import annotations

import csv
import io
import math
import re
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from mtlc.diagnostics import DiagnosticSink, Span
from mtlc.diagnostics.render import render_text, terminal_safe
from mtlc.lint.command import main as lint_main
from mtlc.preview.html import render_page
from mtlc.report.command import main
from mtlc.report.csvout import csv_cell

# what a terminal obeys or reorders: C0/C1 controls but the line break, DEL, bidi controls
OBEYED = re.compile(
    "[\x00-\x09\x0b-\x1f\x7f-\x9f\u061c\u200e\u200f\u2028\u2029\u202a-\u202e\u2066-\u2069]"
)
HOSTILE_TITLE = r"Evil \u{1b}[31mRED\u{1b}]0;pwned\u{7} \u{202e}gnp.exe \u{0}\u{9b}2J =1+1"
HOSTILE = f"""use stdlib.actions

scene s {{
    ground 0 cm
    site a at (0, 100, 40) cm
}}

task t1 "{HOSTILE_TITLE}" {{
    manikin gb10000_1988 male p50
    scene s
    walk_to(a)
}}
"""  # fmt: skip


@pytest.fixture
def hostile(tmp_path: Path) -> Path:
    path = tmp_path / "evil\x1b[2J\u202e.mtask"
    path.write_text(HOSTILE, encoding="utf-8")
    return path


def test_report_shows_control_and_bidi_characters_as_escapes(
    hostile: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    html, table = tmp_path / "r.html", tmp_path / "r.csv"
    args = [
        str(hostile),
        "--manikins",
        "gb10000_1988:male:50",
        "-o",
        str(html),
        "--csv",
        str(table),
    ]
    assert main(args) == 0
    out, err = capsys.readouterr()
    assert not OBEYED.search(out.replace("\n", "")) and not OBEYED.search(err.replace("\n", ""))
    assert r"Evil \u{1b}[31mRED" in out and r"\u{202e}gnp.exe \u{0}\u{9b}2J" in out
    page = html.read_text(encoding="utf-8")
    assert not OBEYED.search(page.replace("\n", ""))
    assert r"\u{202e}gnp.exe" in page
    for row in csv.reader(io.StringIO(table.read_text(encoding="utf-8"))):
        for cell in row:
            assert not cell.startswith(("=", "+", "@", "\t", "\r")) or cell.startswith("'")


@given(st.text(max_size=40))
def test_terminal_safe_leaves_nothing_to_obey_and_keeps_the_rest(text: str) -> None:
    safe = terminal_safe(text)
    assert not OBEYED.search(safe) and "\n" not in safe
    if not OBEYED.search(text) and "\n" not in text:
        assert safe == text  # Chinese, emoji, accents: unchanged


@given(st.text(max_size=20), st.text(max_size=20), st.text(max_size=40))
def test_a_rendered_diagnostic_has_nothing_to_obey(message: str, file: str, line: str) -> None:
    sink = DiagnosticSink()
    sink.report("MT0201", message, Span(file, 1, 1, 1, 2), help=f"help {message}")
    text = render_text(sink.items, {file: line + "\nrest"})
    assert not OBEYED.search(text)


@pytest.mark.parametrize(
    ("cell", "shown"),
    [
        ('=HYPERLINK("http://x")', '\'=HYPERLINK("http://x")'),
        ("+1+cmd|' /C calc'!A0", "'+1+cmd|' /C calc'!A0"),
        ("-2+3", "'-2+3"),
        ("@SUM(A1)", "'@SUM(A1)"),
        ("\tx", "'\tx"),
        ("\rx", "'\rx"),
        ("-0.500", "-0.500"),
        ("+3", "+3"),
        ("-inf", "'-inf"),
        ("12.5", "12.5"),
        ("task_1", "task_1"),
        ("", ""),
    ],
)
def test_csv_cells_that_would_be_formulas_get_an_apostrophe(cell: str, shown: str) -> None:
    assert csv_cell(cell) == shown


@given(st.text(max_size=20))
def test_csv_cell_is_never_a_formula_and_only_adds_an_apostrophe(text: str) -> None:
    cell = csv_cell(text)
    assert cell in (text, "'" + text)
    if cell.startswith(("=", "+", "-", "@", "\t", "\r")):
        assert math.isfinite(float(cell))


def test_lint_text_shows_escapes(hostile: Path, capsys: pytest.CaptureFixture[str]) -> None:
    hostile.write_text(HOSTILE.replace("walk_to(a)", "walk_to(nowhere)"), encoding="utf-8")
    assert lint_main([str(hostile), "--manikins", "gb10000_1988:male:50"]) == 1
    out, err = capsys.readouterr()
    assert not OBEYED.search((out + err).replace("\n", ""))
    assert r"\u{1b}[2J" in out + err  # the file's name, in every location line


def test_the_preview_title_has_nothing_to_obey() -> None:
    page = render_page(None, title="a\u202egnp.exe\x1b[2J</title>")
    head = page.split("</title>", 1)[0]
    assert r"a\u{202e}gnp.exe\u{1b}[2J&lt;/title&gt;" in head


def test_lint_github_annotations_show_escapes() -> None:
    from mtlc.lint.engine import LintResult
    from mtlc.lint.findings import Finding
    from mtlc.lint.output import render_github

    finding = Finding("MT0201", "title \x1b[2J\u202e\nsecond line", Span("t.mtask", 1, 1, 1, 2))
    result = LintResult([finding], {}, [Path("t.mtask")], ())
    out = render_github(result, Path.cwd())
    assert out.endswith(r"::title \u{1b}[2J\u{202e}%0Asecond line" + "\n")
