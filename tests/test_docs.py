"""The docs say what the code does: their examples check as claimed, every code has a page."""

from __future__ import annotations

import json
import os
import re
from pathlib import Path

import pytest
from conftest import ROOT

from mtlc.diagnostics import CODES
from mtlc.frontend import run_frontend

DOCS = ROOT / "docs"
BLOCK = re.compile(r"^```mtask\n(.*?)^```", re.M | re.S)
FMT_CODES = {"MT0109"}


def _blocks(page: Path) -> list[str]:
    return BLOCK.findall(page.read_text(encoding="utf-8"))


def _codes(tmp_path: Path, text: str) -> list[str]:
    path = tmp_path / "example.mtask"
    path.write_text(text, encoding="utf-8")
    return [d.code for d in run_frontend([path]).diagnostics]


def test_every_code_has_a_page_and_every_page_a_code() -> None:
    pages = {p.stem for p in (DOCS / "diagnostics").glob("MT*.md")}
    assert pages == set(CODES)


def test_index_lists_every_code() -> None:
    index = (DOCS / "diagnostics.md").read_text(encoding="utf-8")
    missing = [c for c in CODES if c not in index]
    assert missing == []


@pytest.mark.parametrize("code", sorted(CODES))
def test_diagnostic_page_example_triggers_its_code(code: str, tmp_path: Path) -> None:
    page = DOCS / "diagnostics" / f"{code}.md"
    text = page.read_text(encoding="utf-8")
    assert text.startswith(f"# {code}")
    for block in _blocks(page):
        if code in FMT_CODES:  # found by `mtlc fmt`, not by checking
            from mtlc.fmt import format_source

            found = [d.code for d in format_source(block, "example.mtask").diagnostics]
        else:
            found = _codes(tmp_path, block)
        assert code in found, block


@pytest.mark.parametrize("name", ["language.md", "tutorial.md", "stdlib.md"])
def test_guide_examples_check_clean_unless_marked(name: str, tmp_path: Path) -> None:
    page = DOCS / name
    blocks = _blocks(page)
    assert blocks or name == "stdlib.md"
    for block in blocks:
        codes = _codes(tmp_path, block)
        if "# error" in block:
            assert codes, f"an example marked `# error` in {name} checks clean:\n{block}"
        else:
            errors = [c for c in codes if CODES[c].severity == "error"]
            assert errors == [], f"example in {name} fails with {errors}:\n{block}"


