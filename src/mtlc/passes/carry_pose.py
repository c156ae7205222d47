"""Pass 5c: a part carried on a walk is held near the body, the trunk upright (issue 19).

A walk keeps the arms as the reach before it left them: the avionics unit, slid out of its rack
at 1.65 m, was carried 4.5 s to the trolley at head height, the panel at the height of its
handle. People carry a load they hold in both hands close to the trunk, elbows bent, the load
near waist height: the load's moment about the lower back and the shoulders' is then smallest
(NIOSH lifting equation's horizontal multiplier, Waters, Putz-Anderson, Garg & Fine 1993,
"Revised NIOSH equation for the design and evaluation of manual lifting tasks", Ergonomics
36(7):749-776: the load's horizontal distance from the ankles' mid-point is its largest factor).
A walk also kept the trunk the lift left: 46 of 140 carried walks on bench/procedures and the
examples went bent more than 10 deg from start to end (11-76 deg) (a wheel carried 4.5 s at 76 deg).

Here, on the dense frames of each walk during which both hands hold a part (one two-handed
part, ``carry.carries``, or a part each: a hatch held by its two edges is not recognised as
one, and is kept as it is between the hands), the arms are led to a carry pose and back: the
hands' mid-point at the manikin's standing elbow height (its neutral pose's, arms hanging) and
``HOLD_AHEAD`` in front of the trunk (the middle of a part 30 cm deep), the two hands placed
about it as they were when the walk started (the part keeps its width; the hands' turn is
left to the IK), and the trunk goes upright (``trunk_offset``: lumbar and thorax to their rest
pose) on the same ramps. The pose's arm angles (shoulders, elbows, wrists; not the forearm's
twist) are solved once, at the walk's first frame on the upright trunk; from the walk's start
and before its end minimum-jerk ramps take the hands there and back on straight lines in the
body's frame from where the trunk alone would take them (``hands_on_their_path``, ``_borne``),
so the walk ends with the trunk and arms where the reach after it was solved from (the place
starts from there). The ramps' joint speed peaks at ``ARM_SPEED``, or up to ``FAST_ARM_SPEED``
on a walk too short for that. Where the way takes a forearm or hand into the body's clearance,
or the pose more than ``KEEP_OUT`` into it, the pose is tried higher and further out
(``TRIES``); where none passes with the trunk upright, the trunk is left as it was and the
arms alone are tried. A walk too short for both ramps, whose part is already near the pose,
or with no pose that passes is left as it was.

A part carried in one hand (``carried_alone``: the grip closed, off any site, the arm with no
segment during the walk) is carried at ``CARRY_ARM`` (upper arm near the trunk, elbow at 90
deg), the trunk upright, on the same ramps (``carry_walk_alone``), in joint angles; kept only
if neither arm goes deeper into the body's clearance (the trunk takes the free arm with it),
else the arm alone, else as it was.

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
from mtlc.body.capsules import body_capsules, capsule_segments, collision_capsules
from mtlc.body.ik import Goal, solve_ta
from mtlc.body.ik.clearance import penetrations
from mtlc.body.kinematics import quat_to_matrix
from mtlc.body.skeleton import Skeleton
from mtlc.geometry.clearance import _into_part, scene_pieces
from mtlc.geometry.distance import MeshIndex
from mtlc.geometry.held import _hand_frames as hand_frames
from mtlc.geometry.held import _placements
from mtlc.ir.model import FloatArray, Frames, MotionIR, Segment
from mtlc.passes.carry import Carry, carries, hold_nothing
from mtlc.passes.context import PassContext
from mtlc.passes.detour import WORDS, capsule_depths, grasped_parts
from mtlc.passes.hold import ARM_HAND, _arm_dofs, carried_postures, closed_at, on_site
from mtlc.passes.profile import minimum_jerk
from mtlc.passes.settle import keep_until_keyed, trunk_offset

HANDS = ("r_hand", "l_hand")
SOLES = ("r_heel", "r_toe", "l_heel", "l_toe")
SIDES = ("r", "l")
# m: how far into the body's clearance (5 mm outside the capsules) the carry may take a forearm
# or hand, deeper than it was: the clearance pass swings the elbow out of that much (the
# access panel's left forearm, 20 mm), a held hand's pose kept
KEEP_OUT = -0.025
DEEPER = 0.002  # m: see ``_kept_clear``
HOLD_AHEAD = (
    0.15  # m the hands' mid-point is in front of the trunk: the middle of a part 30 cm deep
)
ARM_SPEED = math.radians(150.0)  # rad/s: the ramps' peak joint speed at most (mean 80)
# rad/s: on a walk too short for ramps at ARM_SPEED, their peak at most (issue 19: 360)
FAST_ARM_SPEED = math.radians(300.0)
# rad/s: a joint on the hands' straight way at most (``_peak_speed``): two dense frames make an
# output frame's step, 10 deg at 30 fps, under issue 19's 12
PATH_SPEED = math.radians(300.0)
RETIME_MARGIN = 0.05  # the re-timed ramps this much longer than the measured speed asks
PEAK = 1.875  # a minimum-jerk ramp's peak speed over its mean
MIN_RAMP = 0.6  # s: the shortest ramp in or out
TRIES = 4  # carry poses tried, each RAISE higher and AWAY further out than the one before
RAISE = 0.05  # m
AWAY = 0.03  # m
NEAR = 0.08  # m: a part whose hands are this close to the carry pose already stays
MESH_CHUNK = 40  # frames a carried CAD part is measured against the body at once
HOLD_WIDTH = 1e-3  # m: two hands holding apart keep their distance this well (``_width_kept``)
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
PATH_LEVELS = 17  # steps along the carry's way where its frames are seeded from it (``_followed``)
MAX_SWING = 0.15  # rad an arm's solved path may change in one dense frame (9 deg at 60 fps)


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


def carry_walk(
    skel: Skeleton, frames: Frames, start: float, end: float, ground: float,
    meshes: CarriedMeshes | None = None, rigid: bool = True,
) -> bool:  # fmt: skip
    """Lead the arms to the carry pose and back over one walk's frames, in place, the trunk
    upright while they are there (``trunk_offset``) where that passes, else as it was
    (``meshes``: the CAD parts the hands hold; ``rigid``: one two-handed part, which the carry
    pass holds rigid after this, or none (``carry.hold_nothing``); else the hands must keep
    their distance). Whether it did
    (not: too short, already near, or no carry pose within ``TRIES`` that the arms reach and
    keep clear of the body on the way)."""
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
    straighten = trunk_offset(skel, q0)
    for trunk in [straighten, None] if straighten is not None else [None]:
        for k in range(TRIES):  # higher and further out each time: clear of the hips and thighs
            targets = base + k * (RAISE * np.array([0.0, 1.0, 0.0]) + AWAY * ahead)
            if trunk is None and float(np.linalg.norm(hands - targets, axis=1).max()) <= NEAR:
                return False
            moved = _carried(
                skel, frames, rows, (start, end), (root, rot), hands, targets, trunk, meshes,
                rigid,
            )  # fmt: skip
            if moved is not None:
                on, q = moved
                frames.q[on] = q
                return True
    return False


def _carried(
    skel: Skeleton, frames: Frames, rows: np.ndarray, walk: tuple[float, float],
    start_root: tuple[FloatArray, FloatArray], hands: FloatArray, targets: FloatArray,
    trunk: tuple[list[int], FloatArray] | None, meshes: CarriedMeshes | None = None,
    rigid: bool = True,
) -> tuple[np.ndarray, FloatArray] | None:  # fmt: skip
    """The walk's frames that the carry to ``targets`` and back changes, and their poses; None
    where the arms do not reach it, the walk is too short for the ramps, or the way there or
    back takes a forearm or hand into the body's clearance. ``trunk``: its dofs and way to
    upright, on the same ramps (the arms solved on it), or None (left as it is)."""
    q0 = frames.q[rows[0]]
    delta = np.zeros_like(q0)
    if trunk is not None:
        delta[trunk[0]] = trunk[1]
    # positions only: a hand turned to hold the part overhead cannot keep that turn at the
    # waist (1.3 rad short); the part's axis is the line between the hands (``carry``)
    goals = [Goal(h, position=targets[k]) for k, h in enumerate(HANDS)]
    dofs = sorted({d for h in HANDS for d in _arm_dofs(skel, h)})
    res = solve_ta(skel, goals, q0 + delta, dofs=dofs, root_position=start_root[0],
                   root_rotation=start_root[1], restarts=RESTARTS, tol=SOLVE_TOL)  # fmt: skip
    if not float(np.max(res.position_error)) <= SOLVE_TOL:
        return None
    delta[dofs] = res.q[0, dofs] - q0[dofs]
    # with the trunk rising, the hands' ways start from where it takes them, or from where
    # they are: each kept a wheel's or a battery's forearm clear where the other did not
    for borne in (True, False) if trunk is not None else (False,):
        stretch = 1.0
        for _ in range(2):  # the ramps timed from the joints' change, then from the path's speed
            on, w = _ramped(frames, rows, walk, delta, stretch)
            if on is None:
                return None
            moved = hands_on_their_path(
                skel, frames, on, w, start_root, hands, targets, delta, dofs, borne
            )
            if moved is None:
                break
            speed = _peak_speed(frames, on, moved, dofs)
            if speed <= PATH_SPEED:
                if _kept_clear(skel, frames, on, w, moved, meshes) and (
                    rigid or _width_kept(skel, frames, on, moved, hands)
                ):
                    return on, moved
                break
            stretch *= speed / PATH_SPEED * (1.0 + RETIME_MARGIN)
    return None


def _width_kept(
    skel: Skeleton, frames: Frames, on: np.ndarray, moved: FloatArray, hands: FloatArray
) -> bool:
    """Whether the hands stay within ``HOLD_WIDTH`` of their distance at the walk's start on
    every frame: no carry pass holds what two hands hold apart (two handles, a hatch's two
    edges) rigid after this one, and a part held by two handles 89 cm apart was stretched
    2 mm (female P5)."""
    now = _hands_at(skel, frames, on, moved)
    width = np.linalg.norm(now[:, 0] - now[:, 1], axis=1)
    return bool(np.abs(width - np.linalg.norm(hands[0] - hands[1])).max() <= HOLD_WIDTH)


def _peak_speed(frames: Frames, on: np.ndarray, moved: FloatArray, dofs: list[int]) -> float:
    """rad/s: the fastest of the ``dofs`` over the rows ``on`` posed ``moved`` (and the frames
    either side, as they are). The hands' straight way is not the joints' straight way: timed
    from the joints' change alone, an arm bringing the avionics unit down moved at 400-440
    deg/s (male P10: 13.7 deg in an output frame)."""
    lo, hi = max(int(on[0]) - 1, 0), min(int(on[-1]) + 1, len(frames.time) - 1)
    q = np.vstack([frames.q[lo, dofs], moved[:, dofs], frames.q[hi, dofs]])
    t = np.r_[frames.time[lo], frames.time[on], frames.time[hi]]
    dt = np.maximum(np.diff(t), EPS)
    return float((np.abs(np.diff(q, axis=0)) / dt[:, None]).max(initial=0.0))


def _ramped(
    frames: Frames, rows: np.ndarray, walk: tuple[float, float], delta: FloatArray,
    stretch: float = 1.0,
) -> tuple[np.ndarray, FloatArray] | tuple[None, None]:  # fmt: skip
    """The walk's rows a ramp of ``delta`` in and out changes and their weights; (None, None)
    where the walk is too short for both ramps at ``FAST_ARM_SPEED``. ``stretch``: the ramps
    that long again (or more) for a way whose joints move faster than ``delta``'s share."""
    start, end = walk
    way = PEAK * float(np.abs(delta).max()) * stretch
    length = max(MIN_RAMP, way / ARM_SPEED)
    if 2.0 * length > end - start:  # a short walk: faster ramps, meeting in its middle
        length = 0.5 * (end - start)
        if length < max(MIN_RAMP, way / FAST_ARM_SPEED) - EPS:
            return None, None
    w = ramp(frames.time[rows], start, end, length)
    return rows[w > 0.0], w[w > 0.0]  # the walk's ends stay as they were, to the bit


