"""Check every definition: names, types, units, calls, where statements may stand, recursion.

Definitions are checked once, with their parameters' declared types, whether or not a task uses
them, so a mistake in a library is found where it is written. An expression already reported as
wrong has type UNKNOWN, which is accepted everywhere so that one mistake gives one diagnostic.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from mtlc.diagnostics import DiagnosticSink, Label, Span
from mtlc.diagnostics.suggest import did_you_mean, suggest
from mtlc.semantics import builtins as B
from mtlc.semantics import types as T
from mtlc.semantics import values as V
from mtlc.semantics.mtm import other_codes
from mtlc.semantics.scopes import Scope, Symbol
from mtlc.syntax import ast

if TYPE_CHECKING:
    from mtlc.geometry.load import MeshFile

# which level may call which
CALLABLE_FROM = {
    "task": ("action", "element"),
    "action": ("action", "element"),
    "element": ("element",),
}
PRIMITIVES = (ast.Goal, ast.Posture, ast.Walk, ast.Grip, ast.Gaze, ast.Still, ast.TimeSetting)
TASK_SETTINGS = (ast.ManikinSetting, ast.SceneSetting, ast.ToolSetting, ast.BudgetSetting)
POSITION = T.VectorType(T.LENGTH_DIM)
DIRECTION = T.VectorType(T.NONE_DIM)
ORIENTATION = T.VectorType(T.ANGLE_DIM)
OPENING_RECT = T.VectorType(T.LENGTH_DIM, 2)
# what each clause of a model or solid holds: (type, what it is called, range)
SHAPE_VALUES: dict[str, tuple[T.Type, str, V.Range | None]] = {
    "at": (POSITION, "a position", V.POSITION),
    "rotate": (ORIENTATION, "a rotation (X, Y, Z angles)", V.FRAME),
    "size": (POSITION, "a size (x, y, z)", V.SOLID_SIZE),
    "radius": (T.LENGTH, "a radius", V.SOLID_SIZE),
    "length": (T.LENGTH, "a length", V.SOLID_SIZE),
    "axis": (DIRECTION, "an axis", V.AXIS),
    "normal": (DIRECTION, "a normal", V.NORMAL),
}
UP_WORDS = ("x", "y", "z")
TOOL_RANGES = {
    "length": V.TOOL_LENGTH,
    "mass": V.TOOL_MASS,
    "grip": V.TOOL_POINT,
    "tip": V.TOOL_POINT,
    "axis": V.TOOL_AXIS,
}
INT_HELP = "whole numbers count things (repeats, turns, knees): write a smaller one"
_UNIT_TYPES = {unit: T.Quantity(dim) for unit, (dim, _) in T.UNITS.items()}  # built once
REPEAT_COUNT = V.Range(
    "a repeat count", "", 0, None, help="repeat a block 0 or more times; 0 runs nothing"
)


@dataclass
class CallEdge:
    caller: ast.Definition
    callee: Symbol
    span: Span


@dataclass
class Env:
    scope: Scope
    level: str  # task, action, element
    locals: dict[str, T.Type] = field(default_factory=dict)
    scene: Symbol | None = None


class Checker:
    def __init__(self, sink: DiagnosticSink) -> None:
        self.sink = sink
        self.edges: list[CallEdge] = []
        # how each name was resolved ("local", "site", "enum", "tool", "scene"), by its span:
        # expansion evaluates names exactly as they were checked
        self.resolved: dict[Span, str] = {}
        self.callees: dict[Span, Symbol] = {}  # each call statement's definition, by callee span
        self._current: ast.Definition | None = None
        self._site_names: dict[int, frozenset[str]] = {}  # by id of the scene declaration
        # each model's file as read (None: it could not be, and that was reported), by id of
        # its declaration: expansion places them
        self.meshes: dict[int, MeshFile | None] = {}
        self.model_files: list[Path] = []  # every model file named, read or not (serve watches)
        # each definition's parameters as check_args takes them, by id of the declaration
        # (worked out once, not per call: the trees live as long as the checker)
        self._signatures: dict[int, list[tuple[str, T.Type, bool]]] = {}

    # ------------------------------------------------------------ declarations
    def check_module(self, scope: Scope) -> None:
        for decl in scope.module.tree.decls:
            if scope.own.get(decl.name) is None or scope.own[decl.name].decl is not decl:
                continue  # a duplicate, already reported
            if isinstance(decl, ast.Scene):
                self.check_scene(decl, scope)
            elif isinstance(decl, ast.ToolDecl):
                self.check_tool(decl, scope)
            elif isinstance(decl, ast.Definition):
                self.check_definition(decl, scope)
            elif isinstance(decl, ast.Task):
                self.check_task(decl, scope)

    def check_scene(self, scene: ast.Scene, scope: Scope) -> None:
        env = Env(scope, "scene")
        if scene.ground is not None:
            self.expect_in(scene.ground, T.LENGTH, env, V.GROUND)
        seen: dict[str, ast.SiteDecl] = {}
        for site in scene.sites:
            if site.name in seen:
                self._twice(site.name, scene, site.name_span, seen[site.name].name_span)
            seen.setdefault(site.name, site)
            self.expect_vector_in(site.position, POSITION, env, "a site's position", V.POSITION)
            if site.normal is not None:
                self.expect_vector_in(site.normal, DIRECTION, env, "a normal", V.NORMAL)
            if site.frame is not None:
                what = "a frame (X, Y, Z rotations)"
                self.expect_vector_in(site.frame, ORIENTATION, env, what, V.FRAME)
        self.check_geometry(scene, env, seen)

    # ------------------------------------------------------------ models and solids
    def check_geometry(self, scene: ast.Scene, env: Env, sites: dict[str, ast.SiteDecl]) -> None:
        """Models and solids (types, units, files), and the sites taken from their nodes."""
        shapes: dict[str, ast.Shape] = {}
        for shape in scene.shapes:
            if shape.name in shapes:
                first = shapes[shape.name].name_span
                self._twice(shape.name, scene, shape.name_span, first, what="")
                continue
            shapes[shape.name] = shape
            self.check_shape(shape, env)
        taken: dict[str, Span] = {name: site.name_span for name, site in sites.items()}
        for node_site in scene.node_sites:
            if node_site.name in taken:
                self._twice(node_site.name, scene, node_site.name_span, taken[node_site.name])
                continue
            taken[node_site.name] = node_site.name_span
            shape = shapes.get(node_site.model)
            if shape is None:
                self.sink.report(
                    "MT0201",
                    f"scene `{scene.name}` has no model `{node_site.model}`",
                    node_site.model_span,
                    help=did_you_mean(node_site.model, list(shapes)),
                )
                continue
            nodes = self.node_names(shape)
            if nodes is not None and node_site.node not in nodes:
                self.sink.report(
                    "MT0211",
                    f"{shape.kind} `{shape.name}` has no node `{node_site.node}`",
                    node_site.node_span,
                    help=did_you_mean(node_site.node, sorted(nodes))
                    or (
                        "a solid has no nodes: write the site's position with `at`"
                        if shape.kind != "model"
                        else "the model's named nodes become sites"
                    ),
                )
        for item in scene.sites_from:
            shape = shapes.get(item.model)
            if shape is None or shape.kind != "model":
                self.sink.report(
                    "MT0201",
                    f"scene `{scene.name}` has no model `{item.model}`",
                    item.model_span,
                    help=did_you_mean(
                        item.model, [s.name for s in shapes.values() if s.kind == "model"]
                    ),
                )
                continue
            for name in self.marker_sites(shape):
                if name in taken:
                    self._twice(name, scene, item.span, taken[name])
                else:
                    taken[name] = item.span

    def _twice(
        self, name: str, scene: ast.Scene, span: Span, first: Span, what: str = "site "
    ) -> None:
        """MT0202: a scene's site (or, with ``what=""``, model or solid) named twice."""
        self.sink.report(
            "MT0202",
            f"{what}`{name}` is defined twice in scene `{scene.name}`",
            span,
            labels=(Label(first, "first defined here"),),
        )

    def check_shape(self, shape: ast.Shape, env: Env) -> None:
        for clause in shape.clauses:
            if clause.keyword in SHAPE_VALUES and clause.value is not None:
                expected, what, rule = SHAPE_VALUES[clause.keyword]
                if isinstance(expected, T.VectorType):
                    self.expect_vector_in(clause.value, expected, env, what, rule)
                else:
                    self.expect_in(clause.value, expected, env, rule)
            elif clause.keyword == "units" and clause.word is not None:
                found = T.UNITS.get(clause.word)
                if found is None or found[0] != T.LENGTH_DIM:
                    lengths = [u for u, (d, _) in T.UNITS.items() if d == T.LENGTH_DIM]
                    self.sink.report(
                        "MT0303",
                        f"`{clause.word}` is not a unit of length",
                        clause.word_span or clause.span,
                        help="a model's units are one of " + ", ".join(f"`{u}`" for u in lengths),
                    )
            elif clause.keyword == "up" and clause.word not in UP_WORDS:
                self.sink.report(
                    "MT0212",
                    f"`up {clause.word}`: a model's up axis is `x`, `y` or `z`",
                    clause.span,
                    help="CAD files are often Z up: `up z`",
                )
            elif clause.keyword == "opening" and clause.value is not None:
                if clause.word == "round":
                    self.expect_in(clause.value, T.LENGTH, env, V.SOLID_SIZE)
                elif clause.word == "rect":
                    what = "a rectangular opening (width, height)"
                    self.expect_vector_in(clause.value, OPENING_RECT, env, what, V.SOLID_SIZE)
                else:
                    self.sink.report(
                        "MT0212",
                        f"an opening is `round` or `rect`, not `{clause.word}`",
                        clause.word_span or clause.span,
                        help="`opening round 8 cm` or `opening rect (10, 6) cm`",
                    )
        if shape.kind == "model":
            self.load_model(shape)

    def load_model(self, shape: ast.Shape) -> MeshFile | None:
        """The model's file, read once; a file mtlc cannot use is reported at the `model` line."""
        key = id(shape)
        if key in self.meshes:
            return self.meshes[key]
        from mtlc.geometry.load import FIXED_FRAME, ModelError, read_mesh, resolve

        mesh = None
        assert shape.file is not None
        try:
            path = resolve(shape.file, Path(shape.span.file).parent)
            self.model_files.append(path)
            mesh = read_mesh(path)
        except ModelError as exc:
            self.sink.report(exc.code, exc.message, shape.span, help=exc.help)
        if mesh is not None:
            units, up = shape.clause("units"), shape.clause("up")
            if mesh.format in FIXED_FRAME and (units or up):
                self.sink.report(
                    "MT0212",
                    f"a glTF model is in metres and +Y up: `{(units or up).keyword}` does not apply",  # type: ignore[union-attr]
                    (units or up).span,  # type: ignore[union-attr]
                    help=f"delete `{(units or up).keyword} ...`",  # type: ignore[union-attr]
                )
            elif mesh.format not in FIXED_FRAME and units is None:
                self.sink.report(
                    "MT0212",
                    f"an {mesh.format.upper()} file does not say its units: model "
                    f"`{shape.name}` needs its `units`",
                    shape.span,
                    help="add `units mm` (or cm, m) after the path; `up z` if the file is Z up",
                )
        self.meshes[key] = mesh
        return mesh

    def node_names(self, shape: ast.Shape) -> frozenset[str] | None:
        """A model's named nodes (a solid has none); None when its file could not be read."""
        if shape.kind != "model":
            return frozenset()
        mesh = self.load_model(shape)
        return None if mesh is None else frozenset(mesh.nodes)

    def marker_sites(self, shape: ast.Shape) -> list[str]:
        """The sites `sites from` takes: the model's nodes without geometry whose names are
        names in the language (others are left out)."""
        mesh = self.load_model(shape)
        if mesh is None:
            return []
        return [m for m in mesh.markers if m.isidentifier()]

    def check_tool(self, tool: ast.ToolDecl, scope: Scope) -> None:
        env = Env(scope, "tool")
        seen: set[str] = set()
        for prop in tool.properties:
            expected = B.TOOL_PROPERTIES.get(prop.name)
            if expected is None:
                self.sink.report(
                    "MT0306",
                    f"tools have no property `{prop.name}`",
                    prop.span,
                    help=suggest(prop.name, B.TOOL_PROPERTIES, "properties"),
                )
                continue
            if prop.name in seen:
                self.sink.report("MT0210", f"`{prop.name}` is given twice", prop.span)
            seen.add(prop.name)
            rule = TOOL_RANGES.get(prop.name)
            if isinstance(expected, T.VectorType):
                what = "axis" if prop.name == "axis" else f"{prop.name} point"
                self.expect_vector_in(prop.value, expected, env, f"a tool's {what}", rule)
            else:
                self.expect_in(prop.value, expected, env, rule)

    def _params(self, params: tuple[ast.Param, ...], scope: Scope) -> dict[str, T.Type]:
        out: dict[str, T.Type] = {}
        spans: dict[str, Span] = {}
        for p in params:
            ptype = T.TYPE_NAMES.get(p.type_name)
            if ptype is None:
                self.sink.report(
                    "MT0304",
                    f"unknown type `{p.type_name}`",
                    p.type_span,
                    help=suggest(p.type_name, T.TYPE_NAMES, "types"),
                )
                ptype = T.UNKNOWN
            if p.name in out:
                self.sink.report(
                    "MT0310",
                    f"parameter `{p.name}` is declared twice",
                    p.span,
                    labels=(Label(spans[p.name], "first declared here"),),
                )
                continue
            if p.default is not None:
                self.expect_in(p.default, ptype, Env(scope, "default"), V.for_type(ptype))
            elif any(q.default is not None for q in params[: params.index(p)]):
                self.sink.report(
                    "MT0313",
                    f"parameter `{p.name}` has no default but follows one that has",
                    p.span,
                    help="move the parameters with defaults to the end",
                )
            out[p.name] = ptype
            spans[p.name] = p.span
        return out

    def check_definition(self, d: ast.Definition, scope: Scope) -> None:
        env = Env(scope, d.kind, self._params(d.params, scope))
        times = [s for s in d.body.stmts if isinstance(s, ast.TimeSetting)]
        for extra in times[1:]:
            self.sink.report(
                "MT0210",
                "the element's `time` is set twice",
                extra.span,
                labels=(Label(times[0].span, "first set here"),),
            )
        self._current = d
        self.check_block(d.body, env, top=True)
        self._current = None

    def check_task(self, task: ast.Task, scope: Scope) -> None:
        env = Env(scope, "task")
        settings: dict[type, ast.Stmt] = {}
        for stmt in task.body.stmts:
            if isinstance(stmt, TASK_SETTINGS):
                if type(stmt) in settings:
                    what = type(stmt).__name__.removesuffix("Setting").lower()
                    self.sink.report(
                        "MT0210",
                        f"the task's {what} is set twice",
                        stmt.span,
                        labels=(Label(settings[type(stmt)].span, "first set here"),),
                    )
                    continue
                settings[type(stmt)] = stmt
                if isinstance(stmt, ast.SceneSetting):
                    env.scene = self.resolve_scene(stmt, scope)
        self.check_block(task.body, env, top=True)

    def resolve_scene(self, stmt: ast.SceneSetting, scope: Scope) -> Symbol | None:
        sym = self.lookup_symbol(stmt.name, stmt.name_span, scope)
        if sym is None:
            return None
        if sym.kind != "scene":
            self.sink.report(
                "MT0301", f"`{stmt.name}` is {_article(sym.kind)}, not a scene", stmt.name_span
            )
            return None
        return sym

    def all_site_names(self, scene: ast.Scene) -> list[str]:
        """A scene's sites: declared, taken from a node, and every marker of `sites from`."""
        names = [s.name for s in scene.sites] + [s.name for s in scene.node_sites]
        models = {s.name: s for s in scene.shapes if s.kind == "model"}
        for item in scene.sites_from:
            if item.model in models:
                names += self.marker_sites(models[item.model])
        return names

    def site_names(self, scene: ast.Scene) -> frozenset[str]:
        """The names of a scene's sites, collected once: each name used is then one set lookup,
        not a walk over the sites (quadratic in a scene of thousands)."""
        names = self._site_names.get(id(scene))
        if names is None:
            names = self._site_names[id(scene)] = frozenset(self.all_site_names(scene))
        return names

    # ------------------------------------------------------------ statements
    def check_block(self, block: ast.Block, env: Env, *, top: bool = False) -> None:
        for stmt in block.stmts:
            self.check_stmt(stmt, env, top)

    def check_stmt(self, stmt: ast.Stmt, env: Env, top: bool) -> None:
        level = env.level
        if isinstance(stmt, TASK_SETTINGS):
            if level != "task" or not top:
                self._misplaced(stmt, "a task setting", "at the top of a task's body")
                return
            self.check_setting(stmt, env)
            return
        if isinstance(stmt, ast.TimeSetting) and level == "element" and not top:
            self._misplaced(stmt, "`time`", "at the top of an element's body")
            return
        if isinstance(stmt, PRIMITIVES) and level != "element":
            what = "`time`" if isinstance(stmt, ast.TimeSetting) else "a primitive"
            self._misplaced(
                stmt, what, "inside an element", "define an element that does this and call it"
            )
            return
        match stmt:  # (no node class has a subclass: the order is the commonest first)
            case ast.Call():
                self.check_call(stmt, env)
            case ast.Block(stmts=_):
                self.check_block(stmt, env)
            case ast.Parallel(body=body):
                self.check_block(body, env)
            case ast.Repeat(count=count, body=body):
                self.expect_in(count, T.INT, env, REPEAT_COUNT)
                self.check_block(body, env)
            case ast.ForEach():
                self.check_for(stmt, env)
            case ast.TimeSetting(duration=duration):
                self.expect_timing(duration, env)
            case ast.Goal():
                self.expect(stmt.effector, T.HAND, env)
                self.expect(stmt.target, T.SITE, env)
                if stmt.approach is not None:
                    self.expect_in(stmt.approach, T.LENGTH, env, V.APPROACH)
                if stmt.offset is not None:
                    self.expect_vector_in(stmt.offset, POSITION, env, "an offset", V.OFFSET)
                self.check_over(stmt.over, env)
            case ast.Posture():
                sig = B.POSTURES.get(stmt.kind)
                if sig is None:
                    self.sink.report(
                        "MT0201",
                        f"unknown posture `{stmt.kind}`",
                        stmt.kind_span,
                        help=suggest(stmt.kind, B.POSTURES, "postures"),
                    )
                else:
                    ranges = {n: r for (k, n), r in V.POSTURE_ARGS.items() if k == sig.name}
                    self.check_args(
                        sig.name, _builtin_params(sig), stmt.args, stmt.span, env, ranges
                    )
                self.check_over(stmt.over, env)
            case ast.Walk():
                if stmt.mode == "to":
                    self.expect(stmt.target, T.SITE, env)
                else:
                    what = "a displacement"
                    self.expect_vector_in(stmt.target, POSITION, env, what, V.DISPLACEMENT)
                if stmt.facing is not None:
                    self.expect(stmt.facing, T.SITE, env)
                self.check_over(stmt.over, env)
            case ast.Grip():
                self.expect(stmt.hand, T.HAND, env)
                if stmt.state not in B.GRIP_STATES:
                    self.sink.report(
                        "MT0309",
                        f"a grip is `open` or `closed`, not `{stmt.state}`",
                        stmt.state_span,
                        help=did_you_mean(stmt.state, B.GRIP_STATES),
                    )
                self.check_over(stmt.over, env)
            case ast.Gaze():
                self.expect(stmt.target, T.SITE, env)
                self.check_over(stmt.over, env)
            case ast.Still(over=over):
                self.check_over(over, env)

    def _misplaced(self, stmt: ast.Stmt, what: str, where: str, help: str | None = None) -> None:
        self.sink.report("MT0209", f"{what} can only stand {where}", stmt.span, help=help)

    def check_setting(self, stmt: ast.Stmt, env: Env) -> None:
        match stmt:
            case ast.ManikinSetting():
                check_manikin(stmt, self.sink)
            case ast.ToolSetting(tool=tool):
                self.expect(tool, T.TOOL, env)
            case ast.BudgetSetting(limit=limit):
                self.expect_in(limit, T.DURATION, env, V.BUDGET)

    def check_over(self, over: ast.Expr | None, env: Env) -> None:
        if over is not None:
            self.expect_timing(over, env)

    def check_for(self, stmt: ast.ForEach, env: Env) -> None:
        items_type = self.infer(stmt.items, env)
        if isinstance(items_type, T.ListType):
            elem = items_type.element
        else:
            if items_type != T.UNKNOWN:
                self.sink.report(
                    "MT0301",
                    f"`for` needs a list, found {items_type}",
                    stmt.items.span,
                    help="write the items in brackets: [a, b, c]",
                )
            elem = T.UNKNOWN
        inner = Env(env.scope, env.level, {**env.locals, stmt.var: elem}, env.scene)
        self.check_block(stmt.body, inner)

    def check_call(self, call: ast.Call, env: Env) -> None:
        sym = self.resolve_callee(call.callee, call.callee_span, env)
        if sym is None:
            for arg in call.args:  # still check what the arguments compute; bare names could be
                if not isinstance(arg.value, ast.Name):  # members of the missing callee's enums
                    self.infer(arg.value, env)
            return
        if sym.kind not in ("element", "action"):
            self.sink.report(
                "MT0208",
                f"`{sym.name}` is {_article(sym.kind)} and cannot be called",
                call.callee_span,
            )
            return
        if sym.kind not in CALLABLE_FROM.get(env.level, ()):
            self.sink.report(
                "MT0208",
                f"{_article(env.level)} cannot call {_article(sym.kind)} (`{sym.name}`)",
                call.callee_span,
                help="elements are built from primitives and other elements; "
                "actions from elements and actions",
            )
        decl = sym.decl
        assert isinstance(decl, ast.Definition)
        params = self._signatures.get(id(decl))
        if params is None:
            params = self._signatures[id(decl)] = [
                (p.name, T.TYPE_NAMES.get(p.type_name, T.UNKNOWN), p.default is None)
                for p in decl.params
            ]
        if sym.name not in sym.module.tree.broken_names:  # its signature may be cut short
            self.check_args(sym.name, params, call.args, call.span, env)
        else:
            for arg in call.args:
                self.infer(arg.value, env)
        self.callees[call.callee_span] = sym
        if self._current is not None:
            self.edges.append(CallEdge(self._current, sym, call.callee_span))

    def resolve_callee(self, callee: tuple[str, ...], span: Span, env: Env) -> Symbol | None:
        scope = env.scope
        if len(callee) == 1:
            return self.lookup_symbol(callee[0], span, scope, callable_only=True)
        prefix = ".".join(callee[:-1])
        if prefix not in scope.aliases:
            self.sink.report(
                "MT0201",
                f"no module `{prefix}` is used here",
                span,
                help=did_you_mean(prefix, [a for a, s in scope.aliases.items() if s is not None]),
            )
            return None
        module = scope.aliases[prefix]
        if module is None:
            self.sink.report(
                "MT0206",
                f"two used modules are called `{prefix}`",
                span,
                help="write the module's whole path, as in its `use`",
            )
            return None
        sym = module.own.get(callee[-1])
        if sym is None:
            self.sink.report(
                "MT0201",
                f"module `{prefix}` has no `{callee[-1]}`",
                span,
                help=did_you_mean(callee[-1], module.own),
            )
        return sym

    def lookup_symbol(
        self, name: str, span: Span, scope: Scope, *, callable_only: bool = False
    ) -> Symbol | None:
        if name in scope.ambiguous:
            options = scope.ambiguous[name]
            self.sink.report(
                "MT0206",
                f"`{name}` is defined in {len(options)} used modules",
                span,
                labels=tuple(Label(s.decl.name_span, "defined here") for s in options),
                help=f"qualify it with its module, for example `{_module_stem(options[0])}.{name}`"
                if callable_only
                else "rename one of the definitions; one name has one definition",
            )
            return None
        sym = scope.lookup(name)
        if sym is None:
            if name in scope.broken or "*" in scope.broken:
                return None
            pool = [
                n
                for n, s in scope.names.items()
                if not callable_only or s.kind in ("element", "action")
            ]
            self.sink.report(
                "MT0201",
                f"unknown name `{name}`",
                span,
                help=_module_hint(name) or did_you_mean(name, pool),
            )
        return sym

    # ------------------------------------------------------------ arguments
    def check_args(
        self,
        fname: str,
        params: list[tuple[str, T.Type, bool]],
        args: tuple[ast.Arg, ...],
        call_span: Span,
        env: Env,
        ranges: dict[str, V.Range] | None = None,
    ) -> None:
        """Match the arguments to the parameters and check each one's type, and its range when
        it is a constant (``ranges`` by parameter name, else by the parameter's type)."""
        given: dict[str, ast.Arg] = {}
        names = [p[0] for p in params]
        types = {p[0]: p[1] for p in params}
        seen_named = False
        misplaced = False
        for i, arg in enumerate(args):
            if arg.name is None:
                if seen_named:
                    self.sink.report(
                        "MT0311",
                        "a positional argument cannot follow a named one",
                        arg.span,
                        help="name this argument too, or move it before the named ones",
                    )
                    misplaced = True
                    self.infer(arg.value, env)
                    continue
                if i >= len(params):
                    n_pos = sum(a.name is None for a in args)
                    self.sink.report(
                        "MT0305",
                        f"`{fname}` takes {len(params)} argument{'s' if len(params) != 1 else ''}, "
                        f"but {n_pos} {'was' if n_pos == 1 else 'were'} given",
                        arg.span,
                        help=f"parameters: {', '.join(names) or '(none)'}",
                    )
                    self.infer(arg.value, env)
                    continue
                pname = names[i]
            else:
                seen_named = True
                pname = arg.name
                if pname not in types:
                    self.sink.report(
                        "MT0306",
                        f"`{fname}` has no parameter `{pname}`",
                        arg.name_span or arg.span,
                        help=suggest(pname, names, "parameters"),
                    )
                    self.infer(arg.value, env)
                    continue
            if pname in given:
                self.sink.report(
                    "MT0308",
                    f"parameter `{pname}` of `{fname}` is given twice",
                    arg.span,
                    labels=(Label(given[pname].span, "first given here"),),
                )
                continue
            given[pname] = arg
            rule = (ranges or {}).get(pname) or V.for_type(types[pname])
            self.expect_in(arg.value, types[pname], env, rule)
        missing = [n for n, _, required in params if required and n not in given]
        if missing and not misplaced:
            listed = ", ".join(f"`{m}`" for m in missing)
            self.sink.report(
                "MT0307",
                f"`{fname}` is missing {'an argument' if len(missing) == 1 else 'arguments'} "
                f"for {listed}",
                call_span,
            )

    # ------------------------------------------------------------ expressions
    def expect(self, expr: ast.Expr, expected: T.Type, env: Env) -> T.Type:
        actual = self.infer(expr, env, expected)
        if not T.is_assignable(actual, expected):
            self.mismatch(expr, actual, expected)
        return actual

    def mismatch(self, expr: ast.Expr, actual: T.Type, expected: T.Type) -> None:
        if isinstance(actual, T.Quantity) and isinstance(expected, T.Quantity):
            if actual.dim == expected.dim:  # a Number where an Int is wanted
                self.sink.report("MT0301", f"expected a whole number, found {actual}", expr.span)
                return
            help = None
            if expected.dim != T.NONE_DIM and actual.dim == T.NONE_DIM:
                unit = {T.LENGTH: "cm", T.ANGLE: "deg", T.DURATION: "s", T.MASS: "kg"}.get(expected)
                if unit and isinstance(expr, ast.Number):
                    help = f"give the number a unit, for example `{_src_number(expr)} {unit}`"
                elif unit:
                    help = f"give it a unit, for example multiply by `1 {unit}`"
            self.sink.report("MT0302", f"expected {expected}, found {actual}", expr.span, help=help)
            return
        self.sink.report("MT0301", f"expected {expected}, found {actual}", expr.span)

    def expect_timing(self, expr: ast.Expr, env: Env) -> None:
        actual = self.infer(expr, env, T.DURATION)
        if actual not in (T.TIMING, T.UNKNOWN) and not T.is_assignable(actual, T.DURATION):
            self.mismatch(expr, actual, T.DURATION)
        elif actual == T.DURATION:
            self.check_range(expr, V.DURATION)

    def expect_in(self, expr: ast.Expr, expected: T.Type, env: Env, rule: V.Range | None) -> T.Type:
        """``expect``, then, for a constant of the right type, its range (MT0309)."""
        actual = self.expect(expr, expected, env)
        if rule is not None and actual != T.UNKNOWN and T.is_assignable(actual, expected):
            self.check_range(expr, rule)
        return actual

    def expect_vector_in(
        self, expr: ast.Expr, expected: T.VectorType, env: Env, what: str, rule: V.Range | None
    ) -> None:
        if self.expect_vector(expr, expected, env, what) and rule is not None:
            self.check_range(expr, rule)

    def check_range(self, expr: ast.Expr, rule: V.Range) -> None:
        """A constant value out of its range is MT0309, at the value; one that names something
        (a parameter) is checked when the task is expanded."""
        problem = V.problem(rule, V.fold(expr))
        if problem is not None:
            self.sink.report("MT0309", problem, expr.span, help=rule.help)

    def expect_vector(self, expr: ast.Expr, expected: T.VectorType, env: Env, what: str) -> bool:
        """Whether ``expr`` is a vector of the expected kind and size (reported if not)."""
        actual = self.infer(expr, env, expected)
        if actual == T.UNKNOWN:
            return False
        if not isinstance(actual, T.VectorType):
            self.sink.report("MT0301", f"{what} is a vector (x, y, z), found {actual}", expr.span)
        elif actual.dim != expected.dim:
            self.sink.report(
                "MT0302",
                f"{what} is a {expected}, found {actual}",
                expr.span,
                help={
                    T.LENGTH_DIM: "give it a length unit: (x, y, z) cm",
                    T.NONE_DIM: "a direction has no unit: (x, y, z)",
                    T.ANGLE_DIM: "give it an angle unit: (rx, ry, rz) deg",
                }.get(expected.dim),
            )
        elif actual.size != expected.size:
            self.sink.report(
                "MT0309", f"{what} has {expected.size} components, not {actual.size}", expr.span
            )
        else:
            return True
        return False

    def infer(self, expr: ast.Expr, env: Env, expected: T.Type | None = None) -> T.Type:
        kind = type(expr)  # the node classes have no subclasses: one look-up, no isinstance chain
        if kind is ast.Number:
            assert isinstance(expr, ast.Number)
            unit = expr.unit
            if unit is None:
                if expr.is_int and (problem := V.int_problem(int(expr.value))):
                    self.sink.report("MT0309", problem, expr.span, help=INT_HELP)
                    return T.UNKNOWN
                return T.INT if expr.is_int else T.NUMBER
            utype, factor = self.unit_type(unit, expr.unit_span or expr.span, expected)
            if utype != T.UNKNOWN and not math.isfinite(expr.value * factor):
                self.sink.report(
                    "MT0309",
                    f"`{expr.value:g} {unit}` is too large: it is not a finite number",
                    expr.span,
                    help="use a larger unit or a smaller number",
                )
                return T.UNKNOWN
            return utype
        if kind is ast.Name:
            assert isinstance(expr, ast.Name)
            return self.infer_name(expr.name, expr.span, env, expected)
        if kind is ast.Vector:
            return self.infer_vector(expr, env, expected)  # type: ignore[arg-type]
        if kind is ast.Attr:
            return self.infer_attr(expr, env)  # type: ignore[arg-type]
        if kind is ast.Binary:
            return self.infer_binary(expr, env, expected)  # type: ignore[arg-type]
        if kind is ast.String:
            return T.STRING
        if kind is ast.CallExpr:
            return self.infer_call(expr, env)  # type: ignore[arg-type]
        if kind is ast.Unary:
            assert isinstance(expr, ast.Unary)
            t = self.infer(expr.operand, env, expected)
            if isinstance(t, T.Quantity | T.VectorType) or t == T.UNKNOWN:
                return t
            self.sink.report("MT0301", f"cannot negate {_article_type(t)}", expr.span)
            return T.UNKNOWN
        if kind is ast.ListExpr:
            assert isinstance(expr, ast.ListExpr)
            items = expr.items
            if not items:
                return T.ListType(T.UNKNOWN)
            elem_expected = expected.element if isinstance(expected, T.ListType) else None
            first = self.infer(items[0], env, elem_expected)
            for item in items[1:]:
                t = self.infer(item, env, first if isinstance(first, T.EnumType) else None)
                if not (T.is_assignable(t, first) or T.is_assignable(first, t)):
                    self.sink.report(
                        "MT0301",
                        f"list items must have one type: found {first} and {t}",
                        item.span,
                    )
            return T.ListType(first)
        return T.UNKNOWN

    def unit_type(
        self, unit: str, span: Span, expected: T.Type | None = None
    ) -> tuple[T.Type, float]:
        found = T.UNITS.get(unit)
        if found is None:
            # `cms` where a Length is wanted means `cm`, not the `ms` that is as close
            dim = getattr(expected, "dim", None)
            same = [u for u, (d, _) in T.UNITS.items() if d == dim and dim != T.NONE_DIM]
            self.sink.report(
                "MT0303",
                f"unknown unit `{unit}`",
                span,
                help=suggest(unit, T.UNITS, "units", preferred=same),
            )
            return T.UNKNOWN, 1.0
        return _UNIT_TYPES[unit], found[1]

    def infer_name(self, name: str, span: Span, env: Env, expected: T.Type | None) -> T.Type:
        """Resolve a bare name; the order here is the language's, and expansion replays it."""
        found = self._resolve_name(name, span, env, expected)
        if found is not None:
            kind, type_ = found
            self.resolved[span] = kind
            return type_
        return T.UNKNOWN

    def _resolve_name(
        self, name: str, span: Span, env: Env, expected: T.Type | None
    ) -> tuple[str, T.Type] | None:
        if name in env.locals:
            return "local", env.locals[name]
        if isinstance(expected, T.EnumType) and name in expected.members:
            return "enum", expected  # `right` is the Hand even if a site is called `right`
        if env.scene is not None:
            scene = env.scene.decl
            assert isinstance(scene, ast.Scene)
            if name in self.site_names(scene):
                return "site", T.SITE
        sym = env.scope.lookup(name) if name not in env.scope.ambiguous else None
        if sym is not None:
            if sym.kind in ("tool", "scene"):
                return sym.kind, T.TOOL if sym.kind == "tool" else T.SCENE
            self.sink.report(
                "MT0301",
                f"`{name}` is {_article(sym.kind)}; it can be called, not used as a value",
                span,
            )
            return None
        owners = [e for e in T.ENUMS if name in e.members]
        if len(owners) == 1 or (owners and expected is not None):
            return "enum", owners[0]  # the caller reports it if another type was wanted
        if owners:
            listed = " and ".join(e.name for e in owners)
            self.sink.report(
                "MT0312",
                f"`{name}` is a member of {listed}",
                span,
                help=f"say which: `{owners[0].name}.{name}`",
            )
            return None
        if name in env.scope.ambiguous:
            self.lookup_symbol(name, span, env.scope)
            return None
        if name in env.scope.broken or "*" in env.scope.broken:
            return None
        pool = list(env.locals) + list(env.scope.names)
        if env.scene is not None:
            pool += self.all_site_names(env.scene.decl)  # type: ignore[arg-type]
        if isinstance(expected, T.EnumType):
            pool += list(expected.members)
        help = _module_hint(name) or did_you_mean(name, pool)
        if help is None and isinstance(expected, T.EnumType):
            help = f"{expected} is one of: {', '.join(expected.members)}"
        if help is None and expected == T.SITE and env.level == "task" and env.scene is None:
            help = "sites come from the task's scene: add `scene <name>` to the task"
        self.sink.report("MT0201", f"unknown name `{name}`", span, help=help)
        return None

    def infer_attr(self, expr: ast.Attr, env: Env) -> T.Type:
        if isinstance(expr.obj, ast.Name) and expr.obj.name == "mtm":
            self.sink.report(
                "MT0301",
                f"`mtm.{expr.name}` is a function: call it, as in `mtm.{expr.name}()`",
                expr.span,
            )
            return T.UNKNOWN
        enum = T.TYPE_NAMES.get(expr.obj.name) if isinstance(expr.obj, ast.Name) else None
        if isinstance(enum, T.EnumType) and expr.obj.name not in env.locals:
            if expr.name in enum.members:
                self.resolved[expr.span] = "enum"
                return enum
            self.sink.report(
                "MT0201",
                f"{enum.name} has no member `{expr.name}`",
                expr.name_span,
                help=suggest(expr.name, enum.members, "members"),
            )
            return T.UNKNOWN
        owner = self.infer(expr.obj, env)
        if owner == T.UNKNOWN:
            return T.UNKNOWN
        if owner == T.SCENE and isinstance(expr.obj, ast.Name):
            sym = env.scope.lookup(expr.obj.name)
            scene = sym.decl if sym else None
            if isinstance(scene, ast.Scene):
                if expr.name in self.site_names(scene):
                    return T.SITE
                self.sink.report(
                    "MT0201",
                    f"scene `{scene.name}` has no site `{expr.name}`",
                    expr.name_span,
                    help=did_you_mean(expr.name, self.all_site_names(scene)),
                )
                return T.UNKNOWN
        if owner == T.TOOL and expr.name in B.TOOL_PROPERTIES:
            return B.TOOL_PROPERTIES[expr.name]
        self.sink.report("MT0301", f"{_article_type(owner)} has no `{expr.name}`", expr.name_span)
        return T.UNKNOWN

    def infer_call(self, expr: ast.CallExpr, env: Env) -> T.Type:
        func = expr.func
        if not (
            isinstance(func, ast.Attr) and isinstance(func.obj, ast.Name) and func.obj.name == "mtm"
        ):
            self.sink.report(
                "MT0301",
                "only the timing functions `mtm.<name>(...)` can be called inside an expression",
                func.span,
                help="call elements and actions as statements, on a line of their own",
            )
            for a in expr.args:
                self.infer(a.value, env)
            return T.UNKNOWN
        sig = B.MTM_FUNCTIONS.get(func.name)
        if sig is None:
            self.sink.report(
                "MT0201",
                f"unknown timing function `mtm.{func.name}`",
                func.name_span,
                help=suggest(func.name, B.MTM_FUNCTIONS, "functions"),
            )
            return T.UNKNOWN
        ranges = {n: r for (f, n), r in V.MTM_ARGS.items() if f == sig.name}
        self.check_args(f"mtm.{sig.name}", _builtin_params(sig), expr.args, expr.span, env, ranges)
        if sig.name == "code":
            for a in expr.args:
                if isinstance(a.value, ast.String) and a.value.value not in other_codes():
                    self.sink.report(
                        "MT0309",
                        f"no MTM-1 element `{a.value.value}` in the tables",
                        a.value.span,
                        help=did_you_mean(a.value.value, other_codes()),
                    )
        return T.TIMING

    def infer_binary(self, expr: ast.Binary, env: Env, expected: T.Type | None) -> T.Type:
        hint = expected if isinstance(expected, T.Quantity | T.VectorType) else None
        if expr.op in "*/":
            hint = None  # `3 s * (30 cm / 1 m)`: the operands need not be of the result's kind
        left = self.infer(expr.left, env, hint)
        right = self.infer(expr.right, env, hint)
        if T.UNKNOWN in (left, right):
            return T.UNKNOWN
        op = expr.op
        numeric = (T.Quantity, T.VectorType)
        if not isinstance(left, numeric) or not isinstance(right, numeric):
            bad = left if not isinstance(left, numeric) else right
            self.sink.report(
                "MT0301", f"`{op}` works on numbers and quantities, not on {bad}", expr.span
            )
            return T.UNKNOWN
        if op in "+-":
            if left != right and not (
                isinstance(left, T.Quantity)
                and isinstance(right, T.Quantity)
                and left.dim == right.dim
            ):
                verb = "add" if op == "+" else "subtract"
                self.sink.report(
                    "MT0302",
                    f"cannot {verb} {left} and {right}",
                    expr.span,
                    help="both sides of + and - need the same unit kind",
                )
                return T.UNKNOWN
            if isinstance(left, T.Quantity):
                return T.Quantity(left.dim, left.integer and right.integer)  # type: ignore[union-attr]
            return left
        if isinstance(left, T.VectorType) and isinstance(right, T.VectorType):
            self.sink.report("MT0301", f"cannot use `{op}` between two vectors", expr.span)
            return T.UNKNOWN
        sign = 1 if op == "*" else -1
        dim = tuple(a + sign * b for a, b in zip(left.dim, right.dim, strict=True))
        if isinstance(left, T.VectorType) or isinstance(right, T.VectorType):
            if op == "/" and isinstance(right, T.VectorType):
                self.sink.report("MT0301", "cannot divide by a vector", expr.span)
                return T.UNKNOWN
            size = left.size if isinstance(left, T.VectorType) else right.size  # type: ignore[union-attr]
            return T.VectorType(dim, size)  # type: ignore[arg-type]
        integer = op == "*" and left.integer and right.integer  # type: ignore[union-attr]
        return T.Quantity(dim, integer)  # type: ignore[arg-type]

    def infer_vector(self, expr: ast.Vector, env: Env, expected: T.Type | None = None) -> T.Type:
        dims = []
        for item in expr.items:
            t = self.infer(item, env)
            if t == T.UNKNOWN:
                return T.UNKNOWN
            if not isinstance(t, T.Quantity):
                self.sink.report("MT0301", f"vector components are numbers, found {t}", item.span)
                return T.UNKNOWN
            dims.append(t.dim)
        if expr.unit is not None:
            utype, _ = self.unit_type(expr.unit, expr.unit_span or expr.span, expected)
            if utype == T.UNKNOWN:
                return T.UNKNOWN
            for item, dim in zip(expr.items, dims, strict=True):
                if dim != T.NONE_DIM:
                    self.sink.report(
                        "MT0302",
                        f"component has its own unit and the vector has `{expr.unit}`",
                        item.span,
                        help="write the unit once, after the parenthesis: (1, 2, 3) cm",
                    )
                    return T.UNKNOWN
            return T.VectorType(utype.dim, len(expr.items))  # type: ignore[attr-defined]
        if len(set(dims)) > 1:
            self.sink.report(
                "MT0302",
                "vector components have different units: " + ", ".join(T.dim_name(d) for d in dims),
                expr.span,
            )
            return T.UNKNOWN
        return T.VectorType(dims[0], len(expr.items))


