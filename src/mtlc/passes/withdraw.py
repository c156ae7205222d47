"""Withdraw: a hand that let go where the other hand still grips backs off before the part goes.

Two hands at one site (``reach(left, bowl)`` beside a ``grasp(right)`` on it): the first lets go
and stays where it was until its next goal, and the other hand then carries the part away
through it (the fuel filter's bowl through the left hand, 50-67 mm in, issue 20). A person takes
the free hand out of the part's way. So when a hand opens at a site whose other hand is closed
on it and that other hand's next reach leaves the site before this hand's own next goal, the
hand backs off ``WITHDRAW_DISTANCE`` half along the site's normal (the way it came in, clear of
the equipment) and half away from where the part is going (the other hand's next target),
shoulder and elbow solved to carry hand and elbow by that offset (the detour's via solve),
over ``WITHDRAW_TIME`` from the release (the fingers open as it goes), as a ``rest`` segment on the arm's track (not restated: gaze's restaters would take a ``rest`` to
the arm's rest pose). Its next reach then starts from there: that reach's
keys on the arm's dofs are offset by the difference, faded out along a minimum-jerk bell, so
it ends where it was solved to.
"""

from __future__ import annotations

import numpy as np

from mtlc.ir.model import FloatArray, GoalSpec, Keyframes, MotionIR, Segment
from mtlc.passes.context import PassContext
from mtlc.passes.detour import solve_via
from mtlc.passes.profile import minimum_jerk
from mtlc.passes.state import PoseState

WITHDRAW_TIME = 0.2  # s: the way out (the way in, a TO, took 0.12-0.2 s)
WITHDRAW_DELAY = 0.05  # s after the release starts: the goal's last frames keep the hand still
WITHDRAW_DISTANCE = 0.08  # m: a goal's usual approach distance (stdlib's 8 cm)
WITHDRAW_KEYS = 7  # keyframes along the way (the interpolation between two keys is no profile)
EPS = 1e-9


def arm_dofs(ir: MotionIR, side: str) -> tuple[str, ...]:
    """The arm's own dofs (clavicle to wrist): what the withdrawal moves."""
    assert ir.skeleton is not None
    words = ("clavicle", "shoulder", "elbow", "wrist")
    return tuple(
        n for n in ir.skeleton.dof_names if n.startswith(f"{side}_") and n.split("_")[1] in words
    )


def reaches(ir: MotionIR, side: str) -> list[Segment]:
    return sorted(
        (s for s in ir.on_track(f"{side}_arm") if s.kind in ("TA", "TO")), key=lambda s: s.start
    )


def grips(ir: MotionIR, side: str) -> list[Segment]:
    return sorted(
        (s for s in ir.on_track(f"{side}_hand") if s.kind == "grip"), key=lambda s: s.start
    )


def closed_at(ir: MotionIR, side: str, t: float) -> bool:
    """``side``'s hand is closed at ``t``: its last grip before ``t`` closed it."""
    before = [g for g in grips(ir, side) if g.start <= t + EPS]
    return bool(before) and before[-1].goal.params.get("state") == "closed"


def withdrawals(ir: MotionIR, side: str) -> list[tuple[Segment, Segment, Segment, Segment | None]]:
    """(release, the reach that brought the hand to the site, the other hand's reach away, the
    arm's next reach) for each release of ``side``'s hand that the rule above withdraws."""
    other = "l" if side == "r" else "r"
    own, theirs = reaches(ir, side), reaches(ir, other)
    out = []
    for g in grips(ir, side):
        if g.goal.params.get("state") != "open":
            continue
        done = [s for s in own if s.end <= g.start + EPS]
        if not done or done[-1].goal.site is None:
            continue
        site = done[-1].goal.site
        nxt = next((s for s in own if s.start >= g.end - EPS), None)
        # the other hand at the same site, closed, and its next reach away before ours
        there = [s for s in theirs if s.end <= g.end + EPS]
        away = next((s for s in theirs if s.start >= g.end - EPS), None)
        if not (there and there[-1].goal.site == site and away is not None):
            continue
        if away.goal.site == site or not closed_at(ir, other, away.start):
            continue
        if nxt is not None and nxt.start < g.start + WITHDRAW_DELAY + WITHDRAW_TIME - EPS:
            continue  # no time: the next reach takes the hand away itself
        if done[-1].goal.position is None or away.goal.position is None:
            continue
        out.append((g, done[-1], away, nxt))
    return out


def run(ir: MotionIR, ctx: PassContext) -> MotionIR:
    """A ``rest`` segment back to the approach pose for each withdrawal (see the docstring)."""
    if ir.skeleton is None or not ir.geometry:
        return ir
    skel = ir.skeleton
    state = PoseState(ir)
    for side in ("r", "l"):
        names = arm_dofs(ir, side)
        idx = [skel.dof_index(n) for n in names]
        for release, reach, away, nxt in withdrawals(ir, side):
            t0 = release.start + WITHDRAW_DELAY
            t1 = t0 + WITHDRAW_TIME
            q0 = state.q_at(t0)
            start = q0[idx]
            offset = withdraw_offset(reach, away)
            root = state.root_at_many(np.array([t1]))
            target = solve_via(skel, q0[None], root, [side], offset[None])[0][idx]
            times = np.linspace(t0, t1, WITHDRAW_KEYS)
            share = minimum_jerk(np.linspace(0.0, 1.0, WITHDRAW_KEYS))
            seg = Segment(
                track=f"{side}_arm",
                kind="rest",
                start=float(t0),
                end=float(t1),
                goal=GoalSpec(effector=f"{side}_hand", params={"rest": True, "withdraw": True}),
                provenance=release.provenance,
                keyframes=Keyframes(
                    time=times,
                    dofs=names,
                    q=start[None] + share[:, None] * (target - start)[None],
                ),
            )
            ir.segments.append(seg)
            state.add(seg)
            if nxt is not None and nxt.keyframes is not None:
                fade_in(nxt, dict(zip(names, target - start, strict=True)))
    return ir


def withdraw_offset(reach: Segment, away: Segment) -> FloatArray:
    """(3,) the hand's way back: ``WITHDRAW_DISTANCE`` along the mean of the site's normal (the
    way it came in) and the way from where the other hand takes the part to the site."""
    site = np.asarray(reach.goal.position, dtype=float).reshape(-1, 3)[0]
    there = np.asarray(away.goal.position, dtype=float).reshape(-1, 3)[0]
    normal = np.asarray(reach.goal.params.get("normal", (0.0, 0.0, 0.0)), dtype=float)
    way = unit(unit(normal) + unit(site - there))
    return WITHDRAW_DISTANCE * way


def unit(v: FloatArray) -> FloatArray:
    n = float(np.linalg.norm(v))
    return v / n if n > EPS else np.zeros(3)


def fade_in(seg: Segment, offset: dict[str, float]) -> None:
    """Start ``seg``'s keys ``offset`` (per dof) from where they were solved, the offset fading
    to none by its end along a minimum-jerk bell."""
    kf = seg.keyframes
    assert kf is not None
    span = max(seg.end - seg.start, EPS)
    keep = 1.0 - minimum_jerk(np.clip((np.asarray(kf.time) - seg.start) / span, 0.0, 1.0))
    q = np.array(kf.q, dtype=float, copy=True)
    for c, name in enumerate(kf.dofs):
        if name in offset:
            q[:, c] += keep * offset[name]
    kf.q = q
