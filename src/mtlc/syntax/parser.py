"""Parse a file into a Module, reporting every syntax error that recovery can reach.

Recovery works at two levels. The token stream is split into top-level items (a `use`, a scene,
a definition...), each parsed on its own, so an error in one item leaves the others intact; an
item left open (a missing `}`) is closed where the next top-level keyword starts a line. Inside an
item, the statement holding an error is deleted and the item parsed again, a bounded number of
times, so that later statements are still checked.
"""

from __future__ import annotations

from collections.abc import Iterator

from lark import Token
from lark.exceptions import UnexpectedInput, UnexpectedToken

from mtlc.diagnostics import DiagnosticSink, Span
from mtlc.diagnostics.suggest import did_you_mean
from mtlc.syntax import ast
from mtlc.syntax.fastparse import Fallback, fast_parse
from mtlc.syntax.gcpause import no_collections
from mtlc.syntax.grammar import builder, lexicon, parser
from mtlc.syntax.lexer import MAX_NESTING, NEWLINE, tokenize

MAX_RECOVERIES_PER_ITEM = 20
MAX_SYNTAX_ERRORS = 50

_TOP_LEVEL = {"USE", "SCENE", "TOOL", "ELEMENT", "ACTION", "TASK"}
# keywords that start an item and never a statement: a safe place to close an item left open
_RESYNC = {"USE", "ELEMENT", "ACTION", "TASK"}
_OPENERS = {"LBRACE": "RBRACE", "LPAR": "RPAR", "LSQB": "RSQB"}
_CLOSERS = {v: k for k, v in _OPENERS.items()}
_STATEMENT_ENDS = {NEWLINE, "SEMICOLON"}
_PUNCTUATION = {*_OPENERS, *_CLOSERS, NEWLINE, "SEMICOLON", "COMMA", "COLON", "DOT", "EQUAL"}
_SPLIT_AT = frozenset({NEWLINE, *_OPENERS, *_CLOSERS, *_RESYNC})


def token_span(file: str, tok: Token) -> Span:
    return Span(
        file, tok.line, tok.column, tok.end_line, tok.end_column, tok.start_pos, tok.end_pos
    )


class ItemMemo:
    """Top-level items that parsed without a diagnostic, by the kinds and texts of their tokens.

    The tree of an item is a function of those alone (positions only go into spans), so a later
    parse given the same memo (`mtlc fmt` parsing its output, which must mean the same) takes
    the node of an item whose tokens are the same instead of running the LALR parser again.
    ``reused`` lists, for each node taken so, the tokens it was parsed from and the new ones,
    in the same order (the new positions of its parts, which its spans do not give).
    """

    def __init__(self) -> None:
        self._items: dict[tuple[tuple[str, str], ...], tuple[ast.Node, list[Token]]] | None = None
        self._recorded: list[tuple[ast.Node, list[Token]]] = []
        self.recording = True
        self.reused: dict[int, tuple[ast.Node, list[Token], list[Token]]] = {}  # by id(node)

    def record(self, node: ast.Node, tokens: list[Token]) -> None:
        """Keep an item that parsed cleanly (keyed only when first looked up: `mtlc fmt` of an
        already canonical file never parses again, and the keys are a tuple per token)."""
        self._recorded.append((node, tokens))
        self._items = None

    @property
    def items(self) -> dict[tuple[tuple[str, str], ...], tuple[ast.Node, list[Token]]]:
        """The recorded items by ``key`` (the first of equal ones)."""
        if self._items is None:
            self._items = {}
            for node, tokens in self._recorded:
                self._items.setdefault(self.key(tokens), (node, tokens))
        return self._items

    @staticmethod
    def key(tokens: list[Token]) -> tuple[tuple[str, str], ...]:
        return tuple([(t.type, str(t.value)) for t in tokens])


def parse_module(
    text: str,
    file: str,
    sink: DiagnosticSink,
    tokens: list[Token] | None = None,
    memo: ItemMemo | None = None,
    item_ends: list[int] | None = None,
) -> ast.Module:
    """``tokens``: what ``tokenize(text, file, sink)`` gave, when the caller already has it
    (`mtlc fmt` tokenizes once for the parser, the printer and the comments); not mutated.
    ``memo``: see ItemMemo (recording on a first parse, reusing on the next).
    ``item_ends``: what ``tokenize`` put in its ``item_ends_out`` for ``tokens``, if known."""
    with no_collections():  # a token and a node per word: many young objects, no cycles
        return _parse_module(text, file, sink, tokens, memo, item_ends)