def _kept_clear(
    skel: Skeleton, frames: Frames, on: np.ndarray, w: FloatArray, moved: FloatArray,
    meshes: CarriedMeshes | None,
) -> bool:  # fmt: skip
    """Whether the poses ``moved`` of the rows ``on`` keep both arms out of the body's
    clearance on the way (``w`` < 1) and no more than ``KEEP_OUT`` into it in the carry pose,
    or no deeper than they were; and the body out of the CAD parts the hands hold
    (``meshes``), or no deeper."""
    root_on = (frames.root_position[on], frames.root_rotation[on])
    before = penetrations(skel, frames.q[on], root_on, SIDES)
    after = penetrations(skel, moved, root_on, SIDES)
    # on the way an arm stays out of the clearance (the clearance pass, fighting the held
    # hands' rigid part there, left forearms 2-7 mm in the trunk: the avionics unit coming
    # down from overhead); held in the carry pose, ``KEEP_OUT`` deep at most
    allowed = np.where(w < 1.0, 0.0, -KEEP_OUT)
    # a frame whose arm was inside already (the overhead hatch's right forearm, 99 mm as the
    # walk starts; the clearance pass takes it out) may go ``DEEPER`` more on the way out
    if any(
        (after[s] > np.maximum(before[s] + np.where(before[s] > 0.0, DEEPER, 0.0), allowed)).any()
        for s in SIDES
    ):
        return False
    return meshes is None or meshes.kept_out(frames, on, moved)


