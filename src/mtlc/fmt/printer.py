"""Print a module back as canonical source: from the AST, plus the comments and the few
spellings (numbers, strings, parentheses, trailing commas) that only the tokens keep.

Comments are attached to the nearest statement or list item: a comment on the line where
something ends stays there (a trailing comment), one on its own line is printed above what
follows it. A comment somewhere no item boundary reaches (inside an expression) moves above its
statement; it is never dropped.
"""

from __future__ import annotations

import bisect
import dataclasses
from collections.abc import Callable, Iterator
from dataclasses import dataclass

from lark import Token

from mtlc.diagnostics import Span
from mtlc.fmt.doc import (
    HARDLINE,
    LINE,
    SOFTLINE,
    BreakParent,
    Doc,
    Flat,
    Group,
    IfBreak,
    LineSuffix,
    Nest,
    Text,
    render,
)
from mtlc.fmt.source import Comment, CommentPool, SourceTokens
from mtlc.lint import suppress
from mtlc.syntax import ast

LINE_LENGTH = 100
# what lint reports findings on (at the first line); a Block is not one, its statements are
ANCHORS = (ast.Call, ast.Repeat, ast.ForEach, ast.Parallel, ast.ManikinSetting, ast.SceneSetting,
           ast.ToolSetting, ast.BudgetSetting, ast.TimeSetting, ast.Goal, ast.Posture, ast.Walk,
           ast.Grip, ast.Gaze, ast.Still, ast.Decl, ast.Use, ast.ToolProperty, ast.Param)  # fmt: skip
TRAILING_COMMENT_GAP = "  "

# binding strength: a child that binds less tightly than its place needs parentheses
_SUM, _PRODUCT, _UNARY, _POSTFIX, _PRIMARY = 1, 2, 3, 4, 5


@dataclass(frozen=True, slots=True)
class _Entry:
    """One line-level item of a sequence (a statement, a scene member, a top-level item)."""

    start: int
    end: int
    line: int
    end_line: int
    build: Callable[[], Doc]
    is_use: bool = False


@dataclass(frozen=True, slots=True)
class _Item:
    """One item of a bracket list (an argument, a parameter, a vector component)."""

    start: int
    end: int
    doc: Doc


def format_module(text: str, module: ast.Module, file: str) -> tuple[str, list[Comment]]:
    """The canonical text of ``module``, and any comment that found no place (none, if correct)."""
    printer = _Printer(text, module, file)
    doc = printer.module()
    return render(doc, LINE_LENGTH), printer.pool.left()


_FIELDS: dict[type, tuple[str, ...]] = {}  # each node class's fields that may hold nodes, reversed
# field types that never hold a node: not walked (a span is a tuple, but not of nodes)
_LEAF_TYPES = frozenset(
    {"Span", "Span | None", "bool", "float", "int", "str", "str | None", "frozenset[str]",
     "tuple[str, ...]"}
)  # fmt: skip


def nodes(node: object) -> Iterator[ast.Node]:
    """Every AST node under ``node``, itself included, parents before children in field order.

    Iterative: a chain of nested generators cost time in proportion to the depth for every
    node, and a deep tree must not reach the recursion limit.
    """
    stack = [node]
    while stack:
        item = stack.pop()
        if isinstance(item, ast.Node):
            yield item
            names = _FIELDS.get(type(item))
            if names is None:
                names = _FIELDS[type(item)] = tuple(
                    f.name for f in reversed(dataclasses.fields(item)) if f.type not in _LEAF_TYPES
                )
            for name in names:
                value = getattr(item, name)
                if type(value) is tuple:
                    stack.extend(reversed(value))
                elif value is not None:
                    stack.append(value)
        elif isinstance(item, tuple) and not isinstance(item, Span):
            stack.extend(reversed(item))


