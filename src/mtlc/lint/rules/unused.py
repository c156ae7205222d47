"""MT0601 unused definitions and MT0602 unused parameters, from the checker's resolutions.

A definition counts as unused only in a procedure file (one that defines a task): a library's
definitions are there for other files to use. A parameter whose name starts with `_` is
deliberately unused.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from typing import Any

from mtlc.diagnostics import Span
from mtlc.frontend import Program
from mtlc.lint.findings import Finding
from mtlc.syntax import ast


def walk(node: Any) -> Iterator[Any]:
    """Every AST node under ``node`` (itself included), depth first."""
    if isinstance(node, tuple | list):
        for item in node:
            yield from walk(item)
        return
    if not isinstance(node, ast.Node):
        return
    yield node
    for f in dataclasses.fields(node):
        value = getattr(node, f.name)
        if isinstance(value, ast.Node | tuple | list):
            yield from walk(value)


def _used_decls(program: Program) -> tuple[set[int], set[str]]:
    """Ids of called definitions, and names used as scenes or tools."""
    assert program.checker is not None
    called = {id(sym.decl) for sym in program.checker.callees.values()}
    resolved = program.checker.resolved
    names: set[str] = set()
    for module in program.modules:
        for node in walk(module.tree.decls):
            scene = isinstance(node, ast.SceneSetting)
            if scene or (
                isinstance(node, ast.Name) and resolved.get(node.span) in ("scene", "tool")
            ):
                names.add(node.name)
    return called, names


def unused_definitions(program: Program) -> list[Finding]:
    if program.checker is None:
        return []
    called, names = _used_decls(program)
    out = []
    for module in program.roots:
        decls = module.tree.decls
        if not any(isinstance(d, ast.Task) for d in decls):
            continue
        for d in decls:
            if isinstance(d, ast.Definition):
                used = id(d) in called
            elif isinstance(d, ast.Scene | ast.ToolDecl):
                used = d.name in names
            else:
                continue
            if not used:
                kind = d.kind if isinstance(d, ast.Definition) else type(d).__name__.lower()
                kind = "tool" if kind == "tooldecl" else kind
                out.append(
                    Finding(
                        "MT0601",
                        f"{kind} `{d.name}` is never used",
                        d.name_span,
                        help="remove it, or use it from a task; a library file (no task) "
                        "is not checked for this",
                    )
                )
    return out


def unused_parameters(program: Program) -> list[Finding]:
    if program.checker is None:
        return []
    resolved = program.checker.resolved
    out = []
    for module in program.roots:
        for d in module.tree.decls:
            if not isinstance(d, ast.Definition):
                continue
            read = {
                n.name
                for n in walk(d.body)
                if isinstance(n, ast.Name) and resolved.get(n.span) == "local"
            }
            for p in d.params:
                if p.name in read or p.name.startswith("_"):
                    continue
                span = Span(
                    p.span.file,
                    p.span.line,
                    p.span.column,
                    p.span.line,
                    p.span.column + len(p.name),
                    p.span.start,
                    p.span.start + len(p.name),
                )
                out.append(
                    Finding(
                        "MT0602",
                        f"parameter `{p.name}` of {d.kind} `{d.name}` is never used",
                        span,
                        help=f"remove it, or rename it `_{p.name}` if callers must still pass it",
                    )
                )
    return out
