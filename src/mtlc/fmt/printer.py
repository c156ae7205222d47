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
from typing import Any

from lark import Token

from mtlc.diagnostics import Span
from mtlc.fmt.doc import (
    HARDLINE,
    INDENT,
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
from mtlc.syntax import ast, suppressions

LINE_LENGTH = 100
# what lint reports findings on (at the first line); a Block is not one, its statements are
ANCHORS = (ast.Call, ast.Repeat, ast.ForEach, ast.Parallel, ast.ManikinSetting, ast.SceneSetting,
           ast.ToolSetting, ast.BudgetSetting, ast.TimeSetting, ast.Goal, ast.Posture, ast.Walk,
           ast.Grip, ast.Gaze, ast.Still, ast.Decl, ast.Use, ast.ToolProperty, ast.Param)  # fmt: skip
TRAILING_COMMENT_GAP = "  "
# False: every statement and block through the general code, without the shortcuts (a line
# printed flat at once, _one_line; a block or entry with no comment to place, _block and
# _sequence; a run of plain lines as one text, _braces); tests/test_fmt_paths.py compares both
FAST_PATHS = True


def _subclasses(cls: type) -> set[type]:
    found = {cls}
    for sub in cls.__subclasses__():
        found |= _subclasses(sub)
    return found


# the node classes that are ANCHORS: a set lookup by type instead of isinstance's walk
_ANCHOR_TYPES = frozenset(c for c in _subclasses(ast.Node) if issubclass(c, ANCHORS))

# what _survey does with a node of each class (no entry: nothing)
_ANCHOR, _BLOCK, _SCENE = "anchor", "block", "scene"
_SURVEY_ROLES: dict[type, str] = {kind: _ANCHOR for kind in _ANCHOR_TYPES}
_SURVEY_ROLES.update(
    {kind: _BLOCK for kind in _subclasses(ast.Block)}
    | {kind: _SCENE for kind in _subclasses(ast.Scene)}
)  # fmt: skip
assert not issubclass(ast.Block, ANCHORS)
assert all(issubclass(k, ANCHORS) for k in (ast.Call, ast.Scene, ast.Posture))

# binding strength: a child that binds less tightly than its place needs parentheses
_SUM, _PRODUCT, _UNARY, _POSTFIX, _PRIMARY = 1, 2, 3, 4, 5


@dataclass(slots=True)  # not frozen: a frozen one costs an object.__setattr__ per field
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


def _node_fields(kind: type) -> tuple[str, ...]:
    """The fields of a node class that may hold nodes (a node, None or a tuple of nodes)."""
    names = _FIELDS.get(kind)
    if names is None:
        names = _FIELDS[kind] = tuple(
            f.name for f in reversed(dataclasses.fields(kind)) if f.type not in _LEAF_TYPES
        )
    return names


_SURVEY_FIELDS: dict[type, tuple[str, ...]] = {}  # _node_fields without expressions
# field types that hold only expressions (and arguments): where no line-level thing can be
_EXPR_TYPES = frozenset({"Expr", "Expr | None", "tuple[Expr, ...]", "tuple[Arg, ...]"})


def _survey_fields(kind: type) -> tuple[str, ...]:
    """The fields of a node class that may hold statements, declarations, scene members or
    parameters (none for an expression)."""
    names = _SURVEY_FIELDS.get(kind)
    if names is None:
        types = {f.name: f.type for f in dataclasses.fields(kind)}
        names = _SURVEY_FIELDS[kind] = tuple(
            name
            for name in _node_fields(kind)
            if not issubclass(kind, ast.Expr) and types[name] not in _EXPR_TYPES
        )
    return names


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
            for name in _node_fields(type(item)):
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
        self.blocks_by_end: dict[int, ast.Block] = {}
        self.anchor_starts = self._survey()
        # the `(` of the calls and postures printed so far (filled by _args and _line_args,
        # which print a call's arguments after its `(` is here): not parentheses the writer
        # put around an argument (_wrapped)
        self.call_parens: set[int] = set()
        # each `# mtlc: ignore[...]`, by its line: where it starts, the last line it covers
        reach: dict[int, int] = {}
        for mark in suppressions.scan(file, text):
            reach[mark.first_line] = max(reach.get(mark.first_line, 0), mark.last_line)
        self.ignores = {
            c.line: (c.start, reach[c.line]) for c in self.pool.all() if c.line in reach
        }
        self.depth = 0  # how many `{` enclose what is being built: its line starts at 4 * depth
        self.fast = FAST_PATHS
        # per flat-text maker (_line_stmt, _line_site): source text -> flat text (None: none)
        self._flat_memo: dict[Callable[[Any], str], dict[str, str | None]] = {}

    def _survey(self) -> list[int]:
        """One walk over the statements, declarations, scene members and parameters (not
        into expressions: no line-level thing is inside one) for:

        - where line-level things start (statements, declarations, scene members,
          parameters): what a comment on their line is about, and where lint reports findings;
        - the blocks, by where they end (``blocks_by_end``).
        """
        found: list[int] = []
        src = self.src
        fields, roles = _SURVEY_FIELDS, _SURVEY_ROLES
        stack: list[ast.Node] = [self.tree]  # every such node, in no particular order
        while stack:
            node = stack.pop()
            kind = type(node)
            names = fields.get(kind)
            if names is None:
                names = _survey_fields(kind)
            for name in names:
                value = getattr(node, name)
                if type(value) is tuple:
                    stack.extend(value)
                elif value is not None:
                    stack.append(value)
            role = roles.get(kind)
            if role is None:
                continue
            if role is _ANCHOR:
                found.append(node.span.start)
            elif role is _BLOCK:
                self.blocks_by_end[node.span.end] = node  # type: ignore[assignment]
            elif role is _SCENE:
                if node.ground is not None:  # type: ignore[attr-defined]
                    keyword = src.starting_at(node.ground.span.start) - 1  # type: ignore[attr-defined]
                    found.append(int(src.at(keyword).start_pos))
                found.append(node.span.start)
        return sorted(found)

    def _wrapped(self, expr: ast.Expr) -> bool:
        """Whether the writer put ``expr`` in parentheses of its own: a `(` just before it,
        not a call's, whose `)` comes just after it."""
        span = expr.span
        # what the text has before it: a `(` token ends in `(` (or a look-alike, not ASCII),
        # and only spaces, or a new line (and comments), come between; anything else, and no
        # token need be looked up
        text, k = self.text, span.start - 1
        while k >= 0 and text[k] in " \t\f\v":
            k -= 1
        if k < 0 or (text[k] not in "(\r\n" and text[k].isascii()):
            return False
        src = self.src
        i = src.index_at(span.start) - 1
        if i < 0 or src.types[i] != "LPAR" or i in self.call_parens:
            return False
        close = src.match.get(i)
        return close is not None and close > i + 1 and src.tokens[close - 1].end_pos == span.end

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
        end_line: int | None = None,
    ) -> tuple[list[Comment], list[tuple[bool, Doc]]]:
        """Entries and the comments around them, each with whether a blank line comes before.

        Blank lines the writer left are kept (a run becomes one); ``forced_blank`` adds one
        between two entries (and before the comments above the second). Comments on the
        opening line come back apart, for the caller to print after its `{`.

        ``end_line``: the line of the closing `}` at ``end``. When no comment starts from
        ``start`` to the end of that line (the comments the entries could take: one after the
        `}` on its line may be hosted by an entry that starts on that line), the entries are
        just built, with the blank lines between them.
        """
        out: list[tuple[bool, Doc]] = []
        if self.fast and end_line is not None and self.pool.quiet(start, end, end_line):
            prev_line = start_line
            previous: _Entry | None = None
            for entry in entries:
                blank = bool(out) and (
                    (previous is not None and forced_blank(previous, entry))
                    or entry.line - prev_line > 1
                )
                out.append((blank, entry.build()))
                prev_line, previous = entry.end_line, entry
            return [], out
        opener_comments: list[Comment] = []
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
            if self.fast and len(group) == 1 and self.pool.quiet(prev_end, last.end, last.end_line):
                # no comment before it, in it, or after it on its last line: nothing to place
                # (what place, _hosted and _built would find out, one look-up at a time)
                hosted_last = False
                out.append((blank_before(first.line, first), first.build()))
                prev_end, prev_line, prev = last.end, last.end_line, last
                continue
            place(self.pool.take(prev_end, first.start), first)
            hosted = self._hosted(first, last)
            hosted_last = bool(hosted) and not self._ends_with_block(last)
            docs = [self._built(e) for e in group]
            joined: Doc = docs[0]  # (no list around one part: fewer parts for the layout)
            if len(docs) > 1:  # kept on one line for an ignore: breaking it would move some
                parts: list[Doc] = [docs[0]]  # statement off the comment's line
                for doc in docs[1:]:
                    parts += [Text("; "), doc]
                joined = Flat(parts)
            if hosted:
                suffix = [LineSuffix(TRAILING_COMMENT_GAP + c.text) for c in hosted]
                joined = [*suffix, joined]
            out.append((blank_before(first.line, first), joined))
            prev_end, prev_line, prev = last.end, last.end_line, last
        place(self.pool.take(prev_end, end), None)
        return opener_comments, out

    def _built(self, entry: _Entry) -> Doc:
        """The entry, after any comment inside it that no item reached (moved above it)."""
        doc = entry.build()
        stray = self.pool.take(entry.start, entry.end)
        if not stray:
            return doc
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
        self.depth += 1  # the entries are built inside _sequence, one level in
        try:
            opener, elements = self._sequence(
                entries,
                lbrace.end_pos,
                lbrace.line,
                rbrace.start_pos,
                _never,
                join=True,
                end_line=rbrace.line,
            )
        finally:
            self.depth -= 1
        return self._braces(opener, elements)

    def _braces(self, opener: list[Comment], elements: list[tuple[bool, Doc]]) -> Doc:
        """`{` with the comments after it, the elements one per line, `}`."""
        if self.fast and not opener:
            plain = self._plain_braces(elements)
            if plain is not None:
                return plain
        head: list[Doc] = [Text("{"), *(LineSuffix(TRAILING_COMMENT_GAP + c.text) for c in opener)]
        if not elements:
            return [*head, HARDLINE, Text("}")] if opener else [*head, Text("}")]
        body: list[Doc] = []
        # a run of lines of plain text is one text with its new lines and indentation, after a
        # real line break (which prints what a line suffix before it holds, and after which
        # none is pending), as the layout would print it: fewer parts for the layout to walk
        indent = " " * (INDENT * (self.depth + 1))
        run: list[str] = []
        for blank, element in elements:
            if run and type(element) is str:
                run.append(("\n\n" if blank else "\n") + indent + element)  # type: ignore[operator]
                continue
            if run:
                body.append("".join(run))
                run = []
            body.append([HARDLINE, HARDLINE] if blank else HARDLINE)
            if self.fast and type(element) is str:
                run = [element]  # type: ignore[list-item]
            else:
                body.append(element)
        if run:
            body.append("".join(run))
        return [*head, Nest(body), HARDLINE, Text("}")]

    def _plain_braces(self, elements: list[tuple[bool, Doc]]) -> str | None:
        """The block as the one text the layout would print for it, new lines and indentation
        included, when every element is a text, at most with one trailing comment (None
        otherwise). No group is inside, so nothing is left to lay out; a comment held to the
        end of a line is written before the next new line, where the layout would print it."""
        inner = "\n" + " " * (INDENT * (self.depth + 1))
        parts = ["{"]
        for blank, element in elements:
            text = element if type(element) is str else _with_suffix(element)
            if not text:
                return None
            parts.append("\n" + inner + text if blank else inner + text)  # type: ignore[operator]
        if len(parts) == 1:
            parts.append("}")
        else:
            parts.append("\n" + " " * (INDENT * self.depth) + "}")
        return "".join(parts)

    def _joined(self, parts: list[Doc]) -> Doc:
        """``parts`` as one text when they are all texts (a block among them, see
        _plain_braces): so the block holding them can be one text too."""
        if self.fast and all(type(p) is str for p in parts):
            return "".join(parts)  # type: ignore[arg-type]
        return parts

    def _block(self, block: ast.Block) -> Doc:
        open_index = self.src.starting_at(block.span.start)
        close_index = self.src.ending_at(block.span.end)
        if self.fast:
            lbrace, rbrace = self.src.at(open_index), self.src.at(close_index)
            if self.pool.quiet(lbrace.end_pos, rbrace.start_pos, rbrace.line):
                return self._braces([], self._quiet_statements(block, lbrace.line))
        entries = [self._entry(s.span, self._bind(self._stmt, s)) for s in block.stmts]
        return self._braced(open_index, close_index, entries)

    def _quiet_statements(self, block: ast.Block, open_line: int) -> list[tuple[bool, Doc]]:
        """What _sequence gives for a block with no comment to place (see there), without
        making an entry per statement."""
        out: list[tuple[bool, Doc]] = []
        prev_line = open_line
        self.depth += 1
        try:
            for stmt in block.stmts:
                out.append((bool(out) and stmt.span.line - prev_line > 1, self._stmt(stmt)))
                prev_line = stmt.span.end_line
        finally:
            self.depth -= 1
        return out

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
                return self._joined([Text(f"scene {node.name} "), self._scene_body(node)])
            case ast.ToolDecl():
                entries = [
                    self._entry(p.span, self._bind(self._tool_property, p)) for p in node.properties
                ]
                return self._joined([Text(f"tool {node.name} "), self._braced_after(node, entries)])
            case ast.Definition():
                return self._joined(
                    [
                        Text(f"{node.kind} {node.name}"),
                        self._params(node),
                        Text(" "),
                        self._block(node.body),
                    ]
                )
            case ast.Task():
                return self._joined(
                    [Text(f"task {node.name}{self._title(node)} "), self._block(node.body)]
                )
        raise TypeError(f"cannot format a top-level {type(node).__name__}")

    def _braced_after(self, decl: ast.Decl, entries: list[_Entry]) -> Doc:
        """The braces of a scene or tool: the `{` follows the name, the `}` ends the span."""
        open_index = self.src.starting_at(decl.name_span.start) + 1
        return self._braced(open_index, self.src.ending_at(decl.span.end), entries)

    def _scene_body(self, scene: ast.Scene) -> Doc:
        entries = [self._entry(s.span, self._bind(self._site, s)) for s in scene.sites]
        entries += [self._entry(s.span, self._bind(self._shape, s)) for s in scene.shapes]
        entries += [
            self._entry(s.span, self._bind(self._scene_line, s))
            for s in (*scene.node_sites, *scene.sites_from)
        ]
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
        line = self._one_line(site, self._line_site)
        if line is not None:
            return line
        doc: list[Doc] = [Text(f"site {site.name} at "), self._expr(site.position)]
        if site.normal is not None:
            doc += [Text(" normal "), self._expr(site.normal)]
        if site.frame is not None:
            doc += [Text(" frame "), self._expr(site.frame)]
        return doc

    def _scene_line(self, member: ast.Node) -> Doc:
        if isinstance(member, ast.NodeSite):
            return Text(f"site {member.name} = {member.model}.{member.node}")
        assert isinstance(member, ast.SitesFrom)
        return Text(f"sites from {member.model}")

    def _shape(self, shape: ast.Node) -> Doc:
        """`model NAME "PATH" clauses` or `box NAME clauses`: the clauses in their order, the
        path's string as written (its escapes kept)."""
        assert isinstance(shape, ast.Shape)
        doc: list[Doc] = [Text(f"{shape.kind} {shape.name}")]
        if shape.file_span is not None:
            doc.append(Text(" " + self.src.text(self.src.starting_at(shape.file_span.start))))
        for clause in shape.clauses:
            doc.append(Text(f" {clause.keyword}"))
            if clause.word is not None:
                doc.append(Text(f" {clause.word}"))
            if clause.value is not None:
                doc += [Text(" "), self._expr(clause.value)]
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
        flat = self._flat_params(definition, open_index, close_index)
        if flat is not None:
            return flat
        items = [_Item(p.span.start, p.span.end, self._param(p)) for p in definition.params]
        return self._delimited(open_index, close_index, items)

    def _flat_params(
        self, definition: ast.Definition, open_index: int, close_index: int
    ) -> str | None:
        """The parameter list as the text the layout prints when its group is flat: when no
        comment is in it, no magic trailing comma, and the line up to the body's `{` (and a
        `}` or comment after it: three characters at most) fits. A definition starts a line at
        the top level, so the group starts at the column of the header's length."""
        if not self.fast:
            return None
        opener, closer = self.src.at(open_index), self.src.at(close_index)
        if self.pool.any_in(opener.start_pos, closer.end_pos):
            return None
        items: list[str] = []
        try:
            for p in definition.params:
                item = f"{p.name}: {p.type_name}"
                if p.default is not None:
                    item += " = " + self._line_expr(p.default)
                items.append(item)
            text = self._line_list(open_index, close_index, items)
        except _NotOneLine:
            return None
        head = len(definition.kind) + 1 + len(definition.name)
        return text if self.depth == 0 and head + len(text) + 3 <= LINE_LENGTH else None

    def _param(self, param: ast.Param) -> Doc:
        doc: list[Doc] = [Text(f"{param.name}: {param.type_name}")]
        if param.default is not None:
            doc += [Text(" = "), self._expr(param.default)]
        return doc

    # ------------------------------------------------------------ one line, without a document
    def _one_line(self, node: ast.Node, line: Callable[[Any], str]) -> str | None:
        """The text of a statement or scene member that prints on one line, or None.

        Most of a file is such lines: the document of groups and line breaks would be built,
        measured and then printed flat. Here the flat text is made at once, and kept when the
        layout would print it so: when no comment starts inside the node (one ends a line or
        forces a break), no bracket list has a magic trailing comma (it always breaks), and
        the text fits in the line at the node's indentation. Then every group in it fits (the
        layout measures each one with what follows it on the line, at most the whole text),
        so the layout's output would be this very text. Otherwise (None) the document is
        built. ``tests/test_fmt.py`` checks both paths give the same output.
        """
        span = node.span
        if not self.fast or self.pool.any_in(span.start, span.end):
            return None
        # the flat text is a function of the node's source text alone (its tokens, hence its
        # tree, parentheses and trailing commas, are all inside it): a line written twice in
        # the file is made once
        memo = self._flat_memo.get(line)
        if memo is None:
            memo = self._flat_memo[line] = {}
        source = self.text[span.start : span.end]
        text = memo.get(source, _UNSEEN)
        if text is _UNSEEN:
            try:
                text = line(node)
            except _NotOneLine:
                text = None
            memo[source] = text
        if text is None:
            return None
        return text if INDENT * self.depth + len(text) <= LINE_LENGTH else None

    def _line_stmt(self, stmt: ast.Node) -> str:
        e = self._line_expr
        match stmt:
            case ast.Call():
                rpar = self.src.ending_at(stmt.span.end)
                return ".".join(stmt.callee) + self._line_args(
                    self.src.match[rpar], rpar, stmt.args
                )
            case ast.ManikinSetting():
                return f"manikin {stmt.population} {stmt.sex} {stmt.percentile}"
            case ast.SceneSetting():
                return f"scene {stmt.name}"
            case ast.ToolSetting():
                return "tool " + e(stmt.tool)
            case ast.BudgetSetting():
                return "budget " + e(stmt.limit)
            case ast.TimeSetting():
                return "time " + e(stmt.duration)
            case ast.Goal():
                text = "goal " + e(stmt.effector) + " at " + e(stmt.target)
                if stmt.approach is not None:
                    text += " approach " + e(stmt.approach)
                if stmt.offset is not None:
                    text += " offset " + e(stmt.offset)
                if stmt.orient:
                    text += " orient"
                return text + self._line_over(stmt.over)
            case ast.Posture():
                text = f"posture {stmt.kind}"
                if stmt.args:
                    lpar = self.src.ending_at(stmt.kind_span.end) + 1
                    text += self._line_args(lpar, self.src.match[lpar], stmt.args)
                return text + self._line_over(stmt.over)
            case ast.Walk():
                text = f"walk {stmt.mode} " + e(stmt.target)
                if stmt.facing is not None:
                    text += " facing " + e(stmt.facing)
                return text + self._line_over(stmt.over)
            case ast.Grip():
                return "grip " + e(stmt.hand) + f" {stmt.state}" + self._line_over(stmt.over)
            case ast.Gaze():
                return "gaze at " + e(stmt.target) + self._line_over(stmt.over)
            case ast.Still():
                return "still" + self._line_over(stmt.over)
        raise _NotOneLine  # a block, or a statement that holds one

    def _line_over(self, over: ast.Expr | None) -> str:
        return "" if over is None else " over " + self._line_expr(over)

    def _line_site(self, site: ast.SiteDecl) -> str:
        text = f"site {site.name} at " + self._line_expr(site.position)
        if site.normal is not None:
            text += " normal " + self._line_expr(site.normal)
        if site.frame is not None:
            text += " frame " + self._line_expr(site.frame)
        return text

    def _line_args(self, open_index: int, close_index: int, args: tuple[ast.Arg, ...]) -> str:
        self.call_parens.add(open_index)
        items = [
            self._line_expr(a.value) if a.name is None else f"{a.name}: " + self._line_expr(a.value)
            for a in args
        ]
        return self._line_list(open_index, close_index, items)

    def _line_list(self, open_index: int, close_index: int, items: list[str]) -> str:
        """A bracket list flat (_delimited and _empty_brackets, without comments)."""
        if items and self.src.comma_before(close_index):
            raise _NotOneLine  # a magic trailing comma: one item per line
        return self.src.text(open_index) + ", ".join(items) + self.src.text(close_index)

    def _line_expr(self, expr: ast.Expr, needs: int = 0, strict: bool = False) -> str:
        """_expr, flat."""
        kind = type(expr)
        if kind is ast.Name:  # the commonest, at once
            text = expr.name  # type: ignore[attr-defined]
            strength = _PRIMARY
        elif kind is ast.Number:
            number = self.src.text_at(expr.span.start)
            unit = expr.unit  # type: ignore[attr-defined]
            text = number if unit is None else f"{number} {unit}"
            strength = _PRIMARY
        else:
            strength = _strength(expr)
            text = self._line_bare(expr)
        bracket = strength < needs or (strict and strength == needs)
        if bracket or self._wrapped(expr):
            return "(" + text + ")"
        return text

    def _line_bare(self, expr: ast.Expr) -> str:
        """_bare, flat."""
        match expr:
            case ast.String():
                return self.src.text_at(expr.span.start)
            case ast.Number():
                number = self.src.text_at(expr.span.start)
                return number if expr.unit is None else f"{number} {expr.unit}"
            case ast.Name():
                return expr.name
            case ast.Binary():
                strength = _strength(expr)
                return (
                    self._line_expr(expr.left, strength)
                    + f" {expr.op} "
                    + self._line_expr(expr.right, strength, strict=True)
                )
            case ast.Unary():
                return expr.op + self._line_expr(expr.operand, _UNARY)
            case ast.Attr():
                return self._line_postfix_object(expr.obj) + f".{expr.name}"
            case ast.CallExpr():
                rpar = self.src.ending_at(expr.span.end)
                return self._line_postfix_object(expr.func) + self._line_args(
                    self.src.match[rpar], rpar, expr.args
                )
            case ast.Vector():
                open_index = self.src.starting_at(expr.span.start)
                items = [self._line_expr(x) for x in expr.items]
                text = self._line_list(open_index, self.src.match[open_index], items)
                return text if expr.unit is None else f"{text} {expr.unit}"
            case ast.ListExpr():
                open_index = self.src.starting_at(expr.span.start)
                items = [self._line_expr(x) for x in expr.items]
                return self._line_list(open_index, self.src.match[open_index], items)
        raise _NotOneLine  # the document path says what is wrong with it

    def _line_postfix_object(self, obj: ast.Expr) -> str:
        if isinstance(obj, ast.Number):
            return self._line_expr(obj, _PRIMARY + 1)
        return self._line_expr(obj, _POSTFIX)

    # ------------------------------------------------------------ statements
    def _stmt(self, stmt: ast.Node) -> Doc:
        line = self._one_line(stmt, self._line_stmt)
        if line is not None:
            return line
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
                return self._joined(
                    [Text("repeat "), self._expr(stmt.count), Text(" "), self._block(stmt.body)]
                )
            case ast.ForEach():
                return self._joined(
                    [
                        Text(f"for {stmt.var} in "),
                        self._expr(stmt.items),
                        Text(" "),
                        self._block(stmt.body),
                    ]
                )
            case ast.Parallel():
                return self._joined([Text("parallel "), self._block(stmt.body)])
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
        self.call_parens.add(open_index)
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
        if bracket or self._wrapped(expr):
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


