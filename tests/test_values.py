"""Every value is checked where it is written: finite, in range, with a code, a span and a help
line (issue 17, section 3; docs/language.md, "Limits"). Nothing reaches MT0900."""

from __future__ import annotations

import math
import tracemalloc
from pathlib import Path

import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from mtlc.diagnostics import DiagnosticSink, Span
from mtlc.frontend import DEFAULT_MOTION_BUDGET, run_frontend
from mtlc.semantics import mtm, schedule
from mtlc.semantics import values as V
from mtlc.semantics.timeline import ManikinSpec
from mtlc.syntax import ast

HEADER = "use stdlib.actions\nuse stdlib.elements\n"
SCENE = "scene s {\n    site a at (0, 100, 50) cm normal (0, 0, -1)\n}\n"


def _run(tmp_path: Path, text: str):  # type: ignore[no-untyped-def]
    path = tmp_path / "main.mtask"
    path.write_text(text, encoding="utf-8")
    return run_frontend([path])


def _found(tmp_path: Path, text: str) -> list[tuple[str, int, int]]:
    return [(d.code, d.span.line, d.span.column) for d in _run(tmp_path, text).diagnostics]


def _task(body: str, extra: str = "") -> str:
    return f"{HEADER}{SCENE}{extra}task t {{\n    scene s\n{body}}}\n"


# (what, text, line, column of the value): constants are reported where they are written
CONSTANTS = [
    ("ground inf", "scene g {\n    ground 1e308 m * 10\n}\n", 2, 12),
    ("zero normal", "scene g {\n    site p at (0, 1, 0) m normal (0, 0, 0) * 2\n}\n", 2, 34),
    ("far site", "scene g {\n    site p at (1e300, 0, 0) m\n}\n", 2, 15),
    ("frame", "scene g {\n    site p at (0, 1, 0) m frame (0, 720, 0) deg\n}\n", 2, 33),
    ("tool mass", "tool w {\n    mass -0.5 kg\n}\n", 2, 10),
    ("tool length", "tool w {\n    length 1e308 m * 10\n}\n", 2, 12),
    ("tool axis", "tool w {\n    axis (0, 0, 0)\n}\n", 2, 10),
    ("tool tip", "tool w {\n    tip (0, 1e9, 0) m\n}\n", 2, 9),
    ("budget", _task("    budget -5 min\n    inspect(a)\n"), 8, 12),
    ("zero budget", _task("    budget 0 s\n    inspect(a)\n"), 8, 12),
    ("budget inf", _task("    budget 1e308 min\n    inspect(a)\n"), 8, 12),
    ("load", _task("    unscrew(right, a, load: -1 kg)\n"), 8, 29),
    ("duration", _task("    inspect(a, -3 s)\n"), 8, 16),
    ("offset", "element e(x: Site) {\n    goal right at x offset (1e308, 0, 0) m * 10\n}\n", 2, 28),
    (
        "walk by nan",
        "element e() {\n    walk by (1e308, 0, 0) m * 10 - (1e308, 0, 0) m * 10\n}\n",
        2,
        13,
    ),
    ("walk by far", "element e() {\n    walk by (0, 0, 1e6) m\n}\n", 2, 13),
    ("twist load", "element e() {\n    posture twist(right, 90 deg, load: -3 kg)\n}\n", 2, 40),
    (
        "move load",
        "element e(x: Site) {\n    goal right at x\n    time mtm.move(load: -2 kg)\n}\n",
        3,
        25,
    ),
    ("fixed tmu", "element e() {\n    still over mtm.fixed(-1)\n}\n", 2, 26),
    ("over", "element e() {\n    still over -2 s\n}\n", 2, 16),
    ("bend", "element e() {\n    posture bend(angle: 200 deg)\n}\n", 2, 25),
    ("repeat", _task("    repeat -1 {\n        inspect(a)\n    }\n"), 8, 12),
    ("default", "element e(m: Mass = -1 kg) {\n    still over 1 s\n}\n", 1, 21),
    ("huge int", _task("    unscrew(right, a, turns: 99999999999999999999)\n"), 8, 30),
    ("unit overflow", _task("    inspect(a, 1e307 min)\n"), 8, 16),
]


