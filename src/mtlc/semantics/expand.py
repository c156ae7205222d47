"""Expand a checked task into its timeline of primitives.

Calls are inlined with their arguments bound, `repeat` and `for` unrolled, sequence and parallel
composition turned into start and end times. Durations are stated (`over`), set for an element
(`time`), or predicted from MTM-1 (mtlc.semantics.mtm). A budget on the number of primitives
turns an exploding expansion into a diagnostic before it costs the memory.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from functools import cache
from typing import TYPE_CHECKING, Any

from mtlc.diagnostics import DiagnosticSink, Label, Span
from mtlc.semantics import builtins as B
from mtlc.semantics import mtm
from mtlc.semantics import types as T
from mtlc.semantics import values as V
from mtlc.semantics.check import TOOL_RANGES, check_manikin
from mtlc.semantics.scopes import Scope, Symbol
from mtlc.semantics.stand import stand_point
from mtlc.semantics.timeline import ManikinSpec, Primitive, Site, Timeline, Tool
from mtlc.syntax import ast

if TYPE_CHECKING:
    import numpy as np

    from mtlc.geometry.load import MeshFile
    from mtlc.geometry.model import SceneModel

DEFAULT_BUDGET = 100_000
MAX_NESTING = 150  # blocks and calls inside each other while expanding
DEFAULT_APPROACH_M = 0.08
TO_SHARE = (0.2, 0.5)  # the contact (TO) phase's share of a goal's time: at least, at most
# m: the farthest a hand travels in one reach or move without a step (P99 male: floor beside the
# foot to overhead, or across the body with the trunk leaning, is under 2.3 m). A goal farther
# than this is out of reach (MT0501 from the motion passes); timing its MTM-1 reach by the whole
# distance made a 90 m "reach" a 72 s motion to compile and lint, for a hand that cannot get there.
MAX_HAND_TRAVEL_M = 2.5
HAND_REST = {"left_hand": (0.2, 0.75, 0.0), "right_hand": (-0.2, 0.75, 0.0)}  # from the root
HANDS = {"left": ("left_hand",), "right": ("right_hand",), "both": ("left_hand", "right_hand")}
# s: a hand that let go and has nothing to do for this long lets its arm down (passes.rest), so
# its next reach is timed from the side
ARM_REST_IDLE = 1.5
ARM_REST_POSTURES = ("stand", "bend")  # squatting or kneeling, the posture places free arms
# m above the ground: a hand that let go lower than this is down already (letting it down
# further swept the forearm through the thigh)
ARM_REST_MIN_HEIGHT = 1.0
_PRIMITIVE_STMTS = frozenset({ast.Goal, ast.Posture, ast.Walk, ast.Grip, ast.Gaze, ast.Still})


@dataclass(frozen=True)
class Timing:
    """An MTM-1 rule from `mtm.<name>(...)`, evaluated for each primitive it times."""

    rule: str
    args: dict[str, Any]


# the MTM-1 rules that time a primitive with no `over` and no element `time`: made once (a
# timing is only read)
_GRASP = Timing("grasp", {"case": "G1A"})
_RELEASE = Timing("release", {})
_LOOK = Timing("code", {"code": "EF"})
_REACH = Timing("reach", {"case": "B"})
_WALK = Timing("walk", {})


@cache
def _code_timing(code: str) -> Timing:
    """``Timing("code", {"code": code})``, one per code."""
    return Timing("code", {"code": code})


class _BudgetExceeded(Exception):
    def __init__(
        self, span: Span, needed: int | None, idle: int = 0, help: str | None = None
    ) -> None:
        self.span = span
        self.needed = needed
        self.idle = idle  # rounds of `for` that produced no primitive, counted in the budget
        self.help = help


class _Abort(Exception):
    """A value error already reported; the task is not expanded further."""


@dataclass
class _Env:
    scope: Scope
    locals: dict[str, Any]
    trace: tuple[tuple[str, Span], ...]  # (name, span of the call) from the task down
    timing: Any = None  # the element's `time`, if any
    path: tuple[str, ...] | None = None  # the trace's names, built by the first primitive


@dataclass(frozen=True)
class _Callee:
    """What every call of one definition needs besides its arguments, worked out once: the
    value range of each parameter's type (``values.for_type``) and the definition's scope."""

    decl: ast.Definition
    scope: Scope
    params: tuple[ast.Param, ...]
    rules: dict[str, V.Range | None]  # by parameter name
    timings: tuple[ast.TimeSetting, ...]  # an element's `time` settings


_UNRESOLVED = object()  # a node the checker left no decision for


class Expander:
    def __init__(
        self,
        sink: DiagnosticSink,
        scopes: dict[int, Scope],
        resolved: dict[Span, str],
        callees: dict[Span, Symbol],
        budget: int = DEFAULT_BUDGET,
        manikin_override: ManikinSpec | None = None,
        site_overrides: Mapping[str, tuple[float, float, float]] | None = None,
        meshes: Mapping[int, MeshFile | None] | None = None,
    ) -> None:
        self.sink = sink
        self.scopes = scopes
        self.resolved = resolved  # the checker's decision for each name: local, site, enum...
        self.callees = callees  # and for each call statement, the definition it calls
        self.budget = budget
        self.manikin_override = manikin_override
        # positions (metres) that replace the scene's, by site name: `mtlc serve` moves sites
        self.site_overrides = dict(site_overrides or {})
        self.meshes = meshes or {}  # the models' files as the checker read them, by declaration
        self.models: dict[int, dict[str, SceneModel]] = {}  # placed, by scene declaration
        # by id() of a node of the checked trees, which live as long as the expander: the
        # checker's decision for a name (``resolved`` hashes a span on every look-up) and the
        # plan of a call statement's callee
        self._kinds: dict[int, str | None] = {}
        self._callees: dict[int, _Callee] = {}  # by call statement
        self._plans: dict[int, _Callee] = {}  # by definition
        # the value of a literal with a unit (`90 deg`) or a vector of literals, by node: the
        # same wherever it is evaluated, so worked out once (an overflow is reported each time)
        self._literals: dict[int, Any] = {}

    # ------------------------------------------------------------ entry
    def expand_task(self, task: ast.Task, scope: Scope) -> Timeline | None:
        self.count = 0
        self.idle = 0  # rounds of `for` that produced nothing (also counted in ``count``)
        self.depth = 0
        self.scenes: dict[int, dict[str, Site]] = {}  # by scene declaration
        self.task_sites: dict[str, Site] = {}
        self.other_sites: dict[str, Site] = {}  # sites of other scenes, named scene.site
        self.hand_pos: dict[str, tuple[float, float, float] | None] = {}
        self.closed: set[str] = set()  # hands whose last grip closed (they hold a part)
        self.root = (0.0, 0.0, 0.0)
        self.mtm_walks: set[int] = set()  # walks timed by MTM paces, which get turn time too
        self.posture = "stand"
        # a hand has gone to a site since the last posture: a reach may have leaned the trunk
        # or left an arm raised, so a `stand()` then is motion, not a no-op
        self.reached_since_posture = False
        self.released_at: dict[str, float] = {}  # when each hand last let go
        self.tool: Tool | None = None
        spec = ManikinSpec(*B.DEFAULT_MANIKIN)
        scene_name: str | None = None
        models: list[SceneModel] = []
        ground = 0.0
        budget: float | None = None
        budget_span = task.name_span
        env = _Env(scope, {}, ((task.name, task.name_span),))
        try:
            for stmt in task.body.stmts:
                if isinstance(stmt, ast.ManikinSetting):
                    value = check_manikin(stmt, DiagnosticSink())  # already reported when checked
                    if value is not None:
                        spec = ManikinSpec(*value)
                elif isinstance(stmt, ast.SceneSetting):
                    sym = scope.lookup(stmt.name)
                    if sym is not None and isinstance(sym.decl, ast.Scene):
                        scene_name = stmt.name
                        models = list(self._scene_models(sym).values())
                        self.task_sites = self._scene_sites(sym)
                        ground = self._ground(sym)
                elif isinstance(stmt, ast.ToolSetting):
                    self.tool = self.eval(stmt.tool, env)
                elif isinstance(stmt, ast.BudgetSetting):
                    budget, budget_span = self.eval(stmt.limit, env), stmt.span
                    self.check(V.BUDGET, budget, env, stmt.limit)
            self.root = (0.0, ground, 0.0)
            timeline = Timeline(
                task=task.name,
                title=task.title,
                file=task.span.file,
                span=task.name_span,
                manikin=self.manikin_override or spec,
                scene=scene_name,
                ground=ground,
                sites=[],
                tool=self.tool,
                budget=budget,
                models=models,
                budget_span=budget_span,
            )
            self.out = timeline.primitives
            self.block(task.body, env, 0.0)
            # the walks' turn and step time depend on the body: added per manikin by
            # semantics.schedule.for_manikin, after expansion
            timeline.mtm_walks = tuple(
                i for i, p in enumerate(timeline.primitives) if id(p) in self.mtm_walks
            )
            timeline.sites = [*self.task_sites.values(), *self.other_sites.values()]
        except _BudgetExceeded as exc:
            needed = f" (it would need about {exc.needed:,})" if exc.needed else ""
            what, help_ = "primitives", "lower the repeat count"
            if exc.idle:
                rounds = f"{exc.idle:,} rounds of `for` move" if exc.idle > 1 else "a round moves"
                what = f"primitives and empty loop rounds ({rounds} nothing)"
                help_ = "remove the loops that do nothing"
            self.sink.report(
                "MT0401",
                f"task `{task.name}` expands into more than {self.budget:,} {what}{needed}",
                exc.span,
                help=exc.help or f"{help_}, or raise the limit with --expansion-budget",
            )
            return None
        except _Abort:
            return None
        if not timeline.primitives:
            self.sink.report("MT0402", f"task `{task.name}` produces no motion", task.name_span)
        return timeline  # its budget (MT0404) is checked once timed for a manikin

    def fail(self, code: str, message: str, env: _Env, at: ast.Node, help: str | None = None):  # type: ignore[no-untyped-def]
        """Report a value error found while expanding, at the task's line that led to it."""
        where = _user_line(env, at)
        labels = () if where == at.span else (Label(at.span, "from here"),)
        self.sink.report(code, message, where, help=help, labels=labels)
        raise _Abort

    def check(self, rule: V.Range, value: Any, env: _Env, at: ast.Node) -> None:
        """A value out of its range (docs/language.md, "Limits") is MT0309, at the line of the
        task that led to it, with the place it was written as a label."""
        problem = V.problem(rule, value)
        if problem is not None:
            self.fail("MT0309", problem, env, at, help=rule.help)

    def _scene_scope(self, sym: Symbol) -> Scope:
        return self.scopes[id(sym.module)]

    def _ground(self, sym: Symbol) -> float:
        scene = sym.decl
        assert isinstance(scene, ast.Scene)
        if scene.ground is None:
            return 0.0
        env = _Env(self._scene_scope(sym), {}, ())
        ground = float(self.eval(scene.ground, env))
        self.check(V.GROUND, ground, env, scene.ground)
        return ground

    def _scene_sites(self, sym: Symbol) -> dict[str, Site]:
        """A scene's sites, evaluated once, in the scope of the module that declares the scene."""
        scene = sym.decl
        assert isinstance(scene, ast.Scene)
        if id(scene) in self.scenes:
            return self.scenes[id(scene)]
        env = _Env(self._scene_scope(sym), {}, ())
        sites: dict[str, Site] = {}
        for site in scene.sites:
            if site.name in sites:
                continue
            position = self.site_overrides.get(site.name) or self.eval(site.position, env)
            self.check(V.POSITION, tuple(position), env, site.position)
            normal = self.eval(site.normal, env) if site.normal is not None else None
            if site.normal is not None:
                self.check(V.NORMAL, normal, env, site.normal)
            frame = self.eval(site.frame, env) if site.frame is not None else None
            if site.frame is not None:
                self.check(V.FRAME, frame, env, site.frame)
            if normal is not None:
                norm = math.hypot(*normal)
                normal = tuple(c / norm for c in normal) if norm > 0 else None
            sites[site.name] = Site(site.name, position, normal, frame, site.name_span)
        models = self._scene_models(sym)
        for node_site in scene.node_sites:
            model = models.get(node_site.model)
            if node_site.name in sites or model is None or node_site.node not in model.nodes:
                continue  # reported by the checker
            sites[node_site.name] = self._node_site(
                node_site.name, model.nodes[node_site.node], node_site.name_span
            )
        for item in scene.sites_from:
            model = models.get(item.model)
            mesh = self._mesh(scene, item.model)
            if model is None or mesh is None:
                continue
            for name in mesh.markers:
                if name.isidentifier() and name not in sites:
                    sites[name] = self._node_site(name, model.nodes[name], item.span)
        # in the order they are written (a `sites from` line's, by node name)
        sites = dict(sorted(sites.items(), key=lambda item: item[1].span.start))
        self.scenes[id(scene)] = sites
        return sites

    def _node_site(self, name: str, node: tuple[np.ndarray, np.ndarray], span: Span) -> Site:
        position = self.site_overrides.get(name) or tuple(float(c) for c in node[0])
        normal = tuple(float(c) for c in node[1])
        return Site(name, position, normal, None, span)  # type: ignore[arg-type]

    def _mesh(self, scene: ast.Scene, model: str) -> MeshFile | None:
        for shape in scene.shapes:
            if shape.name == model and shape.kind == "model":
                return self.meshes.get(id(shape))
        return None

    def _scene_models(self, sym: Symbol) -> dict[str, SceneModel]:
        """A scene's models and solids, placed in the scene frame, once (MT0408 when one lies
        more than 1 km from the origin: a model in millimetres read as metres)."""
        scene = sym.decl
        assert isinstance(scene, ast.Scene)
        if id(scene) in self.models:
            return self.models[id(scene)]
        env = _Env(self._scene_scope(sym), {}, ())
        models: dict[str, SceneModel] = {}
        for shape in scene.shapes:
            if shape.name in models:
                continue
            model = self._place(shape, env)
            if model is None:
                continue
            from mtlc.geometry.model import FAR_AWAY  # numpy: only for scenes with geometry

            far = model.farthest()
            if far > FAR_AWAY:
                units = shape.clause("units")
                self.fail(
                    "MT0408",
                    f"{shape.kind} `{shape.name}` reaches {far / 1000:,.1f} km from the scene's "
                    f"origin",
                    env,
                    shape,
                    help="check its `units`"
                    + (f" (`{units.word}` now)" if units is not None else "")
                    + " and its `at`",
                )
            models[shape.name] = model
        self.models[id(scene)] = models
        return models

    def _value(self, shape: ast.Shape, keyword: str, env: _Env, default: Any = None) -> Any:
        clause = shape.clause(keyword)
        if clause is None or clause.value is None:
            return default
        return self.eval(clause.value, env)

    def _place(self, shape: ast.Shape, env: _Env) -> SceneModel | None:
        """The shape in the scene frame: a model's file as the checker read it (None when it
        could not be), a solid built from its clauses."""
        from mtlc.geometry.model import SceneModel, place_nodes, place_points, placement

        at = tuple(self._value(shape, "at", env, (0.0, 0.0, 0.0)))
        if shape.kind != "model":
            return self._place_solid(shape, env, at)
        mesh = self.meshes.get(id(shape))
        if mesh is None:
            return None
        units, up = shape.clause("units"), shape.clause("up")
        scale = T.UNITS[units.word][1] if units is not None and units.word in T.UNITS else 1.0
        rotate = tuple(self._value(shape, "rotate", env, (0.0, 0.0, 0.0)))
        matrix = placement(at, rotate, scale, up.word if up is not None else "y")  # type: ignore[arg-type]
        return SceneModel(
            name=shape.name,
            vertices=place_points(matrix, mesh.vertices),
            faces=mesh.faces,
            nodes=place_nodes(matrix, mesh.nodes),
            source=shape.file,
            sha256=mesh.sha256,
            solid=None,
            transform=matrix,
            parameters={"units": units.word if units else "m", "up": up.word if up else "y"},
            parts=mesh.parts,
        )

    def _place_solid(self, shape: ast.Shape, env: _Env, at: tuple[float, ...]) -> SceneModel:
        import numpy as np

        from mtlc.geometry import solids
        from mtlc.geometry.model import SceneModel, place_points, placement

        params: dict[str, Any] = {}
        if shape.kind == "box":
            params["size"] = tuple(self._value(shape, "size", env))
            params["rotate"] = tuple(self._value(shape, "rotate", env, (0.0, 0.0, 0.0)))
            vertices, faces = solids.box(params["size"])
            rotation = placement(rotate=params["rotate"])[:3, :3]
        elif shape.kind == "cylinder":
            params["radius"] = float(self._value(shape, "radius", env))
            params["length"] = float(self._value(shape, "length", env))
            params["axis"] = tuple(self._value(shape, "axis", env, (0.0, 1.0, 0.0)))
            vertices, faces = solids.cylinder(params["radius"], params["length"])
            rotation = solids.frame_from_axis(np.asarray(params["axis"]), 1)
        else:
            params["size"] = tuple(self._value(shape, "size", env))
            params["normal"] = tuple(self._value(shape, "normal", env, (0.0, 0.0, 1.0)))
            opening = shape.clause("opening")
            hole = None
            if opening is not None and opening.value is not None:
                dims = self.eval(opening.value, env)
                hole = (opening.word, float(dims) if opening.word == "round" else tuple(dims))
                self._check_opening(shape, hole, params["size"], env, opening)
                params["opening"] = {"shape": hole[0], "size": hole[1]}
            vertices, faces = solids.plate(params["size"], hole)  # type: ignore[arg-type]
            rotation = solids.frame_from_axis(np.asarray(params["normal"]), 2)
        matrix = np.eye(4)
        matrix[:3, :3] = rotation
        matrix[:3, 3] = at
        return SceneModel(
            name=shape.name,
            vertices=place_points(matrix, vertices),
            faces=faces,
            nodes={},
            source=None,
            sha256=None,
            solid=shape.kind,
            transform=matrix,
            parameters=params,
        )

    def _check_opening(
        self, shape: ast.Shape, hole: tuple[Any, Any], size: Any, env: _Env, at: ast.Node
    ) -> None:
        """An opening must leave a rim: smaller than the plate both ways."""
        width, height = size[0], size[1]
        ow, oh = (hole[1], hole[1]) if hole[0] == "round" else hole[1]
        if ow >= width or oh >= height:
            self.fail(
                "MT0309",
                f"plate `{shape.name}`'s opening ({ow * 100:g} x {oh * 100:g} cm) does not fit "
                f"inside the plate ({width * 100:g} x {height * 100:g} cm)",
                env,
                at,
                help="make the opening smaller than the plate's width and height",
            )

    # ------------------------------------------------------------ statements
    def block(self, block: ast.Block, env: _Env, t: float) -> float:
        self.depth += 1
        if self.depth > MAX_NESTING:
            self.fail(
                "MT0405",
                f"calls and blocks nest more than {MAX_NESTING} deep while expanding",
                env,
                block,
                help="flatten the chain of actions calling actions",
            )
        for stmt in block.stmts:
            t = self.stmt(stmt, env, t)
        self.depth -= 1
        return t

    def parallel(self, body: ast.Block, env: _Env, t: float) -> float:
        """Branches start together; the block ends with the last. No hand, no whole-body motion in
        two branches at once (the head may be asked to look by both)."""
        end = t
        owner: dict[str, ast.Stmt] = {}
        for branch in body.stmts:
            first = len(self.out)
            end = max(end, self.stmt(branch, env, t))
            for prim in self.out[first:]:
                if prim.effector == "head":
                    continue  # both hands' actions may look; the gaze pass picks one target
                other = owner.setdefault(prim.effector, branch)
                if other is not branch:
                    where = _user_line(env, branch)
                    self.sink.report(
                        "MT0406",
                        f"two branches of a parallel block move the {_part(prim.effector)}",
                        where,
                        labels=(Label(_user_line(env, other), "it also moves here"),),
                        help="a body part does one thing at a time: put these in sequence",
                    )
                    raise _Abort
        return end

    def stmt(self, stmt: ast.Stmt, env: _Env, t: float) -> float:
        kind = type(stmt)  # the node classes have no subclasses: one look-up, no isinstance chain
        if kind is ast.Call:
            return self.call(stmt, env, t)  # type: ignore[arg-type]
        if kind in _PRIMITIVE_STMTS:
            return self.primitive(stmt, env, t)
        if kind is ast.Block:
            return self.block(stmt, env, t)  # type: ignore[arg-type]
        if kind is ast.Parallel:
            return self.parallel(stmt.body, env, t)  # type: ignore[attr-defined]
        if kind is ast.Repeat:
            return self.repeat(stmt, env, t)  # type: ignore[arg-type]
        if kind is ast.ForEach:
            assert isinstance(stmt, ast.ForEach)
            items = self.eval(stmt.items, env)
            if not stmt.body.stmts and self.depth < MAX_NESTING:
                self._idle_round(stmt, env, len(items))  # nothing to run: all at once
                return t
            for value in items:
                inner = _Env(env.scope, {**env.locals, stmt.var: value}, env.trace, env.timing)
                before = self.count
                t = self.block(stmt.body, inner, t)
                if self.count == before:
                    self._idle_round(stmt, env)
            return t
        return t  # settings and `time`: no motion of their own

    def _idle_round(self, stmt: ast.ForEach, env: _Env, rounds: int = 1) -> None:
        """A round of `for` that produced nothing still took time: it counts against the budget
        as one primitive would, so nested loops around nothing end (10^9 rounds never did)."""
        self.idle += rounds
        self.count += rounds
        if self.count > self.budget:
            raise _BudgetExceeded(_user_line(env, stmt), None, self.idle)

    def repeat(self, stmt: ast.Repeat, env: _Env, t: float) -> float:
        n = self.eval(stmt.count, env)
        if n < 0:
            self.fail(
                "MT0309",
                f"cannot repeat a negative number of times ({n})",
                env,
                stmt.count,
                help="repeat a block 0 or more times; 0 runs nothing",
            )
        for i in range(n):
            before = self.count
            t = self.block(stmt.body, env, t)
            if i == 0:
                per_round = self.count - before
                if per_round == 0:
                    break  # nothing inside moves: the other rounds would add nothing
                if self.count + per_round * (n - 1) > self.budget:
                    raise _BudgetExceeded(_user_line(env, stmt), before + per_round * n, self.idle)
        return t

    def _callee(self, call: ast.Call) -> _Callee:
        """The definition a call statement calls (as the checker resolved it), planned once."""
        plan = self._callees.get(id(call))
        if plan is None:
            sym = self.callees[call.callee_span]
            plan = self._plans.get(id(sym.decl))
            if plan is None:
                plan = self._plans[id(sym.decl)] = self._plan(sym)
            self._callees[id(call)] = plan
        return plan

    def _plan(self, sym: Symbol) -> _Callee:
        decl = sym.decl
        assert isinstance(decl, ast.Definition)
        rules: dict[str, V.Range | None] = {}
        for p in decl.params:
            type_ = T.TYPE_NAMES.get(p.type_name)
            rules[p.name] = V.for_type(type_) if type_ is not None else None
        timings = tuple(
            s for s in decl.body.stmts if isinstance(s, ast.TimeSetting)
        ) if decl.kind == "element" else ()  # fmt: skip
        return _Callee(decl, self.scopes[id(sym.module)], decl.params, rules, timings)

    def call(self, call: ast.Call, env: _Env, t: float) -> float:
        plan = self._callee(call)
        params = plan.params
        rules = plan.rules
        bound: dict[str, Any] = {}
        for i, arg in enumerate(call.args):
            name = arg.name if arg.name is not None else params[i].name
            value = bound[name] = self.eval(arg.value, env)
            rule = rules[name]
            # a parameter passed on: checked where it is written (``check``, called only to
            # report: most values are in range)
            if rule is not None and V.problem(rule, value) is not None:
                self.check(rule, value, env, arg.value)
        if len(bound) < len(params):
            defaults: _Env | None = None  # the definition's scope: one for all its defaults
            for p in params:
                if p.name not in bound and p.default is not None:
                    if defaults is None:
                        defaults = _Env(plan.scope, {}, env.trace)
                    bound[p.name] = self.eval(p.default, defaults)
        trace = (*env.trace, (plan.decl.name, call.span))
        inner = _Env(plan.scope, bound, trace)
        for stmt in plan.timings:
            inner.timing = self.eval(stmt.duration, inner)
        return self.block(plan.decl.body, inner, t)

    # ------------------------------------------------------------ primitives
    def primitive(self, stmt: ast.Stmt, env: _Env, t: float) -> float:
        over = self.eval(stmt.over, env) if getattr(stmt, "over", None) is not None else None
        timing = over if over is not None else env.timing
        match stmt:
            case ast.Goal():
                return self.goal(stmt, env, t, timing)
            case ast.Posture():
                return self.posture_goal(stmt, env, t, timing)
            case ast.Walk():
                return self.walk(stmt, env, t, timing)
            case ast.Grip():
                hands = HANDS[self.eval(stmt.hand, env)]
                default = _GRASP if stmt.state == "closed" else _RELEASE
                d = self.duration(timing, default, stmt, env)
                for h in hands:
                    self.emit("grip", h, t, t + d, {"state": stmt.state}, stmt, env)
                    if stmt.state == "closed":
                        self.closed.add(h)
                        self.released_at.pop(h, None)
                    else:
                        self.closed.discard(h)
                        at = self.hand_pos.get(h)
                        if at is not None and at[1] - self.root[1] >= ARM_REST_MIN_HEIGHT:
                            self.released_at[h] = t + d
                        else:
                            self.released_at.pop(h, None)
                return t + d
            case ast.Gaze():
                site: Site = self.eval(stmt.target, env)
                d = self.duration(timing, _LOOK, stmt, env)
                self.emit(
                    "gaze",
                    "head",
                    t,
                    t + d,
                    {"site": site.name, "position": site.position},
                    stmt,
                    env,
                )
                return t + d
            case ast.Still():
                d = self.duration(timing, None, stmt, env)
                self.emit("hold", "body", t, t + d, {}, stmt, env)
                return t + d
        raise AssertionError(stmt)

    def goal(self, stmt: ast.Goal, env: _Env, t: float, timing: Any) -> float:
        hands = HANDS[self.eval(stmt.effector, env)]
        site: Site = self.eval(stmt.target, env)
        offset = self.eval(stmt.offset, env) if stmt.offset is not None else (0.0, 0.0, 0.0)
        if stmt.offset is not None:
            self.check(V.OFFSET, offset, env, stmt.offset)
        target = tuple(p + o for p, o in zip(site.position, offset, strict=True))
        approach = (
            self.eval(stmt.approach, env) if stmt.approach is not None else DEFAULT_APPROACH_M
        )
        if stmt.approach is not None:
            self.check(V.APPROACH, approach, env, stmt.approach)
        for h in hands:
            let_go = self.released_at.get(h)
            if (
                let_go is not None
                and t - let_go >= ARM_REST_IDLE - 1e-9
                and self.posture in ARM_REST_POSTURES
            ):
                # idle that long, standing, the arm came down to the side (passes.rest): the
                # reach is timed from there, not from the site it let go of
                self.hand_pos[h] = None
        distance = max(_dist(self._hand(h), target) for h in hands)
        d = self.duration(timing, _REACH, stmt, env, min(distance, MAX_HAND_TRAVEL_M))
        if approach == 0:
            share = 0.0  # no approach point: the whole goal is target approaching
        elif distance > 0:
            share = min(max(approach / distance, TO_SHARE[0]), TO_SHARE[1])
        else:
            share = 1.0
        t_contact = t + d * (1.0 - share)
        for h in hands:
            params = {
                "site": site.name,
                "position": target,
                "normal": site.normal,
                "frame": site.frame,
                "orient": stmt.orient,
                "approach": approach,
                "two_handed": len(hands) == 2,
                "phases": {"TA": [t, t_contact], "TO": [t_contact, t + d]},
                "travel": distance,
                **_load(timing),
            }
            self.emit("goal", h, t, t + d, params, stmt, env)
            self.hand_pos[h] = target
            self.reached_since_posture = True
        return t + d

    def posture_goal(self, stmt: ast.Posture, env: _Env, t: float, timing: Any) -> float:
        sig = B.POSTURES[stmt.kind]
        values: dict[str, Any] = {p.name: p.default for p in sig.params}
        written: dict[str, ast.Node] = {}
        for i, arg in enumerate(stmt.args):
            name = arg.name or sig.params[i].name
            values[name], written[name] = self.eval(arg.value, env), arg.value
        kind = stmt.kind
        for name, rule in _posture_rules(kind):  # the ranges a body can take
            self.check(rule, values[name], env, written.get(name, stmt))
        if kind == "twist":
            return self.twist(stmt, env, t, timing, values)
        if (
            kind == "stand"
            and self.posture == "stand"
            and timing is None
            and not self.reached_since_posture
        ):
            return t  # already standing, as it stood up or walked: nothing to do
        default_code = {
            ("stand", "kneel"): "AKBK",
            ("stand", "sit"): "STD",
            ("sit", "stand"): "SIT",
        }.get((kind, self.posture))
        if default_code is None:
            if kind == "stand":
                default_code = "AB"
            elif kind == "kneel" and values.get("knees") == 2:
                default_code = "KBK"
            elif kind == "sit":
                default_code = "SIT"
            else:
                default_code = "B"
        d = self.duration(timing, _code_timing(default_code), stmt, env)
        params = {"posture": kind, **{k: v for k, v in values.items() if k != "hand"}}
        self.emit("posture", "body", t, t + d, params, stmt, env)
        # rising from one knee is MTM-1 AB, from both knees AKBK: remember which
        self.posture = "kneel_one" if kind == "kneel" and values.get("knees") == 1 else kind
        self.reached_since_posture = False
        for h in HAND_REST:
            if h not in self.closed:
                # a free hand does not stay on the site it touched while the body squats,
                # kneels or rises: the next reach travels from the hand's side, not from that
                # site (a reach back to it would otherwise be timed, and planned, as no move)
                self.hand_pos[h] = None
        return t + d

    def twist(
        self, stmt: ast.Posture, env: _Env, t: float, timing: Any, values: dict[str, Any]
    ) -> float:
        """A hand turning what it holds: with a tool, the goal before (the reach onto the
        fastener) addresses the tool's tip, and the turn becomes the tool's strokes (docs/tools.md):
        a wrench's arcs of at most ``swing``, else quarter turns of the forearm."""
        tool = values["tool"] if isinstance(values["tool"], Tool) else None
        if tool is None and values["tool"] == "none" and self.tool is not None:
            # an untimed bare `posture twist` has always carried the task's tool as its load
            load = float(values["load"]) + float(self.tool.properties.get("mass", 0.0))
        else:
            load = float(values["load"]) + _tool_mass(tool)
        arc = tool is not None and tool.properties.get("kind") in B.ARC_TOOL_KINDS
        stroke = values["swing"] if arc else math.pi / 2
        if tool is None and values["tool"] == "none" and abs(values["angle"]) <= math.pi:
            strokes = [values["angle"]]  # a plain twist, as written
        else:  # counted before they are built: `turns: 1000000000` fails fast, in no memory
            hands = len(HANDS[values["hand"]])
            needed = self.count + _stroke_count(values["angle"], stroke) * hands
            if needed > self.budget:
                raise _BudgetExceeded(
                    _user_line(env, stmt),
                    needed,
                    help="lower the turns (or widen the swing), or raise the limit with "
                    "--expansion-budget",
                )
            strokes = _strokes(values["angle"], stroke)
        stated = None if timing is None else self.duration(timing, None, stmt, env)
        if stated is not None and isinstance(timing, Timing) and timing.rule == "turn":
            # MTM-1's turn (the stdlib's `turn`), no faster than a forearm turns (_stroke_tmu)
            floor = sum(_forearm_tmu(a, tool, arc) for a in strokes) * T.TMU_SECONDS
            stated = max(stated, floor)
        for h in HANDS[values["hand"]]:
            fastener = self._hold_tool(h, tool, arc, stmt, env)
            t_h = t
            for i, angle in enumerate(strokes):
                params = _stroke_params(angle, i, len(strokes), tool, fastener, arc)
                if float(values["load"]) > 0:  # held besides the tool (RULA's force score)
                    params["load"] = float(values["load"])
                default = Timing("fixed", {"tmu": _stroke_tmu(angle, load, tool, arc)})
                d = (
                    stated / len(strokes)
                    if stated is not None
                    else self.duration(None, default, stmt, env)
                )
                self.emit("posture", h, t_h, t_h + d, params, stmt, env)
                t_h += d
        return t_h

    def _hold_tool(
        self, hand: str, tool: Tool | None, arc: bool, stmt: ast.Stmt, env: _Env
    ) -> dict[str, Any] | None:
        """The goal this hand last reached (its fastener), now made with the tool's tip."""
        if tool is None:
            return None
        goal = next(
            (p for p in reversed(self.out) if p.kind == "goal" and p.effector == hand), None
        )
        if goal is None:
            self.fail(
                "MT0309",
                f"the {_part(hand)} turns `{tool.name}` on nothing: reach a fastener first",
                env,
                stmt,
            )
        assert goal is not None
        if arc and goal.params.get("normal") is None:
            self.fail(
                "MT0309",
                f"`{tool.name}` swings about the fastener's axis, but site "
                f"`{goal.params['site']}` has no normal",
                env,
                stmt,
                help="give the site its axis: `normal (x, y, z)`",
            )
        goal.params["tool"] = _tool_dict(tool)
        return goal.params

    def walk(self, stmt: ast.Walk, env: _Env, t: float, timing: Any) -> float:
        x, y, z = self.root
        in_front: Site | None = None
        if stmt.mode == "to":
            site: Site = self.eval(stmt.target, env)
            goal, worked_at = stand_point(site.position, site.normal, self.root, y)
            name = site.name
            in_front = site if worked_at else None
        else:
            displacement = self.eval(stmt.target, env)
            self.check(V.DISPLACEMENT, displacement, env, stmt.target)
            dx, _, dz = displacement
            goal, name = (x + dx, y, z + dz), None
        # a site stood in front of is faced, unless the walk names what to face
        facing = self.eval(stmt.facing, env) if stmt.facing is not None else in_front
        distance = _dist(self.root, goal)
        d = self.duration(timing, _WALK, stmt, env, distance)
        params = {
            "site": name,
            "from": self.root,
            "to": goal,
            "facing": facing.name if facing is not None else None,
            "facing_position": facing.position if facing is not None else None,
            "distance": distance,
        }
        self.emit("locomotion", "root", t, t + d, params, stmt, env)
        if timing is None or (isinstance(timing, Timing) and timing.rule == "walk"):
            self.mtm_walks.add(id(self.out[-1]))  # timed by MTM paces: gets turn time too
        self.root = goal
        for h in HAND_REST:
            self.hand_pos[h] = None  # the hands come back to the sides while walking
        return t + d

    def _hand(self, hand: str) -> tuple[float, float, float]:
        pos = self.hand_pos.get(hand)
        if pos is None:
            rest = HAND_REST[hand]
            pos = (self.root[0] + rest[0], self.root[1] + rest[1], self.root[2] + rest[2])
        return pos

    def duration(
        self, timing: Any, default: Timing | None, stmt: ast.Stmt, env: _Env, distance: float = 0.0
    ) -> float:
        """Seconds for one primitive: a stated duration, or an MTM-1 rule evaluated for it."""
        rule = timing if timing is not None else default
        if isinstance(rule, int | float):
            seconds = float(rule)
        else:
            assert isinstance(rule, Timing), rule
            seconds = self._mtm_tmu(rule, stmt, env, distance) * T.TMU_SECONDS
        if V.problem(V.DURATION, seconds) is not None:
            self.check(V.DURATION, seconds, env, stmt)
        return seconds

    def _mtm_tmu(self, rule: Timing, stmt: ast.Stmt, env: _Env, distance: float) -> float:
        a = rule.args
        match rule.rule:
            case "reach":
                return mtm.reach_tmu(a["case"], distance)
            case "move":
                return mtm.move_tmu(a["case"], distance)
            case "turn":
                return mtm.turn_tmu(a["angle"], a["load"])
            case "grasp":
                return mtm.grasp_tmu(a["case"])
            case "release":
                return mtm.code_tmu("RL1")
            case "walk":
                return mtm.walk_tmu(distance)
            case "code":
                if a["code"] not in mtm.other_codes():
                    self.fail("MT0309", f"no MTM-1 element `{a['code']}` in the tables", env, stmt)
                return mtm.code_tmu(a["code"])
            case "fixed":
                return float(a["tmu"])
        raise AssertionError(rule)

    def emit(
        self, kind: str, effector: str, start: float, end: float, params: dict[str, Any],
        stmt: ast.Stmt, env: _Env,
    ) -> None:  # fmt: skip
        self.count += 1
        if self.count > self.budget:
            raise _BudgetExceeded(_user_line(env, stmt), None, self.idle)
        origin = env.trace[1][1] if len(env.trace) > 1 else stmt.span
        path = env.path
        if path is None:
            path = env.path = tuple(name for name, _ in env.trace)
        self.out.append(
            Primitive(
                kind=kind,
                effector=effector,
                start=start,
                end=end,
                params=params,
                path=path,
                span=stmt.span,
                origin=origin,
            )
        )

    # ------------------------------------------------------------ values
    def _kind(self, expr: ast.Expr) -> str | None:
        """The checker's decision for a name (local, site, tool, enum, scene...), or None."""
        kind = self._kinds.get(id(expr), _UNRESOLVED)
        if kind is _UNRESOLVED:
            kind = self._kinds[id(expr)] = self.resolved.get(expr.span)
        return kind  # type: ignore[return-value]

    def eval(self, expr: ast.Expr | None, env: _Env) -> Any:
        kind = type(expr)  # the node classes have no subclasses: one look-up per node
        if kind is ast.Number:
            assert isinstance(expr, ast.Number)
            if expr.unit is None:
                return int(expr.value) if expr.is_int else expr.value
            value = self._literals.get(id(expr), _UNRESOLVED)
            if value is _UNRESOLVED:
                value = self._computed(expr.value * T.UNITS[expr.unit][1], env, expr)
                self._literals[id(expr)] = value
            return value
        if kind is ast.Name:
            assert isinstance(expr, ast.Name)
            name = expr.name
            resolved = self._kinds.get(id(expr), _UNRESOLVED)  # self._kind(expr), inline
            if resolved is _UNRESOLVED:
                resolved = self._kind(expr)
            if resolved == "local":
                return env.locals[name]
            if resolved == "site":
                return self.task_sites[name]
            if resolved == "tool":
                sym = env.scope.lookup(name)
                assert sym is not None and isinstance(sym.decl, ast.ToolDecl)
                tool = self._tool(sym.decl, env)
                if tool.properties.get("kind") == B.TASK_TOOL_KIND:
                    return self.tool  # stdlib.tools.task_tool: the task's tool, or none
                return tool
            return name  # an enum member: its name is its value
        if kind is ast.Vector:
            assert isinstance(expr, ast.Vector)
            value = self._literals.get(id(expr), _UNRESOLVED)
            if value is not _UNRESOLVED:
                return value
            factor = T.UNITS[expr.unit][1] if expr.unit is not None else 1.0
            value = self._computed(
                tuple(float(self.eval(i, env)) * factor for i in expr.items), env, expr
            )
            if all(_is_literal(i) for i in expr.items):
                self._literals[id(expr)] = value
            return value
        if kind is ast.Attr:
            assert isinstance(expr, ast.Attr)
            return self._attr(expr, env)
        if kind is ast.Binary:
            assert isinstance(expr, ast.Binary)
            left, right = self.eval(expr.left, env), self.eval(expr.right, env)
            return self._arith(expr.op, left, right, expr, env)
        if kind is ast.Unary:
            assert isinstance(expr, ast.Unary)
            v = self.eval(expr.operand, env)
            return tuple(-c for c in v) if isinstance(v, tuple) else -v
        if kind is ast.String:
            return expr.value  # type: ignore[union-attr]
        if kind is ast.CallExpr and isinstance(expr.func, ast.Attr):  # type: ignore[union-attr]
            assert isinstance(expr, ast.CallExpr) and isinstance(expr.func, ast.Attr)
            fname = expr.func.name
            sig = B.MTM_FUNCTIONS[fname]
            values = {p.name: p.default for p in sig.params}
            for i, arg in enumerate(expr.args):
                name = arg.name or sig.params[i].name
                values[name] = self.eval(arg.value, env)
                rule = V.MTM_ARGS.get((fname, name))
                if rule is not None:
                    self.check(rule, values[name], env, arg.value)
            return Timing(fname, values)
        if kind is ast.ListExpr:
            return [self.eval(i, env) for i in expr.items]  # type: ignore[union-attr]
        if expr is None:
            return None
        raise AssertionError(f"cannot evaluate {expr!r}")

    def _attr(self, expr: ast.Attr, env: _Env) -> Any:
        """`ReachCase.A` (an enum member), `scene.site` (another scene's site) or `tool.mass`."""
        attr = expr.name
        if self._kind(expr) == "enum":
            return attr  # ReachCase.A
        obj = expr.obj
        if type(obj) is ast.Name and self._kind(obj) == "scene":
            sym = env.scope.lookup(obj.name)
            assert sym is not None and isinstance(sym.decl, ast.Scene)
            site = self._scene_sites(sym)[attr]
            if site is not self.task_sites.get(attr):
                site = dataclasses.replace(site, name=f"{obj.name}.{attr}")
                self.other_sites[site.name] = site
            return site
        tool = self.eval(obj, env)
        if attr not in tool.properties:
            self.sink.report(
                "MT0309",
                f"tool `{tool.name}` does not declare its `{attr}`",
                expr.span,
                help=f"add `{attr} ...` to `tool {tool.name}`",
            )
            raise _Abort
        return tool.properties[attr]

    def _tool(self, decl: ast.ToolDecl, env: _Env) -> Tool:
        properties = {}
        for p in decl.properties:
            properties[p.name] = self.eval(p.value, env)
            rule = TOOL_RANGES.get(p.name)
            if rule is not None:
                self.check(rule, properties[p.name], env, p.value)
        return Tool(decl.name, properties)

    def _arith(self, op: str, a: Any, b: Any, expr: ast.Binary, env: _Env) -> Any:
        try:
            value = V.arith(op, a, b)
        except ZeroDivisionError:
            self.sink.report("MT0403", "division by zero", expr.span)
            raise _Abort from None
        except OverflowError:  # a whole number too large for a float
            value = math.inf
        return self._computed(value, env, expr)

    def _computed(self, value: Any, env: _Env, expr: ast.Expr) -> Any:
        """An arithmetic result, unless it overflowed (MT0309: no inf, NaN or huge whole number
        goes on to the motion; a NaN would not even serialise as JSON)."""
        if V.overflows(value):
            self.fail(
                "MT0309",
                "this value is too large: its arithmetic overflows",
                env,
                expr,
                help=f"keep numbers within the limits of docs/language.md (whole numbers up "
                f"to {V.MAX_INT:.0e})",
            )
        return value


