"""Hostile and large inputs at a reduced size (issue 17, section 2; bench/hostile.py has the
full sizes and the times). Nothing here is timed: the work of the front end and of fmt is counted
(Python lines run in mtlc's own code) at two sizes, and must grow linearly."""

from __future__ import annotations

import io
import sys
from collections.abc import Callable
from contextlib import redirect_stderr, redirect_stdout
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from lark import Token

import mtlc
from mtlc.cli import main
from mtlc.diagnostics import DiagnosticSink
from mtlc.fmt import format_source
from mtlc.frontend import (
    FrontendOptions,
    Program,
    check_definitions,
    collect_scopes,
    load_modules,
    run_frontend,
)
from mtlc.syntax import parse_module
from mtlc.syntax.parser import MAX_NESTING, _split_items

SRC = str(Path(mtlc.__file__).resolve().parent)
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))
import hostile  # noqa: E402  (bench/hostile.py: the same inputs, at full size)


def lines_run(fn: Callable[[], object]) -> int:
    """How many lines of mtlc's own code ``fn`` runs: a measure of work that, unlike time, does
    not depend on the machine or its load (comprehensions and generators count per item)."""
    count = 0

    def local(frame, event, arg):  # type: ignore[no-untyped-def]
        nonlocal count
        if event == "line":
            count += 1
        return local

    def tracer(frame, event, arg):  # type: ignore[no-untyped-def]
        return local if frame.f_code.co_filename.startswith(SRC) else None

    old = sys.gettrace()
    sys.settrace(tracer)
    try:
        fn()
    finally:
        sys.settrace(old)
    return count


def assert_linear(work: Callable[[int], int], n: int) -> None:
    """Four times the input costs about four times the work (a quadratic step costs 16)."""
    small, large = work(n), work(4 * n)
    assert large < 5 * small, f"work {small:,} at n={n} but {large:,} at 4n: not linear"


def _parse(text: str) -> list[str]:
    sink = DiagnosticSink()
    parse_module(text, "hostile.mtask", sink)
    return [d.code for d in sink.items]


# ---------------------------------------------------------------- nesting
@pytest.mark.parametrize(
    "opener, closer", [("(", ")"), ("[", "]"), ("{", "}"), ("(", "]"), ("[", ")")]
)
def test_nested_brackets_are_linear_to_split(opener: str, closer: str) -> None:
    def work(n: int) -> int:
        text = f"task t {{\n    f({opener * n}1{closer * n})\n}}\n"
        return lines_run(lambda: _parse(text))

    assert_linear(work, 300)


def test_twenty_kilobytes_of_nesting_is_one_diagnostic_and_the_next_item_survives() -> None:
    text = "task t {\n    inspect(" + "(" * 10_000 + "1" + ")" * 10_000 + ", 1 s)\n}\n"
    sink = DiagnosticSink()
    module = parse_module(text + "\ntask after {\n}\n", "deep.mtask", sink)
    assert [d.code for d in sink.items] == ["MT0104"]
    assert [d.name for d in module.decls] == ["after"]


def _split_items_before_issue_17(
    tokens: list[Token], sink: DiagnosticSink, limit: int
) -> list[list[Token]]:
    """The quadratic algorithm that the linear one replaced, kept as the reference."""
    from mtlc.syntax.lexer import NEWLINE
    from mtlc.syntax.parser import _CLOSERS, _OPENERS, _RESYNC, _synthetic, token_span

    out: list[list[Token]] = []
    item: list[Token] = []
    stack: list[Token] = []
    too_deep = False

    def close_down_to(depth: int) -> None:
        opener = stack[-1]
        closer = _OPENERS[opener.type]
        sink.report(
            "MT0105",
            f"`{opener.value}` is never closed",
            token_span("f", opener),
            help=f"add `{_synthetic(closer, opener).value}` where it should end",
        )
        while len(stack) > depth:
            item.append(_synthetic(_OPENERS[stack.pop().type], item[-1]))

    def finish() -> None:
        nonlocal item, stack, too_deep
        if item and not too_deep:
            if stack:
                close_down_to(0)
            out.append(item)
        item, stack, too_deep = [], [], False

    for tok in tokens:
        if tok.type == NEWLINE and not stack:
            finish()
            continue
        if stack and tok.type in _RESYNC and tok.column == 1:
            finish()
        if tok.type in _OPENERS:
            stack.append(tok)
            if len(stack) > limit and not too_deep:
                too_deep = True
                sink.report("MT0104", "deep", token_span("f", tok))
        elif tok.type in _CLOSERS and stack:
            match = [i for i, t in enumerate(stack) if t.type == _CLOSERS[tok.type]]
            if match and match[-1] < len(stack) - 1 and not too_deep:
                close_down_to(match[-1] + 1)
            if match:
                del stack[match[-1] :]
        item.append(tok)
    finish()
    return out


