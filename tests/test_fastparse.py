"""The recursive-descent parser (mtlc.syntax.fastparse) never decides otherwise than lark.

Wherever it accepts an item, lark's LALR parser accepts it too and builds the same node (spans
included) with the same builder diagnostics in the same order; where it does not, the item goes
to lark, so the syntax diagnostics are lark's by construction. It must also accept every item
lark accepts in the shipped files and in clean generated programs (else it saves nothing).
"""

from __future__ import annotations

import importlib.util
import random
import sys

from conftest import EXAMPLES, ROOT, STDLIB
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from lark.exceptions import UnexpectedInput

from mtlc.diagnostics import DiagnosticSink
from mtlc.syntax.fastparse import MAX_UNARY, Fallback, fast_parse
from mtlc.syntax.grammar import builder, lexicon, parser
from mtlc.syntax.lexer import tokenize
from mtlc.syntax.parser import _split_items

_spec = importlib.util.spec_from_file_location("mtlc_bench_fuzz_fp", ROOT / "bench" / "fuzz.py")
assert _spec is not None and _spec.loader is not None
fuzz = importlib.util.module_from_spec(_spec)
sys.modules[_spec.name] = fuzz
_spec.loader.exec_module(fuzz)


def _diags(sink: DiagnosticSink) -> list[tuple[str, object, str, object]]:
    return [(d.code, d.span, d.message, d.help) for d in sink.items]


def _both(tokens: list) -> tuple[bool, bool]:  # type: ignore[type-arg]
    """Parse one item both ways; assert they agree where the fast one accepts it.
    (fast accepted, lark accepted)."""
    fast_sink, lark_sink = DiagnosticSink(), DiagnosticSink()
    builder().begin("f.mtask", fast_sink)
    try:
        fast = fast_parse(builder(), tokens)
    except Fallback:
        fast = Fallback
    builder().begin("f.mtask", lark_sink)
    try:
        slow = parser().parse(tokens)
    except UnexpectedInput:
        slow = UnexpectedInput
    long_minus = "-" * (MAX_UNARY + 1) in "".join(str(t.value) for t in tokens)
    if slow is not UnexpectedInput and not long_minus:  # it leaves nothing lark accepts to lark
        assert fast is not Fallback, [t.value for t in tokens]
    if fast is not Fallback:
        assert slow is not UnexpectedInput, [t.value for t in tokens]
        assert fast == slow, [t.value for t in tokens]
        assert getattr(fast, "depth", 1) == getattr(slow, "depth", 1)
        assert _diags(fast_sink) == _diags(lark_sink)
    return fast is not Fallback, slow is not UnexpectedInput


def _items(text: str) -> list[list]:  # type: ignore[type-arg]
    tokens = tokenize(text, "f.mtask", DiagnosticSink())
    return list(_split_items(tokens, "f.mtask", DiagnosticSink()))


def _compare_text(text: str) -> list[tuple[bool, bool]]:
    return [_both(item) for item in _items(text)]


def test_every_item_of_the_shipped_files_is_parsed_fast_and_the_same() -> None:
    for path in (*EXAMPLES, *STDLIB):
        results = _compare_text(path.read_text(encoding="utf-8"))
        assert results and all(fast and slow for fast, slow in results), path


def test_clean_generated_programs_are_parsed_fast_and_the_same() -> None:
    """bench/fuzz.py's calm generated programs: whatever lark accepts, the fast parser does."""
    missed = 0
    for index in range(150):
        text = fuzz.Gen(random.Random(f"fast:{index}"), 0.05).program()
        for fast, slow in _compare_text(text):
            missed += slow and not fast
    assert missed == 0


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.integers(0, 10**9))
def test_fuzz_cases_agree(index: int) -> None:
    """Generated (calm and wild) and byte-mutated cases from bench/fuzz.py."""
    _, data = fuzz.make_case(3, index, fuzz.example_sources())
    _compare_text(data.decode("utf-8", "replace"))


# every kind of token, for token-level mutations that reach the grammar's corners (a keyword
# before `(` or `.`, a name after a number or a vector, trailing commas, empty brackets)
_VOCAB = [  # a new line twice as often
    "\n",
    *sorted({*lexicon().keywords, *lexicon().punctuation, "x", "cm", "1", "2.5", '"t"', "\n"}),
]


