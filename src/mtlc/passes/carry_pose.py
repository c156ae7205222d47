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
manikin's standing elbow height (its neutral pose's, arms hanging) and ``HOLD_AHEAD`` in front
of the trunk (the middle of a part 30 cm deep), the two hands placed about it as they were when
the walk started (the part keeps its width; the hands' turn is left to the IK). The pose's arm
angles (shoulders, elbows, wrists; not the forearm's twist) are solved once, at the walk's
first frame; from the walk's start and before its end minimum-jerk ramps at most ``ARM_SPEED``
fast take the hands there and back on straight lines in the body's frame
(``hands_on_their_path``), so the walk ends with the arms where the reach after it was solved
from (the place starts from there). Where the way takes a forearm or hand into the body's
clearance, or the pose more than ``KEEP_OUT`` into it, the pose is tried higher and further
out (``TRIES``). A walk too short for both ramps, whose part is already near the pose, or with
no pose that passes is left as it was.
"""

from __future__ import annotations

import math

import numpy as np

from mtlc.body import forward, site_positions
from mtlc.body.capsules import body_capsules
from mtlc.body.ik import Goal, solve_ta
from mtlc.body.ik.clearance import penetrations
from mtlc.body.kinematics import quat_to_matrix
from mtlc.body.skeleton import Skeleton
from mtlc.ir.model import FloatArray, Frames, MotionIR
from mtlc.passes.carry import carries
from mtlc.passes.context import PassContext
from mtlc.passes.hold import _arm_dofs
from mtlc.passes.profile import minimum_jerk

HANDS = ("r_hand", "l_hand")
SOLES = ("r_heel", "r_toe", "l_heel", "l_toe")
SIDES = ("r", "l")
# m: how far into the body's clearance (5 mm outside the capsules) the carry may take a forearm
# or hand, deeper than it was: the clearance pass swings the elbow out of that much (the
# access panel's left forearm, 20 mm), a held hand's pose kept
KEEP_OUT = -0.025
HOLD_AHEAD = (
    0.15  # m the hands' mid-point is in front of the trunk: the middle of a part 30 cm deep
)
ARM_SPEED = math.radians(150.0)  # rad/s: the ramps' mean joint speed at most (their peak 280)
PEAK = 1.875  # a minimum-jerk ramp's peak speed over its mean
MIN_RAMP = 0.6  # s: the shortest ramp in or out
TRIES = 4  # carry poses tried, each RAISE higher and AWAY further out than the one before
RAISE = 0.05  # m
AWAY = 0.03  # m
NEAR = 0.08  # m: a part whose hands are this close to the carry pose already stays
PATH_TOL = 0.03  # m: the hands on their way to the carry pose and back within this of their path
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
    did (not: too short, already near, or no carry pose within ``TRIES`` that the arms reach
    and keep clear of the body on the way)."""
    t = frames.time
    rows = np.flatnonzero((t >= start - EPS) & (t <= end + EPS))
    if rows.size < 3:
        return False
    i = rows[0]
    q0, root, rot = frames.q[i], frames.root_position[i], frames.root_rotation[i]
    pose = forward(skel, q0[None], root[None], rot[None], with_axes=False)
    hands = np.asarray(site_positions(skel, pose, list(HANDS)))[0]
    base = carry_targets(skel, q0, root, rot, ground)
    ahead = quat_to_matrix(rot) @ np.array([0.0, 0.0, 1.0])
    ahead[1] = 0.0
    ahead /= max(float(np.linalg.norm(ahead)), EPS)
    for k in range(TRIES):  # higher and further out each time: clear of the hips and thighs
        targets = base + k * (RAISE * np.array([0.0, 1.0, 0.0]) + AWAY * ahead)
        if float(np.linalg.norm(hands - targets, axis=1).max()) <= NEAR:
            return False
        moved = _carried(skel, frames, rows, start, end, (root, rot), hands, targets)
        if moved is not None:
            on, q = moved
            frames.q[on] = q
            return True
    return False


def _carried(
    skel: Skeleton, frames: Frames, rows: np.ndarray, start: float, end: float,
    start_root: tuple[FloatArray, FloatArray], hands: FloatArray, targets: FloatArray,
) -> tuple[np.ndarray, FloatArray] | None:  # fmt: skip
    """The walk's frames that the carry to ``targets`` and back changes, and their poses; None
    where the arms do not reach it, the walk is too short for the ramps, or the way there or
    back takes a forearm or hand into the body's clearance."""
    q0 = frames.q[rows[0]]
    # positions only: a hand turned to hold the part overhead cannot keep that turn at the
    # waist (1.3 rad short); the part's axis is the line between the hands (``carry``)
    goals = [Goal(h, position=targets[k]) for k, h in enumerate(HANDS)]
    dofs = sorted({d for h in HANDS for d in _arm_dofs(skel, h)})
    res = solve_ta(skel, goals, q0, dofs=dofs, root_position=start_root[0],
                   root_rotation=start_root[1], restarts=RESTARTS, tol=SOLVE_TOL)  # fmt: skip
    if not float(np.max(res.position_error)) <= SOLVE_TOL:
        return None
    delta = np.zeros_like(q0)
    delta[dofs] = res.q[0, dofs] - q0[dofs]
    length = max(MIN_RAMP, PEAK * float(np.abs(delta).max()) / ARM_SPEED)
    if 2.0 * length > end - start:
        return None
    w = ramp(frames.time[rows], start, end, length)
    on, w = rows[w > 0.0], w[w > 0.0]  # the walk's ends stay as they were, to the bit
    moved = hands_on_their_path(skel, frames, on, w, start_root, hands, targets, delta, dofs)
    if moved is None:
        return None
    root_on = (frames.root_position[on], frames.root_rotation[on])
    before = penetrations(skel, frames.q[on], root_on, SIDES)
    after = penetrations(skel, moved, root_on, SIDES)
    # on the way an arm stays out of the clearance (the clearance pass, fighting the held
    # hands' rigid part there, left forearms 2-7 mm in the trunk: the avionics unit coming
    # down from overhead); held in the carry pose, ``KEEP_OUT`` deep at most
    allowed = np.where(w < 1.0, 0.0, -KEEP_OUT)
    if any((after[s] > np.maximum(before[s], allowed)).any() for s in SIDES):
        return None  # the way there or back passes an arm by the body: a path planner's
    return on, moved


def hands_on_their_path(
    skel: Skeleton, frames: Frames, rows: np.ndarray, w: FloatArray,
    start_root: tuple[FloatArray, FloatArray], hands: FloatArray, targets: FloatArray,
    delta: FloatArray, dofs: list[int],
) -> FloatArray | None:  # fmt: skip
    """(len(rows), D) poses with both hands ``w`` of the way along straight lines from where
    they were at the walk's start (``hands``) to ``targets``, both in the body's frame (the
    walk's first frame's root, ``start_root``), solved from the joint blend ``w × delta``: blended in joint
    angles alone, the hands went apart from 20 to 58 cm on the way down from overhead and the
    rigid part's re-solve then put one 64 mm into the trunk (avionics unit, female P99). None
    where a frame cannot be solved within ``PATH_TOL``."""
    origin, first = start_root[0], quat_to_matrix(start_root[1])
    local0, local1 = (hands - origin) @ first, (targets - origin) @ first
    rot = np.asarray([quat_to_matrix(r) for r in frames.root_rotation[rows]])
    local = local0[None] + w[:, None, None] * (local1 - local0)[None]
    world = np.einsum("nij,nkj->nki", rot, local) + frames.root_position[rows][:, None, :]
    seed = skel.clip(frames.q[rows] + w[:, None] * delta)
    goals = [Goal(h, position=world[:, k]) for k, h in enumerate(HANDS)]
    res = solve_ta(skel, goals, seed, dofs=dofs, root_position=frames.root_position[rows],
                   root_rotation=frames.root_rotation[rows], restarts=0, tol=SOLVE_TOL)  # fmt: skip
    if not float(np.max(res.position_error)) <= PATH_TOL:
        return None
    return np.asarray(res.q)


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