def _parse_module(
    text: str,
    file: str,
    sink: DiagnosticSink,
    tokens: list[Token] | None,
    memo: ItemMemo | None,
    item_ends: list[int] | None,
) -> ast.Module:
    if tokens is None:
        item_ends = []
        tokens = tokenize(text, file, sink, None, item_ends)
    uses: list[ast.Use] = []
    decls: list[ast.Decl] = []
    # a word reported as an invalid name (MT0108) is not reported again as an unknown name
    broken: set[str] = (
        set()
        if text.isascii()  # then so is every token (no scan of them all)
        else {
            t.value for t in tokens if t.type == "NAME" and not t.isascii() and not t.isidentifier()
        }
    )
    errors_before = len(sink.items)
    for item_tokens in _split_items(tokens, file, sink, item_ends):
        if len(sink.items) - errors_before > MAX_SYNTAX_ERRORS:
            sink.report(
                "MT0106",
                f"more than {MAX_SYNTAX_ERRORS} syntax errors; the rest of the file is not checked",
                token_span(file, item_tokens[0]),
            )
            broken.add("*")
            break
        count = len(sink.items)
        node = _parse_memo(item_tokens, file, sink, memo) if memo else None
        if node is None:
            node = _parse_item(item_tokens, file, sink)
            if (
                memo is not None
                and memo.recording
                and node is not None
                and len(sink.items) == count
            ):
                memo.record(node, item_tokens)
        if node is None or len(sink.items) > count:
            # an item that failed, or parsed only after recovery: its signature is not trusted
            name = _declared_name(item_tokens)
            if name:
                broken.add(name)
        if node is None:
            continue
        if isinstance(node, ast.Use):
            uses.append(node)
        else:
            decls.append(node)
    end = len(text)
    last_line = text.count("\n") + 1
    span = Span(file, 1, 1, last_line, 1, 0, end)
    return ast.Module(
        span=span, path=file, uses=tuple(uses), decls=tuple(decls), broken_names=frozenset(broken)
    )


def _parse_memo(
    item_tokens: list[Token], file: str, sink: DiagnosticSink, memo: ItemMemo
) -> ast.Node | None:
    """The node of an item with these very tokens parsed before, once per parse (None: parse)."""
    if memo.recording:
        return None
    found = memo.items.get(memo.key(item_tokens))
    if found is None or id(found[0]) in memo.reused:
        return None
    memo.reused[id(found[0])] = (found[0], found[1], item_tokens)
    return found[0]


def _declared_name(tokens: list[Token]) -> str | None:
    if len(tokens) >= 2 and tokens[0].type in _TOP_LEVEL and tokens[1].type not in _PUNCTUATION:
        return tokens[1].value
    return None


def _synthetic(kind: str, after: Token) -> Token:
    value = {"RBRACE": "}", "RPAR": ")", "RSQB": "]"}[kind]
    return Token(
        kind, value, after.end_pos, after.end_line, after.end_column, after.end_line,
        after.end_column, after.end_pos,
    )  # fmt: skip