_UNSEEN: Any = object()


def _with_suffix(element: Doc) -> str | None:
    """An element that is a text and one comment held to the end of a line, before or after
    it (a hosted comment, or one placed after the element's last line), as the one text the
    layout prints: the comment goes before the text's first new line (None: another shape)."""
    if type(element) is not list or len(element) != 2:
        return None
    first, second = element
    if type(first) is LineSuffix and type(second) is str:
        comment, text = first.text, second
    elif type(first) is str and type(second) is LineSuffix:
        return first + second.text if first else None
    else:
        return None
    if not text:
        return None
    cut = text.find("\n")
    return text + comment if cut < 0 else text[:cut] + comment + text[cut:]


class _NotOneLine(Exception):
    """What is being printed cannot be one flat line: build its document."""


def _start(node: ast.Node) -> int:
    return node.span.start


def _never(_a: _Entry, _b: _Entry) -> bool:
    return False


def _separate_top_level(before: _Entry, after: _Entry) -> bool:
    """A blank line between top-level items, except within a run of `use` lines."""
    return not (before.is_use and after.is_use)


def _strength(expr: ast.Expr) -> int:
    kind = type(expr)
    if kind is ast.Binary:
        return _SUM if expr.op in "+-" else _PRODUCT  # type: ignore[attr-defined]
    return _STRENGTHS.get(kind, _PRIMARY)


_STRENGTHS: dict[type, int] = {ast.Unary: _UNARY, ast.Attr: _POSTFIX, ast.CallExpr: _POSTFIX}
