"""The tokenizer's lexicon comes from a JSON file beside lark's tables (so lark's tables load
only when an item needs them): it must be the lexicon lark's grammar gives, in the same order,
and a missing or damaged file must be made again from the parser."""

from __future__ import annotations

from pathlib import Path

import pytest

from mtlc.syntax import grammar


def _ordered(lexicon: grammar.Lexicon) -> list[list[tuple[str, str]]]:
    return [list(t.items()) for t in (lexicon.keywords, lexicon.punctuation, lexicon.patterns)]


def test_the_cached_lexicon_is_the_parsers(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    expected = grammar._lexicon_of(grammar.parser())
    made = grammar.lexicon.__wrapped__()  # no file yet: from the parser, then written
    files = list((tmp_path / "mtlc").glob("lexicon-*.json"))
    assert len(files) == 1
    read = grammar.lexicon.__wrapped__()  # from the file
    assert _ordered(made) == _ordered(read) == _ordered(expected)
    assert "GOAL" in read.keywords.values() and read.punctuation["("] == "LPAR"


@pytest.mark.parametrize("damage", ["{not json", '{"keywords": [1]}', '{"keywords": {"a": 1}}'])
def test_a_damaged_file_is_made_again(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, damage: str
) -> None:
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    grammar.lexicon.__wrapped__()
    (file,) = (tmp_path / "mtlc").glob("lexicon-*.json")
    file.write_text(damage, encoding="utf-8")
    assert _ordered(grammar.lexicon.__wrapped__()) == _ordered(grammar.lexicon())
    assert file.read_text(encoding="utf-8") != damage
