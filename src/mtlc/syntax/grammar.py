"""Load the grammar once and expose what the tokenizer needs from it."""

from __future__ import annotations

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
    """The LALR parser with the AST builder inlined; use it through ``parse_tokens``."""
    from mtlc.syntax.builder import AstBuilder

    options = dict(
        parser="lalr",
        lexer=_TokenListLexer,
        start="item",
        maybe_placeholders=True,
        transformer=AstBuilder(),
    )
    text = grammar_path().read_text(encoding="utf-8")
    cache = _cache_file(text)
    if cache is not None:
        try:
            # building the LALR tables costs ~0.1 s per start, loading them ~0.015 s; lark checks
            # the grammar's hash stored in the file before it trusts it
            return Lark(text, cache=str(cache), **options)
        except Exception:  # an unreadable or stale cache is only a lost optimisation
            pass
    return Lark(text, **options)


def _cache_file(grammar: str) -> Path | None:
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
    return folder / f"lalr-{key}.pickle"


def builder() -> AstBuilder:
    """The AST builder the cached parser calls back into."""
    return parser().options.transformer


@cache
def lexicon() -> Lexicon:
    keywords: dict[str, str] = {}
    punctuation: dict[str, str] = {}
    patterns: dict[str, str] = {}
    for term in parser().terminals:
        pattern = term.pattern
        if isinstance(pattern, PatternStr):
            if re.fullmatch(r"[A-Za-z_]\w*", pattern.value):
                keywords[pattern.value] = term.name
            else:
                punctuation[pattern.value] = term.name
        else:
            patterns[term.name] = pattern.value
    return Lexicon(keywords, punctuation, patterns)
