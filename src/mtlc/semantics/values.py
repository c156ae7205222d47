"""The range each declared value must lie in, and a folder of constant expressions.

A number that reaches the timeline, the motion passes or the IR JSON is finite and within a range
a body, a building and a work shift can have, so that no later sum, product, `ceil` or
normalisation overflows or divides by zero: a load is not negative, a budget is more than 0 s, a
normal or a tool's axis has a direction, a position lies within 100 km of the origin. Each value
is checked where it is written: by the checker when the expression is a constant (``fold``),
else when the task is expanded (the parameters are bound then). Both report MT0309 with the
value, the range and a help line (docs/language.md, "Limits").
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from mtlc.semantics import types as T
from mtlc.syntax import ast

MAX_INT = 10**15  # whole numbers: exact as floats, far beyond any count a task needs
MAX_COORD_M = 100_000.0  # positions, offsets, displacements, the ground: 100 km
MAX_TOOL_M = 10.0  # a tool's length, grip and tip
MAX_APPROACH_M = 10.0
MAX_DURATION_S = 86_400.0  # one primitive, a budget: 24 h
MAX_MASS_KG = 1_000.0  # a load or a tool: 1 t
MAX_FRAME_RAD = 2.0 * math.pi  # a frame's rotation about an axis: one turn either way
MIN_DIRECTION = 1e-9  # a direction shorter than this has none (its square underflows)


@dataclass(frozen=True)
class Range:
    """Where a value may lie (SI units, bounds inclusive unless ``low_open``)."""

    what: str  # "a load": the message's subject
    unit: str  # the unit values are shown in: "m", "s", "kg", "deg" or "" (plain)
    low: float | None = None
    high: float | None = None
    low_open: bool = False  # more than ``low``, not ``low`` itself
    direction: bool = False  # a vector that must point somewhere (not (0, 0, 0))
    help: str | None = None


GROUND = Range(
    "the ground's height",
    "m",
    -MAX_COORD_M,
    MAX_COORD_M,
    help="the ground is the height (Y) of the floor; 0 cm is the default",
)
POSITION = Range(
    "a position",
    "m",
    -MAX_COORD_M,
    MAX_COORD_M,
    help="positions are in the world frame, within 100 km of its origin",
)
NORMAL = Range(
    "a normal",
    "",
    direction=True,
    help="a normal is the direction out of the surface, for example (0, 0, -1)",
)
SOLID_SIZE = Range(
    "a solid's size",
    "m",
    0.0,
    100.0,
    low_open=True,
    help="a solid's sizes, radius and length are more than 0 and at most 100 m",
)
AXIS = Range(
    "an axis",
    "",
    direction=True,
    help="an axis is a direction, for example (1, 0, 0)",
)
FRAME = Range(
    "a frame's rotation",
    "deg",
    -MAX_FRAME_RAD,
    MAX_FRAME_RAD,
    help="give each rotation between -360 and 360 deg",
)
TOOL_LENGTH = Range("a tool's length", "m", 0.0, MAX_TOOL_M, help="a tool is 0 to 10 m long")
TOOL_MASS = Range("a tool's mass", "kg", 0.0, MAX_MASS_KG, help="a tool weighs 0 to 1000 kg")
TOOL_POINT = Range(
    "a tool's point",
    "m",
    -MAX_TOOL_M,
    MAX_TOOL_M,
    help="a tool's grip and tip lie within 10 m of the hand",
)
TOOL_AXIS = Range(
    "a tool's axis",
    "",
    direction=True,
    help="the axis points out of the fastener toward the hand, for example (0, -1, 0)",
)
BUDGET = Range(
    "a task's budget",
    "s",
    0.0,
    MAX_DURATION_S,
    low_open=True,
    help="the budget is the time the task may take: more than 0 s, at most 24 h",
)
DURATION = Range(
    "a duration",
    "s",
    0.0,
    MAX_DURATION_S,
    help="a duration is 0 s to 24 h",
)
APPROACH = Range(
    "an approach distance",
    "m",
    0.0,
    MAX_APPROACH_M,
    help="the approach is how far short of the site the hand slows down: 0 cm to 10 m",
)
OFFSET = Range(
    "an offset",
    "m",
    -MAX_COORD_M,
    MAX_COORD_M,
    help="an offset shifts the target in the world frame, at most 100 km",
)
DISPLACEMENT = Range(
    "a walk's displacement",
    "m",
    -MAX_COORD_M,
    MAX_COORD_M,
    help="`walk by` moves the body at most 100 km along each axis",
)
LOAD = Range("a load", "kg", 0.0, MAX_MASS_KG, help="a load is the mass held: 0 to 1000 kg")
MASS = Range("a mass", "kg", 0.0, MAX_MASS_KG, help="a mass is 0 to 1000 kg")
LENGTH = Range("a length", "m", -MAX_COORD_M, MAX_COORD_M, help="lengths are at most 100 km")
TMU = Range(
    "a time in TMU",
    "",
    0.0,
    MAX_DURATION_S / T.TMU_SECONDS,
    help="`mtm.fixed` takes 0 to 2,400,000 TMU (24 h)",
)
FINITE = Range("a number", "", help="write a smaller number")
ANGLE = Range("an angle", "deg", help="write a smaller angle")

MIN_SWING = math.radians(3.0)  # rad: the smallest wrench stroke (a 120-position ratchet)

# posture <kind>(...): the ranges a body can take (docs/language.md, "posture")
POSTURE_ARGS: dict[tuple[str, str], Range] = {
    ("bend", "angle"): Range("a bend", "deg", 0.0, math.radians(120), help="bend 0 to 120 deg"),
    ("squat", "depth"): Range("a squat's depth", "m", 0.0, 1.0, help="squat 0 to 1 m deep"),
    ("kneel", "knees"): Range("kneel", "", 1, 2, help="kneel on 1 or 2 knees"),
    # the finest ratchets advance 3 deg a click (120 positions): a smaller stroke turns
    # nothing, and 0.5 deg made 2,160 strokes of three turns (30 s and 0.9 GB to compile)
    ("twist", "swing"): Range(
        "a wrench's swing",
        "deg",
        MIN_SWING,
        math.pi,
        help="the swing is the largest stroke a wrench takes: 3 to 180 deg (the finest "
        "ratchets click every 3 deg)",
    ),
    ("twist", "load"): LOAD,
    ("twist", "angle"): ANGLE,
}

# mtm.<name>(...): arguments a rule cannot time
MTM_ARGS: dict[tuple[str, str], Range] = {
    ("move", "load"): LOAD,
    ("turn", "load"): LOAD,
    ("turn", "angle"): ANGLE,
    ("fixed", "tmu"): TMU,
}


# the range of an argument of a parameter of each type: masses and durations are never
# negative; every other quantity is finite and of a size a task can have (types compare, and
# hash, by value)
_TYPE_RANGES: dict[T.Type, Range] = {
    T.MASS: MASS,
    T.DURATION: DURATION,
    T.LENGTH: LENGTH,
    T.ANGLE: ANGLE,
    T.NUMBER: FINITE,
    T.INT: FINITE,
    T.VectorType(T.LENGTH_DIM): POSITION,
}


def for_type(type_: T.Type) -> Range | None:
    """The range of an argument of a parameter of this type (``_TYPE_RANGES``), if it has one."""
    return _TYPE_RANGES.get(type_)


def problem(rule: Range, value: Any) -> str | None:
    """What is wrong with ``value`` (a number or a tuple of numbers, SI units), if anything."""
    if (
        (type(value) is float or type(value) is int)  # most values: one number, well in range
        and not rule.direction
        and math.isfinite(value)
        and _within(rule, value)
    ):
        return None
    if type(value) is tuple and value and _vector_within(rule, value):
        return None  # a vector of floats, each well in range
    return _problem(rule, value)


def _vector_within(rule: Range, items: tuple[Any, ...]) -> bool:
    """Every item a finite float within the bounds, pointing somewhere if it must: the vectors
    ``_problem`` finds nothing wrong with, without its scans."""
    for c in items:
        if type(c) is not float or not math.isfinite(c) or not _within(rule, c):
            return False
    return not rule.direction or math.hypot(*items) >= MIN_DIRECTION


def _within(rule: Range, c: float) -> bool:
    """``c`` lies inside the rule's bounds (``_problem`` says how it does not)."""
    low, high = rule.low, rule.high
    if low is not None and (c <= low if rule.low_open else c < low):
        return False
    return high is None or c <= high


