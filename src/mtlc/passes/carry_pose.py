"""Pass 5c: a part carried in both hands on a walk is held near the body (issue 19).

A walk keeps the arms as the reach before it left them: the avionics unit, slid out of its rack
at 1.65 m, was carried 4.5 s to the trolley at head height, the panel at the height of its
handle. People carry a load they hold in both hands close to the trunk, elbows bent, the load
near waist height: the load's moment about the lower back and the shoulders' is then smallest
(NIOSH lifting equation's horizontal multiplier, Waters, Putz-Anderson, Garg & Fine 1993,
"Revised NIOSH equation for the design and evaluation of manual lifting tasks", Ergonomics
36(7):749-776: the load's horizontal distance from the ankles' mid-point is its largest factor).

Here, on the dense frames of each walk during which both hands hold one two-handed part
(``carry.carries``), the arms are led to a carry pose and back: the hands' mid-point at the
manikin's standing elbow height (its neutral pose's, arms hanging) and
``HOLD_AHEAD`` in front of the trunk (the middle of a part 30 cm deep), the two hands as far
apart and turned as they were when the walk started (the part keeps its width and attitude).
Its arm angles (shoulders, elbows, wrists; not the forearm's twist) are solved once, at the
walk's first frame, and the difference is blended in from the walk's start and out before its
end by a minimum-jerk ramp at most ``ARM_SPEED`` fast: the walk ends with the arms where the
reach after it was solved from (the place starts from there). A walk too short for both ramps,
or whose part is already near that pose, is left as it was.
"""

from __future__ import annotations

import math

import numpy as np

from mtlc.body import forward, site_positions
from mtlc.body.capsules import body_capsules
from mtlc.body.ik import Goal, solve_ta
from mtlc.body.kinematics import quat_to_matrix
from mtlc.body.skeleton import Skeleton
from mtlc.ir.model import FloatArray, Frames, MotionIR
from mtlc.passes.carry import carries
from mtlc.passes.context import PassContext
from mtlc.passes.hold import _arm_dofs
from mtlc.passes.profile import minimum_jerk

HANDS = ("r_hand", "l_hand")
SOLES = ("r_heel", "r_toe", "l_heel", "l_toe")
HOLD_AHEAD = (
    0.15  # m the hands' mid-point is in front of the trunk: the middle of a part 30 cm deep
)
ARM_SPEED = math.radians(150.0)  # rad/s: the ramps' mean joint speed at most (their peak 280)
PEAK = 1.875  # a minimum-jerk ramp's peak speed over its mean
MIN_RAMP = 0.6  # s: the shortest ramp in or out
NEAR = 0.08  # m: a part whose hands are this close to the carry pose already stays
SOLVE_TOL = 2e-3  # m: the carry pose's hands within this of their targets, or no carry pose
RESTARTS = (
    4  # random restarts where the descent from the walk's first pose stalls (male P5: 33 mm short)
)
EPS = 1e-9


def elbow_height(skel: Skeleton) -> float:
    """The standing elbow's height above the soles (m): the neutral pose's, arms hanging."""
    q = np.zeros((1, len(skel.dof_names)))
    pose = forward(skel, q, np.zeros((1, 3)), np.array([[1.0, 0.0, 0.0, 0.0]]), with_axes=False)
    soles = np.asarray(site_positions(skel, pose, list(SOLES)))[0]
    return float(pose.p[0, skel.joint_index("r_elbow"), 1] - soles[:, 1].min())


def carry_targets(
    skel: Skeleton, q: FloatArray, root: FloatArray, rotation: FloatArray, ground: float
) -> FloatArray:
    """(2, 3) where the right and left hands go for the carry, from the pose at a walk's start
    (``q``, root position and rotation): their mid-point at standing elbow height
    (``elbow_height``: a trunk still bent from a lift at the walk's start does not lower it)
    and ``HOLD_AHEAD`` in front of the trunk's surface (its capsule, ``mtlc.body.capsules``) at
    the lumbar joint, the hands keeping their offset from it."""
    pose = forward(skel, q[None], root[None], rotation[None], with_axes=False)
    hands = np.asarray(site_positions(skel, pose, list(HANDS)))[0]
    trunk = next(c.radius for c in body_capsules(skel) if c.name == "trunk")
    ahead = quat_to_matrix(rotation) @ np.array([0.0, 0.0, 1.0])
    ahead[1] = 0.0
    ahead /= max(float(np.linalg.norm(ahead)), EPS)
    middle = pose.p[0, skel.joint_index("lumbar")] + (trunk + HOLD_AHEAD) * ahead
    middle[1] = ground + elbow_height(skel)
    return middle + (hands - hands.mean(axis=0))


def ramp(t: FloatArray, start: float, end: float, length: float) -> FloatArray:
    """(T,) the carry pose's weight at times ``t``: up from ``start`` over ``length``, held,
    down to 0 at ``end`` (minimum-jerk both ways)."""
    rise = minimum_jerk((t - start) / length)
    fall = minimum_jerk((end - t) / length)
    return np.minimum(rise, fall) * ((t >= start - EPS) & (t <= end + EPS))


def carry_walk(skel: Skeleton, frames: Frames, start: float, end: float, ground: float) -> bool:
    """Lead the arms to the carry pose and back over one walk's frames, in place. Whether it
    did (not: too short, already near, or the pose out of the arms' reach)."""
    t = frames.time
    rows = np.flatnonzero((t >= start - EPS) & (t <= end + EPS))
    if rows.size < 3:
        return False
    i = rows[0]
    q0, root, rot = frames.q[i], frames.root_position[i], frames.root_rotation[i]
    targets = carry_targets(skel, q0, root, rot, ground)
    pose = forward(skel, q0[None], root[None], rot[None], with_axes=False)
    hands = np.asarray(site_positions(skel, pose, list(HANDS)))[0]
    if float(np.linalg.norm(hands - targets, axis=1).max()) <= NEAR:
        return False
    # positions only: a hand turned to hold the part overhead cannot keep that turn at the
    # waist (1.3 rad short); the part's axis is the line between the hands (``carry``)
    goals = [Goal(h, position=targets[k]) for k, h in enumerate(HANDS)]
    dofs = sorted({d for h in HANDS for d in _arm_dofs(skel, h)})
    res = solve_ta(skel, goals, q0, dofs=dofs, root_position=root, root_rotation=rot,
                   restarts=RESTARTS, tol=SOLVE_TOL)  # fmt: skip
    if not float(np.max(res.position_error)) <= SOLVE_TOL:
        return False
    delta = np.zeros_like(q0)
    delta[dofs] = res.q[0, dofs] - q0[dofs]
    length = max(MIN_RAMP, PEAK * float(np.abs(delta).max()) / ARM_SPEED)
    if 2.0 * length > end - start:
        return False
    w = ramp(t[rows], start, end, length)
    on = rows[w > 0.0]  # the walk's ends stay as they were, to the bit
    frames.q[on] = skel.clip(frames.q[on] + w[w > 0.0, None] * delta)
    return True


def run(ir: MotionIR, ctx: PassContext) -> MotionIR:
    frames = ir.frames
    if frames is None or not len(frames.time) or ir.skeleton is None:
        return ir
    spans = carries(ir)
    walks = sorted((s.start, s.end) for s in ir.on_track("root") if s.kind == "locomotion")
    for a, b in walks:
        if any(c.start <= a + EPS and c.end >= b - EPS for c in spans):
            carry_walk(ir.skeleton, frames, a, b, ir.ground)
    return ir