@cache
def _posture_rules(kind: str) -> tuple[tuple[str, V.Range], ...]:
    """The ranges of a posture's arguments (``values.POSTURE_ARGS``), by parameter, in order."""
    return tuple(
        (name, rule) for (posture, name), rule in V.POSTURE_ARGS.items() if posture == kind
    )


def _is_literal(expr: ast.Expr) -> bool:
    """A number as written, negated or not: its value is the same wherever it is evaluated."""
    while type(expr) is ast.Unary:
        expr = expr.operand
    return type(expr) is ast.Number


def _load(timing: Any) -> dict[str, float]:
    """The mass (kg) a goal carries: the `load` of its `mtm.move` timing, when there is one; read
    by the lifting analysis (mtlc.ergonomics.niosh), not by the MTM-1 time."""
    load = float(timing.args.get("load", 0.0)) if isinstance(timing, Timing) else 0.0
    return {"load": load} if load > 0 else {}


def _tool_mass(tool: Tool | None) -> float:
    return float(tool.properties.get("mass", 0.0)) if tool is not None else 0.0


def _tool_dict(tool: Tool) -> dict[str, Any]:
    """The tool as plain data for the timeline and the IR (SI units, as declared)."""
    return {"name": tool.name, **tool.properties}


def _stroke_count(angle: float, stroke: float) -> int:
    """How many strokes of at most ``stroke`` turn ``angle`` (the angle and the stroke are
    finite, the stroke more than 0: their ranges are checked before)."""
    return max(1, math.ceil(abs(angle) / stroke - 1e-9))


