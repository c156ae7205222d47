"""Lowering: the expanded timeline becomes segments on tracks, and a plan of where the root is.

Each goal primitive becomes two segments, target approaching (TA) to the approach point short of
the site and target overlapping (TO) onto it, in the time windows the front end gave them. The
root plan says where the body stands and which way it faces at every moment: walking moves it
along a straight line facing the way it goes, and arrives facing its work: the walk's `facing`
site, else the site of the next reach (the gait steps that turn; the standing body never turns
without stepping, which would twist the planted feet).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from mtlc.diagnostics import Span
from mtlc.ir.model import GoalSpec, MotionIR, Provenance, RootPlan, Segment, SourceRef
from mtlc.passes.tool import tool_site
from mtlc.semantics.timeline import Primitive, Timeline
from mtlc.semantics.turning import arrival_heading, heading_to, wrap

HAND_TRACK = {"left_hand": "l_arm", "right_hand": "r_arm"}
HAND_SITE = {"left_hand": "l_hand", "right_hand": "r_hand"}
GRIP_TRACK = {"left_hand": "l_hand", "right_hand": "r_hand"}
TURN_TIME = 0.5  # seconds the plan takes to turn toward the way a walk goes (the gait steps it)


def _ref(span: Span) -> SourceRef:
    return SourceRef(span.file, span.line, span.column, span.end_line, span.end_column)


def _provenance(p: Primitive) -> Provenance:
    return Provenance(path=p.path, span=_ref(p.span), origin=_ref(p.origin))


def _vec(v: Any) -> np.ndarray | None:
    return None if v is None else np.asarray(v, dtype=float)


def frame_matrix(frame: Any) -> np.ndarray:
    """A site's frame: rotations about X, then Y, then Z (radians), as one matrix."""
    rx, ry, rz = frame
    cx, sx, cy, sy, cz, sz = (math.cos(rx), math.sin(rx), math.cos(ry), math.sin(ry),
                              math.cos(rz), math.sin(rz))  # fmt: skip
    X = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    Y = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    Z = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return X @ Y @ Z


def lower(timeline: Timeline) -> MotionIR:
    ir = MotionIR(
        task=timeline.task,
        title=timeline.title,
        file=timeline.file,
        manikin={
            "population": timeline.manikin.population,
            "sex": timeline.manikin.sex,
            "percentile": timeline.manikin.percentile,
        },
        ground=timeline.ground,
        sites=[
            {"name": s.name, "position": list(s.position), "normal": s.normal, "frame": s.frame}
            for s in timeline.sites
        ],
        models=[m.record() for m in timeline.models],
        geometry=list(timeline.models),
    )
    for prim in timeline.primitives:
        ir.segments.extend(_segments(prim))
    ir.segments.sort(key=lambda s: (s.start, s.end, s.track))
    ir.root_plan = plan_root(timeline)
    return ir


def _segments(p: Primitive) -> list[Segment]:
    prov = _provenance(p)
    params = p.params
    if p.kind == "goal":
        target = np.asarray(params["position"], dtype=float)
        normal = _vec(params.get("normal"))
        orientation = (
            frame_matrix(params["frame"]) if params.get("orient") and params.get("frame") else None
        )
        (ta0, ta1), (to0, to1) = params["phases"]["TA"], params["phases"]["TO"]
        site = HAND_SITE[p.effector]
        track = HAND_TRACK[p.effector]
        common = {"two_handed": params["two_handed"], "normal": params.get("normal")}
        if params.get("load"):  # the mass the hand carries to this goal (RULA's force score)
            common["load"] = params["load"]
        if params.get("tool") is not None:  # the goal is the tool's working point's
            site = tool_site(site, params["tool"])
            common["tool"] = params["tool"]
        out = []
        if ta1 > ta0:
            out.append(Segment(track, "TA", ta0, ta1, GoalSpec(
                site, params["site"], target, orientation, params["approach"],
                {**common, "approach_normal": None if normal is None else normal.tolist()},
            ), prov))  # fmt: skip
        if to1 > to0:
            out.append(Segment(track, "TO", to0, to1, GoalSpec(
                site, params["site"], target, orientation, 0.0, common), prov))  # fmt: skip
        return out
    if p.kind == "posture":
        if params["posture"] == "stroke":
            return [_stroke(p, prov)]
        if params["posture"] == "twist":
            return [Segment(GRIP_TRACK[p.effector], "posture", p.start, p.end,
                            GoalSpec(HAND_SITE[p.effector], params=dict(params)), prov)]  # fmt: skip
        return [
            Segment("root", "posture", p.start, p.end, GoalSpec("body", params=dict(params)), prov)
        ]
    if p.kind == "locomotion":
        goal = GoalSpec("root", params.get("site"), _vec(params["to"]), params=dict(params))
        return [Segment("root", "locomotion", p.start, p.end, goal, prov)]
    if p.kind == "grip":
        goal = GoalSpec(HAND_SITE[p.effector], params={"state": params["state"]})
        return [Segment(GRIP_TRACK[p.effector], "grip", p.start, p.end, goal, prov)]
    if p.kind == "gaze":
        goal = GoalSpec("gaze", params["site"], _vec(params["position"]))
        return [Segment("head", "gaze", p.start, p.end, goal, prov)]
    if p.kind == "hold":
        return [Segment("root", "hold", p.start, p.end, GoalSpec("body"), prov)]
    raise AssertionError(f"unknown primitive kind {p.kind}")


def _stroke(p: Primitive, prov: Provenance) -> Segment:
    """A wrench's stroke: a TO of the tool's tip on the fastener, on the arm's track, solved by
    the tool pass (the hand swings on an arc about the fastener while the tip stays on it)."""
    params = p.params
    site = tool_site(HAND_SITE[p.effector], params["tool"])
    spec = {k: params[k] for k in ("angle", "stroke", "strokes", "tool", "normal", "load")
            if k in params}  # fmt: skip
    goal = GoalSpec(site, params["site"], _vec(params["position"]), None, 0.0,
                    {**spec, "two_handed": False})  # fmt: skip
    return Segment(HAND_TRACK[p.effector], "TO", p.start, p.end, goal, prov)


def plan_root(timeline: Timeline) -> RootPlan:
    """Knots of the root's ground position and heading (the height is added by the manikin).

    A walk turns toward its way at the start, goes straight, and arrives already facing its
    work (``arrival_heading``): the plan's heading at a walk's end is the heading it stands in.
    """
    pos = np.array([0.0, timeline.ground, 0.0])
    heading = 0.0
    times, positions, headings = [0.0], [pos.copy()], [heading]
    prims = sorted(timeline.primitives, key=lambda p: p.start)

    def knot(t: float, p: np.ndarray, h: float) -> None:
        if t <= times[-1] + 1e-9:  # same instant: the later knot wins
            times[-1], positions[-1], headings[-1] = max(t, times[-1]), p.copy(), h
        else:
            times.append(t)
            positions.append(p.copy())
            headings.append(h)

    for p in prims:
        if p.kind != "locomotion":
            continue
        goal = np.asarray(p.params["to"], dtype=float)
        walk_heading = heading_to(pos, goal, heading)
        heading = arrival_heading(prims, p, walk_heading)
        # turn toward the way to go at the start, arrive facing the work
        knot(p.start, pos, headings[-1])
        knot(min(p.start + TURN_TIME / 2, p.end), pos, walk_heading)
        knot(p.end, goal, headings[-1] + wrap(heading - headings[-1]))
        pos = goal
    return RootPlan(time=np.array(times), position=np.array(positions), heading=np.array(headings))