_PIECES = ["(", ")", "[", "]", "{", "}", "\n", "x", ",", "task", "\ntask", "use"]


@settings(max_examples=300, deadline=None)
@given(st.lists(st.sampled_from(_PIECES), max_size=120), st.integers(1, 5))
def test_split_items_agrees_with_the_quadratic_reference(pieces: list[str], depth: int) -> None:
    """Same items, same synthetic closers, same diagnostics, for any brackets in any order (the
    nesting limit is lowered so that it is reached too)."""
    from mtlc.syntax import parser as P
    from mtlc.syntax.lexer import tokenize

    tokens = tokenize(" ".join(pieces), "f", DiagnosticSink())
    old_limit = P.MAX_NESTING
    P.MAX_NESTING = depth
    try:
        mine, theirs = DiagnosticSink(), DiagnosticSink()
        got = list(_split_items(tokens, "f", mine))
    finally:
        P.MAX_NESTING = old_limit
    want = _split_items_before_issue_17(tokens, theirs, depth)
    assert [[(t.type, t.value, t.start_pos) for t in i] for i in got] == [
        [(t.type, t.value, t.start_pos) for t in i] for i in want
    ]
    assert [(d.code, d.span.start) for d in mine.items] == [
        (d.code, d.span.start) for d in theirs.items
    ]


_SHAPES = {
    "unary": "- " * 98 + "1 s",
    "sum": " + ".join(["1 s"] * 100),
    "attribute": "x" + ".a" * 99,
    "call": "x" + "()" * 99,
    "mixed": "- x" + ".a()" * 49,
}


def _deepest(shape: str) -> str:
    """The deepest file the parser accepts: blocks to the nesting limit around an expression to
    the depth limit, in a shape the printer and the checker recurse on in their own way."""
    blocks = MAX_NESTING - 3  # the action's `{`, `hold(` and a call's `(` count too
    body = "repeat 1 {\n" * blocks + f"hold({_SHAPES[shape]})\n" + "}\n" * blocks
    return f"use stdlib.elements\n\naction deep() {{\n{body}}}\n\ntask t {{\n    deep()\n}}\n"


@pytest.mark.parametrize("shape", list(_SHAPES))
def test_deepest_accepted_file_never_reaches_the_recursion_limit(
    shape: str, tmp_path: Path
) -> None:
    text = _deepest(shape)
    path = tmp_path / f"{shape}.mtask"
    path.write_text(text, encoding="utf-8")
    assert sys.getrecursionlimit() <= 1000  # Python's default: what users run with
    for command in (["check"], ["check", "--dump", "ast"], ["fmt", "--check"], ["lint"]):
        out, err = io.StringIO(), io.StringIO()
        with redirect_stdout(out), redirect_stderr(err):
            status = main([*command, str(path)])
        assert status in (0, 1), (command, err.getvalue()[-2000:])
        assert "MT0900" not in out.getvalue() + err.getvalue(), command
    result = format_source(text, str(path))
    assert result.text is not None and format_source(result.text, str(path)).text == result.text


# ---------------------------------------------------------------- sites
def test_site_lookup_is_linear_in_the_number_of_sites(tmp_path: Path) -> None:
    """The checker alone (parsing is measured above): each name used is one lookup."""

    def work(n: int) -> int:
        path = hostile.many_sites(n)(tmp_path, 1.0)
        program = collect_scopes(load_modules(Program([path], FrontendOptions(expand=False))))
        count = lines_run(lambda: check_definitions(program))
        assert program.diagnostics == []
        return count

    assert_linear(work, 200)


