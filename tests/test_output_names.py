"""Text from a task file reaches file names and generated code only in a safe form: output
names have no newline, U+2028 or U+202E (a documented percent-encoding, collisions refused),
and no title or file name escapes from JackScript's string literals and comments."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from mtlc.cli import main
from mtlc.output import safe_file_name

UNSAFE = re.compile(
    "[\x00-\x1f\x7f-\x9f/\\\\\u061c\u200e\u200f\u2028\u2029\u202a-\u202e\u2066-\u2069]"
)

TASK = """use stdlib.actions

scene s {{
    ground 0 cm
    site button at (0, 100, 60) cm normal (0, 0, -1)
}}

task press_it "{title}" {{
    manikin gb10000_1988 female p50
    scene s
    press(right, button)
}}
"""

HOSTILE_TITLE = (
    r"x'''\"\"\" \\ \n \u{2028}\u{2029}\u{85} \u{202e} \u{0}\u{1b} \"); import os; "
    r"os.system(\"rm -rf /\"); #"
)


@pytest.mark.parametrize(
    ("name", "safe"),
    [
        ("a\nb.t.bvh", "a%0Ab.t.bvh"),
        ("a\u2028b.t.bvh", "a%E2%80%A8b.t.bvh"),
        ("\u202egnp.exe.t.bvh", "%E2%80%AEgnp.exe.t.bvh"),
        ("a/b\\c.t.ir.json", "a%2Fb%5Cc.t.ir.json"),
        ("螺栓.拆卸.bvh", "螺栓.拆卸.bvh"),
        ("plain 100%.t.bvh", "plain 100%.t.bvh"),
    ],
)
def test_safe_file_names(name: str, safe: str) -> None:
    assert safe_file_name(name) == safe


@given(st.text(max_size=30))
def test_a_safe_name_has_nothing_unsafe_and_keeps_safe_names(name: str) -> None:
    safe = safe_file_name(name)
    assert not UNSAFE.search(safe)
    if not UNSAFE.search(name):
        assert safe == name


def test_compile_writes_safe_names_and_prints_them_safely(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    src = tmp_path / "panel\n\u2028\u202eexe.mtask"
    src.write_text(TASK.format(title="t"), encoding="utf-8")
    out = tmp_path / "out"
    assert main(["compile", str(src), "--target", "timeline", "-o", str(out)]) == 0
    names = sorted(p.name for p in out.iterdir())
    assert names == ["panel%0A%E2%80%A8%E2%80%AEexe.press_it.timeline.json"]
    printed = capsys.readouterr().out
    assert not UNSAFE.search(printed.replace("\n", "").replace("/", ""))


def test_names_that_become_equal_are_refused_and_nothing_is_written(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    for folder, name in (("a", "p\n.mtask"), ("b", "p%0A.mtask")):
        (tmp_path / folder).mkdir()
        (tmp_path / folder / name).write_text(TASK.format(title="t"), encoding="utf-8")
    out = tmp_path / "out"
    files = [str(tmp_path / "a" / "p\n.mtask"), str(tmp_path / "b" / "p%0A.mtask")]
    assert main(["compile", *files, "--target", "timeline", "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert "two outputs would both be written to" in err and "p%0A.press_it" in err
    assert not UNSAFE.search(err.replace("\n", "").replace("/", ""))
    assert not out.exists()


def _without_strings(tree: ast.AST) -> str:
    """The module's code with every string constant blanked: what the script does."""
    for node in ast.walk(tree):
        if isinstance(node, ast.Constant) and isinstance(node.value, str):
            node.value = ""
    return ast.dump(tree)


def test_hostile_titles_and_file_names_stay_inside_jackscript_strings_and_comments(
    tmp_path: Path,
) -> None:
    """The same task with a plain and a hostile title (quotes, triple quotes, backslashes,
    newlines, U+2028/U+2029/U+0085, U+202E, NUL, ESC, an injected statement) in a file whose
    name is hostile too: both scripts are printable ASCII and have the same code once their
    string literals are blanked, and the title reads back exactly from a literal."""
    plain = tmp_path / "plain.mtask"
    plain.write_text(TASK.format(title="plain"), encoding="utf-8")
    hostile = tmp_path / 'h\'"""\\\n\u2028\u202e.mtask'
    hostile.write_text(TASK.format(title=HOSTILE_TITLE), encoding="utf-8")
    out = tmp_path / "out"
    args = ["compile", str(plain), str(hostile), "--fps", "10", "--source-map", "-o", str(out)]
    assert main(args) == 0
    scripts = {p.name: p.read_text(encoding="utf-8") for p in out.glob("*.py")}
    assert len(scripts) == 2
    trees = {}
    for name, text in scripts.items():
        assert all(" " <= ch <= "~" for ch in text.replace("\n", "")), name
        trees[name] = ast.parse(text)
    (hostile_name,) = [n for n in scripts if n != "plain.py"]
    title = (
        'x\'\'\'""" \\ \n \u2028\u2029\x85 \u202e \x00\x1b "); import os; os.system("rm -rf /"); #'
    )
    assert "plain" in _constants(trees["plain.py"])  # the title is a string literal
    assert title in _constants(trees[hostile_name])  # ... read back exactly
    assert _without_strings(trees["plain.py"]) == _without_strings(trees[hostile_name])


def _constants(tree: ast.AST) -> set[str]:
    return {
        n.value for n in ast.walk(tree) if isinstance(n, ast.Constant) and isinstance(n.value, str)
    }