@pytest.mark.parametrize(
    ("what", "text", "line", "column"), CONSTANTS, ids=[c[0] for c in CONSTANTS]
)
def test_a_constant_out_of_range_is_mt0309_where_it_is_written(
    tmp_path: Path, what: str, text: str, line: int, column: int
) -> None:
    program = _run(tmp_path, text)
    assert [(d.code, d.span.line, d.span.column) for d in program.diagnostics] == [
        ("MT0309", line, column)
    ], what
    assert program.diagnostics[0].help, what


def test_values_in_range_are_accepted(tmp_path: Path) -> None:
    extra = "tool w {\n    mass 0 kg\n    length 10 m\n    axis (0, 1e-6, 0)\n}\n"
    body = "    budget 24 * 60 min\n    unscrew(right, a, turns: 0, load: 1000 kg, tool: w)\n"
    assert _found(tmp_path, _task(body, extra)) == []


def test_a_value_through_a_parameter_is_reported_at_the_users_line(tmp_path: Path) -> None:
    extra = "action hold_it(m: Mass) {\n    turn(right, 90 deg, m - 2 kg)\n}\n"
    program = _run(tmp_path, _task("    hold_it(1 kg)\n", extra))
    (diag,) = program.diagnostics
    assert (diag.code, diag.span.line, diag.span.column) == ("MT0309", 11, 5)
    assert "-1 kg" in diag.message and diag.help
    assert [label.message for label in diag.labels] == ["from here"]


@pytest.mark.parametrize(
    ("param", "arg", "use"),
    [
        ("n: Int", "1000000000000000", "    repeat n * n {\n        look(x)\n    }\n"),
        ("d: Duration", "1e300 s", "    still over d * 1e300\n"),
        ("l: Length", "1 m", "    walk by (l, 0 m, 0 m) / 1e-320\n"),
        ("v: Number", "1e308", "    still over 1 s * (v + v)\n"),
    ],
)
def test_arithmetic_that_overflows_while_expanding_is_mt0309(
    tmp_path: Path, param: str, arg: str, use: str
) -> None:
    extra = f"element big(x: Site, {param}) {{\n{use}}}\n"
    codes = [code for code, *_ in _found(tmp_path, _task(f"    big(a, {arg})\n", extra))]
    assert codes == ["MT0309"]


def test_a_billion_turns_is_the_expansion_budget_fast_and_small(tmp_path: Path) -> None:
    """The strokes were built before the budget was checked: MemoryError (issue 17)."""
    tracemalloc.start()
    try:
        program = _run(tmp_path, _task("    unscrew(right, a, turns: 1000000000)\n"))
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    (diag,) = program.diagnostics
    assert (diag.code, diag.span.line) == ("MT0401", 8)
    assert "4,000,000,00" in diag.message and "turns" in (diag.help or "")
    assert peak < 50_000_000


def test_a_huge_twist_angle_is_the_expansion_budget_not_an_overflow(tmp_path: Path) -> None:
    extra = "element spin(a: Angle) {\n    posture twist(right, a, swing: 3 deg)\n}\n"
    body = "    reach(right, a)\n    spin(1e300 deg)\n"
    codes = [code for code, *_ in _found(tmp_path, _task(body, extra))]
    assert codes == ["MT0401"]


def test_walk_time_of_an_infinite_distance_does_not_overflow() -> None:
    assert mtm.walk_tmu(math.inf) == math.inf


def test_a_tool_without_a_tip_works_at_its_grip(tmp_path: Path) -> None:
    """KeyError in the skeleton's site lookup before (issue 17)."""
    from mtlc.passes import run_motion

    extra = 'tool w {\n    kind "wrench"\n    mass 0.1 kg\n}\n'
    program = _run(tmp_path, _task("    unscrew(right, a, turns: 1, tool: w)\n", extra))
    assert program.diagnostics == []
    (timeline,) = program.timelines
    timeline = schedule.for_manikin(timeline, ManikinSpec("gb10000_1988", "male", 50))
    ir = run_motion(timeline, DiagnosticSink(), until="tool")
    reach = [s for s in ir.segments if s.kind == "TO" and "stroke" not in s.goal.params]
    assert reach and all(s.goal.effector == "r_tool_w" for s in reach)


