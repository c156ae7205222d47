"""The docs say what the code does: their examples check as claimed, every code has a page."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from conftest import ROOT

from mtlc.diagnostics import CODES
from mtlc.frontend import run_frontend

DOCS = ROOT / "docs"
BLOCK = re.compile(r"^```mtask\n(.*?)^```", re.M | re.S)


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
        assert code in _codes(tmp_path, block), block


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
