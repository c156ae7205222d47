"""What the hands carry: held tools and carried loads, and the centre of mass with them.

One home for "what mass is in which hand, when", read by the balance pass and the metrics (the
centre of mass), and by RULA's force/load score (``mtlc.ergonomics.rula.held_load``). It reads
the IR's segments and a pose only, so the metrics and the ergonomics import it without the
passes (the layers: passes -> metrics -> ir -> body).

* A **tool** is held from the first segment made with it to its last (``held_spans``); its mass
  is a point at the middle of grip and tip (docs/tools.md).
* A **load** is the `load` of a goal (`move(hand, site, load: 9 kg)`, through `carry` and
  `lift`) or of a turn. The hand holds it from the grasp that closed it before that goal (the
  last `grip closed` of that hand at or before the goal starts, with no `grip open` between)
  until the end of the next `grip open` of that hand after the goal, or the end of the motion;
  with no grasp before the goal, from the goal's start. Its mass is a point at the hand's grip
  point, its weight taken up over ``LOAD_RAMP`` (0.3 s) after the window starts and put down
  over 0.3 s before it ends; a two-handed goal puts half in each hand. Several loaded goals in one grasp carry the
  same part: the heaviest counts, once (docs/stdlib.md, "Loads").
"""

from __future__ import annotations

from bisect import bisect_left, bisect_right
from typing import Any, NamedTuple

import numpy as np

from mtlc.body import center_of_mass, site_positions
from mtlc.ir.model import FloatArray, MotionIR

SIDES = ("r", "l")
# s: a part's weight comes onto the hand over this long after the grasp starts, and off it over
# this long before the release ends (taking up 40 kg in one 60 fps frame moved the centre of
# mass 14 cm at once, and the balance correction with it)
LOAD_RAMP = 0.3
AXIAL_KINDS = ("screwdriver", "pliers")  # tools turned by the forearm about their own axis
EPS = 1e-9  # s


def tool_site(hand_site: str, tool: dict[str, Any]) -> str:
    """The name of a tool's working point on a hand (``r_hand`` + wrench_10mm -> r_tool_...)."""
    return f"{hand_site[0]}_tool_{tool['name']}"


def held_spans(ir: MotionIR) -> list[tuple[str, dict[str, Any], float, float]]:
    """(tool site, tool, start, end) per tool a hand holds: from the first segment made with it
    to its last (reach to last stroke or turn)."""
    spans: dict[str, list[Any]] = {}
    for seg in ir.segments:
        tool, side = seg.goal.params.get("tool"), seg.goal.effector[:1]
        if not isinstance(tool, dict) or side not in SIDES:
            continue
        span = spans.setdefault(tool_site(f"{side}_hand", tool), [tool, seg.start, seg.end])
        span[1], span[2] = min(span[1], seg.start), max(span[2], seg.end)
    return [(site, tool, start, end) for site, (tool, start, end) in sorted(spans.items())]


class Load(NamedTuple):
    """A carried part's mass in one hand over one hold window."""

    side: str  # "r" or "l"
    mass: float  # kg the whole part weighs (the goal's `load`)
    share: float  # kg in this hand: half the mass when both hands carry it
    start: float  # s
    end: float  # s


def _grips(ir: MotionIR, side: str) -> list[tuple[float, float, bool]]:
    """(start, end, closed) of one hand's grip segments, by start."""
    out = [
        (seg.start, seg.end, seg.goal.params.get("state") == "closed")
        for seg in ir.segments
        if seg.kind == "grip" and seg.goal.effector[:1] == side
    ]
    return sorted(out)


def _motion_end(ir: MotionIR) -> float:
    return max((seg.end for seg in ir.segments), default=0.0)


def carried_loads(ir: MotionIR) -> list[Load]:
    """Each carried part per hand and hold window (see the module's doc), by start."""
    end_of_motion = _motion_end(ir)
    found: dict[tuple[str, float, float], Load] = {}
    grips = {side: _grips(ir, side) for side in SIDES}
    # per hand its closing and its opening grips, by start (bisected per loaded goal: a scan of
    # every grip per goal was quadratic in a long procedure)
    closing = {side: [g for g in grips[side] if g[2]] for side in SIDES}
    opening = {side: [g for g in grips[side] if not g[2]] for side in SIDES}
    closing_starts = {side: [g[0] for g in closing[side]] for side in SIDES}
    opening_starts = {side: [g[0] for g in opening[side]] for side in SIDES}
    for seg in ir.segments:
        side = seg.goal.effector[:1]
        mass = float(seg.goal.params.get("load", 0.0) or 0.0)
        if side not in SIDES or seg.kind == "grip" or not mass > 0.0:
            continue
        # the last grasp that closed at or before the goal starts
        i = bisect_right(closing_starts[side], seg.start + EPS)
        start = closing[side][i - 1][0] if i else seg.start
        j = bisect_right(opening_starts[side], start)  # the first release after that grasp
        if j < len(opening_starts[side]) and opening_starts[side][j] < seg.start - EPS:
            start = seg.start  # opened since that grasp: the part was taken up without one
        # the first release at or after the goal's end
        k = bisect_left(opening_starts[side], seg.end - EPS)
        end = opening[side][k][1] if k < len(opening[side]) else max(end_of_motion, seg.end)
        share = mass / 2.0 if seg.goal.params.get("two_handed") else mass
        key = (side, round(start, 9), round(end, 9))
        if key not in found or found[key].mass < mass:
            found[key] = Load(side, mass, share, start, end)
    return sorted(found.values(), key=lambda x: (x.start, x.side))


