"""Rest: an arm whose hand let go and has nothing to do for a while comes down to the side.

A hand keeps the pose of its last goal until its next one. After a release that pose is where the
work was, overhead or at arm's length, and no one holds an arm up there while the other hand
works, while they look at a gauge or walk away: the right arm stayed at 130° of shoulder flexion
for 15 s over an overhead hatch while the left hand undid its fasteners, and RULA scored an arm
that was doing nothing. So a released hand whose next use (a goal, a grip or a turn on its own
tracks, or a posture that moves its arm) is at least ``ARM_REST_IDLE`` away lets its arm down to
the standing body's rest pose (the comfortable pose's arm, what a stand lets a free arm down to),
over ``REST_TIME`` with a minimum-jerk profile, as its own segment (kind ``rest``) on the arm's
track. The next reach then starts from the side, as the front end timed it
(``semantics.expand``: a reach after such a spell travels from the hand's side).

Only a standing body rests its arms here, and only an arm that let go at least
``ARM_REST_MIN_HEIGHT`` above the ground: squatting, kneeling or sitting, a hanging arm would go
into the thighs or the floor (those postures place free arms themselves), and a hand that let go
at the hip is down already (taken to the side from there, the forearm swept through the thigh).
"""

from __future__ import annotations

import numpy as np

from mtlc.ir.model import GoalSpec, Keyframes, MotionIR, Segment
from mtlc.passes.context import PassContext
from mtlc.passes.posture import standing_arm_dofs
from mtlc.passes.profile import minimum_jerk
from mtlc.passes.state import PoseState, mark
from mtlc.semantics.expand import ARM_REST_IDLE, ARM_REST_MIN_HEIGHT, ARM_REST_POSTURES

REST_DELAY = 0.1  # s after the release before the arm starts down (the fingers open first)
REST_TIME = 0.8  # s: the arm's way down to the side
REST_KEYS = 7  # keyframes along the way (the interpolation between two keys is not a profile)
UPRIGHT = (None, *ARM_REST_POSTURES)  # postures a hanging arm is clear of the body in
EPS = 1e-9


def resting_dofs(side: str) -> tuple[str, ...]:
    """The dofs an idle arm lets down: a stand's (``standing_arm_dofs``) but the clavicle, which
    a reach from the side keyed on the arm alone does not key. Keyed here, the clavicle held a
    copy of the pose before the rest that the contacts solved after it then changed: restated
    last, it took the next grasp 81 mm off its knob and the hold's re-solve stepped the
    shoulder 19 deg in one frame (tests/data/arms/a01, female P5)."""
    return tuple(n for n in standing_arm_dofs((f"{side}_shoulder_flex",)) if "clavicle" not in n)


def idle_spells(ir: MotionIR, side: str) -> list[tuple[Segment, float]]:
    """(release, end of the idle spell after it) of ``side``'s hand, for spells of at least
    ``ARM_REST_IDLE`` in which the body stands."""
    own = sorted(
        (s for s in ir.segments if s.track in (f"{side}_arm", f"{side}_hand")),
        key=lambda s: s.start,
    )
    arm = set(standing_arm_dofs((f"{side}_shoulder_flex",)))
    postures = sorted(
        (s for s in ir.on_track("root") if s.kind == "posture"), key=lambda s: s.start
    )
    spells = []
    duration = ir.duration  # (a scan of every segment: once, not once per release)
    for g in own:
        if g.kind != "grip" or g.goal.params.get("state") != "open":
            continue
        reached = [s for s in own if s.kind in ("TA", "TO") and s.end <= g.start + EPS]
        site = reached[-1].goal.position if reached else None
        if site is None or float(site[1]) - ir.ground < ARM_REST_MIN_HEIGHT:
            continue  # let go low, the arm is down already
        after = [s.start for s in own if s.start >= g.end - EPS and s is not g]
        end = min(after, default=duration)
        before = [p for p in postures if p.start < g.end + EPS]
        if before and before[-1].goal.params.get("posture") not in UPRIGHT:
            continue  # squatting or kneeling: the posture places the free arms
        moving = [
            p.start
            for p in postures
            if p.end > g.end + EPS and p.keyframes is not None and arm & set(p.keyframes.dofs)
        ]
        end = min([end, *moving])
        if end - g.end >= ARM_REST_IDLE - EPS:
            spells.append((g, end))
    return spells


def run(ir: MotionIR, ctx: PassContext) -> MotionIR:
    """A ``rest`` segment on each arm's track for each idle spell after a release."""
    if ir.skeleton is None:
        return ir
    skel = ir.skeleton
    state = PoseState(ir)
    for side in ("r", "l"):
        names = resting_dofs(side)
        idx = [skel.dof_index(n) for n in names]
        rest = np.asarray(skel.q_comfort, dtype=float)[idx]
        for release, end in idle_spells(ir, side):
            t0 = release.end + REST_DELAY
            t1 = min(t0 + REST_TIME, end - REST_DELAY)
            times = np.linspace(t0, t1, REST_KEYS)
            start = state.q_at(t0)[idx]
            share = minimum_jerk(np.linspace(0.0, 1.0, REST_KEYS))
            seg = Segment(
                track=f"{side}_arm",
                kind="rest",
                start=float(t0),
                end=float(t1),
                goal=GoalSpec(effector=f"{side}_hand", params={"rest": True}),
                provenance=release.provenance,
                keyframes=Keyframes(
                    time=times,
                    dofs=names,
                    q=start[None] + share[:, None] * (rest - start)[None],
                ),
            )
            ir.segments.append(seg)
            state.add(seg)
            mark(ctx.cache, seg, "rest")
    return ir
