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

Through a posture (``carry_posture``, the posture analogue): a hand that carries its part
through a squat, kneel, stand or bend (``hold.carried_postures``) and has no goal of its own
kept its arm's angles, so a box picked off the floor with the shoulder flexed 110-120 deg ended
the stand above the shoulder (male P50 hand 1.57 m, shoulder 1.29 m). Over the posture the arm
now goes on a minimum-jerk ramp to ``CARRY_ARM`` (upper arm near the trunk, elbow at 90 deg,
the part in front of the body at forearm height); for two hands on one part both arms go there
and are solved to keep the part's width (the carry pass then holds it rigid). The pose stays
until the arm's next segment and is let go of over it (``settle.keep_until_keyed``). Where the
pose would take a forearm or hand into the body (``KEEP_OUT``), the posture is left as it was.
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
from mtlc.ir.model import FloatArray, Frames, MotionIR, Segment
from mtlc.passes.carry import Carry, carries
from mtlc.passes.context import PassContext
from mtlc.passes.hold import ARM_HAND, _arm_dofs, carried_postures
from mtlc.passes.profile import minimum_jerk
from mtlc.passes.settle import keep_until_keyed

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
# deg: the arm carrying a part through a posture, the rest of the arm (clavicle, abduction) at
# its comfort pose: upper arm 15 deg forward of the trunk, turned 20 deg in, elbow at 90 deg,
# wrist straight: the hand ~20 cm above the elbow's standing height, 30-40 cm in front of the
# lumbar joint and 10-12 cm off the mid-line (female P5 to male P95)
CARRY_ARM = {"shoulder_flex": 15.0, "shoulder_rot": 20.0, "elbow_flex": 90.0,
             "wrist_flex": 0.0, "wrist_dev": 0.0}  # fmt: skip
# shares of the posture after which the arm starts in, tried in turn: rising from a squat, an arm
# brought in from the start swept the hand through the thighs while they were still level
# (84 mm deep, male P50); from halfway it clears them
LATE = (0.0, 0.25, 0.4, 0.5, 0.6)
POSE_NEAR = math.radians(5.0)
RISE_MIN = 0.05  # m the shoulders rise or fall over a posture to set the part's progress
MAX_SWING = 0.15  # rad an arm's solved path may change in one dense frame (9 deg at 60 fps)  # rad: an arm this close to the carry pose already stays


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


def carry_arm(skel: Skeleton, track: str) -> tuple[list[int], FloatArray]:
    """(dofs, angles) of the arm ``track`` in the carry pose (``CARRY_ARM``; the rest of the
    arm at its comfort pose; the forearm's twist, a `turn`'s, not part of it)."""
    dofs = _arm_dofs(skel, ARM_HAND[track])
    rest = np.asarray(skel.q_comfort, dtype=float)
    angles = np.array([
        math.radians(CARRY_ARM[n[2:]]) if n[2:] in CARRY_ARM else rest[d]
        for d in dofs for n in [skel.dof_names[d]]
    ])  # fmt: skip
    return dofs, np.clip(angles, skel.lower[dofs], skel.upper[dofs])


def _free_of_own_goals(ir: MotionIR, track: str, posture: Segment) -> bool:
    return not any(
        s.start < posture.end - EPS and s.end > posture.start + EPS for s in ir.on_track(track)
    )


def _hands_at(skel: Skeleton, frames: Frames, rows: np.ndarray, q: FloatArray) -> FloatArray:
    """(len(rows), 2, 3) the right and left hands' sites with poses ``q`` on ``rows``' roots."""
    pose = forward(skel, q, frames.root_position[rows], frames.root_rotation[rows],
                   with_axes=False)  # fmt: skip
    return np.asarray(site_positions(skel, pose, list(HANDS)))


def carry_goal(
    skel: Skeleton, frames: Frames, rows: np.ndarray, tracks: list[str], rigid: bool,
    ground: float,
) -> tuple[FloatArray, FloatArray]:  # fmt: skip
    """(the posture's last pose with the arms of ``tracks`` in the carry pose, where their
    hands go: (2, 3)). One hand: where ``CARRY_ARM`` puts it. Two hands on one part: the
    walk's carry point (``carry_targets``: the hands' mid-point at standing elbow height in
    front of the trunk), the hands placed about it as at the posture's start (the part keeps
    its width; the carry pass then holds it rigid), and the walk after finds the part there."""
    last = rows[-1:]
    pose = frames.q[last[0]].copy()
    for track in tracks:
        arm, angles = carry_arm(skel, track)
        pose[arm] = angles
    targets = _hands_at(skel, frames, last, pose[None])[0]
    if rigid:
        start = _hands_at(skel, frames, rows[:1], frames.q[rows[:1]])[0]
        root, rotation = frames.root_position[last[0]], frames.root_rotation[last[0]]
        middle = carry_targets(skel, pose, root, rotation, ground).mean(axis=0)
        targets = middle + (start - start.mean(axis=0))
    return pose, targets


