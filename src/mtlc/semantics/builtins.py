"""What the language provides without a `use`: MTM-1 timing functions, postures, manikins."""

from __future__ import annotations

from dataclasses import dataclass

from mtlc.semantics import types as T


@dataclass(frozen=True)
class ParamSpec:
    name: str
    type: T.Type
    default: object | None = None  # a value in SI units, or an enum member name

    @property
    def required(self) -> bool:
        return self.default is None


@dataclass(frozen=True)
class Signature:
    name: str
    params: tuple[ParamSpec, ...]


def _sig(name: str, *params: ParamSpec) -> Signature:
    return Signature(name, params)


P = ParamSpec

# mtm.<name>(...) -> Timing. The travel distance of reach and move comes from the primitive they
# time (see docs/language.md, "Timing").
MTM_FUNCTIONS: dict[str, Signature] = {
    s.name: s
    for s in (
        _sig("reach", P("case", T.REACH_CASE, "B")),
        _sig("move", P("case", T.MOVE_CASE, "B"), P("load", T.MASS, 0.0)),
        _sig("turn", P("angle", T.ANGLE), P("load", T.MASS, 0.0)),
        _sig("grasp", P("case", T.GRASP_CASE, "G1A")),
        _sig("release"),
        _sig("walk"),
        _sig("code", P("code", T.STRING)),
        _sig("fixed", P("tmu", T.NUMBER)),
    )
}

# posture <kind>(...): whole-body and joint goals the IK passes know how to pose
POSTURES: dict[str, Signature] = {
    s.name: s
    for s in (
        _sig("stand"),
        _sig("bend", P("angle", T.ANGLE, 0.7853981633974483)),
        _sig("squat", P("depth", T.LENGTH, 0.0)),
        _sig("kneel", P("knees", T.INT, 2)),
        _sig("sit"),
        # a turn of the hand on what it holds; with a tool, that tool's strokes (mtlc.passes.tool):
        # "none" is the bare hand, `swing` the largest stroke a wrench may take (clearance)
        _sig(
            "twist",
            P("hand", T.HAND),
            P("angle", T.ANGLE),
            P("tool", T.TOOL, "none"),
            P("swing", T.ANGLE, 1.0471975511965976),
            P("load", T.MASS, 0.0),
        ),
    )
}

GRIP_STATES = ("open", "closed")

# manikin <population> <sex> p<percentile>
POPULATIONS: dict[str, tuple[int, ...]] = {
    "gb10000_1988": (1, 5, 10, 50, 90, 95, 99),
    "ansur2": (1, 5, 10, 50, 90, 95, 99),
}
SEXES = ("male", "female")
DEFAULT_MANIKIN = ("gb10000_1988", "male", 50)

TOOL_PROPERTIES: dict[str, T.Type] = {
    "length": T.LENGTH,
    "mass": T.MASS,
    "grip": T.VectorType(T.LENGTH_DIM),
    "tip": T.VectorType(T.LENGTH_DIM),
    "kind": T.STRING,
    "axis": T.VectorType(T.NONE_DIM),
}

# what a tool's `kind` does to a fastener (docs/tools.md): wrenches swing on an arc about it,
# a ratchet swings back without letting go, a screwdriver and pliers turn with the forearm
ARC_TOOL_KINDS = ("wrench", "ratchet")
TOOL_KINDS = (*ARC_TOOL_KINDS, "screwdriver", "pliers")
TASK_TOOL_KIND = "task"  # stdlib.tools.task_tool: whatever tool the task's `tool` setting names