@settings(max_examples=250, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    st.sampled_from([p.read_text(encoding="utf-8") for p in EXAMPLES]),
    st.lists(
        st.tuples(st.integers(0, 10**6), st.integers(0, 3), st.sampled_from(_VOCAB)),
        min_size=1,
        max_size=4,
    ),
)
def test_token_mutations_agree(source: str, edits: list[tuple[int, int, str]]) -> None:
    """An item of an example with tokens inserted, deleted, replaced or duplicated."""
    items = _items(source)
    for at, op, word in edits:
        item = items[at % len(items)]
        words = [str(t.value) for t in item]
        i = at % len(words)
        if op == 0:
            words.insert(i, word)
        elif op == 1:
            del words[i]
        elif op == 2:
            words[i] = word
        else:
            words[i:i] = words[i : i + 3]
        for tokens in _items(" ".join(words)):
            _both(tokens)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    st.sampled_from(["task", "action", "scene", "tool", "element", "use"]),
    st.lists(st.sampled_from(_VOCAB), min_size=1, max_size=25),
)
def test_random_token_strings_agree(head: str, words: list[str]) -> None:
    text = f"{head} " + " ".join(words)
    for tokens in _items(text):
        _both(tokens)


_KEYWORDS = sorted(lexicon().keywords)
_WORD = st.sampled_from(["x", "cm", "s", *_KEYWORDS])  # keywords are names almost anywhere


def _corner_exprs() -> st.SearchStrategy[str]:
    leaves = st.one_of(
        _WORD,
        st.sampled_from(["1", "2.5", ".5", '"t"', '"a\\nb"']),
        st.builds(lambda n, u: f"{n} {u}", st.sampled_from(["1", "3"]), _WORD),
    )

    def extend(inner: st.SearchStrategy[str]) -> st.SearchStrategy[str]:
        def join(items: list[str], trailing: bool) -> str:
            return ", ".join(items) + ("," if trailing and items else "")

        return st.one_of(
            st.builds(lambda a, op, b: f"{a} {op} {b}", inner, st.sampled_from("+-*/"), inner),
            st.builds(lambda n, a: "- " * n + a, st.integers(1, 3), inner),
            st.builds(lambda a: f"({a})", inner),
            st.builds(
                lambda xs, t, u: f"({join(xs, t)}) {u}",
                st.lists(inner, min_size=2, max_size=3),
                st.booleans(),
                st.sampled_from(["", "cm", "at"]),
            ),
            st.builds(lambda xs, t: f"[{join(xs, t)}]", st.lists(inner, max_size=3), st.booleans()),
            st.builds(lambda a, w: f"{a}.{w}", inner, _WORD),
            st.builds(lambda a, xs: f"{a}({', '.join(xs)})", inner, st.lists(inner, max_size=2)),
            st.builds(lambda w, a: f"f({w}: {a})", _WORD, inner),
        )

    return st.recursive(leaves, extend, max_leaves=5)


_CE = _corner_exprs()


_STATEMENT_KEYWORDS = [
    "repeat",
    "for",
    "parallel",
    "manikin",
    "scene",
    "tool",
    "budget",
    "time",
    "goal",
    "posture",
    "walk",
    "grip",
    "gaze",
    "still",
]


def _corner_stmts() -> st.SearchStrategy[str]:
    """Simple statements, with every keyword at a statement's start followed by `(`, `.` or its own
    continuation: the places where LALR's one token of lookahead decides."""
    head = st.one_of(st.sampled_from(_KEYWORDS), st.sampled_from(_STATEMENT_KEYWORDS))
    simple = st.one_of(
        st.builds(lambda k, e: f"{k} {e}", head, _CE),
        st.builds(lambda k, e: f"{k}({e})", head, _CE),
        st.builds(lambda k, e: f"{k} ({e}) + 1", head, _CE),
        st.builds(lambda k, w, e: f"{k}.{w}({e})", head, _WORD, _CE),
        st.builds(lambda a, b, c: f"goal {a} at {b} approach {c} orient over {a}", _CE, _CE, _CE),
        st.builds(lambda a, w: f"grip {a} {w} over 1 s", _CE, _WORD),
        st.builds(lambda w, a: f"posture {w}({a}) over 1 s", _WORD, _CE),
        st.builds(lambda a, b: f"walk to {a} facing {b}", _CE, _CE),
        st.builds(lambda w: f"manikin {w} {w} {w}", _WORD),
    )

    return simple


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(_corner_stmts(), min_size=1, max_size=6), st.sampled_from(_STATEMENT_KEYWORDS))
def test_statements_at_the_grammars_corners_agree(stmts: list[str], keyword: str) -> None:
    """Each statement in a task of its own (one bad statement would send the whole item to
    lark), then all of them in blocks, and the first as a scene's ground."""
    accepted = 0
    for stmt in stmts:
        accepted += sum(fast for fast, _ in _compare_text(f"task t {{\n{stmt}\n}}"))
    body = "{\n" + "; ".join(stmts) + "\n}"
    _compare_text(f"action a(x: y = {stmts[0]},) {{ {keyword} x {body}; parallel {body} }}")
    _compare_text(f"scene b {{ ground {stmts[0]}\nsite a at {stmts[-1]} normal (0, 0, 1) }}")
    _ACCEPTED.append(accepted / len(stmts))