def _module_stem(sym: Symbol) -> str:
    return sym.module.display.rsplit("/", 1)[-1].removesuffix(".mtask")


def _module_hint(name: str) -> str | None:
    """If a stdlib module defines ``name``, say which `use` brings it in (only on the error path)."""
    import re

    from mtlc.resources import stdlib_dir

    pattern = re.compile(rf"^\s*(element|action|tool|scene)\s+{re.escape(name)}\b", re.M)
    for path in sorted(stdlib_dir().glob("*.mtask")):
        if pattern.search(path.read_text(encoding="utf-8")):
            return f"`{name}` is defined in the standard library: add `use stdlib.{path.stem}`"
    return None


def _builtin_params(sig: B.Signature) -> list[tuple[str, T.Type, bool]]:
    return [(p.name, p.type, p.required) for p in sig.params]


def _article(kind: str) -> str:
    return ("an " if kind[0] in "aeiou" else "a ") + kind


def _article_type(t: T.Type) -> str:
    return _article(t.name) if t.name[0].isalpha() else t.name


def _src_number(expr: ast.Number) -> str:
    v = expr.value
    return str(int(v)) if v.is_integer() else str(v)


def check_manikin(stmt: ast.ManikinSetting, sink: DiagnosticSink) -> tuple[str, str, int] | None:
    """Validate `manikin <population> <sex> p<N>`; the value, or None after a diagnostic."""
    ok = True
    if stmt.population not in B.POPULATIONS:
        sink.report(
            "MT0309",
            f"unknown population `{stmt.population}`",
            stmt.population_span,
            help=suggest(stmt.population, B.POPULATIONS, "populations"),
        )
        ok = False
    if stmt.sex not in B.SEXES:
        sink.report(
            "MT0309",
            f"sex is `male` or `female`, not `{stmt.sex}`",
            stmt.sex_span,
            help=did_you_mean(stmt.sex, B.SEXES),
        )
        ok = False
    pct_text = stmt.percentile
    allowed = B.POPULATIONS.get(stmt.population, (1, 5, 10, 50, 90, 95, 99))
    pct = int(pct_text[1:]) if pct_text[:1] == "p" and pct_text[1:].isdigit() else None
    if pct is None or pct not in allowed:
        sink.report(
            "MT0309",
            f"percentile `{pct_text}` is not in the table",
            stmt.percentile_span,
            help="percentiles: " + ", ".join(f"p{p}" for p in allowed),
        )
        ok = False
    return (stmt.population, stmt.sex, pct) if ok and pct is not None else None