def carry_walk_alone(
    skel: Skeleton, frames: Frames, walk: tuple[float, float], tracks: list[str],
    meshes: CarriedMeshes | None = None,
) -> bool:  # fmt: skip
    """Lead each arm of ``tracks`` (its hand carries a part of its own) to ``CARRY_ARM`` and
    the trunk upright over the walk, and back before it ends, in place; the arms alone where
    the trunk's way does not pass. Whether it did (not: too short, already near, or every way
    takes an arm deeper into the body)."""
    t = frames.time
    rows = np.flatnonzero((t >= walk[0] - EPS) & (t <= walk[1] + EPS))
    if rows.size < 3:
        return False
    q0 = frames.q[rows[0]]
    arm = np.zeros_like(q0)
    for track in tracks:
        dofs, angles = carry_arm(skel, track)
        arm[dofs] = angles - q0[dofs]
    trunk = trunk_offset(skel, q0)
    tries = [arm]
    if trunk is not None:
        both = arm.copy()
        both[trunk[0]] = trunk[1]
        tries.insert(0, both)
    # the trunk takes the free arm with it: its hand met a swinging thigh as the trunk bent
    # again at the walk's end (the rack's spare, male P50: 53 mm)
    for delta in tries:
        if float(np.abs(delta).max()) <= POSE_NEAR:
            continue
        on, w = _ramped(frames, rows, walk, delta)
        if on is None:
            continue
        moved = skel.clip(frames.q[on] + w[:, None] * delta[None])
        if _kept_clear(skel, frames, on, w, moved, meshes):
            frames.q[on] = moved
            return True
    return False