# ---------------------------------------------------------------- empty loops
def _frontend(text: str, tmp_path: Path, budget: int = 100_000) -> list[str]:
    path = tmp_path / "loops.mtask"
    path.write_text(text, encoding="utf-8")
    program = run_frontend([path], FrontendOptions(expansion_budget=budget))
    return [f"{d.code} {d.message}" for d in program.diagnostics]


def test_nested_empty_for_loops_end_in_the_budget(tmp_path: Path) -> None:
    """10^9 rounds of nothing: each round counts as a primitive would, so 100,000 end it."""
    path = hostile.nested_empty_for(tmp_path, 1.0)
    got = _frontend(path.read_text(encoding="utf-8"), tmp_path)
    assert len(got) == 1 and got[0].startswith("MT0401 ")
    assert "empty loop rounds" in got[0]


def test_deeply_nested_for_loops_over_two_items_end_in_the_budget(tmp_path: Path) -> None:
    path = hostile.deep_for(tmp_path, 1.0)
    got = _frontend(path.read_text(encoding="utf-8"), tmp_path, budget=2_000)
    assert len(got) == 1 and got[0].startswith("MT0401 ")
    assert "rounds of `for` move nothing" in got[0]


def test_a_few_empty_rounds_are_fine_and_change_no_timeline(tmp_path: Path) -> None:
    head = "use stdlib.actions\n\nscene s {\n    site bolt at (0, 100, 40) cm\n}\n\n"
    plain = head + "task t {\n    scene s\n    inspect(bolt)\n}\n"
    looped = head + (
        "task t {\n    scene s\n    for a in [1, 2, 3] {\n        for b in [1, 2] {\n"
        "        }\n    }\n    inspect(bolt)\n    for c in [1, 2] {\n    }\n}\n"
    )
    assert _frontend(plain, tmp_path) == [] and _frontend(looped, tmp_path) == []
    timelines = []
    for text in (plain, looped):
        path = tmp_path / "t.mtask"
        path.write_text(text, encoding="utf-8")
        (timeline,) = run_frontend([path]).timelines
        timelines.append([(p.kind, p.effector, p.start, p.end) for p in timeline.primitives])
    assert timelines[0] == timelines[1]


def test_empty_rounds_count_in_the_budget_with_the_primitives(tmp_path: Path) -> None:
    """A budget of 10: `inspect` makes 2 primitives, so 8 empty rounds fit and 9 do not."""

    def task(rounds: int) -> str:
        items = ", ".join(["1"] * rounds)
        return (
            "use stdlib.actions\n\nscene s {\n    site bolt at (0, 100, 40) cm\n}\n\n"
            f"task t {{\n    scene s\n    inspect(bolt)\n    for a in [{items}] {{\n    }}\n}}\n"
        )

    path = tmp_path / "one.mtask"
    path.write_text(task(1), encoding="utf-8")
    (timeline,) = run_frontend([path]).timelines
    assert len(timeline.primitives) == 2
    assert _frontend(task(8), tmp_path, budget=10) == []
    (message,) = _frontend(task(9), tmp_path, budget=10)
    assert message.startswith("MT0401 ") and "a round moves" not in message


# ---------------------------------------------------------------- fmt and check of big files
@pytest.mark.parametrize("shape", ["steps", "trailing comments"])
def test_fmt_is_linear_and_keeps_every_comment(shape: str, tmp_path: Path) -> None:
    def work(n: int) -> int:
        if shape == "steps":
            build = hostile.steps_file(len(hostile._CHUNK) * n, f"big{n}.mtask")
        else:
            build = hostile.trailing_comments(n)
        path = build(tmp_path, 1.0)
        text = path.read_text(encoding="utf-8")
        result = None

        def run() -> None:
            nonlocal result
            result = format_source(text, str(path))

        count = lines_run(run)
        assert result is not None and result.text == text  # already canonical, comments kept
        return count

    assert_linear(work, 3 if shape == "steps" else 200)


def test_check_of_many_valid_steps_is_linear(tmp_path: Path) -> None:
    def work(chunks: int) -> int:
        path = hostile.steps_file(len(hostile._CHUNK) * chunks, f"s{chunks}.mtask")(tmp_path, 1.0)
        program = None

        def run() -> None:
            nonlocal program
            program = run_frontend([path])

        count = lines_run(run)
        assert program is not None and program.diagnostics == []
        assert len(program.timelines) == chunks
        return count

    assert_linear(work, 2)
