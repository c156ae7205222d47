"""Load the grammar once and expose what the tokenizer needs from it."""

from __future__ import annotations

import dataclasses
import json
import os
import re
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import TYPE_CHECKING

from lark import Lark
from lark.lexer import Lexer, PatternStr

if TYPE_CHECKING:
    from mtlc.syntax.builder import AstBuilder

from mtlc.resources import grammar_path


class _TokenListLexer(Lexer):
    """mtlc tokenizes on its own (for recovery and limits); lark only parses the token list."""

    def __init__(self, lexer_conf: object) -> None:
        pass

    def lex(self, data):  # type: ignore[override]
        return iter(data)


@dataclass(frozen=True)
class Lexicon:
    keywords: dict[str, str]  # "goal" -> "GOAL"
    punctuation: dict[str, str]  # "{" -> "LBRACE"
    patterns: dict[str, str]  # "NAME" -> regex


@cache
def parser() -> Lark:
    """The LALR parser with the AST builder inlined; use it through ``parse_tokens``.

    Built on first use: the fast parser (fastparse.py) reads most items without it, so a
    file that parses cleanly never loads the tables (~0.015 s from the cache file)."""
    options = dict(
        parser="lalr",
        lexer=_TokenListLexer,
        start="item",
        maybe_placeholders=True,
        transformer=builder(),
    )
    text = _grammar_text()
    cache = _cache_file(text, "pickle")
    if cache is not None:
        try:
            # building the LALR tables costs ~0.1 s per start, loading them ~0.015 s; lark checks
            # the grammar's hash stored in the file before it trusts it
            return Lark(text, cache=str(cache), **options)
        except Exception:  # an unreadable or stale cache is only a lost optimisation
            pass
    return Lark(text, **options)


@cache
def _grammar_text() -> str:
    return grammar_path().read_text(encoding="utf-8")


def _cache_file(grammar: str, suffix: str) -> Path | None:
    """A per-user cache file (never a shared temp folder: lark unpickles what it finds)."""
    import hashlib

    import lark

    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    folder = Path(base) / "mtlc"
    try:
        folder.mkdir(parents=True, exist_ok=True, mode=0o700)
        if folder.stat().st_uid != os.getuid() or folder.stat().st_mode & 0o022:
            return None  # not ours alone
    except OSError:
        return None
    key = hashlib.sha256(f"{lark.__version__}\n{grammar}".encode()).hexdigest()[:16]
    prefix = "lalr" if suffix == "pickle" else "lexicon"
    return folder / f"{prefix}-{key}.{suffix}"


@cache
def builder() -> AstBuilder:
    """The AST builder: the fast parser calls it directly, lark's parser calls back into it."""
    from mtlc.syntax.builder import AstBuilder

    return AstBuilder()


@cache
def lexicon() -> Lexicon:
    """The grammar's keywords, punctuation and patterns, by terminal name: read from a JSON
    cache file beside the tables' when there is one for this grammar and lark, so that the
    tokenizer does not load the parser (lark names the terminals; the file keeps its order)."""
    cache = _cache_file(_grammar_text(), "json")
    if cache is not None:
        try:
            data = json.loads(cache.read_text(encoding="utf-8"))
            found = Lexicon(data["keywords"], data["punctuation"], data["patterns"])
            if all(
                type(table) is dict and all(type(x) is str for pair in table.items() for x in pair)
                for table in (found.keywords, found.punctuation, found.patterns)
            ):
                return found
        except (OSError, ValueError, KeyError, TypeError):
            pass  # no file yet, or not one we wrote: make it from the parser
    found = _lexicon_of(parser())
    if cache is not None:
        try:
            temporary = cache.with_suffix(f".{os.getpid()}.tmp")
            temporary.write_text(json.dumps(dataclasses.asdict(found)), encoding="utf-8")
            os.replace(temporary, cache)
        except OSError:
            pass
    return found


def _lexicon_of(lark_parser: Lark) -> Lexicon:
    keywords: dict[str, str] = {}
    punctuation: dict[str, str] = {}
    patterns: dict[str, str] = {}
    for term in lark_parser.terminals:
        pattern = term.pattern
        if isinstance(pattern, PatternStr):
            if re.fullmatch(r"[A-Za-z_]\w*", pattern.value):
                keywords[pattern.value] = term.name
            else:
                punctuation[pattern.value] = term.name
        else:
            patterns[term.name] = pattern.value
    return Lexicon(keywords, punctuation, patterns)