def hands_on_their_path(
    skel: Skeleton, frames: Frames, rows: np.ndarray, w: FloatArray,
    start_root: tuple[FloatArray, FloatArray], hands: FloatArray, targets: FloatArray,
    delta: FloatArray, dofs: list[int], borne: bool = False,
) -> FloatArray | None:  # fmt: skip
    """(len(rows), D) poses with both hands ``w`` of the way along straight lines from where
    they were at the walk's start (``hands``; ``borne``: where the trunk alone takes them,
    ``_borne``) to ``targets``, both in the body's frame (the walk's first frame's root,
    ``start_root``), solved from the joint blend ``w × delta``:
    blended in joint angles alone, the hands went apart from 20 to 58 cm on the way down from
    overhead and the rigid part's re-solve then put one 64 mm into the trunk (avionics unit,
    female P99). Where that seed takes a frame onto another branch of the arm, the frames are
    seeded from the way followed in ``PATH_LEVELS`` steps (``_followed``). None where a frame
    cannot be solved within ``PATH_TOL`` or an arm swings (``MAX_SWING``)."""
    origin, first = start_root[0], quat_to_matrix(start_root[1])
    local1 = (targets - origin) @ first
    if borne:
        local0 = _borne(skel, frames.q[rows[0]], start_root, hands, delta, dofs, w)
    else:
        local0 = np.broadcast_to((hands - origin) @ first, (len(w), *hands.shape))
    rot = quat_to_matrix(frames.root_rotation[rows])  # all rows at once: row by row's numbers
    local = local0 + w[:, None, None] * (local1[None] - local0)
    world = np.einsum("nij,nkj->nki", rot, local) + frames.root_position[rows][:, None, :]
    seed = skel.clip(frames.q[rows] + w[:, None] * delta)
    q = _path_solved(skel, frames, rows, world, seed, dofs)
    if q is None:
        way = _followed(skel, frames.q[rows[0]], start_root, local1, hands, delta, dofs, borne)
        for k, d in enumerate(dofs):
            seed[:, d] = np.interp(w, np.linspace(0.0, 1.0, PATH_LEVELS), way[:, k])
        q = _path_solved(skel, frames, rows, world, seed, dofs)
    return q


