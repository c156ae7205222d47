"""Time for the turns a walk makes: MTM-1 turn body (TBC) added to the walk's paces.

A walk's MTM time counts paces by distance, so a walk that only turns (its destination is where
the body stands) would get no time, and the pivot steps of the gait would turn the planted feet
on the spot. The front end follows the headings the root plan and the gait will take (the same
rules as ``passes/lower.py`` and ``passes/locomotion.py``, whose thresholds live here) and gives
each walk timed by ``mtm.walk()`` one MTM-1 TBC2 (turn body 45–90°, the lagging leg down before
the next motion: 37.2 TMU) for every started 90° of each turn the gait steps in place.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Iterable, Sequence
from itertools import islice

from mtlc.semantics import gait, mtm
from mtlc.semantics import types as T
from mtlc.semantics.timeline import Primitive

TURN_IN_PLACE = math.radians(30)  # a larger turn toward the way to go is stepped in place first
MAX_TWIST = math.radians(35)  # the closing steps of a walk land this much turned toward the work
FINAL_TURN = math.radians(3)  # a smaller turn left after arriving is not stepped
MIN_DISTANCE = 0.02  # m: shorter walks only turn
MAX_TURN_STEP = gait.MAX_TURN_STEP  # heading change per pivot step
WORK_MIN_DISTANCE = 0.1  # m: work closer than this to where a walk ends gives no direction
TURN_BODY_CODE = "TBC2"  # turn body 45-90°, complete when the lagging leg is down
TURN_BODY_ANGLE = math.radians(90)  # the most one TBC turns


Point = Sequence[float]


def wrap(a: float) -> float:
    """An angle in [-pi, pi)."""
    return (a + math.pi) % (2 * math.pi) - math.pi


def heading_to(src: Point, dst: Point, default: float) -> float:
    """Yaw about +Y from ``src`` toward ``dst`` (0 faces +Z); ``default`` when they coincide."""
    dx, dz = dst[0] - src[0], dst[2] - src[2]
    if math.hypot(dx, dz) < 1e-6:
        return default
    return math.atan2(dx, dz)


def work_after(prims: Iterable[Primitive], walk: Primitive) -> Point | None:
    """Where the work is after ``walk``: the mean site of the reaches before the next walk
    (a site reached often weighs more), which the body faces when the walk names no ``facing``.
    Lowering's root plan uses this too: the time given to turning and the turn made agree."""
    sites = []
    for p in prims:
        if p is walk or p.start < walk.end - 1e-9:
            continue
        if p.kind == "locomotion":
            break
        if p.kind == "goal":
            sites.append(tuple(float(c) for c in p.params["position"]))
    # summed in order, as numpy's mean over rows does (the front end needs no numpy: issue 21)
    return tuple(sum(c) / len(sites) for c in zip(*sites, strict=True)) if sites else None  # type: ignore[return-value]


def arrival_heading(prims: Iterable[Primitive], walk: Primitive, walking: float) -> float:
    """The heading a walk arrives in: toward its ``facing`` site, else the next work, else the
    way it walked."""
    goal = walk.params["to"]
    face = walk.params.get("facing_position")
    work = face if face is not None else work_after(prims, walk)
    if work is None or math.hypot(work[0] - goal[0], work[2] - goal[2]) < WORK_MIN_DISTANCE:
        return walking
    return heading_to(goal, work, walking)


def stepped_turns(h0: float, walking: float, arrival: float, distance: float) -> list[float]:
    """The turns (rad, unsigned) the gait makes by pivot steps in place: toward the way to go
    when that is over ``TURN_IN_PLACE``, and at the goal what the closing steps' twist (at most
    ``MAX_TWIST``) leaves of the turn toward the work. A walk shorter than ``MIN_DISTANCE``
    only turns, from where the feet face to the arrival heading."""
    if distance < MIN_DISTANCE:
        rest = abs(wrap(arrival - h0))
        return [rest] if rest > FINAL_TURN else []
    turns = []
    start = abs(wrap(walking - h0))
    if start > TURN_IN_PLACE:
        turns.append(start)
    rest = abs(wrap(arrival - walking)) - MAX_TWIST
    if rest > FINAL_TURN:
        turns.append(rest)
    return turns


def turn_body_seconds(turns: Iterable[float]) -> float:
    """MTM-1 turn body time: one TBC2 per started 90° of each stepped turn."""
    count = sum(math.ceil(a / TURN_BODY_ANGLE - 1e-9) for a in turns)
    return count * mtm.code_tmu(TURN_BODY_CODE) * T.TMU_SECONDS


def add_turn_time(
    prims: list[Primitive],
    mtm_walks: set[int],
    ground_start: Point,
    body: tuple[float, str] | None = None,
) -> None:
    """Lengthen each MTM-timed walk by the turn-body time of its stepped turns, and further to
    the time its steps need at a human cadence (``semantics.gait``, for ``body`` = (stature m,
    sex)) when MTM's is shorter; what starts at or after the walk's end moves later by as much,
    so sequences keep their order."""
    ordered = sorted(prims, key=lambda p: p.start)
    delays: list[tuple[Primitive, float]] = []  # (walk, seconds added at its end)
    pos: Point = ground_start
    heading = 0.0
    for i, walk in enumerate(ordered):
        if walk.kind != "locomotion":
            continue
        goal = walk.params["to"]
        walking = heading_to(pos, goal, heading)
        arrival = arrival_heading(islice(ordered, i + 1, None), walk, walking)
        if id(walk) in mtm_walks:
            turns = stepped_turns(heading, walking, arrival, walk.params["distance"])
            seconds = turn_body_seconds(turns)
            if seconds > 0:
                walk.params["turn_time"] = seconds
            if body is not None:
                need = gait.walk_seconds(walk.params["distance"], turns, *body, MIN_DISTANCE)
                mtm_total = walk.end - walk.start + seconds
                if need > mtm_total + 1e-9:
                    walk.params["gait_time"] = need  # the steps' time replaces MTM's
                    seconds = need - (walk.end - walk.start)
            if seconds > 0:
                delays.append((walk, seconds))
        pos, heading = goal, arrival
    _apply_delays(ordered, delays)


def _apply_delays(ordered: list[Primitive], delays: list[tuple[Primitive, float]]) -> None:
    """Move each primitive later by the time added at every walk end at or before its start
    (original times); a walk given time also ends later by its own share."""
    if not delays:
        return
    ends = [walk.end - 1e-9 for walk, _ in delays]
    total = [0.0]
    for _, seconds in delays:
        total.append(total[-1] + seconds)
    own = {id(walk): k for k, (walk, _) in enumerate(delays)}
    for p in ordered:
        k = own.get(id(p))
        if k is None:
            _shift(p, total[bisect.bisect_right(ends, p.start)])
        else:
            p.start, p.end = p.start + total[k], p.end + total[k + 1]


def _shift(p: Primitive, seconds: float) -> None:
    """Move a primitive and the absolute times it carries (a goal's TA and TO windows)."""
    p.start, p.end = p.start + seconds, p.end + seconds
    phases = p.params.get("phases")
    if phases is not None:
        p.params["phases"] = {k: [a + seconds, b + seconds] for k, (a, b) in phases.items()}
