"""MT0608: a lift whose NIOSH lifting index is above 1.

A lift is a goal that carries a load (`move(..., load: 9 kg)`, through `lift` and `carry`): its
origin is where the hands are when it starts, its destination where they are when it ends. Both
ends are scored with the revised NIOSH equation (mtlc.ergonomics.niosh) on the compiled frames,
frequency, duration and coupling from the configuration; the worse end is reported at the task
line that asked for the lift.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mtlc.diagnostics import Span
from mtlc.ergonomics import niosh
from mtlc.lint.findings import Finding
from mtlc.lint.rules.view import MotionView
from mtlc.lint.rules.visibility import pose_frames


@dataclass(frozen=True)
class Lift:
    """A loaded goal of one or both hands: one time window at one task line."""

    load: float  # kg
    start: float
    end: float
    origin: Span
    path: tuple[str, ...]


def loaded_goals(view: MotionView) -> list[Lift]:
    """The lifts of the task, once per (task line, time window), in time order."""
    if view.timeline is None:
        return []
    seen: dict[tuple[Span, float, float], Lift] = {}
    for p in view.timeline.primitives:
        load = float(p.params.get("load", 0.0)) if p.kind == "goal" else 0.0
        if load <= 0:
            continue
        key = (p.origin, round(p.start, 9), round(p.end, 9))
        if key not in seen or load > seen[key].load:
            seen[key] = Lift(load, p.start, p.end, p.origin, p.path)
    return sorted(seen.values(), key=lambda lift: (lift.start, lift.origin.line))


def assess(view: MotionView, lift: Lift) -> tuple[niosh.LiftAssessment, niosh.LiftAssessment]:
    """``lift`` scored at its origin and destination on this manikin's frames."""
    ends = np.array([_frame_at(view.time, lift.start), _frame_at(view.time, lift.end)])
    pose = pose_frames(view.pose, ends)
    origin, destination = niosh.lift_geometry(view.ir.skeleton, pose, view.ir.ground)
    cfg = view.config
    return niosh.assess_lift(
        lift.load, origin, destination, cfg.lift_frequency, cfg.lift_duration, cfg.lift_coupling
    )


def _frame_at(time: np.ndarray, t: float) -> int:
    return min(int(np.searchsorted(time, t - 1e-9)), len(time) - 1)


def lifting_index(view: MotionView) -> list[Finding]:
    out = []
    for lift in loaded_goals(view):
        origin, destination = assess(view, lift)
        worse = niosh.worst((origin, destination))
        if worse.lifting_index > 1.0:
            travel = abs(destination.point.vertical - origin.point.vertical)
            out.append(_finding(view, lift, worse, travel))
    return out


def describe(a: niosh.LiftAssessment, travel: float) -> str:
    """LI, RWL and the geometry and multipliers behind them, for a message."""
    m, p = a.multipliers, a.point
    li = "inf" if math.isinf(a.lifting_index) else f"{a.lifting_index:.2f}"
    return (
        f"LI {li}, RWL {a.rwl:.1f} kg at the {a.end} (H {p.horizontal * 100:.0f} cm, "
        f"V {p.vertical * 100:.0f} cm, D {travel * 100:.0f} cm, A {math.degrees(p.asymmetry):.0f}°; "
        f"HM {m.hm:.2f}, "
        f"VM {m.vm:.2f}, DM {m.dm:.2f}, AM {m.am:.2f}, FM {m.fm:.2f}, CM {m.cm:.2f})"
    )


def _finding(view: MotionView, lift: Lift, a: niosh.LiftAssessment, travel: float) -> Finding:
    msg = (
        f"the {lift.load:g} kg lift in `{' > '.join(lift.path)}` is over the NIOSH recommended "
        f"weight limit: {describe(a, travel)}"
    )
    return Finding(
        "MT0608",
        msg,
        lift.origin,
        help="bring the part's start and end between knee and shoulder height and close to the "
        "body, lighten it, or share the lift (two people, a hoist)",
        manikins=(view.manikin,),
        details=(msg,),
    )