def _path_solved(
    skel: Skeleton, frames: Frames, rows: np.ndarray, world: FloatArray, seed: FloatArray,
    dofs: list[int],
) -> FloatArray | None:  # fmt: skip
    """Both hands onto ``world`` (len(rows), 2, 3) on each row, from ``seed``; None where a
    row is more than ``PATH_TOL`` off or an arm swings more than ``MAX_SWING`` a frame."""
    goals = [Goal(h, position=world[:, k]) for k, h in enumerate(HANDS)]
    res = solve_ta(skel, goals, seed, dofs=dofs, root_position=frames.root_position[rows],
                   root_rotation=frames.root_rotation[rows], restarts=0, tol=SOLVE_TOL)  # fmt: skip
    if not float(np.max(res.position_error)) <= PATH_TOL:
        return None
    q = skel.clip(np.asarray(res.q))  # the solver's steps end up to 0.03 deg past a limit
    # with the frames either side: a frame's solve that changed branch swung a shoulder's
    # abduction 87 deg in one dense frame (the avionics unit, female P50, trunk straightened)
    lo, hi = max(int(rows[0]) - 1, 0), min(int(rows[-1]) + 1, len(frames.time) - 1)
    way = np.vstack([frames.q[lo, dofs], q[:, dofs], frames.q[hi, dofs]])
    if float(np.abs(np.diff(way, axis=0)).max(initial=0.0)) > MAX_SWING:
        return None
    return q


def _borne(
    skel: Skeleton, q0: FloatArray, start_root: tuple[FloatArray, FloatArray],
    hands: FloatArray, delta: FloatArray, dofs: list[int], w: FloatArray,
) -> FloatArray:  # fmt: skip
    """(len(w), 2, 3) where the hands would be, in the body's frame at the walk's start, with
    the trunk ``w`` of its way (``delta`` off the arm ``dofs``) and the arms' angles as they
    were: the ends the carry's straight ways start from. From the hands where the walk found
    them, a trunk coming up from a 45 deg lean left them out of the arms' reach on the way
    (a 14 kg battery, female P10: 141 mm)."""
    origin, first = start_root[0], quat_to_matrix(start_root[1])
    trunk = delta.copy()
    trunk[dofs] = 0.0
    if not trunk.any():
        return np.broadcast_to((hands - origin) @ first, (len(w), *hands.shape))
    q = skel.clip(q0[None] + w[:, None] * trunk[None])
    n = len(w)
    pose = forward(skel, q, np.repeat(origin[None], n, axis=0),
                   np.repeat(np.asarray(start_root[1])[None], n, axis=0), with_axes=False)  # fmt: skip
    return (np.asarray(site_positions(skel, pose, list(HANDS))) - origin) @ first