def test_tutorial_compile_writes_what_it_says(tmp_path: Path) -> None:
    """Section 7: the final lamp task compiles to out/replace_lamp.py, blocks naming their line."""
    from mtlc.cli import main

    final = [b for b in _blocks(DOCS / "tutorial.md") if "task replace_lamp" in b][-1]
    src = tmp_path / "replace_lamp.mtask"
    src.write_text(final, encoding="utf-8")
    out = tmp_path / "out"
    assert main(["compile", str(src), "-o", str(out), "--source-map"]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["replace_lamp.py", "replace_lamp.py.map.json"]
    script = (out / "replace_lamp.py").read_text(encoding="utf-8")
    assert "def replace_lamp():" in script and "human.Walk(" in script
    assert re.search(r"# \S*replace_lamp\.mtask:\d+:\d+ replace_lamp > walk_to > travel", script)


def test_the_examples_suppressions_are_explained() -> None:
    """Each example's `# mtlc: ignore[...]` is listed, code for code, in docs/lint.md."""
    lint = (DOCS / "lint.md").read_text(encoding="utf-8")
    for path in sorted((ROOT / "examples").glob("*.mtask")):
        found = re.findall(r"mtlc: ignore\[([^\]]*)\]", path.read_text(encoding="utf-8"))
        codes = sorted(c.strip() for group in found for c in group.split(","))
        row = re.search(rf"^\| `{path.stem}` \| ([^|]*) \|", lint, re.M)
        assert row is not None, f"docs/lint.md does not explain {path.name}'s suppressions"
        assert sorted(c.strip() for c in row.group(1).split(",")) == codes, path.name


# -- the commands shown in the README and the tutorials, run ---------------------------------
#
# Every ```text/```sh block line that starts with `$ ` (or every line of a ```sh block) is a
# command. It runs in a fresh folder holding `examples/` and `stdlib/` of this checkout, after
# the page's latest ```mtask block has been written to each `.mtask` file the command names
# outside them (the tutorial's `replace_lamp.mtask` grows block by block). What the page
# shows after the command is compared with what it prints (stdout and stderr, interleaved),
# with trailing spaces dropped and the folder's path removed. A line `...` in the page stands
# for any lines. Commands that set up the environment are not run: they are listed here.

NOT_RUN = {
    "pip install .": "installs mtlc: the test runs the checkout's own mtlc instead",
    "pip install -e '.[test]'": "installs mtlc and the test tools: already done",
    "python -m pytest -q": "the test suite itself",
}
RUN_PAGES = [
    "README.md",
    *sorted(p.relative_to(ROOT).as_posix() for p in DOCS.glob("tutorial*.md")),
]
FENCE = re.compile(r"^```(\w*)\n(.*?)^```", re.M | re.S)


def _commands(page: str) -> list[tuple[str, str | None, str]]:
    """(command, output shown or None, mtask source current at that point) in page order."""
    found: list[tuple[str, str | None, str]] = []
    source = ""
    for lang, body in FENCE.findall(page):
        if lang == "mtask":
            source = body
        elif lang == "sh":
            found += [(line.strip(), None, source) for line in body.splitlines() if line.strip()]
        elif lang == "json" or (lang == "text" and body.startswith("kind ")):
            found.append((f"<{lang}>", body, source))  # output shown of an earlier command
        elif lang == "text" and body.startswith("$ "):
            chunks = re.split(r"^\$ ", body, flags=re.M)[1:]
            for chunk in chunks:
                command, _, shown = chunk.partition("\n")
                found.append((command.strip(), shown, source))
    return found


def _run(command: str, cwd: Path) -> tuple[int, str]:
    import contextlib
    import io
    import shlex

    from mtlc.cli import main

    words = shlex.split(command)
    target = None
    if ">" in words:
        words, target = words[: words.index(">")], words[words.index(">") + 1]
    assert words[0] == "mtlc", f"a shown command the doc test cannot run: {command}"
    out = io.StringIO()
    err = out if target is None else io.StringIO()
    old = Path.cwd()
    try:
        os.chdir(cwd)
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                code = main(words[1:])
            except SystemExit as exc:  # --version, --help
                code = exc.code if isinstance(exc.code, int) else 0
    finally:
        os.chdir(old)
    if target is not None:
        (cwd / target).write_text(out.getvalue(), encoding="utf-8")
        return code, err.getvalue()
    return code, out.getvalue()


def _matches(shown: list[str], printed: list[str]) -> bool:
    """``shown`` equals ``printed``, a `...` line standing for any lines."""
    if not shown:
        return not printed
    if shown[0] == "...":
        return any(_matches(shown[1:], printed[i:]) for i in range(len(printed) + 1))
    return bool(printed) and shown[0] == printed[0] and _matches(shown[1:], printed[1:])


def _lines(text: str, folder: Path) -> list[str]:
    text = text.replace(str(folder) + os.sep, "").replace(str(folder), ".")
    lines = [line.rstrip() for line in text.splitlines()]
    while lines and not lines[-1]:
        lines.pop()
    return lines


@pytest.mark.parametrize("page", RUN_PAGES)
def test_shown_commands_print_what_the_page_shows(page: str, tmp_path: Path) -> None:
    commands = _commands((ROOT / page).read_text(encoding="utf-8"))
    assert commands, f"{page} shows no command"
    folder = tmp_path / "work"
    folder.mkdir()
    for name in ("examples", "stdlib"):
        (folder / name).symlink_to(ROOT / name, target_is_directory=True)
    written: list[Path] = []  # files the commands wrote with `>`
    for command, shown, source in commands:
        if command in ("<json>", "<text>"):
            assert written and shown is not None, f"{page}: output shown before any command"
            _check_shown_data(command, shown, json.loads(written[-1].read_text("utf-8")), page)
            continue
        if ">" in command:
            written.append(folder / command.rsplit(">", 1)[1].strip())
        for part in command.split("&&"):
            part = part.strip()
            if part in NOT_RUN:
                continue
            for word in part.split():
                if word.endswith(".mtask") and not word.startswith(("examples/", "stdlib/")):
                    (folder / word).write_text(source, encoding="utf-8")
            code, printed = _run(part, folder)
            if shown is None:  # a ```sh block shows no output: it must succeed
                assert code == 0, f"{page}: `{part}` fails (exit {code}):\n{printed}"
                continue
            expected = _lines(shown, folder)
            actual = _lines(printed, folder)
            assert _matches(expected, actual), (
                f"{page}: `{part}` (exit {code}) prints\n"
                + "\n".join(actual)
                + "\n\nbut the page shows\n"
                + "\n".join(expected)
            )
            # lint fails on warnings too (its default --fail-on), the other commands on errors
            failing = ("error", "warning") if part.startswith("mtlc lint") else ("error",)
            assert code == (1 if any(line.startswith(failing) for line in expected) else 0), part

    for quoted in re.findall(r"`(# [^`]*\.mtask:\d+:\d+ [^`]*?)(?:\.\.\.)?`", page_text(page)):
        scripts = "".join(p.read_text("utf-8") for p in folder.glob("out/*.py"))
        assert quoted.strip() in scripts, f"{page} quotes `{quoted}`, not in the compiled script"


def page_text(page: str) -> str:
    return (ROOT / page).read_text(encoding="utf-8")


def _contains(shown: object, actual: object) -> bool:
    """Every key and value ``shown`` is in ``actual`` (the docs may shorten an object)."""
    if isinstance(shown, dict):
        return isinstance(actual, dict) and all(
            k in actual and _contains(v, actual[k]) for k, v in shown.items()
        )
    return shown == actual


def _check_shown_data(kind: str, shown: str, data: list, page: str) -> None:
    """A ```json block shown after `--dump timeline` is part of a timeline or of a primitive;
    a table headed `kind effector start end path` lists the primitives in order."""
    timelines = data if isinstance(data, list) else [data]
    if kind == "<json>":
        value = json.loads(shown)
        candidates = [t for t in timelines] + [p for t in timelines for p in t["primitives"]]
        assert any(_contains(value, c) for c in candidates), (
            f"{page} shows JSON not in the output:\n{shown}"
        )
        return
    rows = [line.split(None, 4) for line in shown.splitlines()[1:] if line.strip()]
    actual = [
        [p["kind"], p["effector"], str(p["start"]), str(p["end"]), p["path"]]
        for t in timelines
        for p in t["primitives"]
    ]
    assert rows == actual, f"{page}: the table of primitives differs from the timeline"


def test_readme_excerpt_is_the_example_as_it_is() -> None:
    """The README's task is said to be an excerpt of the flagship example: it must be one."""
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    (excerpt,) = BLOCK.findall(readme)
    assert "an excerpt" in readme and "examples/remove_access_panel.mtask" in readme

    def code(text: str) -> list[str]:
        return [line.split("  #")[0].rstrip() for line in text.splitlines()]

    example = code((ROOT / "examples" / "remove_access_panel.mtask").read_text(encoding="utf-8"))
    lines = code(excerpt)
    starts = [i for i, line in enumerate(example) if line == lines[0]]
    assert any(example[i : i + len(lines)] == lines for i in starts), excerpt


def test_language_reference_lists_the_grammars_keywords_and_number_pattern() -> None:
    from mtlc.syntax.grammar import lexicon

    text = (DOCS / "language.md").read_text(encoding="utf-8")
    listed = re.search(r"The keywords are: `([^`]*)`", text)
    assert listed is not None
    assert set(listed.group(1).split()) == set(lexicon().keywords)
    number = lexicon().patterns["NUMBER"]
    assert number == r"([0-9]+(\.[0-9]*)?|\.[0-9]+)([eE][+-]?[0-9]+)?"  # as the page writes it
    assert "`([0-9]+(.[0-9]*)? | .[0-9]+) ([eE][+-]?[0-9]+)?`" in text