def _split_items(
    tokens: list[Token], file: str, sink: DiagnosticSink, item_ends: list[int] | None = None
) -> Iterator[list[Token]]:
    """Yield the token lists of top-level items; close items left open; refuse deep nesting.

    Linear in the number of tokens, however deep or unbalanced the brackets: ``open_at`` keeps,
    for each kind of opener, where it stands on ``stack``, so a closer finds its opener at once
    instead of searching the stack (which made 100 KB of brackets take minutes).

    ``item_ends`` (see ``tokenize``'s ``item_ends_out``; empty or None: not known): the lexer
    found the brackets plainly nested, so an item ends at each new line outside them and at
    the end, with nothing to close or report: the same items, by slices.
    """
    if item_ends:
        taken = 0
        for end in item_ends:
            if end > taken:
                yield tokens[taken:end]
            taken = end + 1  # the new line belongs to no item
        return
    item: list[Token] = []  # the item's tokens before ``taken`` (and any closer added)
    taken = 0  # tokens[taken:i] go to the item too: copied by slices, not one by one
    stack: list[Token] = []
    open_at: dict[str, list[int]] = {kind: [] for kind in _OPENERS}  # indices into ``stack``
    too_deep = False

    def take(upto: int) -> None:
        nonlocal taken
        item.extend(tokens[taken:upto])
        taken = upto

    def pop_down_to(depth: int) -> None:
        """Forget the brackets open above ``depth``; each one is popped once, so linear overall."""
        while len(stack) > depth:
            open_at[stack.pop().type].pop()

    def close_down_to(depth: int) -> None:
        """Close the brackets left open above ``depth``, reporting the innermost."""
        opener = stack[-1]
        closer = _OPENERS[opener.type]
        sink.report(
            "MT0105",
            f"`{opener.value}` is never closed",
            token_span(file, opener),
            help=f"add `{_synthetic(closer, opener).value}` where it should end",
        )
        while len(stack) > depth:
            item.append(_synthetic(_OPENERS[stack[-1].type], item[-1]))
            pop_down_to(len(stack) - 1)

    def finish(at: int) -> Iterator[list[Token]]:
        """End the item before ``tokens[at]``."""
        nonlocal item, too_deep
        take(at)
        if item and not too_deep:
            if stack:
                close_down_to(0)
            yield item
        pop_down_to(0)
        item, too_deep = [], False

    # only the tokens that end an item or open or close a bracket are looked at one by one
    for i in [i for i, t in enumerate(tokens) if t.type in _SPLIT_AT]:
        tok = tokens[i]
        ttype = tok.type
        if ttype == NEWLINE and not stack:
            yield from finish(i)
            taken = i + 1  # the new line belongs to no item
            continue
        if stack and ttype in _RESYNC and tok.column == 1:
            yield from finish(i)
        if ttype in _OPENERS:
            open_at[ttype].append(len(stack))
            stack.append(tok)
            if len(stack) > MAX_NESTING and not too_deep:
                too_deep = True
                sink.report(
                    "MT0104",
                    f"blocks and brackets nest more than {MAX_NESTING} deep",
                    token_span(file, tok),
                    help="split the definition into smaller actions or elements",
                )
        elif ttype in _CLOSERS and stack:
            found = open_at[_CLOSERS[ttype]]
            if found:
                at = found[-1]
                if at < len(stack) - 1 and not too_deep:
                    take(i)
                    close_down_to(at + 1)
                pop_down_to(at)
    yield from finish(len(tokens))


def _describe(term: str) -> str:
    lx = lexicon()
    for text, name in (*lx.keywords.items(), *lx.punctuation.items()):
        if name == term:
            return f"`{text}`"
    return {
        "NAME": "a name",
        "NUMBER": "a number",
        "STRING": "a string",
        NEWLINE: "a new line",
        "$END": "the end of the definition",
    }.get(term, term)


def _describe_token(tok: Token) -> str:
    if tok.type == "$END":
        return "end of the definition"
    if tok.type == NEWLINE:
        return "new line"
    if tok.type in ("NAME", "NUMBER", "STRING"):
        return f"{_describe(tok.type)[2:]} `{tok.value}`"
    return f"`{tok.value}`"


def _parse_item(tokens: list[Token], file: str, sink: DiagnosticSink) -> ast.Node | None:
    attempt = DiagnosticSink()
    builder().begin(file, attempt)
    try:
        node = fast_parse(builder(), tokens)
    except Fallback:  # an error, or input the fast parser leaves to lark: lark decides
        pass
    else:
        sink.items.extend(attempt.items)
        return node
    return _parse_item_lark(tokens, file, sink)


def _parse_item_lark(tokens: list[Token], file: str, sink: DiagnosticSink) -> ast.Node | None:
    """lark's LALR parser, with recovery: every syntax diagnostic is made here."""
    lark = parser()
    for _attempt in range(MAX_RECOVERIES_PER_ITEM):
        attempt = DiagnosticSink()  # what the builder finds counts only for the parse that succeeds
        builder().begin(file, attempt)
        try:
            node = lark.parse(tokens)
            sink.items.extend(attempt.items)
            return node
        except UnexpectedToken as err:
            bad = err.token
            at_end = bad.type == "$END"
            known = any(t is bad for t in tokens)
            where = bad if known and not at_end else tokens[-1]
            expected = sorted(
                _describe(t) for t in err.expected if not t.startswith("__") and t != "$END"
            )
            if at_end:
                sink.report(
                    "MT0105",
                    "the definition ends too early",
                    token_span(file, where),
                    help=f"expected {_one_of(expected)}" if expected else None,
                )
                return None
            index = next(i for i, t in enumerate(tokens) if t is bad)
            gap, between = _missing_comma(tokens, index, err.expected)
            if between:
                before, bad = tokens[gap - 1], tokens[gap]
                sink.report(
                    "MT0101",
                    f"expected `,` between {between}",
                    Span(
                        file,
                        before.end_line,
                        before.end_column,
                        bad.line,
                        bad.column,
                        before.end_pos,
                        bad.start_pos,
                    ),
                    help=f"add `,` after `{before.value}`",
                )
            else:
                sink.report(
                    "MT0101",
                    f"unexpected {_describe_token(bad)}",
                    token_span(file, where),
                    notes=(f"expected {_one_of(expected)}",) if 0 < len(expected) <= 8 else (),
                    help=_keyword_hint(tokens[index - 1]) if index > 0 else None,
                )
            tokens = _drop_statement(tokens, index)
            if not tokens:
                return None
        except UnexpectedInput:
            return None
    return None