def _followed(
    skel: Skeleton, q0: FloatArray, start_root: tuple[FloatArray, FloatArray],
    local1: FloatArray, hands: FloatArray, delta: FloatArray, dofs: list[int], borne: bool,
) -> FloatArray:  # fmt: skip
    """(PATH_LEVELS, len(dofs)) the arms' angles with the hands at ``PATH_LEVELS`` even shares
    of their way to ``local1`` (in the body's frame; from ``hands``, or ``_borne``), each solved from the
    one before (the trunk at the same share of ``delta``). The hands' way and the trunk are
    the same in the body's frame on every frame of the walk, so one pass along it serves
    them all: the arms stay on the branch they start on."""
    origin, first = start_root[0], quat_to_matrix(start_root[1])
    shares = np.linspace(0.0, 1.0, PATH_LEVELS)
    if borne:
        local0 = _borne(skel, q0, start_root, hands, delta, dofs, shares)
    else:
        local0 = np.broadcast_to((hands - origin) @ first, (PATH_LEVELS, *hands.shape))
    out = np.empty((PATH_LEVELS, len(dofs)))
    arm = q0[dofs]
    for k, share in enumerate(shares):
        seed = skel.clip(q0 + share * delta)
        seed[dofs] = arm
        world = (local0[k] + share * (local1 - local0[k])) @ first.T + origin
        goals = [Goal(h, position=world[j]) for j, h in enumerate(HANDS)]
        res = solve_ta(skel, goals, seed, dofs=dofs, root_position=origin,
                       root_rotation=start_root[1], restarts=0, tol=SOLVE_TOL)  # fmt: skip
        arm = np.asarray(res.q).reshape(-1)[dofs]
        out[k] = arm
    return out


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

    lo = max(int(rows[0]) - 1, 0)
    dt = np.maximum(np.diff(np.r_[t[lo], t[rows]]), EPS)[:, None]
    # the arms' own speed over the posture, as the frames came: the most a way may add up to
    came = np.abs(np.diff(np.vstack([frames.q[lo, dofs], frames.q[rows][:, dofs]]), axis=0)) / dt

    def in_time(moved: FloatArray) -> bool:
        """No arm joint faster than ``PATH_SPEED`` (or than it came in) over the posture, from
        the frame before it (the pose is held after it): a box picked off the floor, brought
        to the carry pose over a 1.2 s stand, swung the shoulder 516 deg/s (generated
        procedure 24002, female P1: 17 deg in an output frame)."""
        q = np.vstack([frames.q[lo, dofs], moved[:, dofs]])
        speed = np.abs(np.diff(q, axis=0)) / dt
        return bool((speed <= np.maximum(came, PATH_SPEED)).all())

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
        if moved is None or not clear(moved, 0.0) or not in_time(moved):
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
        a = span[0] + late * (span[1] - span[0])
        # no faster than ``FAST_ARM_SPEED`` at the ramp's peak: past the posture's end if
        # it is short (the arm goes on into what follows, ``keep_until_keyed``)
        rise = (a, max(span[1], a + PEAK * float(np.abs(change).max()) / FAST_ARM_SPEED))
        ramp = minimum_jerk(np.clip((t[rows] - rise[0]) / (rise[1] - rise[0]), 0.0, 1.0))
        moved = frames.q[rows].copy()
        moved[:, dofs] += ramp[:, None] * change[None]
        if not clear(moved, 0.0) or not in_time(moved):
            return False
        if rise[1] > span[1] + EPS:  # the pose itself, which the ramp reaches after the posture
            held = frames.q[rows].copy()
            held[:, dofs] += change[None]
            if not clear(held, 0.0):
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