def test_problem_names_the_range() -> None:
    assert V.problem(V.LOAD, -1.0) == "a load must be between 0 kg and 1,000 kg, not -1 kg"
    assert V.problem(V.BUDGET, 0.0) is not None and "more than 0 s" in V.problem(V.BUDGET, 0.0)
    assert V.problem(V.NORMAL, (0.0, 0.0, 1e-300)) == "a normal cannot be the zero vector"
    assert V.problem(V.POSITION, (0.0, math.nan, 0.0)) is not None
    assert V.problem(V.LOAD, 0.5) is None


_SLOTS = [
    ("    inspect(a, {v} s)\n", V.DURATION, 1.0),
    ("    unscrew(right, a, turns: 1, load: {v} kg)\n", V.MASS, 1.0),
    ("    budget {v} min\n    inspect(a)\n", V.BUDGET, 60.0),
]


@settings(
    max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    slot=st.sampled_from(_SLOTS),
    value=st.floats(allow_nan=False, allow_infinity=False, width=64),
)
@example(slot=_SLOTS[0], value=900.0)  # over the motion budget: MT0407
def test_any_written_number_is_accepted_or_mt0309_and_the_timeline_is_finite(
    tmp_path: Path, slot: tuple[str, V.Range, float], value: float
) -> None:
    template, rule, factor = slot
    program = _run(tmp_path, _task(template.format(v=repr(value))))
    codes = [d.code for d in program.diagnostics if d.severity == "error"]
    in_range = V.problem(rule, value * factor) is None
    # a legal duration near or over the motion budget is a longer motion than a task may have
    # by default: MT0407, not a bad number (hypothesis drew `inspect(a, 900 s)`)
    long = in_range and rule is V.DURATION and value * factor > DEFAULT_MOTION_BUDGET - 60.0
    allowed = [["MT0407"], []] if long else [[] if in_range else ["MT0309"]]
    assert codes in allowed, (value, program.diagnostics)
    for timeline in program.timelines:
        assert math.isfinite(timeline.duration)
        for prim in timeline.primitives:
            assert math.isfinite(prim.start) and math.isfinite(prim.end)


_RULES = [
    v
    for v in vars(V).values()
    if isinstance(v, V.Range)
] + list(V.POSTURE_ARGS.values()) + list(V.MTM_ARGS.values())  # fmt: skip


def _near_bounds(rule: V.Range) -> list[float]:
    """The rule's bounds, the floats either side of them, and their negatives."""
    near = {0.0, -0.0}
    for bound in (rule.low, rule.high):
        if bound is not None:
            near |= {bound, math.nextafter(bound, -math.inf), math.nextafter(bound, math.inf)}
    return sorted(near | {-x for x in near})


def _values(rule: V.Range) -> st.SearchStrategy[tuple[V.Range, object]]:
    return st.tuples(
        st.just(rule),
        st.one_of(
            st.sampled_from(_near_bounds(rule)),
            st.floats(allow_nan=True, allow_infinity=True),
            st.integers(min_value=-(10**30), max_value=10**30),
            st.booleans(),
            st.tuples(st.floats(), st.floats(), st.floats()),
            st.lists(st.sampled_from(_near_bounds(rule)), min_size=0, max_size=3).map(tuple),
            st.tuples(st.floats(-1e-8, 1e-8), st.floats(-1e-8, 1e-8), st.floats(-1e-8, 1e-8)),
            st.tuples(st.integers(-5, 5), st.floats(-1.0, 1.0), st.booleans()),
            st.text(max_size=3),
        ),
    )


