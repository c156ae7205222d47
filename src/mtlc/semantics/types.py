"""The language's types, units and dimensions.

A quantity's dimension is a vector of exponents over (length, angle, time, mass), so arithmetic
on units is exact: Length / Duration is a speed, Length / Length a plain number. Units are
converted to SI once, here, when a literal is read.
"""

from __future__ import annotations

from dataclasses import dataclass

Dim = tuple[int, int, int, int]  # length, angle, time, mass

NONE_DIM: Dim = (0, 0, 0, 0)
LENGTH_DIM: Dim = (1, 0, 0, 0)
ANGLE_DIM: Dim = (0, 1, 0, 0)
TIME_DIM: Dim = (0, 0, 1, 0)
MASS_DIM: Dim = (0, 0, 0, 1)

TMU_SECONDS = 0.036  # 1 TMU = 0.00001 h (MTM-1)

# unit -> (dimension, factor to SI)
UNITS: dict[str, tuple[Dim, float]] = {
    "mm": (LENGTH_DIM, 0.001),
    "cm": (LENGTH_DIM, 0.01),
    "m": (LENGTH_DIM, 1.0),
    "deg": (ANGLE_DIM, 3.141592653589793 / 180.0),
    "rad": (ANGLE_DIM, 1.0),
    "s": (TIME_DIM, 1.0),
    "ms": (TIME_DIM, 0.001),
    "min": (TIME_DIM, 60.0),
    "tmu": (TIME_DIM, TMU_SECONDS),
    "kg": (MASS_DIM, 1.0),
    "g": (MASS_DIM, 0.001),
}

_DIM_NAMES = {
    NONE_DIM: "Number",
    LENGTH_DIM: "Length",
    ANGLE_DIM: "Angle",
    TIME_DIM: "Duration",
    MASS_DIM: "Mass",
}


def dim_name(dim: Dim) -> str:
    if dim in _DIM_NAMES:
        return _DIM_NAMES[dim]
    parts = []
    for base, exp in zip(("Length", "Angle", "Duration", "Mass"), dim, strict=True):
        if exp == 1:
            parts.append(base)
        elif exp:
            parts.append(f"{base}^{exp}")
    return "·".join(parts)


class Type:
    """Base of all types; types compare by value."""

    @property
    def name(self) -> str:
        raise NotImplementedError

    def __str__(self) -> str:
        return self.name


@dataclass(frozen=True)
class Quantity(Type):
    dim: Dim
    integer: bool = False  # an Int: a unitless whole number

    @property
    def name(self) -> str:
        return "Int" if self.integer else dim_name(self.dim)


@dataclass(frozen=True)
class VectorType(Type):
    dim: Dim
    size: int = 3  # components; positions, directions and frames have 3

    @property
    def name(self) -> str:
        sized = "" if self.size == 3 else f" ({self.size} components)"
        return f"Vector of {dim_name(self.dim)}{sized}"


@dataclass(frozen=True)
class EnumType(Type):
    enum_name: str
    members: tuple[str, ...]

    @property
    def name(self) -> str:
        return self.enum_name


@dataclass(frozen=True)
class Simple(Type):
    simple_name: str

    @property
    def name(self) -> str:
        return self.simple_name


@dataclass(frozen=True)
class ListType(Type):
    element: Type

    @property
    def name(self) -> str:
        return f"List of {self.element.name}"


INT = Quantity(NONE_DIM, integer=True)
NUMBER = Quantity(NONE_DIM)
LENGTH = Quantity(LENGTH_DIM)
ANGLE = Quantity(ANGLE_DIM)
DURATION = Quantity(TIME_DIM)
MASS = Quantity(MASS_DIM)
SITE = Simple("Site")
TOOL = Simple("Tool")
STRING = Simple("String")
SCENE = Simple("Scene")
TIMING = Simple("Timing")  # an MTM-1 rule, evaluated per primitive when the task expands
UNKNOWN = Simple("<error>")  # the type of an expression already reported as wrong

HAND = EnumType("Hand", ("left", "right", "both"))
REACH_CASE = EnumType("ReachCase", ("A", "B", "C", "D", "E"))
MOVE_CASE = EnumType("MoveCase", ("A", "B", "C"))
GRASP_CASE = EnumType("GraspCase", ("G1A", "G1B", "G1C", "G2", "G3", "G4A", "G4B", "G4C", "G5"))

ENUMS: tuple[EnumType, ...] = (HAND, REACH_CASE, MOVE_CASE, GRASP_CASE)

# the names a parameter's type may have
TYPE_NAMES: dict[str, Type] = {
    "Int": INT,
    "Number": NUMBER,
    "Length": LENGTH,
    "Angle": ANGLE,
    "Duration": DURATION,
    "Mass": MASS,
    "Site": SITE,
    "Tool": TOOL,
    "String": STRING,
    "Position": VectorType(LENGTH_DIM),
    "Direction": VectorType(NONE_DIM),
    **{e.enum_name: e for e in ENUMS},
}


def is_assignable(actual: Type, expected: Type) -> bool:
    if actual is expected:  # the commonest answer (types are mostly the constants above)
        return True
    if actual == UNKNOWN or expected == UNKNOWN:
        return True
    if isinstance(actual, Quantity) and isinstance(expected, Quantity):
        return actual.dim == expected.dim and (actual.integer or not expected.integer)
    return actual == expected