class CarriedMeshes:
    """The model parts (``geometry.held``: a CAD node a hand grasps) the hands hold on a walk,
    to keep the body out of them: a carry pose knows nothing of a part's shape, and the
    access panel's CAD part, brought in to the waist, went 12 mm into the pelvis and a forearm
    13 mm into it (MT0515, female P5). The part is rigid in the hand that carries it over the
    walk (it closed first; the right on a tie), where it was at the walk's start."""

    def __init__(self, ir: MotionIR, walk: tuple[float, float]) -> None:
        self.skel = ir.skeleton
        self.ir = ir
        self.parts: list[tuple[MeshIndex, str, FloatArray]] = []  # index, carrier, anchor
        self.was: FloatArray | None = None  # the depth of the frames as they were (NaN: not yet)
        models = [m for m in ir.geometry if len(m.faces)]
        grasped = grasped_parts(ir, models) if models else []
        if not grasped:
            return
        frames = ir.frames
        t = frames.time
        first = int(np.searchsorted(t, walk[0] - EPS))
        pose = forward(self.skel, frames.q[: first + 1], frames.root_position[: first + 1],
                       frames.root_rotation[: first + 1], with_axes=False)  # fmt: skip
        hands = {side: hand_frames(ir, pose, side) for side in SIDES}
        _, _, pieces = scene_pieces(models, grasped)
        holding: set[str] = set()  # the hands that hold them: not measured against them
        for part, index in pieces:
            placement, kept = _placements(t[: first + 1], hands, part.holds)
            over = [h for h in kept if h.start <= walk[0] + EPS and h.end >= walk[1] - EPS]
            if not over:
                continue
            carrier = min(over, key=lambda h: (h.start, SIDES.index(h.side))).side
            anchor = np.linalg.inv(hands[carrier][first]) @ placement[first]
            holding |= {h.side for h in over}
            self.parts.append((index, carrier, anchor))
        names = {f"{WORDS[s]} hand" for s in holding}
        self.caps = tuple(c for c in collision_capsules(self.skel) if c.name not in names)

    def deepest(self, frames: Frames, rows: np.ndarray, q: FloatArray) -> FloatArray:
        """(len(rows),) how deep the body (not the hands that hold them) goes into the parts
        with poses ``q`` on ``rows`` (m, positive inside; -inf: no part)."""
        out = np.full(len(rows), -np.inf)
        if not self.parts:
            return out
        pose = forward(self.skel, q, frames.root_position[rows], frames.root_rotation[rows],
                       with_axes=False)  # fmt: skip
        a, b, radii = capsule_segments(self.skel, pose, self.caps)
        for index, carrier, anchor in self.parts:
            place = hand_frames(self.ir, pose, carrier) @ anchor
            depth = capsule_depths(index, _into_part(a, place), _into_part(b, place), radii)
            out = np.maximum(out, depth.max(axis=1))
        return out

    def kept_out(self, frames: Frames, rows: np.ndarray, moved: FloatArray) -> bool:
        """Whether ``moved`` takes the body no deeper into the parts than it was (or in). The
        frames as they were are measured once a walk (``self.was``): measured again for each
        pose tried, they were half of the pass's time on the CAD access panel."""
        if not self.parts:
            return True
        if self.was is None:
            self.was = np.full(len(frames.time), np.nan)
        new = rows[np.isnan(self.was[rows])]
        if new.size:
            self.was[new] = self.deepest(frames, new, frames.q[new])
        # the middle first (the carry pose, where the part is nearest the body), in chunks: a
        # pose that fails is known after a few of them
        order = np.argsort(np.abs(np.arange(len(rows)) - 0.5 * (len(rows) - 1)), kind="stable")
        for chunk in np.array_split(order, max(1, len(rows) // MESH_CHUNK)):
            after = self.deepest(frames, rows[chunk], moved[chunk])
            if (after > np.maximum(self.was[rows[chunk]], 0.0)).any():
                return False
        return True


def carried_alone(ir: MotionIR, start: float, end: float) -> list[str]:
    """The arm tracks whose hand carries a part of its own over the walk ``start``..``end``:
    its grip closed at the start, not on a site, no segment of the arm during the walk."""
    held = on_site(ir, np.array([start + EPS]))
    out = []
    for track, hand in ARM_HAND.items():
        grips = sorted((s for s in ir.on_track(hand) if s.kind == "grip"), key=lambda s: s.start)
        busy = any(s.start < end - EPS and s.end > start + EPS for s in ir.on_track(track))
        if not busy and closed_at(grips, start + EPS) and not bool(held[hand][0]):
            out.append(track)
    return out


def run(ir: MotionIR, ctx: PassContext) -> MotionIR:
    frames = ir.frames
    skel = ir.skeleton
    if frames is None or not len(frames.time) or skel is None:
        return ir
    carry_postures(ir, frames)
    spans = carries(ir)
    walks = sorted((s.start, s.end) for s in ir.on_track("root") if s.kind == "locomotion")
    for a, b in walks:
        tracks = carried_alone(ir, a, b)
        # both hands closed: one part, or two kept as they are to each other (a hatch held by
        # its two edges is not a two-handed part: carried apart, the arms would squeeze it)
        rigid = any(c.start <= a + EPS and c.end >= b - EPS for c in spans)
        # hands closed where they fell short of a part hold nothing: no distance to keep
        # between them (the avionics unit out of the smaller manikins' reach was carried at
        # 1.65 m, the trunk bent 28-50 deg, because two hands apart must keep theirs to 1 mm)
        rigid |= hold_nothing(ir, a, b)
        alone = tracks and not any(c.start < b - EPS and c.end > a + EPS for c in spans)
        if not (rigid or alone):
            continue
        meshes = CarriedMeshes(ir, (a, b)) if ir.geometry else None
        if rigid or len(tracks) == 2:
            carry_walk(skel, frames, a, b, ir.ground, meshes, rigid)
        else:
            carry_walk_alone(skel, frames, (a, b), tracks, meshes)
    return ir
