"""A task's timeline timed for one manikin: the one step of the front end that reads the body.

The expander's timeline is the same for every manikin: MTM-1 times each element from the scene
(distances, weights), not from who does it. A walk timed by ``mtm.walk()`` is the exception: it
gets the turn-body time of its stepped turns (``semantics.turning``) and, when MTM's paces are
quicker, the time its steps need at the cadence of this body's stature and sex
(``semantics.gait``), and everything after it moves later. ``for_manikin`` does that on a copy,
so one expanded timeline serves every manikin: `mtlc compile` times it for the task's manikin
(or ``--manikin``), `mtlc lint` and `mtlc report` for each manikin they sweep, and the motion of
a manikin is the same whichever command asks for it.
"""

from __future__ import annotations

import dataclasses
from functools import cache

from mtlc.body.anthropometry import dimensions
from mtlc.diagnostics import DiagnosticSink
from mtlc.semantics import turning
from mtlc.semantics.timeline import ManikinSpec, Timeline


def for_manikin(timeline: Timeline, spec: ManikinSpec) -> Timeline:
    """A copy of the expander's ``timeline`` timed for manikin ``spec``: its MTM-timed walks
    lengthened for that body and what follows them moved later. ``timeline`` is left as it is
    (lint times one timeline for several manikins); a timeline already timed for a manikin is
    timed again from its untimed source (``expanded``)."""
    base = timeline.expanded if timeline.timed_for is not None else timeline
    if base is None:
        raise ValueError(f"task `{timeline.task}` is timed, and its untimed timeline is gone")
    # the timing sets a walk's `turn_time`/`gait_time` and moves start, end and a goal's
    # `phases` (a new dict): a copy of each primitive and of its params is enough
    prims = [dataclasses.replace(p, params=dict(p.params)) for p in base.primitives]
    walks = {id(prims[i]) for i in base.mtm_walks}
    turning.add_turn_time(prims, walks, (0.0, base.ground, 0.0), body(spec))
    return dataclasses.replace(base, manikin=spec, primitives=prims, timed_for=spec, expanded=base)


def check_timed(timeline: Timeline) -> None:
    """Refuse a timeline whose walks are not timed for its manikin: one never timed, or one
    timed for another manikin whose ``manikin`` was replaced (its walks would keep the other
    body's step time: the motion no command gives that manikin)."""
    if timeline.timed_for == timeline.manikin:
        return
    spec = timeline.manikin
    who = f"{spec.population}:{spec.sex}:{spec.percentile}"
    raise ValueError(
        f"task `{timeline.task}` is not timed for {who}: time it for that manikin with "
        "mtlc.semantics.schedule.for_manikin (or frontend.time_task), not by replacing its manikin"
    )


def check_budget(timeline: Timeline, sink: DiagnosticSink) -> None:
    """MT0404 when the (timed) task takes longer than its `budget` statement allows."""
    budget = timeline.budget
    if budget is None or not timeline.duration > budget:
        return
    sink.report(
        "MT0404",
        f"task `{timeline.task}` takes {timeline.duration:.1f} s, over its budget of "
        f"{budget:.1f} s",
        timeline.budget_span or timeline.span,
        notes=("the time is predicted from MTM-1 and the stated durations",),
    )


@cache
def body(spec: ManikinSpec) -> tuple[float, str] | None:
    """Stature (m) and sex of the manikin, which time a walk's steps (``semantics.gait``); worked
    out once per manikin (its table rows are fixed), not once per task."""
    try:
        dims = dimensions(spec.population, spec.sex, spec.percentile)
    except (KeyError, ValueError):
        return None  # an unknown manikin is reported elsewhere; MTM times its walks
    return dims.stature, spec.sex