@settings(max_examples=400, deadline=None)
@given(case=st.sampled_from(_RULES).flatmap(_values))
def test_problem_quick_path_says_what_the_reference_says(case: tuple[V.Range, object]) -> None:
    """values.problem answers one in-range number without the general scan (issue 21): the same
    answer, or the same exception, as values._problem for every rule and value."""
    rule, value = case
    try:
        expected: object = V._problem(rule, value)
    except OverflowError as exc:
        expected = type(exc)
    try:
        got: object = V.problem(rule, value)
    except OverflowError as exc:
        got = type(exc)
    assert got == expected


def _for_type_reference(type_: object) -> V.Range | None:
    """values.for_type as a chain of comparisons (before it became a table, issue 21)."""
    from mtlc.semantics import types as T

    if type_ == T.MASS:
        return V.MASS
    if type_ == T.DURATION:
        return V.DURATION
    if type_ == T.LENGTH:
        return V.LENGTH
    if type_ == T.ANGLE:
        return V.ANGLE
    if type_ in (T.NUMBER, T.INT):
        return V.FINITE
    if type_ == T.VectorType(T.LENGTH_DIM):
        return V.POSITION
    return None


def test_for_type_table_says_what_the_comparisons_said() -> None:
    from mtlc.semantics import types as T

    dims = [T.NONE_DIM, T.LENGTH_DIM, T.ANGLE_DIM, T.TIME_DIM, T.MASS_DIM, (1, 0, -1, 0)]
    types: list[T.Type] = [*T.TYPE_NAMES.values(), T.UNKNOWN, T.TIMING, T.SCENE]
    types += [T.Quantity(d, integer) for d in dims for integer in (False, True)]
    types += [T.VectorType(d, size) for d in dims for size in (2, 3, 4)]
    types += [T.ListType(t) for t in list(types)]
    for type_ in types:
        assert V.for_type(type_) is _for_type_reference(type_), type_


_SPAN = Span("t.mtask", 1, 1, 1, 2, 0, 1)


def _number_nodes() -> st.SearchStrategy[ast.Expr]:
    return st.builds(
        lambda value, is_int, unit: ast.Number(
            span=_SPAN, value=float(int(value)) if is_int else value, is_int=is_int, unit=unit
        ),
        st.one_of(st.floats(-1e6, 1e6), st.sampled_from([0.0, -0.0, 1e308, 5e-324])),
        st.booleans(),
        st.sampled_from([None, "cm", "deg", "kg", "s", "furlong"]),
    )


def _expressions() -> st.SearchStrategy[ast.Expr]:
    leaves = st.one_of(
        _number_nodes(),
        st.just(ast.Name(span=_SPAN, name="x")),
        st.just(ast.String(span=_SPAN, value="s")),
    )
    return st.recursive(
        leaves,
        lambda inner: st.one_of(
            st.builds(lambda e: ast.Unary(span=_SPAN, op="-", operand=e), inner),
            st.builds(
                lambda op, a, b: ast.Binary(span=_SPAN, op=op, left=a, right=b),
                st.sampled_from("+-*/"),
                inner,
                inner,
            ),
            st.builds(
                lambda items, unit: ast.Vector(span=_SPAN, items=tuple(items), unit=unit),
                st.lists(inner, min_size=0, max_size=3),
                st.sampled_from([None, "cm", "m", "nope"]),
            ),
        ),
        max_leaves=8,
    )


@settings(max_examples=400, deadline=None)
@given(expr=_expressions())
def test_fold_dispatch_says_what_the_class_patterns_say(expr: ast.Expr) -> None:
    """values._fold dispatches on the node's class (issue 21): the same value, or the same
    refusal, as the class patterns it replaced (values._fold_reference), on any expression."""
    try:
        expected: object = V._fold_reference(expr)
    except (V._NotConstant, ArithmeticError, TypeError, KeyError, ValueError) as exc:
        expected = type(exc)
    try:
        got: object = V._fold(expr)
    except (V._NotConstant, ArithmeticError, TypeError, KeyError, ValueError) as exc:
        got = type(exc)
    assert repr(got) == repr(expected)
