"""A wide stance for a squat whose hands work in front of the knees (issue 18).

With the feet together a squat's thighs lie side by side in front of the pelvis: a hand that
works low in front of them (a drain valve in front of the right knee, a plug on the midline)
has its forearm come down onto a thigh, and no elbow swivel takes it out. People place their
feet apart and turned out before such a squat, the knees go out over the toes, and the arm
comes down between them. The manikin does the same: the walk that ends before the squat lands
its last two steps that much wider and turned out (``widen``), and the postures until the next
walk fold the legs over those feet (``posture``: the leg IK keeps each foot where it stands).

Whether a squat needs it is decided by geometry, not by the task: a reach during the squat to a
site lower than the knees whose distance to the side of the body's midline is within reach of a
thigh (hip to thigh surface plus the forearm's thickness), in front of the hips.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from mtlc.body.capsules import ARM_LIMBS, CLEARANCE_MARGIN, body_capsules, limb_radius
from mtlc.ir.model import FloatArray, MotionIR, Segment

# each foot lands this much further out than the walk's stance (× the leg's length: 8 cm for
# a 50th-percentile man): the ankles about shoulder width apart
WIDE_STEP = 0.095
WIDE_TURN_OUT = math.radians(20.0)  # each foot's toes turned out (a squat's usual 15-30°)
WIDE_RESULT = "wide_stance"  # a walk's result key: the extra half width and turn-out it landed


def _heading_axes(heading: float) -> tuple[FloatArray, FloatArray]:
    """The body's left (+X at heading 0) and forward (+Z at heading 0) directions."""
    c, s = math.cos(heading), math.sin(heading)
    return np.array([c, 0.0, -s]), np.array([s, 0.0, c])


def _squat_segment(ir: MotionIR, t0: float, t1: float) -> Segment | None:
    """The first whole-body posture in [t0, t1) when it is a squat (a wrist turn is a posture
    of a hand's track, not the body's)."""
    postures = sorted(
        (s for s in ir.on_track("root") if s.kind == "posture" and t0 - 1e-9 <= s.start < t1),
        key=lambda s: s.start,
    )
    if postures and postures[0].goal.params.get("posture") == "squat":
        return postures[0]
    return None


def thigh_zone(skel: Any) -> float:
    """Half the width (m) in front of the body where a forearm coming down meets a thigh of a
    squat with the knees together: the hip's distance from the midline, the thigh's radius and
    the forearm's, and the clearance's margin."""
    hip = float(abs(skel.joints[skel.joint_index("r_hip")].offset[0]))
    thigh = body_capsules(skel)[1].radius
    return hip + thigh + limb_radius(skel, ARM_LIMBS[0]) + CLEARANCE_MARGIN


def needs_wide_squat(
    ir: MotionIR, t_walk_end: float, t_next_walk: float, root: FloatArray, heading: float
) -> bool:
    """Whether the body that stops at ``root`` facing ``heading`` squats next (before any other
    posture) to reach a site in front of its knees: below the standing knee, within
    ``thigh_zone`` of the midline, in front of the hips."""
    skel = ir.skeleton
    squat = _squat_segment(ir, t_walk_end, t_next_walk)
    if skel is None or squat is None:
        return False
    later = [s for s in ir.on_track("root") if s.kind == "posture" and s.start >= squat.end - 1e-9]
    until = min([s.start for s in later if s.start < t_next_walk], default=t_next_walk)
    left, ahead = _heading_axes(heading)
    ankle = skel.joints[skel.joint_index("r_ankle")].offset
    heel = skel.site("r_heel").offset
    knee_height = float(-ankle[1] - heel[1])  # the standing knee above the sole
    zone = thigh_zone(skel)
    for seg in ir.segments:
        if seg.kind != "TA" or not (squat.start - 1e-9 <= seg.start < until):
            continue
        if seg.goal.position is None:
            continue
        for site in np.asarray(seg.goal.position, dtype=float).reshape(-1, 3):
            d = site - root
            side, front = float(d @ left), float(d @ ahead)
            if abs(side) < zone and site[1] - ir.ground < knee_height and front > 0.0:
                return True
    return False
