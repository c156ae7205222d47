"""Syntax: tokens, the grammar, the parser with recovery, and the AST."""

from mtlc.syntax.parser import parse_module

__all__ = ["parse_module"]