def _problem(rule: Range, value: Any) -> str | None:
    """``problem`` for every value: the reference the quick path for one number agrees with."""
    items = value if isinstance(value, tuple) else (value,)
    if not items or not all(_is_number(c) for c in items):
        return None  # not a numeric value: the type checks say what it is
    if not all(math.isfinite(c) for c in items):
        return f"{rule.what} is too large: it is not a finite number"
    if rule.direction and math.hypot(*items) < MIN_DIRECTION:
        return f"{rule.what} cannot be the zero vector"
    for c in items:
        below = rule.low is not None and (c < rule.low or (rule.low_open and c <= rule.low))
        above = rule.high is not None and c > rule.high
        if below or above:
            return f"{rule.what} must be {_bounds(rule)}, not {_shown(c, rule.unit)}"
    return None


def int_problem(value: int) -> str | None:
    if abs(value) > MAX_INT:
        return f"whole number {_shown_int(value)} is too large (at most {MAX_INT:.0e})"
    return None


def _is_number(x: Any) -> bool:
    return isinstance(x, int | float) and not isinstance(x, bool)


def _bounds(rule: Range) -> str:
    low = None if rule.low is None else _shown(rule.low, rule.unit)
    high = None if rule.high is None else _shown(rule.high, rule.unit)
    if rule.low is not None and rule.high is not None:
        if rule.low_open:
            return f"more than {low} and at most {high}"
        if rule.low == -rule.high:
            return f"between -{high} and {high}"
        return f"between {low} and {high}"
    if low is not None:
        return f"more than {low}" if rule.low_open else f"at least {low}"
    if high is not None:
        return f"at most {high}"
    return "finite"


