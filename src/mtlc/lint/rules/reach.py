"""MT0501 for the manikins between the selection's extremes, without a full compile each.

The extremes are compiled in full (every motion pass). For each other manikin every contact
goal (TO segment; a tool's tip on its site, the screened manikin holding the same tools) is
re-solved in one batched IK call per hand: the body starts in the joint
angles the nearest extreme (by stature) had when its hand arrived, its root where that extreme's
root was, lowered or raised so the feet (or knees) stay on the ground, and the arm with the
trunk (the TA pass's second strategy) reaches for the site. A hand left more than the passes'
1 mm short is reported as the passes report it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mtlc.body import build_manikin, forward, site_positions
from mtlc.body.anthropometry import measure
from mtlc.body.ik import Goal, solve_ta
from mtlc.diagnostics import Span
from mtlc.ir.model import FloatArray, MotionIR, Segment
from mtlc.lint.findings import Finding
from mtlc.lint.manikins import label
from mtlc.metrics import lowest_point
from mtlc.passes.approach import HAND_NAMES, TOLERANCE, effector_name
from mtlc.passes.tool import held_tools, is_stroke, with_tools
from mtlc.semantics.timeline import ManikinSpec

# the start pose is already the nearby manikin's solution: a few iterations from there suffice,
# and rows that cannot reach stop early instead of restarting (measured in bench/lint.py)
SCREEN_ITERATIONS = 40
SCREEN_RESTARTS = 1


def stature(spec: ManikinSpec) -> float:
    return measure(spec.population, spec.sex, spec.percentile, "stature")


@dataclass
class Reach:
    segment: Segment
    frame: int  # the extreme's frame where the hand arrives


def contact_goals(ir: MotionIR) -> list[Reach]:
    """Each TO segment of the arms with a world target, once per (task line, site, arm)."""
    assert ir.frames is not None
    t = ir.frames.time
    seen: set[tuple[object, ...]] = set()
    out = []
    for seg in ir.segments:
        if seg.kind != "TO" or seg.goal.position is None or is_stroke(seg):
            continue
        if seg.goal.effector not in HAND_NAMES and "tool" not in seg.goal.params:
            continue  # a hand, or a tool's tip on its site (docs/tools.md)
        key = (seg.provenance.origin, seg.goal.site, seg.track)
        if key in seen:
            continue
        seen.add(key)
        out.append(Reach(seg, min(int(np.searchsorted(t, seg.end - 1e-9)), len(t) - 1)))
    return out


def _grounded_roots(ir: MotionIR, skel: object, frames: list[int]) -> tuple[FloatArray, ...]:
    """Start angles and roots for another skeleton: the extreme's, with the root height moved
    so the lowest body point is where the extreme's was."""
    f = ir.frames
    assert f is not None
    q = f.q[frames]
    rot = f.root_rotation[frames]
    pos = f.root_position[frames].copy()
    theirs = lowest_point(ir.skeleton, forward(ir.skeleton, q, pos, rot))
    at_zero = pos.copy()
    at_zero[:, 1] = 0.0
    ours = lowest_point(skel, forward(skel, q, at_zero, rot))
    pos[:, 1] = theirs - ours
    return q, pos, rot


def _pairs(goals: list[Reach]) -> list[tuple[Reach, ...]]:
    """Goals grouped as the TA pass groups them: both hands in one time window share a trunk."""
    by: dict[tuple[float, float], list[Reach]] = {}
    for g in goals:
        by.setdefault((round(g.segment.start, 9), round(g.segment.end, 9)), []).append(g)
    return [tuple(sorted(v, key=lambda g: g.segment.track)) for v in by.values()]


def screen(ir: MotionIR, spec: ManikinSpec) -> list[Finding]:
    """MT0501 findings for ``spec``, from the compiled motion ``ir`` of a nearby manikin."""
    return [
        _finding(seg, short, label(spec))
        for seg, short in screen_distances(ir, spec)
        if short > TOLERANCE
    ]


def screen_distances(ir: MotionIR, spec: ManikinSpec) -> list[tuple[Segment, float]]:
    """Each contact goal of ``ir`` (its TO segment) with how far ``spec``'s hand stays from
    the site (m), reached or not: the screen's measurement, which mtlc report tabulates.

    One batched solve per hand combination (right alone, left alone, both together)."""
    goals = contact_goals(ir)
    if not goals:
        return []
    # the other manikin holds the same tools: their tips are the goals' effectors
    skel = with_tools(build_manikin(spec.population, spec.sex, spec.percentile), held_tools(ir))
    by_hands: dict[tuple[str, ...], list[tuple[Reach, ...]]] = {}
    for group in _pairs(goals):
        by_hands.setdefault(tuple(g.segment.goal.effector for g in group), []).append(group)
    out = []
    for hands, groups in sorted(by_hands.items()):
        q, pos, rot = _grounded_roots(ir, skel, [grp[0].frame for grp in groups])
        targets = [
            np.array([np.asarray(grp[k].segment.goal.position, dtype=float) for grp in groups])
            for k in range(len(hands))
        ]
        goal_list = [Goal(h, position=t) for h, t in zip(hands, targets, strict=True)]
        result = solve_ta(
            skel,
            goal_list,
            q,
            reach="torso",
            root_position=pos,
            root_rotation=rot,
            max_iter=SCREEN_ITERATIONS,
            restarts=SCREEN_RESTARTS,
        )
        reached = forward(skel, result.q, pos, rot)
        for k, hand in enumerate(hands):
            short = np.linalg.norm(site_positions(skel, reached, hand) - targets[k], axis=-1)
            out.extend((grp[k].segment, float(d)) for grp, d in zip(groups, short, strict=True))
    return out


def _finding(seg: Segment, short: float, manikin: str) -> Finding:
    o = seg.provenance.origin
    msg = (
        f"the {effector_name(seg.goal.effector)} cannot reach site `{seg.goal.site}`: "
        f"{short * 1000:.0f} mm short"
    )
    span = Span(o.file, o.line, o.column, o.end_line, o.end_column)
    return Finding("MT0501", msg, span, manikins=(manikin,), details=(msg,))
