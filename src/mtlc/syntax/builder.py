"""Build AST nodes from lark's parse tree, with spans, and limit expression depth.

The limit keeps every later pass (which recurses over expressions) far from Python's recursion
limit, whatever the input: a 100,000-term sum is reported, not crashed on.
"""

from __future__ import annotations

from typing import Any

from lark import Token
from lark.visitors import Transformer

from mtlc.diagnostics import DiagnosticSink, Span
from mtlc.syntax import ast
from mtlc.syntax.lexer import decode_string

MAX_EXPR_DEPTH = 100
_INF = float("inf")
_new_span = tuple.__new__  # Span(...) without the NamedTuple constructor's extra call
# the commonest nodes, built by position (ast.maker: the same nodes, without keyword calls)
_name = ast.maker(ast.Name, "span", "name")
_string = ast.maker(ast.String, "span", "value")
_number = ast.maker(ast.Number, "span", "value", "is_int", "unit", "unit_span")
_arg = ast.maker(ast.Arg, "span", "name", "value")
_named_arg = ast.maker(ast.Arg, "span", "name", "value", "name_span")
_call = ast.maker(ast.Call, "span", "callee", "callee_span", "args")
_binary = ast.maker(ast.Binary, "span", "op", "left", "right")
_vector = ast.maker(ast.Vector, "span", "items", "unit", "unit_span")
_block = ast.maker(ast.Block, "span", "stmts")
_set_depth = ast.Expr.depth.__set__  # type: ignore[attr-defined]
_site_decl = ast.maker(ast.SiteDecl, "span", "name", "name_span", "position", "normal", "frame")
_scene = ast.maker(
    ast.Scene, "span", "name", "name_span", "ground", "sites", "shapes", "node_sites", "sites_from"
)
# the clauses each kind of shape takes, and those it needs (docs/language.md, "Models and solids")
SHAPE_CLAUSES: dict[str, tuple[str, ...]] = {
    "model": ("at", "rotate", "units", "up"),
    "box": ("size", "at", "rotate"),
    "cylinder": ("radius", "length", "axis", "at"),
    "plate": ("size", "at", "normal", "opening"),
}
SHAPE_NEEDS: dict[str, tuple[str, ...]] = {
    "model": (),
    "box": ("size",),
    "cylinder": ("radius", "length"),
    "plate": ("size",),
}
_param = ast.maker(ast.Param, "span", "name", "type_name", "type_span", "default")
_definition = ast.maker(ast.Definition, "span", "name", "name_span", "kind", "params", "body")
_task = ast.maker(ast.Task, "span", "name", "name_span", "title", "body")
_repeat = ast.maker(ast.Repeat, "span", "count", "body")
_parallel = ast.maker(ast.Parallel, "span", "body")
_manikin_setting = ast.maker(
    ast.ManikinSetting,
    "span",
    "population",
    "population_span",
    "sex",
    "sex_span",
    "percentile",
    "percentile_span",
)
_scene_setting = ast.maker(ast.SceneSetting, "span", "name", "name_span")
_time_setting = ast.maker(ast.TimeSetting, "span", "duration")
_goal = ast.maker(ast.Goal, "span", "effector", "target", "approach", "offset", "orient", "over")
_unary = ast.maker(ast.Unary, "span", "op", "operand")
_attr = ast.maker(ast.Attr, "span", "obj", "name", "name_span")
_call_expr = ast.maker(ast.CallExpr, "span", "func", "args")


_SHAPE_EXAMPLES = {
    "box": "e.g. `box bracket size (20, 5, 10) cm at (0, 120, 100) cm`",
    "cylinder": "e.g. `cylinder pipe radius 2 cm length 80 cm axis (1, 0, 0) at (0, 90, 100) cm`",
    "plate": "e.g. `plate panel size (60, 40, 0.2) cm at (0, 120, 112) cm normal (0, 0, -1)`",
}


