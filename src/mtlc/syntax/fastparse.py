"""A recursive-descent parser for items that parse cleanly, in front of lark's LALR parser.

Why: lark's LALR loop spends most of its time on unit reductions (a number goes through
primary, postfix, unary, product, sum and expr before it is an argument), about 15 us a token;
this parser reads the same grammar directly, several times faster. What it may not do is
decide differently: it calls the very ``AstBuilder`` methods lark calls, with the same
children (placeholders, dropped literals), in the same order (post-order, left to right), and
it takes lark's two conflict resolutions (shift on both):

- a NAME after a number or a vector is its unit (`grip 3 closed` is refused by both);
- `tool`, `goal`, `grip`, `repeat`, `budget` and `time` followed by `(` start their statement,
  not a call (other keywords followed by `(` or `.` are the name of a call).

Anything else it does not accept (every error, and a chain of more than ``MAX_UNARY`` minus
signs) raises ``Fallback``, and the caller parses the item with lark: so every diagnostic,
recovery and message comes from lark as before, and this parser only needs to be right on
input it accepts. ``tests/test_fastparse.py`` compares both on generated and mutated input.
"""

from __future__ import annotations

from functools import cache
from typing import Any

from lark import Token

from mtlc.syntax.builder import AstBuilder
from mtlc.syntax.grammar import lexicon
from mtlc.syntax.lexer import NEWLINE

MAX_UNARY = 200  # longer runs of `-` go to lark (which is iterative), not into recursion

# keywords whose statement may go on with `(`: lark shifts (the statement), never reduces
# the keyword to the name of a call
_PAREN_STATEMENTS = frozenset({"TOOL", "GOAL", "GRIP", "REPEAT", "BUDGET", "TIME"})
_SOLIDS = frozenset({"BOX", "CYLINDER", "PLATE"})
_VALUE_CLAUSES = frozenset({"AT", "ROTATE", "SIZE", "RADIUS", "LENGTH", "AXIS", "NORMAL"})
_SEPARATORS = frozenset({NEWLINE, "SEMICOLON"})
# what goes on with the expression after a primary (and its unit): `.`, `(`, an operator
_GOES_ON = frozenset({"DOT", "LPAR", "STAR", "SLASH", "PLUS", "MINUS"})


class Fallback(Exception):
    """The item is not one this parser accepts as it stands: let lark parse it."""


@cache
def _idents() -> frozenset[str]:
    """Token kinds that may stand where the grammar says ``ident``: NAME and every keyword."""
    return frozenset({"NAME", *lexicon().keywords.values()})


_END = Token("$END", "")