_ACCEPTED: list[float] = []


def test_the_corner_statements_are_mostly_accepted() -> None:
    """The test above compares something: most of its statements parse (run after it)."""
    if not _ACCEPTED:
        test_statements_at_the_grammars_corners_agree()
    assert sum(_ACCEPTED) / len(_ACCEPTED) > 0.3


def test_the_conflicts_are_resolved_as_lark_does() -> None:
    """The two shift/reduce conflicts of the grammar, both ways round, with input both accept."""
    cases = [
        "task t { time (1 s) }",  # `time (`: the statement
        "task t { tool (a) }",
        "task t { repeat (2) { f() } }",
        "task t { walk(x) }",  # `walk (`: a call
        "task t { scene(x); posture(a); still(b) }",
        "task t { time.x(1) }",
        "task t { f(1 cm, (1, 2, 3) m, (1, 2,) cm) }",
        "task t { grip 3 closed }",  # the unit takes the NAME: refused by both
        "task t { f(- - - 1, -x.y(2).z) }",
        "element e(a: B, c: D = 1 + 2 * 3 - 4 / 5,) { goal h at s approach 1 cm orient over 1 s }",
    ]
    accepted = [fast for text in cases for fast, _ in _compare_text(text)]
    assert accepted == [True] * 7 + [False, True, True]


def _split_both(text: str) -> bool:
    """Split ``text`` by the lexer's item ends and by the parser's own walk; assert the same
    items and no diagnostic where the lexer gave ends. Whether it gave them."""
    ends: list[int] = []
    tokens = tokenize(text, "f.mtask", DiagnosticSink(), None, ends)
    walked_sink, sliced_sink = DiagnosticSink(), DiagnosticSink()
    walked = list(_split_items(tokens, "f.mtask", walked_sink))
    sliced = list(_split_items(tokens, "f.mtask", sliced_sink, ends))
    if ends:
        assert [[(t.type, t.start_pos) for t in item] for item in sliced] == [
            [(t.type, t.start_pos) for t in item] for item in walked
        ]
        assert not walked_sink.items and not sliced_sink.items
    return bool(ends)


def test_the_lexers_item_ends_split_as_the_parser_does() -> None:
    assert all(_split_both(p.read_text(encoding="utf-8")) for p in (*EXAMPLES, *STDLIB))
    # what it must refuse: an open or crossed bracket, a word starting a line inside one
    assert not _split_both("task t {\n    a(\n}\n")
    assert not _split_both("task t {\n    a(]\n}\n")
    assert not _split_both("task t {\n    a(\ntask u {\n}\n")
    assert not _split_both("task t {\n" + "(" * 70 + ")" * 70 + "\n}\n")


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    st.sampled_from([p.read_text(encoding="utf-8") for p in (*EXAMPLES, *STDLIB)]),
    st.lists(
        st.tuples(
            st.integers(0, 10**6),
            st.integers(0, 6),
            st.sampled_from(["", "(", ")", "[", "]", "{", "}", "\n", "task", "use a", "x", "（"]),
        ),
        max_size=4,
    ),
)
def test_the_lexers_item_ends_agree_on_mutated_files(
    source: str, edits: list[tuple[int, int, str]]
) -> None:
    text = source
    for at, cut, insert in edits:
        at %= len(text) + 1
        text = text[:at] + insert + text[at + cut :]
    _split_both(text)


_SHAPE_CLAUSES = [
    "at (0, 1, 2) cm",
    "rotate (0, 90, 0) deg",
    "size (1, 2, 3) cm",
    "radius 2 cm",
    "length x",
    "axis (1, 0, 0)",
    "normal (0, 0, -1)",
    "units mm",
    "up z",
    "opening round 8 cm",
    "opening rect (1, 2) cm",
    "at",
    "opening round",
    "units",
]
_SCENE_MEMBERS = st.one_of(
    st.builds(
        lambda head, clauses: head + " " + " ".join(clauses),
        st.sampled_from(['model m "a.glb"', "box b", "cylinder c", "plate p", "model m", "box"]),
        st.lists(st.sampled_from(_SHAPE_CLAUSES), max_size=4),
    ),
    st.sampled_from(
        [
            "site a = m.n",
            "site a = m.n.o",
            "site a = m",
            "sites from m",
            "sites m",
            "site up = box.length",
            "site a at (0, 0, 0) m",
        ]
    ),
)


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(_SCENE_MEMBERS, max_size=4), st.sampled_from(["\n", "; "]))
def test_models_and_solids_agree(members: list[str], sep: str) -> None:
    """Scene members of every new kind, with their clauses in any order, some cut short."""
    for tokens in _items("scene s {" + sep.join(members) + "}\n"):
        _both(tokens)