class AstBuilder(Transformer):
    """Runs inside lark's LALR parser (one callback per reduced rule), so no parse tree is built.

    One instance is bound to the cached parser; ``begin`` points it at the file being parsed.
    """

    def __init__(self) -> None:
        super().__init__()
        self.file = ""
        self.sink = DiagnosticSink()

    def begin(self, file: str, sink: DiagnosticSink) -> None:
        self.file = file
        self.sink = sink

    # ------------------------------------------------------------ helpers
    def _sp(self, x: Any) -> Span:
        if type(x) is Token or isinstance(x, Token):  # (the tuple built directly: a Span per
            # token and node; the exact type first: the lexer's tokens are all of it)
            return _new_span(
                Span,
                (self.file, x.line, x.column, x.end_line, x.end_column, x.start_pos, x.end_pos),
            )
        if isinstance(x, ast.Node):
            return x.span
        if isinstance(x, tuple) and x and isinstance(x[-1], Span):
            return x[-1]
        raise TypeError(f"no span for {x!r}")

    def _join(self, first: Any, last: Any) -> Span:
        """first's span .to(last's), built directly: a token's fields are read where they are
        (no span is made for either end: there is a join per node)."""
        if type(first) is Token:
            file, line, column, start = self.file, first.line, first.column, first.start_pos
        else:  # (a node's span read at once: _sp's answer, without its call)
            a = first.span if isinstance(first, ast.Node) else self._sp(first)
            file, line, column, start = a[0], a[1], a[2], a[5]
        if type(last) is Token:
            return _new_span(
                Span, (file, line, column, last.end_line, last.end_column, start, last.end_pos)
            )
        b = last.span if isinstance(last, ast.Node) else self._sp(last)
        return _new_span(Span, (file, line, column, b[3], b[4], start, b[6]))

    def _expr(self, node: ast.Expr, *children: ast.Expr) -> ast.Expr:
        depth = 1  # 1 + the deepest child's (a loop: most nodes have one to three children)
        for child in children:
            if child.depth >= depth:
                depth = child.depth + 1
        if depth > MAX_EXPR_DEPTH:
            if not any(isinstance(c, ast.Error) for c in children):
                self.sink.report(
                    "MT0104",
                    f"expression nests more than {MAX_EXPR_DEPTH} deep",
                    node.span,
                    help="break it into parameters or smaller definitions",
                )
            node = ast.Error(span=node.span)
        _set_depth(node, depth)  # frozen: set once, here, before anyone sees it (by its slot)
        return node

    @staticmethod
    def _present(items: Any) -> list[Any]:
        return [x for x in items if x is not None]

    def _args(self, args: Any) -> tuple[ast.Arg, ...]:
        if args is None:
            return ()
        return tuple(args)

    # ------------------------------------------------------------ modules
    def qualname(self, c: list[Token]) -> tuple[tuple[str, ...], Span]:
        return tuple([t.value for t in c]), self._join(c[0], c[-1])

    def use_decl(self, c: list[Any]) -> ast.Use:
        names, span = c[1]
        return ast.Use(span=self._join(c[0], c[1]), module=names, module_span=span)

    # ------------------------------------------------------------ scenes and tools
    def ground_decl(self, c: list[Any]) -> tuple[str, ast.Expr, Span]:
        return ("ground", c[1], self._join(c[0], c[1]))

    def site_normal(self, c: list[Any]) -> tuple[str, ast.Expr, Span]:
        return ("normal", c[1], self._join(c[0], c[1]))

    def site_frame(self, c: list[Any]) -> tuple[str, ast.Expr, Span]:
        return ("frame", c[1], self._join(c[0], c[1]))

    def site_decl(self, c: list[Any]) -> ast.SiteDecl:
        clauses: dict[str, ast.Expr] = {}
        for kind, expr, span in c[3:]:
            if kind in clauses:
                self.sink.report("MT0210", f"`{kind}` is given twice for this site", span)
            elif clauses:
                self.sink.report(
                    "MT0210",
                    "a site takes a normal or a frame, not both",
                    span,
                    help="a frame already fixes the site's orientation; keep one of them",
                )
            else:
                clauses[kind] = expr
        return _site_decl(
            self._join(c[0], c[-1]),
            c[1].value,
            self._sp(c[1]),
            c[2],
            clauses.get("normal"),
            clauses.get("frame"),
        )

    def node_site_decl(self, c: list[Token]) -> ast.NodeSite:
        kw, name, model, node = c
        return ast.NodeSite(
            span=self._join(kw, node),
            name=name.value,
            name_span=self._sp(name),
            model=model.value,
            model_span=self._sp(model),
            node=node.value,
            node_span=self._sp(node),
        )

    def sites_from_decl(self, c: list[Token]) -> ast.SitesFrom:
        kw, _from, model = c
        return ast.SitesFrom(
            span=self._join(kw, model), model=model.value, model_span=self._sp(model)
        )

    def value_clause(self, c: list[Any]) -> ast.ShapeClause:
        kw, value = c
        return ast.ShapeClause(
            span=self._join(kw, value), keyword=kw.value, word=None, word_span=None, value=value
        )

    def word_clause(self, c: list[Token]) -> ast.ShapeClause:
        kw, word = c
        return ast.ShapeClause(
            span=self._join(kw, word),
            keyword=kw.value,
            word=word.value,
            word_span=self._sp(word),
            value=None,
        )

    def opening_clause(self, c: list[Any]) -> ast.ShapeClause:
        kw, word, value = c
        return ast.ShapeClause(
            span=self._join(kw, value),
            keyword=kw.value,
            word=word.value,
            word_span=self._sp(word),
            value=value,
        )

    def model_decl(self, c: list[Any]) -> ast.Shape:
        kw, name, path, *clauses = c
        return self._shape(kw, name, decode_string(path, self.file, self.sink), path, clauses)

    def solid_decl(self, c: list[Any]) -> ast.Shape:
        kw, name, *clauses = c
        return self._shape(kw, name, None, None, clauses)

    def _shape(
        self, kw: Token, name: Token, path: str | None, path_tok: Token | None, clauses: list[Any]
    ) -> ast.Shape:
        """A model or solid, its clauses checked against its kind (MT0212; twice: MT0210)."""
        kind = kw.value
        allowed = SHAPE_CLAUSES[kind]
        kept: list[ast.ShapeClause] = []
        for clause in clauses:
            if clause.keyword not in allowed:
                self.sink.report(
                    "MT0212",
                    f"a {kind} takes no `{clause.keyword}`",
                    clause.span,
                    help=f"a {kind} takes " + ", ".join(f"`{a}`" for a in allowed),
                )
            elif any(k.keyword == clause.keyword for k in kept):
                self.sink.report("MT0210", f"`{clause.keyword}` is given twice", clause.span)
            else:
                kept.append(clause)
        last = clauses[-1] if clauses else (path_tok if path_tok is not None else name)
        span = self._join(kw, last)
        for needed in SHAPE_NEEDS[kind]:
            if not any(k.keyword == needed for k in kept):
                self.sink.report(
                    "MT0212",
                    f"{kind} `{name.value}` needs its `{needed}`",
                    span,
                    help=_SHAPE_EXAMPLES[kind],
                )
        return ast.Shape(
            span=span,
            name=name.value,
            name_span=self._sp(name),
            kind=kind,
            file=path,
            file_span=self._sp(path_tok) if path_tok is not None else None,
            clauses=tuple(kept),
        )

    def scene_decl(self, c: list[Any]) -> ast.Scene:
        ground: ast.Expr | None = None
        sites = []
        shapes = []
        node_sites = []
        sites_from = []
        for member in self._present(c[2:-1]):
            if isinstance(member, ast.SiteDecl):
                sites.append(member)
            elif isinstance(member, ast.Shape):
                shapes.append(member)
            elif isinstance(member, ast.NodeSite):
                node_sites.append(member)
            elif isinstance(member, ast.SitesFrom):
                sites_from.append(member)
            elif ground is not None:
                self.sink.report("MT0210", "the scene's ground is given twice", member[2])
            else:
                ground = member[1]
        return _scene(
            self._join(c[0], c[-1]),
            c[1].value,
            self._sp(c[1]),
            ground,
            tuple(sites),
            tuple(shapes),
            tuple(node_sites),
            tuple(sites_from),
        )

    def tool_prop(self, c: list[Any]) -> ast.ToolProperty:
        return ast.ToolProperty(span=self._join(c[0], c[1]), name=c[0].value, value=c[1])

    def tool_decl(self, c: list[Any]) -> ast.ToolDecl:
        return ast.ToolDecl(
            span=self._join(c[0], c[-1]),
            name=c[1].value,
            name_span=self._sp(c[1]),
            properties=tuple(self._present(c[2:-1])),
        )

    # ------------------------------------------------------------ definitions
    def param(self, c: list[Any]) -> ast.Param:
        name, type_tok, default = c
        return _param(
            self._join(name, default if default is not None else type_tok),
            name.value,
            type_tok.value,
            self._sp(type_tok),
            default,
        )

    def definition(self, c: list[Any]) -> ast.Definition:
        kind, name, *params, body = c
        return _definition(
            self._join(kind, body),
            name.value,
            self._sp(name),
            kind.value,
            tuple(self._present(params)),
            body,
        )

    def task_decl(self, c: list[Any]) -> ast.Task:
        kw, name, title, body = c
        return _task(
            self._join(kw, body),
            name.value,
            self._sp(name),
            decode_string(title, self.file, self.sink) if title is not None else None,
            body,
        )

    def block(self, c: list[Any]) -> ast.Block:
        return _block(self._join(c[0], c[-1]), tuple(self._present(c[1:-1])))

    # ------------------------------------------------------------ statements
    def args(self, c: list[Any]) -> tuple[ast.Arg, ...]:
        return tuple([a if type(a) is ast.Arg else _arg(a.span, None, a) for a in c])

    def named_arg(self, c: list[Any]) -> ast.Arg:
        return _named_arg(self._join(c[0], c[1]), c[0].value, c[1], self._sp(c[0]))

    def call_stmt(self, c: list[Any]) -> ast.Call:
        (names, name_span), args, rpar = c
        if type(rpar) is Token:  # name_span.to(self._sp(rpar)), built directly
            span = _new_span(
                Span,
                (name_span[0], name_span[1], name_span[2], rpar.end_line, rpar.end_column,
                 name_span[5], rpar.end_pos),
            )  # fmt: skip
        else:
            span = name_span.to(self._sp(rpar))
        return _call(span, names, name_span, self._args(args))

    def repeat_stmt(self, c: list[Any]) -> ast.Repeat:
        return _repeat(self._join(c[0], c[2]), c[1], c[2])

    def for_stmt(self, c: list[Any]) -> ast.ForEach:
        kw, var, items, body = c
        return ast.ForEach(
            span=self._join(kw, body),
            var=var.value,
            var_span=self._sp(var),
            items=items,
            body=body,
        )

    def parallel_stmt(self, c: list[Any]) -> ast.Parallel:
        return _parallel(self._join(c[0], c[1]), c[1])

    def manikin_stmt(self, c: list[Token]) -> ast.ManikinSetting:
        kw, pop, sex, pct = c
        return _manikin_setting(
            self._join(kw, pct),
            pop.value,
            self._sp(pop),
            sex.value,
            self._sp(sex),
            pct.value,
            self._sp(pct),
        )

    def scene_stmt(self, c: list[Token]) -> ast.SceneSetting:
        return _scene_setting(self._join(c[0], c[1]), c[1].value, self._sp(c[1]))

    def tool_stmt(self, c: list[Any]) -> ast.ToolSetting:
        return ast.ToolSetting(span=self._join(c[0], c[1]), tool=c[1])

    def budget_stmt(self, c: list[Any]) -> ast.BudgetSetting:
        return ast.BudgetSetting(span=self._join(c[0], c[1]), limit=c[1])

    def time_stmt(self, c: list[Any]) -> ast.TimeSetting:
        return _time_setting(self._join(c[0], c[1]), c[1])

    def approach_clause(self, c: list[Any]) -> tuple[str, Any, Span]:
        return ("approach", c[0], self._sp(c[0]))

    def offset_clause(self, c: list[Any]) -> tuple[str, Any, Span]:
        return ("offset", c[0], self._sp(c[0]))

    def orient_clause(self, c: list[Any]) -> tuple[str, Any, Span]:
        return ("orient", True, self._sp(c[0]))

    def over_clause(self, c: list[Any]) -> tuple[str, Any, Span]:
        return ("over", c[0], self._sp(c[0]))

    def goal_stmt(self, c: list[Any]) -> ast.Goal:
        kw, effector, target, *clauses = c
        found: dict[str, Any] = {}
        for kind, value, span in clauses:
            if kind in found:
                self.sink.report("MT0210", f"`{kind}` is given twice in this goal", span)
            else:
                found[kind] = value
        last = clauses[-1] if clauses else target
        return _goal(
            self._join(kw, last),
            effector,
            target,
            found.get("approach"),
            found.get("offset"),
            bool(found.get("orient", False)),
            found.get("over"),
        )

    def posture_args(self, c: list[Any]) -> tuple[tuple[ast.Arg, ...], Span]:
        return self._args(c[0]), self._sp(c[1])

    def posture_stmt(self, c: list[Any]) -> ast.Posture:
        kw, kind, args, over = c
        last = over if over is not None else args if args is not None else kind
        return ast.Posture(
            span=self._join(kw, last),
            kind=kind.value,
            kind_span=self._sp(kind),
            args=args[0] if args is not None else (),
            over=over[1] if over is not None else None,
        )

    def walk_stmt(self, c: list[Any]) -> ast.Walk:
        kw, mode, target, facing, over = c
        last = over if over is not None else facing if facing is not None else target
        return ast.Walk(
            span=self._join(kw, last),
            mode=mode.value,
            target=target,
            facing=facing,
            over=over[1] if over is not None else None,
        )

    def grip_stmt(self, c: list[Any]) -> ast.Grip:
        kw, hand, state, over = c
        return ast.Grip(
            span=self._join(kw, over if over is not None else state),
            hand=hand,
            state=state.value,
            state_span=self._sp(state),
            over=over[1] if over is not None else None,
        )

    def gaze_stmt(self, c: list[Any]) -> ast.Gaze:
        kw, target, over = c
        return ast.Gaze(
            span=self._join(kw, over if over is not None else target),
            target=target,
            over=over[1] if over is not None else None,
        )

    def still_stmt(self, c: list[Any]) -> ast.Still:
        return ast.Still(span=self._join(c[0], c[1]), over=c[1][1])

    # ------------------------------------------------------------ expressions
    def _binary(self, op: str, c: list[Any]) -> ast.Expr:
        left, right = c
        node = _binary(self._join(left, right), op, left, right)
        return self._expr(node, left, right)

    def add(self, c: list[Any]) -> ast.Expr:
        return self._binary("+", c)

    def sub(self, c: list[Any]) -> ast.Expr:
        return self._binary("-", c)

    def mul(self, c: list[Any]) -> ast.Expr:
        return self._binary("*", c)

    def div(self, c: list[Any]) -> ast.Expr:
        return self._binary("/", c)

    def neg(self, c: list[Any]) -> ast.Expr:
        return self._expr(_unary(self._join(c[0], c[1]), "-", c[1]), c[1])

    def attr(self, c: list[Any]) -> ast.Expr:
        obj, name = c
        node = _attr(self._join(obj, name), obj, name.value, self._sp(name))
        return self._expr(node, obj)

    def call_expr(self, c: list[Any]) -> ast.Expr:
        func, args, rpar = c
        args_t = self._args(args)
        node = _call_expr(self._join(func, rpar), func, args_t)
        return self._expr(node, func, *(a.value for a in args_t))

    def number(self, c: list[Any]) -> ast.Expr:
        num, unit = c
        text = num.value
        is_int = text.isascii() and text.isdigit()
        try:
            value = float(text)
        except ValueError:  # the pattern only admits valid floats; keep the tree whole anyway
            value = 0.0
        if value == _INF:
            self.sink.report(
                "MT0309",
                "number is too large",
                self._sp(num),
                help="a number must be finite: below 1.8e308",
            )
            return ast.Error(span=self._sp(num))
        if type(num) is not Token or (unit is not None and type(unit) is not Token):
            if unit is None:
                return _number(self._sp(num), value, is_int, None, None)
            return _number(self._join(num, unit), value, is_int, unit.value, self._sp(unit))
        # the same spans, built directly from the tokens (a number per literal)
        file, line, column, start = self.file, num.line, num.column, num.start_pos
        if unit is None:
            span = (file, line, column, num.end_line, num.end_column, start, num.end_pos)
            return _number(_new_span(Span, span), value, is_int, None, None)
        end_line, end_column, end = unit.end_line, unit.end_column, unit.end_pos
        unit_span = (file, unit.line, unit.column, end_line, end_column, unit.start_pos, end)
        return _number(
            _new_span(Span, (file, line, column, end_line, end_column, start, end)),
            value,
            is_int,
            unit.value,
            _new_span(Span, unit_span),
        )

    def string(self, c: list[Token]) -> ast.Expr:
        return _string(self._sp(c[0]), decode_string(c[0], self.file, self.sink))

    def name(self, c: list[Token]) -> ast.Expr:
        x = c[0]
        if type(x) is not Token:
            return _name(self._sp(x), x.value)
        span = (self.file, x.line, x.column, x.end_line, x.end_column, x.start_pos, x.end_pos)
        return _name(_new_span(Span, span), x.value)  # (_sp's span, built here: a name per word)

    def vector(self, c: list[Any]) -> ast.Expr:
        lpar, *items, rpar, unit = c
        node = _vector(
            self._join(lpar, unit if unit is not None else rpar),
            tuple(items),
            unit.value if unit is not None else None,
            self._sp(unit) if unit is not None else None,
        )
        return self._expr(node, *items)

    def list(self, c: list[Any]) -> ast.Expr:
        lsqb, *items, rsqb = c
        items = self._present(items)
        return self._expr(ast.ListExpr(span=self._join(lsqb, rsqb), items=tuple(items)), *items)
