"""The syntax tree: frozen dataclasses, each carrying the span it was parsed from.

Nodes are keyword-only so that adding a field never silently shifts positional arguments.
``Error`` stands in for an expression that could not be built (too deep, bad literal), so the
tree stays well-formed after a reported error.
"""

from __future__ import annotations

import dataclasses
import sys
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, TypeVar

from mtlc.diagnostics import Span

_N = TypeVar("_N")
_dataclass_node = dataclass(frozen=True, slots=True, kw_only=True)  # what ``_node`` makes


def _node(cls: type[_N]) -> type[_N]:
    """``@dataclass(frozen=True, slots=True, kw_only=True)``, made with one ``exec`` per class.

    Why: dataclasses compiles each generated method on its own (six per class here) and
    reads the class's signature back for its docstring: 0.024 s of CPU for the 44 node classes,
    on every command that parses (`mtlc check` starts in 0.15 s). This makes the same class:
    the same fields (``dataclasses.fields``, ``replace``), methods (the same source), slots,
    ``__match_args__``, docstring and parameters; tests/test_ast_nodes.py compares
    every node class with the one ``_dataclass_node`` makes. On another Python than 3.11,
    whose dataclasses write other bodies, it is ``_dataclass_node`` itself.
    """
    if sys.version_info[:2] != (3, 11):  # what follows is Python 3.11's dataclasses
        return _dataclass_node(cls)
    own = cls.__dict__.get("__annotations__", {})  # noqa: RUF063 - as dataclasses reads them
    fields: dict[str, dataclasses.Field[Any]] = {}
    for base in cls.__mro__[-1:0:-1]:
        fields.update(getattr(base, "__dataclass_fields__", {}))
    for name, type_ in own.items():
        default = cls.__dict__.get(name, dataclasses.MISSING)
        f = default if isinstance(default, dataclasses.Field) else field(default=default)
        f.name, f.type, f._field_type = name, type_, dataclasses._FIELD  # type: ignore[attr-defined]
        if f.kw_only is dataclasses.MISSING:
            f.kw_only = True
        assert type(type_) is str and not type_.startswith(("ClassVar", "InitVar", "KW_ONLY"))
        assert f.default_factory is dataclasses.MISSING and f.default.__class__.__hash__
        fields[name] = f
    every = list(fields.values())
    namespace: dict[str, Any] = {
        "cls": cls,
        "FrozenInstanceError": dataclasses.FrozenInstanceError,
        "__dataclass_builtins_object__": object,
        **{f"__dataclass_dflt_{f.name}__": f.default for f in every},
    }
    names = "(" + "".join(f"{f.name!r}," for f in every) + ")"

    def each(owner: str, chosen: list[dataclasses.Field[Any]]) -> str:
        return "(" + "".join(f"{owner}.{f.name}," for f in chosen) + ")"

    compared = [f for f in every if f.compare]
    hashed = [f for f in every if (f.compare if f.hash is None else f.hash)]
    params = ", ".join(
        f.name if f.default is dataclasses.MISSING else f"{f.name}=__dataclass_dflt_{f.name}__"
        for f in every
    )
    shown = ", ".join(f"{f.name}={{self.{f.name}!r}}" for f in every if f.repr)
    assigns = "".join(
        f"\n    __dataclass_builtins_object__.__setattr__(self,{f.name!r},{f.name})" for f in every
    )
    exec(  # the bodies dataclasses writes for these options (Python 3.11)
        f"def __init__(self, *, {params}) -> None:{assigns or chr(10) + '    pass'}\n"
        f"def __repr__(self):\n"
        f'    return self.__class__.__qualname__ + f"({shown})"\n'
        f"def __eq__(self, other):\n"
        f"    if other.__class__ is self.__class__:\n"
        f"        return {each('self', compared)}=={each('other', compared)}\n"
        f"    return NotImplemented\n"
        f"def __setattr__(self, name, value):\n"
        f"    if type(self) is cls or name in {names}:\n"
        f'        raise FrozenInstanceError(f"cannot assign to field {{name!r}}")\n'
        f"    super(cls, self).__setattr__(name, value)\n"
        f"def __delattr__(self, name):\n"
        f"    if type(self) is cls or name in {names}:\n"
        f'        raise FrozenInstanceError(f"cannot delete field {{name!r}}")\n'
        f"    super(cls, self).__delattr__(name)\n"
        f"def __hash__(self):\n"
        f"    return hash({each('self', hashed)})\n",
        namespace,
    )
    body = dict(cls.__dict__)
    namespace["__init__"].__annotations__ = {f.name: f.type for f in every} | {"return": None}
    namespace["__repr__"] = dataclasses._recursive_repr(namespace["__repr__"])  # type: ignore[attr-defined]
    for method in ("__init__", "__repr__", "__eq__", "__setattr__", "__delattr__", "__hash__"):
        namespace[method].__qualname__ = f"{cls.__qualname__}.{method}"
        body[method] = namespace[method]
    signature = ", ".join(
        f"{f.name}: {f.type!r}" + ("" if f.default is dataclasses.MISSING else f" = {f.default!r}")
        for f in every
    )
    inherited = {slot for base in cls.__mro__[1:-1] for slot in base.__dict__.get("__slots__", ())}
    body.update(
        __dataclass_params__=dataclasses._DataclassParams(True, True, True, False, False, True),  # type: ignore[attr-defined]
        __dataclass_fields__=fields,
        __doc__=cls.__doc__ or f"{cls.__name__}(*, {signature})",
        __match_args__=(),
        __slots__=tuple(f.name for f in every if f.name not in inherited),
    )
    for name in (*fields, "__dict__", "__weakref__"):
        body.pop(name, None)
    made = type(cls)(cls.__name__, cls.__bases__, body)
    made.__qualname__ = cls.__qualname__
    made.__getstate__ = dataclasses._dataclass_getstate  # type: ignore[attr-defined]
    made.__setstate__ = dataclasses._dataclass_setstate  # type: ignore[attr-defined]
    return made


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