def _shown(value: float, unit: str) -> str:
    if unit == "deg":
        value = math.degrees(value)
    if isinstance(value, int):
        text = _shown_int(value)
    else:
        text = f"{value:,.6g}" if abs(value) < 1e6 else f"{value:.6g}"
    return f"{text} {unit}" if unit else text


def _shown_int(value: int) -> str:
    return f"{value:,}" if abs(value) < 10**21 else f"{float(value):.3g}"


# ------------------------------------------------------------ constant folding
class _NotConstant(Exception):
    pass


def fold(expr: ast.Expr) -> Any:
    """The value of a constant expression (numbers, units, arithmetic, vectors) in SI units, or
    None when it names something (a parameter, a tool) or divides by zero: then the expansion
    computes it. An overflow folds to inf, for ``problem`` to report."""
    try:
        return _fold(expr)
    except (_NotConstant, ZeroDivisionError, OverflowError, TypeError, KeyError):
        return None


def _fold(expr: ast.Expr) -> Any:
    kind = type(expr)  # the node classes have no subclasses: one look-up, no class patterns
    if kind is ast.Number:
        unit = expr.unit  # type: ignore[union-attr]
        if unit is None:
            return int(expr.value) if expr.is_int else expr.value  # type: ignore[union-attr]
        if unit in T.UNITS:
            return expr.value * T.UNITS[unit][1]  # type: ignore[union-attr]
    elif kind is ast.Unary:
        v = _fold(expr.operand)  # type: ignore[union-attr]
        return tuple(-c for c in v) if isinstance(v, tuple) else -v
    elif kind is ast.Binary:
        op, left, right = expr.op, expr.left, expr.right  # type: ignore[union-attr]
        return _bound(arith(op, _fold(left), _fold(right)))
    elif kind is ast.Vector:
        unit = expr.unit  # type: ignore[union-attr]
        factor = T.UNITS[unit][1] if unit is not None else 1.0
        return tuple(_bound(float(_fold(i)) * factor) for i in expr.items)  # type: ignore[union-attr]
    raise _NotConstant


def _fold_reference(expr: ast.Expr) -> Any:
    """``_fold`` as class patterns: the reference tests compare the quick dispatch with."""
    match expr:
        case ast.Number(unit=None, is_int=True, value=v):
            return int(v)
        case ast.Number(unit=None, value=v):
            return v
        case ast.Number(unit=unit, value=v) if unit in T.UNITS:
            return v * T.UNITS[unit][1]
        case ast.Unary(operand=operand):
            v = _fold_reference(operand)
            return tuple(-c for c in v) if isinstance(v, tuple) else -v
        case ast.Binary(op=op, left=left, right=right):
            return _bound(arith(op, _fold_reference(left), _fold_reference(right)))
        case ast.Vector(items=items, unit=unit):
            factor = T.UNITS[unit][1] if unit is not None else 1.0
            return tuple(_bound(float(_fold_reference(i)) * factor) for i in items)
    raise _NotConstant


def _bound(value: Any) -> Any:
    """Whole numbers beyond MAX_INT become inf, as floats beyond their range do."""
    if isinstance(value, int) and abs(value) > MAX_INT:
        return math.inf
    return value


def arith(op: str, a: Any, b: Any) -> Any:
    """`+ - * /` on numbers and vectors (the checker has matched their types); ZeroDivisionError
    for a division by zero."""
    if op in "+-":
        sign = 1 if op == "+" else -1
        if isinstance(a, tuple):
            return tuple(x + sign * y for x, y in zip(a, b, strict=True))
        return a + sign * b
    if op == "*":
        if isinstance(a, tuple):
            return tuple(x * b for x in a)
        if isinstance(b, tuple):
            return tuple(a * y for y in b)
        return a * b
    if b == 0:
        raise ZeroDivisionError
    if isinstance(a, tuple):
        return tuple(x / b for x in a)
    return a / b


def overflows(value: Any) -> bool:
    """Whether an arithmetic result left the numbers mtlc computes with."""
    items = value if isinstance(value, tuple) else (value,)
    for c in items:
        if isinstance(c, int) and not isinstance(c, bool):
            if abs(c) > MAX_INT:
                return True
        elif isinstance(c, float) and not math.isfinite(c):
            return True
    return False
