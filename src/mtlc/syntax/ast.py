"""The syntax tree: frozen dataclasses, each carrying the span it was parsed from.

Nodes are keyword-only so that adding a field never silently shifts positional arguments.
``Error`` stands in for an expression that could not be built (too deep, bad literal), so the
tree stays well-formed after a reported error.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, TypeVar

from mtlc.diagnostics import Span

_node = dataclass(frozen=True, slots=True, kw_only=True)
_N = TypeVar("_N")


@_node
class Node:
    span: Span


# ---------------------------------------------------------------- expressions


@_node
class Expr(Node):
    # how deeply the expression nests; set by the builder, which refuses very deep ones
    depth: int = field(default=1, compare=False, repr=False)


@_node
class Number(Expr):
    value: float
    is_int: bool
    unit: str | None
    unit_span: Span | None = None


@_node
class String(Expr):
    value: str


@_node
class Name(Expr):
    name: str


@_node
class Attr(Expr):
    obj: Expr
    name: str
    name_span: Span


@_node
class Arg(Node):
    name: str | None
    value: Expr
    name_span: Span | None = None


@_node
class CallExpr(Expr):
    func: Expr
    args: tuple[Arg, ...]


@_node
class Unary(Expr):
    op: str
    operand: Expr


@_node
class Binary(Expr):
    op: str
    left: Expr
    right: Expr


@_node
class Vector(Expr):
    items: tuple[Expr, ...]
    unit: str | None
    unit_span: Span | None = None


@_node
class ListExpr(Expr):
    items: tuple[Expr, ...]


@_node
class Error(Expr):
    pass


# ---------------------------------------------------------------- statements


@_node
class Stmt(Node):
    pass


@_node
class Block(Stmt):
    """A sequence of statements; as a statement of its own, a sequence branch."""

    stmts: tuple[Stmt, ...]


@_node
class Call(Stmt):
    callee: tuple[str, ...]
    callee_span: Span
    args: tuple[Arg, ...]


@_node
class Repeat(Stmt):
    count: Expr
    body: Block


@_node
class ForEach(Stmt):
    var: str
    var_span: Span
    items: Expr
    body: Block


@_node
class Parallel(Stmt):
    body: Block


@_node
class ManikinSetting(Stmt):
    population: str
    population_span: Span
    sex: str
    sex_span: Span
    percentile: str
    percentile_span: Span


@_node
class SceneSetting(Stmt):
    name: str
    name_span: Span


@_node
class ToolSetting(Stmt):
    tool: Expr


@_node
class BudgetSetting(Stmt):
    limit: Expr


@_node
class TimeSetting(Stmt):
    duration: Expr


@_node
class Goal(Stmt):
    effector: Expr
    target: Expr
    approach: Expr | None
    offset: Expr | None
    orient: bool
    over: Expr | None


@_node
class Posture(Stmt):
    kind: str
    kind_span: Span
    args: tuple[Arg, ...]
    over: Expr | None


@_node
class Walk(Stmt):
    mode: str  # "to" a site or "by" a displacement
    target: Expr
    facing: Expr | None
    over: Expr | None


@_node
class Grip(Stmt):
    hand: Expr
    state: str
    state_span: Span
    over: Expr | None


@_node
class Gaze(Stmt):
    target: Expr
    over: Expr | None


@_node
class Still(Stmt):
    over: Expr


# ---------------------------------------------------------------- declarations


@_node
class Decl(Node):
    name: str
    name_span: Span


@_node
class Use(Node):
    module: tuple[str, ...]
    module_span: Span


@_node
class SiteDecl(Decl):
    position: Expr
    normal: Expr | None
    frame: Expr | None


@_node
class NodeSite(Decl):
    """`site NAME = MODEL.NODE`: a site whose position and normal come from a model's node."""

    model: str
    model_span: Span
    node: str
    node_span: Span


@_node
class SitesFrom(Node):
    """`sites from MODEL`: a site for every named marker node of the model."""

    model: str
    model_span: Span


@_node
class ShapeClause(Node):
    """One clause of a model or solid: `at EXPR`, `units WORD`, `opening WORD EXPR` ..."""

    keyword: str
    word: str | None  # units mm, up z, opening round
    word_span: Span | None
    value: Expr | None


@_node
class Shape(Decl):
    """Equipment geometry in a scene: a mesh file (`model`) or a `box`, `cylinder`, `plate`."""

    kind: str  # "model", "box", "cylinder" or "plate"
    file: str | None  # the model's file, as written (relative to the declaring file's folder)
    file_span: Span | None
    clauses: tuple[ShapeClause, ...]

    def clause(self, keyword: str) -> ShapeClause | None:
        """The clause ``keyword`` (the builder reports a clause given twice and keeps the first)."""
        for c in self.clauses:
            if c.keyword == keyword:
                return c
        return None


@_node
class Scene(Decl):
    ground: Expr | None
    sites: tuple[SiteDecl, ...]
    shapes: tuple[Shape, ...] = ()
    node_sites: tuple[NodeSite, ...] = ()
    sites_from: tuple[SitesFrom, ...] = ()


@_node
class ToolProperty(Node):
    name: str
    value: Expr


@_node
class ToolDecl(Decl):
    properties: tuple[ToolProperty, ...]


@_node
class Param(Node):
    name: str
    type_name: str
    type_span: Span
    default: Expr | None


@_node
class Definition(Decl):
    kind: str  # "element" or "action"
    params: tuple[Param, ...]
    body: Block


@_node
class Task(Decl):
    title: str | None
    body: Block


@_node
class Module(Node):
    """One parsed file."""

    path: str
    uses: tuple[Use, ...]
    decls: tuple[Decl, ...]
    # names of items that failed to parse: resolution stays quiet about them
    broken_names: frozenset[str] = frozenset()


def maker(cls: type[_N], *names: str) -> Callable[..., _N]:
    """A function taking the fields ``names`` of ``cls`` by position (the others at their
    defaults) that builds the same node as ``cls(name=value, ...)``, several times faster:
    calling a class with keywords packs them into a dict for ``__init__``, which then sets
    each field with ``object.__setattr__``; this sets the slots directly. For the parser's
    commonest nodes (a node per name, number, argument and call)."""
    fields = {f.name: f for f in dataclasses.fields(cls)}  # type: ignore[arg-type]
    assert set(names) <= set(fields), (cls, names)
    namespace: dict[str, Any] = {"_new": object.__new__, "_cls": cls}
    lines = [f"def make({', '.join(names)}):", "    node = _new(_cls)"]
    for name, f in fields.items():
        namespace[f"_set_{name}"] = getattr(cls, name).__set__
        if name in names:
            value = name
        else:
            assert f.default is not dataclasses.MISSING, (cls, name)  # required: must be given
            namespace[f"_default_{name}"] = f.default
            value = f"_default_{name}"
        lines.append(f"    _set_{name}(node, {value})")
    lines.append("    return node")
    exec("\n".join(lines), namespace)
    make: Callable[..., _N] = namespace["make"]
    make.__qualname__ = make.__name__ = f"make_{cls.__name__}"
    return make