def _strokes(angle: float, stroke: float) -> list[float]:
    """``angle`` in strokes of at most ``stroke``, the last taking the rest: 1080 deg at 60 deg
    is 18 strokes."""
    n = _stroke_count(angle, stroke)
    sign = 1.0 if angle >= 0 else -1.0
    out = [sign * stroke] * (n - 1)
    return [*out, angle - sign * stroke * (n - 1)]


def _stroke_params(
    angle: float,
    index: int,
    count: int,
    tool: Tool | None,
    fastener: dict[str, Any] | None,
    arc: bool,
) -> dict[str, Any]:
    """A twist primitive's params; a wrench's stroke also names its fastener and its place in
    the series (``stroke`` of ``strokes``)."""
    if not arc:
        return {"posture": "twist", "angle": angle, **({"tool": _tool_dict(tool)} if tool else {})}
    assert tool is not None and fastener is not None
    return {
        "posture": "stroke",
        "angle": angle,
        "stroke": index + 1,
        "strokes": count,
        "tool": _tool_dict(tool),
        "site": fastener["site"],
        "position": fastener["position"],
        "normal": fastener["normal"],
    }


# The forearm's peak speed in a twist (issue 19): a person's joints move at most 360 deg/s in
# this work, a tool's quarter turns on a fastener at most 600 deg/s (the wrist's looser goal);
# a little under each so a frame's step stays under it at 30 fps.
FOREARM_SPEED = math.radians(340.0)  # rad/s: a hand turning what it holds
TOOL_FOREARM_SPEED = math.radians(570.0)  # rad/s: a screwdriver's or pliers' quarter turns
SMOOTH_PEAK = 1.5  # a twist starts and ends at rest: its peak speed is 1.5x its mean