def shoulders_rise(skel: Skeleton, frames: Frames, rows: np.ndarray) -> FloatArray:
    """(len(rows),) how far the shoulders' mid-point has come from its height at the first
    row to its height at the last, 0 to 1, never going back: the part's progress. On a clock
    of its own (minimum-jerk over the posture), the part lagged the rising body and the arms
    could not keep the hands on its line (71 mm short, female P5)."""
    pose = forward(skel, frames.q[rows], frames.root_position[rows],
                   frames.root_rotation[rows], with_axes=False)  # fmt: skip
    joints = [skel.joint_index(f"{side}_shoulder") for side in SIDES]
    height = pose.p[:, joints, 1].mean(axis=1)
    change = height[-1] - height[0]
    if abs(change) < RISE_MIN:  # a bend that does not raise the body: the posture's own clock
        t = frames.time[rows]
        return minimum_jerk((t - t[0]) / max(t[-1] - t[0], EPS))
    return np.clip(np.maximum.accumulate((height - height[0]) / change), 0.0, 1.0)


def _hands_straight(
    skel: Skeleton, frames: Frames, rows: np.ndarray, w: FloatArray, seed: FloatArray,
    tracks: list[str], targets: FloatArray,
) -> FloatArray | None:  # fmt: skip
    """(len(rows), D) poses whose hands of ``tracks`` are ``w`` of the way along straight lines
    in the world from where they are at the posture's start to ``targets``, solved from
    ``seed``: the part rises in front of the knees. In joint angles alone the arms keep their
    angles to the trunk, and a trunk coming up from 60 deg swings them back into the rising
    thighs (the clearance pass then squeezed a crate held in both hands by 107 mm, male P50).
    None where a frame is not solved within ``PATH_TOL`` or an arm swings (``MAX_SWING``)."""
    sides = [HANDS.index(ARM_HAND[track]) for track in tracks]
    start = _hands_at(skel, frames, rows[:1], frames.q[rows[:1]])[0]
    world = start[None] + w[:, None, None] * (targets - start)[None]
    goals = [Goal(HANDS[k], position=world[:, k]) for k in sides]
    dofs = sorted({d for track in tracks for d in _arm_dofs(skel, ARM_HAND[track])})
    res = solve_ta(skel, goals, seed, dofs=dofs, root_position=frames.root_position[rows],
                   root_rotation=frames.root_rotation[rows], restarts=0, tol=SOLVE_TOL)  # fmt: skip
    q = np.asarray(res.q)
    if not float(np.max(res.position_error)) <= PATH_TOL:
        return None
    if float(np.abs(np.diff(q[:, dofs], axis=0)).max(initial=0.0)) > MAX_SWING:
        return None
    return q


