"""A stable, readable JSON form of the AST, for golden tests and `mtlc check --dump ast`."""

from __future__ import annotations

import dataclasses
import json
from typing import Any

from mtlc.diagnostics import Span
from mtlc.syntax import ast


def to_data(node: Any) -> Any:
    if isinstance(node, Span):
        return f"{node.line}:{node.column}-{node.end_line}:{node.end_column}"
    if isinstance(node, ast.Node):
        out: dict[str, Any] = {"node": type(node).__name__}
        for f in dataclasses.fields(node):
            value = getattr(node, f.name)
            if f.name in ("path", "depth"):
                continue
            if value is None or value == () or value == frozenset():
                continue
            out[f.name] = to_data(value)
        return out
    if isinstance(node, tuple | list):
        return [to_data(x) for x in node]
    if isinstance(node, frozenset):
        return sorted(node)
    return node


def dump_module(module: ast.Module) -> str:
    return json.dumps(to_data(module), indent=1, ensure_ascii=False) + "\n"
