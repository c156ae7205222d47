"""The motion passes, in order: timeline → keyframe IR → solved, corrected, sampled frames.

Each pass is a function ``(MotionIR, PassContext) -> MotionIR`` in its own module; MOTION_PASSES
below is the one place that orders them. A pass that cannot meet a goal reports a diagnostic at
the source of the element that asked for it and leaves the IR usable for the passes after it.
"""

from __future__ import annotations

from collections.abc import Callable

from mtlc.body.kinematics import forget_output_pose
from mtlc.diagnostics import DiagnosticSink
from mtlc.ir.model import MotionIR
from mtlc.passes import (
    approach,
    balance,
    carry,
    carry_pose,
    clearance,
    contact,
    despike,
    detour,
    footing,
    gaze,
    hold,
    interpolate,
    joint_speed,
    locomotion,
    manikin,
    pace,
    posture,
    rest,
    retime,
    sample,
    settle,
    smooth,
    tool,
    upright,
    verify,
)
from mtlc.passes.context import MotionOptions, PassContext
from mtlc.passes.lower import lower
from mtlc.semantics import schedule
from mtlc.semantics.timeline import Timeline

MotionPass = Callable[[MotionIR, PassContext], MotionIR]

MOTION_PASSES: list[tuple[str, MotionPass]] = [
    ("manikin", manikin.build),  # 1. skeleton from population, sex, percentile
    ("equip", tool.equip),  # tools' tips become hand sites, their mass the hand's
    # 4. the gait comes before anything that starts "from the pose the body is in": the legs
    # and root a walk leaves behind are where the following postures and reaches begin
    ("footing", footing.run),  # each walk's stance moved back out of the scene's models
    ("locomotion", locomotion.generate),  # footsteps, stance, step segmentation
    ("posture", posture.solve),  # whole-body postures (squat, kneel, bend...) and wrist turns
    ("rest", rest.run),  # a released arm with nothing to do for a while comes down
    ("approach", approach.solve),  # 2. TA: damped least squares to the approach point
    ("contact", contact.solve),  # 3. TO: gradient path onto the site, kept as keyframes
    ("tool", tool.solve),  # a wrench's strokes: arcs about the fastener, the tip held on it
    ("upright", upright.run),  # the trunk a reach leaned comes back up when nothing needs it
    ("gaze", gaze.solve),  # neck and head aim the eyes at the looked-at site
    ("detour", detour.run),  # a reach's path bent around the scene's models by a via key
    ("pace", pace.run),  # each reach re-timed as one minimum-jerk movement (Flash & Hogan 1985)
    ("joint_speed", joint_speed.run),  # the clock stretched where a joint would outrun a person
    ("interpolate", interpolate.run),  # 5. interpolation with base-coordinate correction
    ("hold", hold.run),  # a hand on a site stays there while the body moves (verify: MT0511)
    ("carry_pose", carry_pose.run),  # a carried part near the body: on a walk, through a posture
    ("settle", settle.run),  # a walk starts from a natural stand: trunk upright, free arms down
    ("balance", balance.run),  # 6. centre of mass over the support polygon
    ("smooth", smooth.run),  # 7. blend offsets at segment boundaries
    ("carry", carry.run),  # a part in both hands is rigid: its pose drives both (MT0511)
    ("clearance", clearance.run),  # forearms and hands out of the trunk and thighs (MT0514)
    ("retime", retime.run),  # a reach the corrections bent is one bell of hand speed again
    ("despike", despike.run),  # an arm's few frames out and back faster than a person: straight
    ("sample", sample.run),  # 8. frames at the output rate
    ("verify", verify.run),  # every claim checked on the frames the user receives: keep last
]


def run_motion(
    timeline: Timeline,
    sink: DiagnosticSink,
    options: MotionOptions | None = None,
    *,
    until: str | None = None,
) -> MotionIR:
    """Lower a timeline and run the passes in order (``until`` stops after the named pass).
    The timeline must be timed for its manikin (``schedule.check_timed``): the motion of a
    manikin is then the same whichever command asks for it."""
    schedule.check_timed(timeline)
    forget_output_pose()  # the last compile's output pose, if no one took it
    ctx = PassContext(sink, options or MotionOptions())
    ir = lower(timeline)
    for name, motion_pass in MOTION_PASSES:
        ir = motion_pass(ir, ctx)
        if name == until:
            break
    ctx.flush_claims()  # stopped before verify: the passes' own words
    return ir


__all__ = ["MOTION_PASSES", "MotionOptions", "PassContext", "lower", "run_motion"]