def carry_posture(
    ir: MotionIR, frames: Frames, posture: Segment, tracks: list[str], rigid: bool
) -> bool:
    """Lead the arms of ``tracks`` (their hands carry a part through ``posture``) to the carry
    pose over the posture, in place (``rigid``: both hold one part, which keeps its width).
    Whether it did (not: already near, or every way tried takes an arm into the body).

    First the hands on straight lines in the world (``_hands_straight``); where that fails,
    the arms' angles on a minimum-jerk ramp, from the posture's start or later (``LATE``)."""
    skel = ir.skeleton
    t = frames.time
    rows = np.flatnonzero((t >= posture.start - EPS) & (t <= posture.end + EPS))
    if rows.size < 2:
        return False
    last = int(rows[-1])
    pose, targets = carry_goal(skel, frames, rows, tracks, rigid, ir.ground)
    dofs = sorted({d for track in tracks for d in _arm_dofs(skel, ARM_HAND[track])})
    offset = pose[dofs] - frames.q[last, dofs]
    if float(np.abs(offset).max()) <= POSE_NEAR:
        return False
    root = (frames.root_position[rows], frames.root_rotation[rows])
    sides = tuple(track[0] for track in tracks)
    before = penetrations(skel, frames.q[rows], root, sides)

    def clear(moved: FloatArray, deep: float) -> bool:
        after = penetrations(skel, moved, root, sides)
        return all((after[s] <= np.maximum(before[s], deep)).all() for s in sides)

    span = (posture.start, posture.end)
    w = shoulders_rise(skel, frames, rows)
    seed = frames.q[rows].copy()
    seed[:, dofs] += w[:, None] * offset[None]
    ahead = quat_to_matrix(frames.root_rotation[last]) @ np.array([0.0, 0.0, 1.0])
    ahead[1] = 0.0
    ahead /= max(float(np.linalg.norm(ahead)), EPS)

    def straight(k: int) -> bool:
        """The hands on straight lines to the carry point ``k`` tries higher and further out."""
        lifted = targets + k * (RAISE * np.array([0.0, 1.0, 0.0]) + AWAY * ahead)
        moved = _hands_straight(skel, frames, rows, w, skel.clip(seed), tracks, lifted)
        if moved is None or not clear(moved, 0.0):
            return False
        frames.q[rows[:-1]] = moved[:-1]
        at = float(t[last])  # the posture's last frame, on or just before its end
        keep_until_keyed(skel, ir, frames, dofs, moved[-1, dofs] - frames.q[last, dofs], (at, at))
        return True

    def angles(late: float) -> bool:
        """The arms' angles ramped to the carry pose from ``late`` of the posture on."""
        end = _end_pose(skel, frames, last, pose, dofs, targets) if rigid else pose
        if end is None:
            return False
        change = end[dofs] - frames.q[last, dofs]
        rise = (span[0] + late * (span[1] - span[0]), span[1])
        ramp = minimum_jerk(np.clip((t[rows] - rise[0]) / (rise[1] - rise[0]), 0.0, 1.0))
        moved = frames.q[rows].copy()
        moved[:, dofs] += ramp[:, None] * change[None]
        if not clear(moved, 0.0):
            return False
        keep_until_keyed(skel, ir, frames, dofs, change, rise)
        return True

    # the natural carry pose first, by either way; then the higher ones
    return (
        straight(0)
        or any(angles(late) for late in LATE)
        or any(straight(k) for k in range(1, TRIES))
    )


def _end_pose(
    skel: Skeleton, frames: Frames, last: int, pose: FloatArray, dofs: list[int],
    targets: FloatArray,
) -> FloatArray | None:  # fmt: skip
    """``pose`` with both arms solved onto ``targets`` (2, 3) at row ``last``: the two-handed
    part's width kept. None where the arms do not reach them."""
    goals = [Goal(h, position=targets[k]) for k, h in enumerate(HANDS)]
    res = solve_ta(skel, goals, pose, dofs=dofs, root_position=frames.root_position[last],
                   root_rotation=frames.root_rotation[last], restarts=0, tol=SOLVE_TOL)  # fmt: skip
    if not float(np.max(res.position_error)) <= SOLVE_TOL:
        return None
    return np.asarray(res.q).reshape(-1)


def carry_postures(ir: MotionIR, frames: Frames) -> None:
    """The carry pose through every posture a hand carries its part through on its own (no
    goal of its arm during it); both arms together where they hold one part (``carries``)."""
    spans = carries(ir)
    by_posture: dict[int, tuple[Segment, list[str]]] = {}
    for track, postures in carried_postures(ir).items():
        for p in postures:
            if _free_of_own_goals(ir, track, p):
                by_posture.setdefault(id(p), (p, []))[1].append(track)
    for p, tracks in sorted(by_posture.values(), key=lambda item: item[0].start):
        rigid = len(tracks) == 2 and _one_part(spans, p)
        if len(tracks) == 2 and not rigid:
            for track in tracks:  # two parts, one in each hand
                carry_posture(ir, frames, p, [track], False)
        else:
            carry_posture(ir, frames, p, tracks, rigid)


def _one_part(spans: list[Carry], posture: Segment) -> bool:
    return any(c.start <= posture.start + EPS and c.end >= posture.end - EPS for c in spans)


def run(ir: MotionIR, ctx: PassContext) -> MotionIR:
    frames = ir.frames
    if frames is None or not len(frames.time) or ir.skeleton is None:
        return ir
    carry_postures(ir, frames)
    spans = carries(ir)
    walks = sorted((s.start, s.end) for s in ir.on_track("root") if s.kind == "locomotion")
    for a, b in walks:
        if any(c.start <= a + EPS and c.end >= b - EPS for c in spans):
            carry_walk(ir.skeleton, frames, a, b, ir.ground)
    return ir