class _Printer:
    def __init__(self, text: str, module: ast.Module, file: str) -> None:
        self.text = text
        self.tree = module
        self.src = SourceTokens(text, file)
        self.pool = CommentPool(text)
        self.nodes = list(nodes(module))
        self.call_parens = self._call_parens()
        self.anchor_starts = self._anchor_starts()
        self.blocks_by_end = {n.span.end: n for n in self.nodes if isinstance(n, ast.Block)}
        # each `# mtlc: ignore[...]`, by its line: where it starts, the last line it covers
        reach: dict[int, int] = {}
        for mark in suppress.scan(file, text):
            reach[mark.first_line] = max(reach.get(mark.first_line, 0), mark.last_line)
        self.ignores = {
            c.line: (c.start, reach[c.line]) for c in self.pool.all() if c.line in reach
        }

    def _anchor_starts(self) -> list[int]:
        """Where line-level things start (statements, declarations, scene members, parameters):
        what a comment on their line is about, and where lint reports findings."""
        found = [n.span.start for n in self.nodes if isinstance(n, ANCHORS)]
        for node in self.nodes:
            if isinstance(node, ast.Scene) and node.ground is not None:
                keyword = self.src.starting_at(node.ground.span.start) - 1
                found.append(int(self.src.at(keyword).start_pos))
        return sorted(found)

    def _call_parens(self) -> set[int]:
        """The `(` of calls and postures: not parentheses the writer put around an argument."""
        found: set[int] = set()
        for node in self.nodes:
            if isinstance(node, ast.Call | ast.CallExpr):
                found.add(self.src.match[self.src.ending_at(node.span.end)])
            elif isinstance(node, ast.Posture):
                after = self.src.ending_at(node.kind_span.end) + 1
                if self.src.kind(after) == "LPAR":
                    found.add(after)
        return found

    # ------------------------------------------------------------ sequences and blocks
    def module(self) -> Doc:
        items: list[ast.Node] = sorted([*self.tree.uses, *self.tree.decls], key=_start)
        entries = [self._entry(n.span, self._top_item(n), isinstance(n, ast.Use)) for n in items]
        _, elements = self._sequence(entries, 0, 0, len(self.text), _separate_top_level)
        doc: list[Doc] = []
        for i, (blank, element) in enumerate(elements):
            if i:
                doc.append([HARDLINE, HARDLINE] if blank else HARDLINE)
            doc.append(element)
        if doc:
            doc.append(HARDLINE)
        return doc

    @staticmethod
    def _entry(span: Span, build: Callable[[], Doc], is_use: bool = False) -> _Entry:
        return _Entry(span.start, span.end, span.line, span.end_line, build, is_use)

    def _sequence(
        self,
        entries: list[_Entry],
        start: int,
        start_line: int,
        end: int,
        forced_blank: Callable[[_Entry, _Entry], bool],
        join: bool = False,
    ) -> tuple[list[Comment], list[tuple[bool, Doc]]]:
        """Entries and the comments around them, each with whether a blank line comes before.

        Blank lines the writer left are kept (a run becomes one); ``forced_blank`` adds one
        between two entries (and before the comments above the second). Comments on the
        opening line come back apart, for the caller to print after its `{`.
        """
        opener_comments: list[Comment] = []
        out: list[tuple[bool, Doc]] = []
        prev_line = start_line
        prev: _Entry | None = None
        hosted_last = False  # the last entry may be one line, which already ends with a comment

        def blank_before(line: int, following: _Entry | None) -> bool:
            if not out:
                return False
            forced = prev is not None and following is not None and forced_blank(prev, following)
            return forced or line - prev_line > 1

        def place(found: list[Comment], following: _Entry | None) -> None:
            nonlocal prev_line, prev
            for c in found:
                if c.line == prev_line and not out:
                    opener_comments.append(c)
                elif c.line == prev_line and not hosted_last:
                    blank, doc = out[-1]
                    out[-1] = (blank, [doc, LineSuffix(TRAILING_COMMENT_GAP + c.text)])
                else:  # (after a hosted comment, one that ended a later line gets its own)
                    out.append((blank_before(c.line, following), Text(c.text)))
                    prev_line, prev = c.line, None  # a blank line is forced only once

        prev_end = start
        for group in self._line_groups(entries, join, end):
            first, last = group[0], group[-1]
            place(self.pool.take(prev_end, first.start), first)
            hosted = self._hosted(first, last)
            hosted_last = bool(hosted) and not self._ends_with_block(last)
            docs = [self._built(e) for e in group]
            joined: list[Doc] = [docs[0]]
            for doc in docs[1:]:
                joined += [Text("; "), doc]
            if len(docs) > 1:  # kept on one line for an ignore: breaking it would move some
                joined = [Flat(joined)]  # statement off the comment's line
            suffix = [LineSuffix(TRAILING_COMMENT_GAP + c.text) for c in hosted]
            out.append((blank_before(first.line, first), [*suffix, joined]))
            prev_end, prev_line, prev = last.end, last.end_line, last
        place(self.pool.take(prev_end, end), None)
        return opener_comments, out

    def _built(self, entry: _Entry) -> Doc:
        """The entry, after any comment inside it that no item reached (moved above it)."""
        doc = entry.build()
        stray = self.pool.take(entry.start, entry.end)
        lead: list[Doc] = [[Text(c.text), HARDLINE] for c in stray]
        return [*lead, doc]

    def _hosted(self, first: _Entry, last: _Entry) -> list[Comment]:
        """The comment ending the line on which ``first`` starts, when it is this group's.

        It is printed at the end of the group's first line, so that the lines a
        `# mtlc: ignore[...]` covers (its own line, or the block a `{` before it opens) hold the
        same statements after formatting as before. It is not this group's when another entry
        starts on that line before it: a later one beside the group, or (when the comment is
        inside the group) a nested one, which then hosts it.
        """
        c = self.pool.next_after(first.start)
        if c is None or c.line != first.line or self._follows_opener(c):
            return []  # one after `{`, `(` or `[` stays there: the bracket prints it
        after = last.end if c.start >= last.end else last.start + 1
        first_after = bisect.bisect_left(self.anchor_starts, after)  # sorted: no scan of all
        if first_after < len(self.anchor_starts) and self.anchor_starts[first_after] < c.start:
            return []
        self.pool.claim(c)
        return [c]

    def _follows_opener(self, comment: Comment) -> bool:
        """Whether only spaces stand between an opening bracket and the comment (looked for
        backwards from the comment: copying the text before it made formatting quadratic)."""
        i = comment.start
        while i > 0 and self.text[i - 1] in " \t":
            i -= 1
        return i > 0 and self.text[i - 1] in "{(["

    def _ends_with_block(self, entry: _Entry) -> bool:
        """Whether the entry ends with a `}` printed on its own line (a block not empty)."""
        block = self.blocks_by_end.get(entry.end)
        return block is not None and bool(block.stmts)

    def _line_groups(self, entries: list[_Entry], join: bool, end: int) -> list[list[_Entry]]:
        """Entries one by one; with ``join``, statements sharing a line that a
        `# mtlc: ignore[...]` ends stay together on it (`a(); b()  # mtlc: ignore[...]`), as
        that comment covers them all. The comment may sit inside one of them, after a bracket
        it opens there (`a(); b(  # mtlc: ignore[...]`), and cover a later line through a `{` it
        follows (`repeat 2 {  # mtlc: ignore[...]` ... `}; b()`): that is how such a line prints
        when its brackets break, so formatting it again keeps it (idempotence). A comment
        after the sequence's ``end`` (its `}`) is the enclosing statement's: printed after this
        block's `{`, it covers the whole block, so the statements here need not stay together."""
        groups: list[list[_Entry]] = []
        for entry in entries:
            group = groups[-1] if groups else []
            if join and group and group[-1].end_line == entry.line:
                start, reach = self.ignores.get(group[0].line, (end, 0))
                if start < end and entry.line <= reach:
                    group.append(entry)
                    continue
            groups.append([entry])
        return groups

    def _braced(self, open_index: int, close_index: int, entries: list[_Entry]) -> Doc:
        """`{`, one entry per line, `}`."""
        lbrace, rbrace = self.src.at(open_index), self.src.at(close_index)
        opener, elements = self._sequence(
            entries, lbrace.end_pos, lbrace.line, rbrace.start_pos, _never, join=True
        )
        head: list[Doc] = [Text("{"), *(LineSuffix(TRAILING_COMMENT_GAP + c.text) for c in opener)]
        if not elements:
            return [*head, HARDLINE, Text("}")] if opener else [*head, Text("}")]
        body: list[Doc] = []
        for blank, element in elements:
            body.append([HARDLINE, HARDLINE] if blank else HARDLINE)
            body.append(element)
        return [*head, Nest(body), HARDLINE, Text("}")]

    def _block(self, block: ast.Block) -> Doc:
        entries = [self._entry(s.span, self._bind(self._stmt, s)) for s in block.stmts]
        return self._braced(
            self.src.starting_at(block.span.start), self.src.ending_at(block.span.end), entries
        )

    @staticmethod
    def _bind(fn: Callable[[ast.Node], Doc], node: ast.Node) -> Callable[[], Doc]:
        return lambda: fn(node)

    def _delimited(self, open_index: int, close_index: int, items: list[_Item]) -> Doc:
        """A bracket list: flat if it fits, else one item per line with a trailing comma.

        A trailing comma after the last item, or a comment, keeps it one item per line.
        """
        opener_tok, closer_tok = self.src.at(open_index), self.src.at(close_index)
        open_text, close_text = opener_tok.value, closer_tok.value
        if not items:
            return self._empty_brackets(opener_tok, closer_tok)
        force = self.src.comma_before(close_index)
        head: list[Doc] = [Text(open_text)]
        inner: list[Doc] = []
        prev_end, prev_line = opener_tok.end_pos, opener_tok.line

        def place(found: list[Comment], is_first: bool) -> list[Doc]:
            lead: list[Doc] = []
            for c in found:
                suffix = [LineSuffix(TRAILING_COMMENT_GAP + c.text), BreakParent()]
                if c.line == prev_line:
                    (head if is_first else inner).extend(suffix)
                else:
                    lead.extend([Text(c.text), HARDLINE])
            return lead

        for k, item in enumerate(items):
            lead = place(self.pool.take(prev_end, item.start), k == 0)
            inner.extend([SOFTLINE if k == 0 else LINE, *lead, item.doc])
            inner.append(Text(",") if k < len(items) - 1 else IfBreak(","))
            prev_end, prev_line = item.end, self.src.line_of(item.end)
        for c in self.pool.take(prev_end, closer_tok.start_pos):
            force = True
            if c.line == prev_line:
                inner.append(LineSuffix(TRAILING_COMMENT_GAP + c.text))
            else:
                inner.extend([HARDLINE, Text(c.text)])
        return Group([*head, Nest(inner), SOFTLINE, Text(close_text)], force_break=force)

    def _empty_brackets(self, opener: Token, closer: Token) -> Doc:
        """`()`, or the comments inside the brackets, one per line."""
        found = self.pool.take(opener.end_pos, closer.start_pos)
        if not found:
            return Text(opener.value + closer.value)
        inner: list[Doc] = []
        for c in found:
            if c.line == opener.line:
                inner.extend([LineSuffix(TRAILING_COMMENT_GAP + c.text), BreakParent()])
            else:
                inner.extend([HARDLINE, Text(c.text)])
        return [Text(opener.value), Nest(inner), HARDLINE, Text(closer.value)]

    # ------------------------------------------------------------ top level
    def _top_item(self, node: ast.Node) -> Callable[[], Doc]:
        return self._bind(self._top_level, node)

    def _top_level(self, node: ast.Node) -> Doc:
        match node:
            case ast.Use():
                return Text("use " + ".".join(node.module))
            case ast.Scene():
                return [Text(f"scene {node.name} "), self._scene_body(node)]
            case ast.ToolDecl():
                entries = [
                    self._entry(p.span, self._bind(self._tool_property, p)) for p in node.properties
                ]
                return [Text(f"tool {node.name} "), self._braced_after(node, entries)]
            case ast.Definition():
                return [
                    Text(f"{node.kind} {node.name}"),
                    self._params(node),
                    Text(" "),
                    self._block(node.body),
                ]
            case ast.Task():
                return [Text(f"task {node.name}{self._title(node)} "), self._block(node.body)]
        raise TypeError(f"cannot format a top-level {type(node).__name__}")

    def _braced_after(self, decl: ast.Decl, entries: list[_Entry]) -> Doc:
        """The braces of a scene or tool: the `{` follows the name, the `}` ends the span."""
        open_index = self.src.starting_at(decl.name_span.start) + 1
        return self._braced(open_index, self.src.ending_at(decl.span.end), entries)

    def _scene_body(self, scene: ast.Scene) -> Doc:
        entries = [self._entry(s.span, self._bind(self._site, s)) for s in scene.sites]
        if scene.ground is not None:
            ground = scene.ground
            keyword = self.src.at(self.src.starting_at(ground.span.start) - 1)
            whole = Span(
                ground.span.file, keyword.line, keyword.column, ground.span.end_line,
                ground.span.end_column, keyword.start_pos, ground.span.end,
            )  # fmt: skip
            entries.append(self._entry(whole, lambda: [Text("ground "), self._expr(ground)]))
        entries.sort(key=lambda e: e.start)
        return self._braced_after(scene, entries)

    def _site(self, site: ast.Node) -> Doc:
        assert isinstance(site, ast.SiteDecl)
        doc: list[Doc] = [Text(f"site {site.name} at "), self._expr(site.position)]
        if site.normal is not None:
            doc += [Text(" normal "), self._expr(site.normal)]
        if site.frame is not None:
            doc += [Text(" frame "), self._expr(site.frame)]
        return doc

    def _tool_property(self, prop: ast.Node) -> Doc:
        assert isinstance(prop, ast.ToolProperty)
        return [Text(f"{prop.name} "), self._expr(prop.value)]

    def _title(self, task: ast.Task) -> str:
        after_name = self.src.ending_at(task.name_span.end) + 1
        if task.title is not None and self.src.kind(after_name) == "STRING":
            return " " + self.src.text(after_name)
        return ""

    def _params(self, definition: ast.Definition) -> Doc:
        open_index = self.src.starting_at(definition.name_span.start) + 1
        close_index = self.src.starting_at(definition.body.span.start) - 1
        items = [_Item(p.span.start, p.span.end, self._param(p)) for p in definition.params]
        return self._delimited(open_index, close_index, items)

    def _param(self, param: ast.Param) -> Doc:
        doc: list[Doc] = [Text(f"{param.name}: {param.type_name}")]
        if param.default is not None:
            doc += [Text(" = "), self._expr(param.default)]
        return doc

    # ------------------------------------------------------------ statements
    def _stmt(self, stmt: ast.Node) -> Doc:
        match stmt:
            case ast.Block():
                return self._block(stmt)
            case ast.Call():
                rpar = self.src.ending_at(stmt.span.end)
                return [
                    Text(".".join(stmt.callee)),
                    self._args(self.src.match[rpar], rpar, stmt.args),
                ]
            case ast.Repeat():
                return [Text("repeat "), self._expr(stmt.count), Text(" "), self._block(stmt.body)]
            case ast.ForEach():
                return [
                    Text(f"for {stmt.var} in "),
                    self._expr(stmt.items),
                    Text(" "),
                    self._block(stmt.body),
                ]
            case ast.Parallel():
                return [Text("parallel "), self._block(stmt.body)]
            case ast.ManikinSetting():
                return Text(f"manikin {stmt.population} {stmt.sex} {stmt.percentile}")
            case ast.SceneSetting():
                return Text(f"scene {stmt.name}")
            case ast.ToolSetting():
                return [Text("tool "), self._expr(stmt.tool)]
            case ast.BudgetSetting():
                return [Text("budget "), self._expr(stmt.limit)]
            case ast.TimeSetting():
                return [Text("time "), self._expr(stmt.duration)]
        return self._primitive(stmt)

    def _primitive(self, stmt: ast.Node) -> Doc:
        match stmt:
            case ast.Goal():
                doc: list[Doc] = [
                    Text("goal "),
                    self._expr(stmt.effector),
                    Text(" at "),
                    self._expr(stmt.target),
                ]
                if stmt.approach is not None:
                    doc += [Text(" approach "), self._expr(stmt.approach)]
                if stmt.offset is not None:
                    doc += [Text(" offset "), self._expr(stmt.offset)]
                if stmt.orient:
                    doc.append(Text(" orient"))
                return [*doc, self._over(stmt.over)]
            case ast.Posture():
                doc = [Text(f"posture {stmt.kind}")]
                if stmt.args:
                    lpar = self.src.ending_at(stmt.kind_span.end) + 1
                    doc.append(self._args(lpar, self.src.match[lpar], stmt.args))
                return [*doc, self._over(stmt.over)]
            case ast.Walk():
                doc = [Text(f"walk {stmt.mode} "), self._expr(stmt.target)]
                if stmt.facing is not None:
                    doc += [Text(" facing "), self._expr(stmt.facing)]
                return [*doc, self._over(stmt.over)]
            case ast.Grip():
                doc = [Text("grip "), self._expr(stmt.hand), Text(f" {stmt.state}")]
                return [*doc, self._over(stmt.over)]
            case ast.Gaze():
                return [Text("gaze at "), self._expr(stmt.target), self._over(stmt.over)]
            case ast.Still():
                return [Text("still"), self._over(stmt.over)]
        raise TypeError(f"cannot format a {type(stmt).__name__} statement")

    def _over(self, over: ast.Expr | None) -> Doc:
        return [] if over is None else [Text(" over "), self._expr(over)]

    def _args(self, open_index: int, close_index: int, args: tuple[ast.Arg, ...]) -> Doc:
        items = [_Item(a.span.start, a.span.end, self._arg(a)) for a in args]
        return self._delimited(open_index, close_index, items)

    def _arg(self, arg: ast.Arg) -> Doc:
        if arg.name is None:
            return self._expr(arg.value)
        return [Text(f"{arg.name}: "), self._expr(arg.value)]

    # ------------------------------------------------------------ expressions
    def _expr(self, expr: ast.Expr, needs: int = 0, strict: bool = False) -> Doc:
        """``expr``, in parentheses where the writer put them or where its place needs them:
        where it binds less tightly than ``needs`` (or as tightly, if ``strict``)."""
        strength = _strength(expr)
        doc = self._bare(expr)
        bracket = strength < needs or (strict and strength == needs)
        if bracket or self.src.wrapped_in_parens(expr.span, self.call_parens):
            return [Text("("), doc, Text(")")]
        return doc

    def _bare(self, expr: ast.Expr) -> Doc:
        match expr:
            case ast.Number():
                number = self.src.text(self.src.starting_at(expr.span.start))
                return Text(number if expr.unit is None else f"{number} {expr.unit}")
            case ast.String():
                return Text(self.src.text(self.src.starting_at(expr.span.start)))
            case ast.Name():
                return Text(expr.name)
            case ast.Binary():
                strength = _strength(expr)
                return [
                    self._expr(expr.left, strength),
                    Text(f" {expr.op} "),
                    self._expr(expr.right, strength, strict=True),
                ]
            case ast.Unary():
                return [Text(expr.op), self._expr(expr.operand, _UNARY)]
            case ast.Attr():
                return [self._postfix_object(expr.obj), Text(f".{expr.name}")]
            case ast.CallExpr():
                rpar = self.src.ending_at(expr.span.end)
                return [
                    self._postfix_object(expr.func),
                    self._args(self.src.match[rpar], rpar, expr.args),
                ]
            case ast.Vector():
                return self._vector(expr)
            case ast.ListExpr():
                open_index = self.src.starting_at(expr.span.start)
                items = [_Item(x.span.start, x.span.end, self._expr(x)) for x in expr.items]
                return self._delimited(open_index, self.src.match[open_index], items)
        raise TypeError(f"cannot format a {type(expr).__name__} expression")

    def _postfix_object(self, obj: ast.Expr) -> Doc:
        """`1.x` would read as the number `1.` with a unit: a number before `.` or `(` is bracketed."""
        if isinstance(obj, ast.Number):
            return self._expr(obj, _PRIMARY + 1)
        return self._expr(obj, _POSTFIX)

    def _vector(self, vector: ast.Vector) -> Doc:
        open_index = self.src.starting_at(vector.span.start)
        items = [_Item(x.span.start, x.span.end, self._expr(x)) for x in vector.items]
        doc = self._delimited(open_index, self.src.match[open_index], items)
        return doc if vector.unit is None else [doc, Text(f" {vector.unit}")]


def _start(node: ast.Node) -> int:
    return node.span.start


def _never(_a: _Entry, _b: _Entry) -> bool:
    return False


def _separate_top_level(before: _Entry, after: _Entry) -> bool:
    """A blank line between top-level items, except within a run of `use` lines."""
    return not (before.is_use and after.is_use)


def _strength(expr: ast.Expr) -> int:
    match expr:
        case ast.Binary():
            return _SUM if expr.op in "+-" else _PRODUCT
        case ast.Unary():
            return _UNARY
        case ast.Attr() | ast.CallExpr():
            return _POSTFIX
    return _PRIMARY