class FastParser:
    """One item's tokens -> its node, through ``builder``; raises ``Fallback`` when unsure."""

    __slots__ = ("b", "i", "idents", "toks", "types")

    def __init__(self, builder: AstBuilder, tokens: list[Token]) -> None:
        self.b = builder
        self.toks = [*tokens, _END, _END]  # two: a look at the token after the next is safe
        self.types = [t.type for t in self.toks]
        self.i = 0
        self.idents = _idents()

    # ------------------------------------------------------------ helpers
    def take(self, kind: str) -> Token:
        i = self.i
        if self.types[i] != kind:
            raise Fallback
        self.i = i + 1
        return self.toks[i]

    def ident(self) -> Token:
        i = self.i
        if self.types[i] not in self.idents:
            raise Fallback
        self.i = i + 1
        return self.toks[i]

    def skip_seps(self) -> bool:
        """Skip a run of `_sep` tokens; whether there was one."""
        i = start = self.i
        types = self.types
        while types[i] in _SEPARATORS:
            i += 1
        self.i = i
        return i > start

    # ------------------------------------------------------------ items
    def item(self) -> Any:
        kind = self.types[0]
        if kind == "USE":
            use = self.toks[0]
            self.i = 1
            node = self.b.use_decl([use, self.qualname()])
        elif kind == "SCENE":
            node = self.braced(self.scene_member, self.b.scene_decl)
        elif kind == "TOOL":
            node = self.braced(self.tool_prop, self.b.tool_decl)
        elif kind in ("ELEMENT", "ACTION"):
            node = self.definition()
        elif kind == "TASK":
            node = self.task()
        else:
            raise Fallback
        if self.types[self.i] != "$END":
            raise Fallback
        return node

    def qualname(self) -> tuple[tuple[str, ...], Any]:
        parts = [self.ident()]
        while self.types[self.i] == "DOT":
            self.i += 1
            parts.append(self.ident())
        return self.b.qualname(parts)

    def braced(self, member: Any, build: Any) -> Any:
        """`KW ident "{" _sep? [member (_sep member)* _sep?] RBRACE` (scene and tool)."""
        kw = self.toks[0]
        self.i = 1
        name = self.ident()
        self.take("LBRACE")
        members = self.members(member, "RBRACE")
        return build([kw, name, *members, self.take("RBRACE")])

    def members(self, member: Any, close: str) -> list[Any]:
        """`_sep? [member (_sep member)* _sep?]` before ``close``: [None] when empty."""
        self.skip_seps()
        if self.types[self.i] == close:
            return [None]
        out = [member()]
        while self.skip_seps():
            if self.types[self.i] == close:
                break
            out.append(member())
        return out

    def scene_member(self) -> Any:
        kind = self.types[self.i]
        kw = self.toks[self.i]
        if kind == "GROUND":
            self.i += 1
            return self.b.ground_decl([kw, self.expr()])
        if kind == "MODEL":
            self.i += 1
            name = self.ident()
            path = self.take("STRING")
            return self.b.model_decl([kw, name, path, *self.shape_clauses()])
        if kind in _SOLIDS:
            self.i += 1
            name = self.ident()
            return self.b.solid_decl([kw, name, *self.shape_clauses()])
        if kind == "SITES":
            self.i += 1
            return self.b.sites_from_decl([kw, self.take("FROM"), self.ident()])
        if kind != "SITE":
            raise Fallback
        self.i += 1
        name = self.ident()
        if self.types[self.i] == "EQUAL":
            self.i += 1
            model = self.ident()
            self.take("DOT")
            return self.b.node_site_decl([kw, name, model, self.ident()])
        self.take("AT")
        c = [kw, name, self.expr()]
        while True:
            kind = self.types[self.i]
            if kind == "NORMAL":
                clause_kw = self.toks[self.i]
                self.i += 1
                c.append(self.b.site_normal([clause_kw, self.expr()]))
            elif kind == "FRAME":
                clause_kw = self.toks[self.i]
                self.i += 1
                c.append(self.b.site_frame([clause_kw, self.expr()]))
            else:
                return self.b.site_decl(c)

    def shape_clauses(self) -> list[Any]:
        """`shape_clause*`: a keyword and its expression, its word, or both (`opening`)."""
        out = []
        b = self.b
        while True:
            kind = self.types[self.i]
            kw = self.toks[self.i]
            if kind in _VALUE_CLAUSES:
                self.i += 1
                out.append(b.value_clause([kw, self.expr()]))
            elif kind in ("UNITS", "UP"):
                self.i += 1
                out.append(b.word_clause([kw, self.ident()]))
            elif kind == "OPENING":
                self.i += 1
                word = self.ident()
                out.append(b.opening_clause([kw, word, self.expr()]))
            else:
                return out

    def tool_prop(self) -> Any:
        name = self.ident()
        return self.b.tool_prop([name, self.expr()])

    def definition(self) -> Any:
        kw = self.toks[0]
        self.i = 1
        name = self.ident()
        self.take("LPAR")
        params: list[Any] = []
        while self.types[self.i] != "RPAR":
            params.append(self.param())
            if self.types[self.i] != "COMMA":
                break
            self.i += 1
        self.take("RPAR")
        return self.b.definition([kw, name, *(params or [None]), self.block()])

    def param(self) -> Any:
        name = self.ident()
        self.take("COLON")
        type_tok = self.ident()
        default = None
        if self.types[self.i] == "EQUAL":
            self.i += 1
            default = self.expr()
        return self.b.param([name, type_tok, default])

    def task(self) -> Any:
        kw = self.toks[0]
        self.i = 1
        name = self.ident()
        title = None
        if self.types[self.i] == "STRING":
            title = self.toks[self.i]
            self.i += 1
        return self.b.task_decl([kw, name, title, self.block()])

    # ------------------------------------------------------------ statements
    def block(self) -> Any:
        lbrace = self.take("LBRACE")
        stmts = self.members(self.stmt, "RBRACE")
        return self.b.block([lbrace, *stmts, self.take("RBRACE")])

    def stmt(self) -> Any:
        i = self.i
        kind = self.types[i]
        if kind == "NAME":
            return self.call_stmt()
        if kind == "LBRACE":
            return self.block()
        after = self.types[i + 1]
        if after == "DOT" or (after == "LPAR" and kind not in _PAREN_STATEMENTS):
            return self.call_stmt()  # a keyword that names an action: `walk(...)`
        b = self.b
        kw = self.toks[i]
        self.i = i + 1
        if kind == "REPEAT":
            count = self.expr()
            return b.repeat_stmt([kw, count, self.block()])
        if kind == "FOR":
            var = self.ident()
            self.take("IN")
            items = self.expr()
            return b.for_stmt([kw, var, items, self.block()])
        if kind == "PARALLEL":
            return b.parallel_stmt([kw, self.block()])
        if kind == "MANIKIN":
            return b.manikin_stmt([kw, self.ident(), self.ident(), self.ident()])
        if kind == "SCENE":
            return b.scene_stmt([kw, self.ident()])
        if kind == "TOOL":
            return b.tool_stmt([kw, self.expr()])
        if kind == "BUDGET":
            return b.budget_stmt([kw, self.expr()])
        if kind == "TIME":
            return b.time_stmt([kw, self.expr()])
        if kind == "GOAL":
            return self.goal(kw)
        if kind == "POSTURE":
            kind_tok = self.ident()
            args = None
            if self.types[self.i] == "LPAR":
                self.i += 1
                inner = self.args_or_none()
                args = b.posture_args([inner, self.take("RPAR")])
            return b.posture_stmt([kw, kind_tok, args, self.over_or_none()])
        if kind == "WALK":
            mode = self.toks[self.i]
            if self.types[self.i] not in ("TO", "BY"):
                raise Fallback
            self.i += 1
            target = self.expr()
            facing = None
            if self.types[self.i] == "FACING":
                self.i += 1
                facing = self.expr()
            return b.walk_stmt([kw, mode, target, facing, self.over_or_none()])
        if kind == "GRIP":
            hand = self.expr()
            state = self.ident()
            return b.grip_stmt([kw, hand, state, self.over_or_none()])
        if kind == "GAZE":
            self.take("AT")
            target = self.expr()
            return b.gaze_stmt([kw, target, self.over_or_none()])
        if kind == "STILL":
            if self.types[self.i] != "OVER":
                raise Fallback
            return b.still_stmt([kw, self.over_or_none()])
        self.i = i
        return self.call_stmt()  # any other keyword is a name here

    def call_stmt(self) -> Any:
        name = self.qualname()
        self.take("LPAR")
        args = self.args_or_none()
        return self.b.call_stmt([name, args, self.take("RPAR")])

    def goal(self, kw: Token) -> Any:
        b = self.b
        effector = self.expr()
        self.take("AT")
        c = [kw, effector, self.expr()]
        while True:
            kind = self.types[self.i]
            if kind == "APPROACH":
                self.i += 1
                c.append(b.approach_clause([self.expr()]))
            elif kind == "OFFSET":
                self.i += 1
                c.append(b.offset_clause([self.expr()]))
            elif kind == "ORIENT":
                c.append(b.orient_clause([self.toks[self.i]]))
                self.i += 1
            elif kind == "OVER":
                self.i += 1
                c.append(b.over_clause([self.expr()]))
            else:
                return b.goal_stmt(c)

    def over_or_none(self) -> Any:
        if self.types[self.i] != "OVER":
            return None
        self.i += 1
        return self.b.over_clause([self.expr()])

    def args_or_none(self) -> Any:
        """`[args]` before a `)`: None when there are none."""
        if self.types[self.i] == "RPAR":
            return None
        b = self.b
        types = self.types
        out = []
        while True:
            i = self.i
            if types[i] in self.idents and types[i + 1] == "COLON":
                name = self.toks[i]
                self.i = i + 2
                out.append(b.named_arg([name, self.expr()]))
            else:
                out.append(self.expr())
            if types[self.i] != "COMMA":
                break
            self.i += 1
            if types[self.i] == "RPAR":
                break
        return b.args(out)

    # ------------------------------------------------------------ expressions
    def expr(self) -> Any:
        """sum and product, left-associative, with a loop each (as lark reduces them)."""
        b = self.b
        types = self.types
        i = self.i
        kind = types[i]
        # a lone name, string or number (with its unit): most expressions, built at once
        # instead of through product, unary, postfix and primary (the same builder calls)
        if kind == "NUMBER":
            end = i + 2 if types[i + 1] == "NAME" else i + 1
            if types[end] not in _GOES_ON:
                self.i = end
                return b.number([self.toks[i], self.toks[i + 1] if end == i + 2 else None])
        elif types[i + 1] not in _GOES_ON:
            if kind in self.idents:
                self.i = i + 1
                return b.name([self.toks[i]])
            if kind == "STRING":
                self.i = i + 1
                return b.string([self.toks[i]])
        left = self.product()
        while True:
            op = types[self.i]
            if op == "PLUS":
                self.i += 1
                left = b.add([left, self.product()])
            elif op == "MINUS":
                self.i += 1
                left = b.sub([left, self.product()])
            else:
                return left

    def product(self) -> Any:
        b = self.b
        types = self.types
        left = self.unary()
        while True:
            op = types[self.i]
            if op == "STAR":
                self.i += 1
                left = b.mul([left, self.unary()])
            elif op == "SLASH":
                self.i += 1
                left = b.div([left, self.unary()])
            else:
                return left

    def unary(self) -> Any:
        """`-` unary | postfix; the minus signs are counted, not recursed into."""
        types = self.types
        start = i = self.i
        while types[i] == "MINUS":
            i += 1
        if i - start > MAX_UNARY:
            raise Fallback
        self.i = i
        value = self.postfix()
        toks = self.toks
        neg = self.b.neg
        for k in range(i - 1, start - 1, -1):  # innermost first, as lark reduces them
            value = neg([toks[k], value])
        return value

    def postfix(self) -> Any:
        b = self.b
        types = self.types
        value = self.primary()
        while True:
            kind = types[self.i]
            if kind == "DOT":
                self.i += 1
                value = b.attr([value, self.ident()])
            elif kind == "LPAR":
                self.i += 1
                args = self.args_or_none()
                value = b.call_expr([value, args, self.take("RPAR")])
            else:
                return value

    def unit_or_none(self) -> Token | None:
        i = self.i
        if self.types[i] == "NAME":  # lark shifts: a NAME here is always the unit
            self.i = i + 1
            return self.toks[i]
        return None

    def primary(self) -> Any:
        i = self.i
        kind = self.types[i]
        tok = self.toks[i]
        self.i = i + 1
        if kind == "NUMBER":
            return self.b.number([tok, self.unit_or_none()])
        if kind in self.idents:
            return self.b.name([tok])
        if kind == "STRING":
            return self.b.string([tok])
        if kind == "LPAR":
            first = self.expr()
            if self.types[self.i] == "RPAR":
                self.i += 1
                return first  # `"(" expr ")"`: the expression itself
            self.take("COMMA")
            items = [first, self.expr()]
            while self.types[self.i] == "COMMA":
                self.i += 1
                if self.types[self.i] == "RPAR":
                    break
                items.append(self.expr())
            rpar = self.take("RPAR")
            return self.b.vector([tok, *items, rpar, self.unit_or_none()])
        if kind == "LSQB":
            items = []
            while self.types[self.i] != "RSQB":
                items.append(self.expr())
                if self.types[self.i] != "COMMA":
                    break
                self.i += 1
            rsqb = self.take("RSQB")
            return self.b.list([tok, *(items or [None]), rsqb])
        raise Fallback


def fast_parse(builder: AstBuilder, tokens: list[Token]) -> Any:
    """The node lark would build from ``tokens`` (one item), or ``Fallback``."""
    try:
        return FastParser(builder, tokens).item()
    except RecursionError:  # not reached within MAX_NESTING brackets; lark is iterative
        raise Fallback from None