def check_recursion(edges: list[CallEdge], sink: DiagnosticSink) -> set[int]:
    """Report each cycle of calls once, at the call that closes it; the ids of definitions in cycles.

    An iterative depth-first search, so that a long chain of definitions cannot exhaust the stack.
    """
    graph: dict[int, list[CallEdge]] = {}
    names: dict[int, str] = {}
    for e in edges:
        graph.setdefault(id(e.caller), []).append(e)
        names[id(e.caller)] = e.caller.name
        names[id(e.callee.decl)] = e.callee.name
    in_cycle: set[int] = set()
    reported: set[frozenset[int]] = set()
    state: dict[int, int] = {}  # 1 on the current path, 2 finished
    for e in edges:
        root = id(e.caller)
        if root in state:
            continue
        path: list[int] = [root]
        iters = [iter(graph.get(root, []))]
        state[root] = 1
        while iters:
            edge = next(iters[-1], None)
            if edge is None:
                state[path.pop()] = 2
                iters.pop()
                continue
            target = id(edge.callee.decl)
            if state.get(target) == 1:
                members = path[path.index(target) :]
                in_cycle.update(members)
                key = frozenset(members)
                if key not in reported:
                    reported.add(key)
                    chain = " → ".join(f"`{names[m]}`" for m in [*members, target])
                    sink.report(
                        "MT0207",
                        f"`{names[target]}` calls itself: {chain}",
                        edge.span,
                        help="a motion must expand into a finite list of primitives; "
                        "use `repeat` for repetition",
                    )
            elif target not in state:
                state[target] = 1
                path.append(target)
                iters.append(iter(graph.get(target, [])))
    return in_cycle
