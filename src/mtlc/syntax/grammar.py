"""Load the grammar once and expose what the tokenizer needs from it."""

from __future__ import annotations

import re
from dataclasses import dataclass
from functools import cache

from lark import Lark
from lark.lexer import Lexer, PatternStr

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
    try:
        # lark keys its table cache (in the temp folder) on the grammar and options: building the
        # LALR tables costs ~0.1 s per start, loading them ~0.015 s
        return Lark(text, cache=True, **options)
    except OSError:
        return Lark(text, **options)


def builder():  # type: ignore[no-untyped-def]
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