def _stroke_tmu(angle: float, load: float, tool: Tool | None, arc: bool) -> float:
    """MTM-1 for one stroke: the turn; a wrench is then let go (RL1), moved back over the arc's
    chord (R-B) and re-grasped (G1A); a ratchet swings back engaged (a second turn). A forearm
    twist takes at least the time a person's forearm needs for it (``FOREARM_SPEED``): MTM-1's
    T90S (0.19 s) would turn it at 700 deg/s at its peak."""
    turn = mtm.turn_tmu(angle, load)
    if not arc or tool is None:
        return max(turn, _forearm_tmu(angle, tool, arc))
    if tool.properties.get("kind") == "ratchet":
        return 2.0 * turn
    chord = 2.0 * _tool_radius(tool) * math.sin(abs(angle) / 2.0)
    return turn + mtm.code_tmu("RL1") + mtm.reach_tmu("B", chord) + mtm.grasp_tmu("G1A")


def _forearm_tmu(angle: float, tool: Tool | None, arc: bool) -> float:
    """The least time (TMU) of a forearm's twist by ``angle`` at a person's speed (0 for a
    wrench's arc: the shoulder and elbow swing it)."""
    if arc and tool is not None:
        return 0.0
    speed = FOREARM_SPEED if tool is None else TOOL_FOREARM_SPEED
    return SMOOTH_PEAK * abs(angle) / speed / T.TMU_SECONDS


def _tool_radius(tool: Tool) -> float:
    """Distance from the fastener's axis (through the tip, along ``axis``) to the grip (m)."""
    grip = tool.properties.get("grip", (0.0, 0.0, 0.0))
    tip = tool.properties.get("tip", grip)
    axis = tool.properties.get("axis", (0.0, -1.0, 0.0))
    d = [g - p for g, p in zip(grip, tip, strict=True)]
    norm = math.hypot(*axis) or 1.0
    along = sum(c * a / norm for c, a in zip(d, axis, strict=True))
    return math.sqrt(max(0.0, sum(c * c for c in d) - along * along))


def _part(effector: str) -> str:
    return {"root": "whole body (walking)", "body": "whole body", "head": "head"}.get(
        effector, effector.replace("_", " ")
    )


def _user_line(env: _Env, stmt: ast.Node) -> Span:
    """The statement in the task's own body that led to ``stmt``: where the user can act."""
    return env.trace[1][1] if len(env.trace) > 1 else stmt.span


def _dist(a: tuple[float, ...], b: tuple[float, ...]) -> float:
    return math.dist(a, b)