def load_weight(load: Load, time: FloatArray) -> FloatArray:
    """(T,) share (0..1) of a load's weight on its hand: 0 outside its window, rising over
    ``LOAD_RAMP`` from its start and falling over ``LOAD_RAMP`` to its end (the whole window
    when it is shorter)."""
    t = np.asarray(time, dtype=float)
    ramp = max(min(LOAD_RAMP, 0.5 * (load.end - load.start)), 1e-6)
    rise = np.clip((t - load.start) / ramp, 0.0, 1.0)
    fall = np.clip((load.end - t) / ramp, 0.0, 1.0)
    return np.minimum(rise, fall) * ((t >= load.start - EPS) & (t <= load.end + EPS))


class Held(NamedTuple):
    """What the hands hold over the motion: ``held_spans`` and ``carried_loads`` of one IR
    (they read the segments only), for a caller that asks ``carried_com`` many times."""

    spans: list[tuple[str, dict[str, Any], float, float]]
    loads: list[Load]


def held(ir: MotionIR) -> Held:
    """The tools and loads the hands hold, read from the segments once."""
    return Held(held_spans(ir), carried_loads(ir))


def carried_com(ir: MotionIR, pose: Any, time: Any, holding: Held | None = None) -> FloatArray:
    """(T, 3) centre of mass of the body with the tools and loads it holds at ``time`` (T,).

    Each held tool is a point mass at the middle of grip and tip during its held window
    (``held_spans``), each carried load a point mass at its hand's grip point during its hold
    window (``carried_loads``), taken up and put down over ``LOAD_RAMP`` (``load_weight``);
    outside their windows they weigh nothing. The solvers' CoM
    Jacobian leaves them out: the balance pass measures with them and iterates. ``holding``:
    ``held(ir)``, for a caller that asks many times.
    """
    skel = ir.skeleton
    assert skel is not None
    if holding is None:
        holding = held(ir)
    t = np.asarray(time, dtype=float)
    big_m = float(skel.total_mass)
    moment = big_m * center_of_mass(skel, pose)
    mass = np.full(t.shape, big_m)
    names = {s.name for s in skel.sites}
    for site, tool, start, end in holding.spans:
        m = float(tool.get("mass", 0.0))
        if m <= 0.0 or site not in names:
            continue
        held_mass = m * ((t >= start - EPS) & (t <= end + EPS))
        ends = np.asarray(site_positions(skel, pose, [f"{site[0]}_hand", site]))
        moment += held_mass[:, None] * 0.5 * (ends[..., 0, :] + ends[..., 1, :])
        mass += held_mass
    # each hand's grip point placed once, not once per load it carries (a procedure of 81 lifts
    # placed a hand 81 times over every frame asked for: most of the balance pass's CoM time)
    hands: dict[str, FloatArray] = {}
    for load in holding.loads:
        held_mass = load.share * load_weight(load, t)
        if not held_mass.any():
            continue
        if load.side not in hands:
            hands[load.side] = np.asarray(site_positions(skel, pose, f"{load.side}_hand"))
        moment += held_mass[:, None] * hands[load.side]
        mass += held_mass
    return moment / mass[:, None]


def held_load(ir: MotionIR, time: FloatArray) -> dict[str, FloatArray]:
    """Mass (kg) each hand holds per frame, for RULA's force/load score: a tool over its held
    window, plus each carried part over its hold window. A hand of a two-handed lift scores the
    whole part (RULA scores the load handled, not a share of it)."""
    t = np.asarray(time, dtype=float)
    out = {side: np.zeros(len(t)) for side in SIDES}
    for site, tool, start, end in held_spans(ir):
        inside = (t >= start - EPS) & (t <= end + EPS)
        out[site[0]] += np.where(inside, float(tool.get("mass", 0.0)), 0.0)
    for load in carried_loads(ir):
        inside = (t >= load.start - EPS) & (t <= load.end + EPS)
        out[load.side] += np.where(inside, load.mass, 0.0)
    return out