_STARTS_EXPR = {"NAME", "NUMBER", "STRING", "LPAR", "LSQB", "MINUS"}


def _missing_comma(tokens: list[Token], index: int, expected: set[str]) -> tuple[int, str | None]:
    """`f(a b)`, `(0 120, 60) cm`: where a `,` is missing, and what it separates.

    Only when a `,` could come here, the token could start the next item, and the innermost
    open bracket is a `(` or `[` of this statement: "arguments" after a call's name, else "items".
    In `f(turns: 1 load: 2 kg)` the parser took `load` for the unit of `1` and stops at the `:`:
    the comma is missing before `load`.
    """
    keywords = set(lexicon().keywords.values())
    if (
        tokens[index].type == "COLON"
        and index >= 2
        and tokens[index - 2].type == "NUMBER"
        and tokens[index - 1].type in keywords | {"NAME"}
    ):
        index -= 1
        expected = {"COMMA"}
    bad = tokens[index]
    starts = bad.type in _STARTS_EXPR or bad.type in keywords
    if index == 0 or "COMMA" not in expected or not starts:
        return index, None
    depth = 0
    for i in range(index - 1, -1, -1):
        t = tokens[i].type
        if t in _CLOSERS:
            depth += 1
        elif t in _OPENERS:
            if depth == 0:
                if t == "LBRACE":
                    return index, None
                return index, "arguments" if t == "LPAR" and _is_callee(tokens, i - 1) else "items"
            depth -= 1
    return index, None


def _is_callee(tokens: list[Token], i: int) -> bool:
    """Is ``tokens[i]`` (before a `(`) a name being called, not a keyword such as `at`?"""
    if i < 0:
        return False
    if tokens[i].type in ("NAME", "RPAR"):
        return True
    keyword = tokens[i].type in lexicon().keywords.values()
    return keyword and (i == 0 or tokens[i - 1].type in (NEWLINE, "SEMICOLON", "LBRACE", "DOT"))


def _keyword_hint(previous: Token) -> str | None:
    """`repet 3 {`: the word before the error is probably a misspelt keyword."""
    if previous.type != "NAME":
        return None
    hint = did_you_mean(previous.value, lexicon().keywords)
    return hint and f"`{previous.value}` is not a keyword; {hint}"


def _one_of(items: list[str]) -> str:
    if len(items) == 1:
        return items[0]
    return "one of " + ", ".join(items)


def _drop_statement(tokens: list[Token], index: int) -> list[Token]:
    """Remove the statement around ``tokens[index]``: from the end of the previous statement in
    the same block to the end of this one, skipping over nested blocks, so the item stays balanced.
    Parentheses and brackets never hold statement ends (newlines inside them are dropped)."""
    if index == 0:
        return []  # the item's own header is broken: nothing to recover
    start, depth = index, 0
    while start > 0:
        t = tokens[start - 1].type
        if t == "RBRACE":
            depth += 1
        elif t == "LBRACE":
            if depth == 0:
                break
            depth -= 1
        elif depth == 0 and t in _STATEMENT_ENDS:
            break
        start -= 1
    end, depth = index, 0
    while end < len(tokens):
        t = tokens[end].type
        if t == "LBRACE":
            depth += 1
        elif t == "RBRACE":
            if depth == 0:
                break
            depth -= 1
        elif depth == 0 and t in _STATEMENT_ENDS:
            break
        end += 1
    if start == 0 or end <= start:
        # the error is in the item's header: drop the offending token alone
        return tokens[:index] + tokens[index + 1 :]
    return tokens[:start] + tokens[end:]
