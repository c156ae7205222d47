"""Pass 7b: hands and forearms kept out of the trunk and the thighs (issues 18 and 19).

The reach solvers place the hand; the arm's redundant dof (the elbow's swivel about the line
from shoulder to wrist) falls where the solver's comfort pull leaves it, and the posture and
balance passes then move the trunk and thighs under the arm. A squat to a valve 20 cm up put
the forearm through the thigh for every manikin; two hands setting a panel down on a bench at
the hip put a 5th-percentile woman's forearm 79 mm into her trunk. Here, on the final dense
frames, every frame where a forearm or hand comes within its clearance of a capsule is
re-solved by ``mtlc.body.ik.clearance.keep_clear``: the body's volume is a constraint of that
arm's IK, the hand's pose is kept where the hand has a goal, and the correction is what the
constraint needs, no more.

Where the hand is on a site, holds a part, or arrives at a goal (``pinned_weights``), its
pose keeps a weight ``PINNED`` against the clearance: only the elbow swings out, the goal is
kept. Elsewhere (a free hand between goals, at rest) the weight is ``FREE`` and the hand may
move out too. The weight changes over ``RAMP`` seconds so the correction does not jump.
A row the first solve leaves inside is solved again with the clearance weighing ``FIRM``
(``keep_clear``'s ``firm``: the hand's orientation yields sooner, its site does not), kept
where a held hand stays put and no dof swings. What the arm cannot clear is measured and
reported by verify (MT0514; the definition: docs/metrics.md, "Hands inside the body").

It runs after smoothing and the two-handed carry (``carry``), on the frames ``sample`` turns
into the output: nothing after it moves the arms.
"""

from __future__ import annotations

import math

import numpy as np

from mtlc.body.ik import Goal, prepare, solve_ta
from mtlc.body.ik.clearance import (
    arm_dofs,
    keep_clear,
    penetration,
    penetration_dofs,
    penetrations,
    swivel_clearance,
    swiveled,
)
from mtlc.body.kinematics import bits_differ, forward, site_positions, site_rotation
from mtlc.body.skeleton import Skeleton
from mtlc.ir.model import FloatArray, MotionIR, runs_of
from mtlc.passes.context import FramesPosed, PassContext
from mtlc.passes.hold import carried_postures
from mtlc.passes.joint_speed import speed_limited, worse_runs_undone

PINNED = 30.0  # weight of the hand's pose where it has a goal (per metre of the clearance)
FREE = 0.3  # ...and where it is free
RAMP = 0.2  # s over which the weight changes between the two
GOAL_LEAD = 0.15  # s before a reach's end the hand counts as arriving at its goal
ARM_TRACK = {"r": "r_arm", "l": "l_arm"}
HAND_TRACK = {"r": "r_hand", "l": "l_hand"}
EPS = 1e-9
MAX_SWING = 0.6  # rad a corrected dof may move between two dense frames, if the motion did not
FIRM = 30.0  # the clearance's weight where the first solve leaves an arm inside (keep_clear)
SWING_SMOOTH = 6  # dense frames each side a correction that swings is averaged over
# rad/s: the fastest a correction turns a free arm's joint (``joint_speed.speed_limited``);
# issue 19 allows 360 deg/s
CORRECTED_JOINT_SPEED = math.radians(330.0)
# s: a frame the solve leaves inside takes its neighbours' correction from cleared frames this
# close on either side (a gap of a few frames); the local solve, frame by frame, gets stuck
# where the arm is deepest and leaves a one-frame spike between two corrected frames
RESEED_REACH = 0.1
LEFT_DEPTH = 5e-3  # m: a solved frame still this deep inside is left inside (reseeded)
KEPT_HAND = 1.0  # weight from which the hand's pose is kept (``keep_clear``'s ``KEPT``)
RESEED_HAND_TOL = 5e-4  # m a kept hand may move in it (``keep_clear``'s FIRM_HAND_TOL)
RESEED_ROUNDS = 3  # ...and solved again from its neighbours at most this many times
# rad a reseeded frame's dof may end from its neighbours' poses, interpolated: more is a new
# spike (the frame-by-frame solve's own wrist turns differ 10-20 deg between frames)
RESEED_TURN = 0.3
HELD_TOL = 5e-4  # m a held hand's site may end from where the solve kept it, widened in time
HELD_TURN = math.radians(1.0)  # ...and its orientation
HELD_ROUNDS = 3  # ...widened and put back this many times: putting it back turns the arm a little
HELD_DEEPER = 1e-3  # m deeper than the solve left it a widened held arm may end
# rad a dof may turn from the widened pose to put the hand back: more is a new branch, not the
# widening's (an arm 80 mm inside a panel's screw stood 13 deg out of both neighbours)
HELD_SEED_TURN = math.radians(4.0)
# the elbow turns a held hand's arm may take about its shoulder-wrist line (``swivel_plan``)
SWIVEL_STEP = math.radians(2.5)
SWIVEL_TURNS = SWIVEL_STEP * np.arange(-72, 73)
SWIVEL_SPEED = math.radians(180.0)  # rad/s the plan turns the elbow at most
STRAIGHT_ARM = 0.03  # m: an elbow this close to the shoulder-wrist line is not turned
# dense frames a planned run may have at most (with its margins): a longer one (a long hold
# with the arm inside) is left to the frame-by-frame solve, which bounds its own work
PLAN_FRAMES = 1800
SWIVEL_PRICE = 0.003  # m of depth a radian of turn is worth: turned no further than it must
# a held arm's run of corrected frames (and where the plan turned the elbow) is evened out
# where a step goes this share of ``CORRECTED_JOINT_SPEED`` over it: issue 19's 360 deg/s. (At
# three times the share, four times the speed, steps of 20 deg in an output frame stood:
# bench/procedures had 100 of 182 outputs over 12 deg, 37 since.)
GIVE_BACK_SLACK = math.radians(360.0) / CORRECTED_JOINT_SPEED - 1.0
# ...but a run of corrected frames longer than this (an arm kept clear through a long carry)
# only where it flips (four times the speed): one fast frame in a 5.6-minute walk's run gave
# the whole walk's correction back (the arm inside the body throughout) after 4.7 s of trying
# to even out 20,128 frames (fuzz case 6270); a short spike there is the despike pass's
LONG_RUN = PLAN_FRAMES
FLIP_SLACK = 3.0
SPREAD = 120  # dense frames (2 s) on each side of a run its widened correction is tried over
FLIP_SHARES = (0.75, 0.5, 0.25)  # ...or of its correction, tried before it is given back


def pinned(ir: MotionIR, side: str, t: FloatArray) -> np.ndarray:
    """(N,) frames where the ``side`` hand's pose is a goal: the last ``GOAL_LEAD`` seconds of
    each reach or move and its contact phase (TO), a wrench's strokes, and while its grip is
    closed (it holds a site or carries a part), except through a posture that carries the part
    (``hold.carried_postures``)."""
    out = np.zeros(len(t), dtype=bool)
    for seg in ir.on_track(ARM_TRACK[side]):
        start = seg.start if seg.kind == "TO" else seg.end - GOAL_LEAD
        out |= (t >= start - EPS) & (t <= seg.end + EPS)
    grips = sorted(
        (s for s in ir.on_track(HAND_TRACK[side]) if s.kind == "grip"), key=lambda s: s.start
    )
    for k, g in enumerate(grips):
        if g.goal.params.get("state") != "closed":
            continue
        opens = [o.start for o in grips[k + 1 :] if o.goal.params.get("state") == "open"]
        out |= (t >= g.start - EPS) & (t < min(opens, default=np.inf) + EPS)
    # a part carried through a posture goes where the hand goes: the hand may move out of the way
    for seg in carried_postures(ir)[ARM_TRACK[side]]:
        out &= ~((t > seg.start + EPS) & (t < seg.end - EPS))
    return out


def pinned_weights(ir: MotionIR, side: str, t: FloatArray) -> FloatArray:
    """(N,) the hand pose's weight per frame: ``PINNED`` where ``pinned``, ``FREE`` elsewhere,
    each pinned span widened by ``RAMP`` on both sides and ramped over it."""
    on = pinned(ir, side, t).astype(float)
    if not on.any():
        return np.full(len(t), FREE)
    dt = float(np.median(np.diff(t))) if len(t) > 1 else 1.0
    n = max(1, round(RAMP / dt))
    # distance (in frames) to the nearest pinned frame, then a linear ramp over n frames
    idx = np.flatnonzero(on)
    pos = np.searchsorted(idx, np.arange(len(t)))
    left = np.abs(np.arange(len(t)) - idx[np.clip(pos - 1, 0, len(idx) - 1)])
    right = np.abs(idx[np.clip(pos, 0, len(idx) - 1)] - np.arange(len(t)))
    gap = np.minimum(left, right)
    share = np.clip(1.0 - gap / n, 0.0, 1.0)
    return FREE + (PINNED - FREE) * share


def without_swings(q: FloatArray, correction: FloatArray) -> FloatArray:
    """The per-frame ``correction`` (N, D) of frames ``q``, where it makes a dof swing between
    two frames by more than ``MAX_SWING`` and more than the motion did (solved frame by frame,
    two neighbours can land on opposite sides of the thigh), replaced on that run of corrected
    frames by its average over ``SWING_SMOOTH`` frames each side, fading to nothing at the
    run's ends: a jump becomes a ramp. What that gives back of the depth, verify reports."""
    before = np.abs(np.diff(q, axis=0))
    after = np.abs(np.diff(q + correction, axis=0))
    swings = np.flatnonzero((after > np.maximum(before, MAX_SWING)).any(axis=1))
    out = correction.copy()
    moved = np.abs(correction).max(axis=1) > 0.0
    for a, b in runs_of(moved):
        if np.any((swings >= a - 1) & (swings < b)):
            out[a:b] = _averaged(correction[a:b])
    return out


def swings_ramped(skel: Skeleton, q: FloatArray, solved: FloatArray) -> FloatArray:
    """``solved`` with ``without_swings`` applied to its correction of ``q``: the frames whose
    correction it changed posed again, every other frame ``solved`` itself, to the bit. Adding
    a correction back (``q + (solved - q)``) is ``solved`` only to the last bit, and which frames
    the next step solves again was decided by exact equality: a different BLAS build's last
    bits re-solved other frames and turned the access panel's last left-arm pose 1.3 deg."""
    correction = solved - q
    ramped = without_swings(q, correction)
    changed = (ramped != correction).any(axis=1)
    out = np.array(solved, dtype=float)
    out[changed] = skel.clip(q[changed] + ramped[changed])
    return out


def run(ir: MotionIR, ctx: PassContext) -> MotionIR:
    frames = ir.frames
    if frames is None or not len(frames.time):
        return ir
    root = (frames.root_position, frames.root_rotation)
    skel = ir.skeleton
    # how deep each arm starts inside, both from one whole-body pose of every frame; after
    # that only the frames a correction changed are posed again
    sides = ("r", "l")
    handed = FramesPosed.take(ctx.cache, frames)  # smooth's pose, brought up to date
    posed = None if handed is None else handed.all_now(skel, frames)
    inside = penetrations(skel, frames.q, root, sides, posed)
    if posed is not None:  # handed on as the pose of the frames as they are now
        handed = FramesPosed.of(frames, [posed])
    del posed
    for k, side in enumerate(sides):
        keep = pinned_weights(ir, side, frames.time)
        q = frames.q
        # a held hand's elbow turned round the body first, over time (``swivel_planned``):
        # where the solve starts
        start, depth = swivel_planned(skel, q, root, side, keep, frames.time, inside[side])
        cleared = keep_clear(skel, q, root, side, keep, start=start, firm=FIRM, inside=depth)
        cleared = reseeded(skel, q, cleared, root, side, keep, frames.time, inside[side])
        smooth = swings_ramped(skel, q, cleared)
        if np.array_equal(smooth, cleared):
            result = cleared
        else:
            # solved again from the ramp: each frame starts where its neighbours' average is;
            # only the ramped frames (a frame the ramp left alone keeps its own solve)
            from_smooth = depth_after(skel, inside[side], q, smooth, root, side)
            from_smooth[(smooth == cleared).all(axis=1)] = 0.0
            again = keep_clear(
                skel, q, root, side, keep, start=smooth, firm=FIRM, inside=from_smooth
            )
            result = swings_ramped(skel, q, again)
        # the correction's ends ramped no faster than a person turns a joint, where the hand
        # is free (a held hand keeps its own correction: it stays on its goal)
        held = keep > FREE + EPS
        widened = speed_limited(q, result - q, skel.lower, skel.upper, frames.time,
                                CORRECTED_JOINT_SPEED, fixed=held)  # fmt: skip
        moved = np.flatnonzero((widened != result - q).any(axis=1))
        if moved.size:
            result = result.copy()
            result[moved] = q[moved] + widened[moved]
        kept = result
        for _ in range(HELD_ROUNDS):
            was = result
            result = held_in_time(skel, q, result, kept, root, side, frames.time, held)
            if result is was or not bits_differ(result, was).any():
                break  # a fixed point: the next round is this one again, to the bit
        # a held hand's arm (the speed limit above leaves it be: the hand stays on its goal):
        # where the plan turned the elbow, no step faster than issue 19's 360 deg/s (the plan
        # is the fallback there, clear where a turn can clear the arm, and that slowly);
        # elsewhere no flip (a fuel filter's bowl carried past the thigh turned the wrist
        # 26 deg in one output frame where the solve yielded the hand's orientation)
        if start is not q:
            planned = (start != q).any(axis=1)
            result = flips_evened(skel, start, result, root, side, frames.time, planned)
        result = flips_evened(skel, start, result, root, side, frames.time, held)
        if start is not q:
            # measured against the plan, a run given back is the plan's, whose own turn can
            # step 13 deg in a frame where the motion turns (the aircraft panel's relay, female
            # P1: 21 deg in an output frame): against the motion as it came, too
            result = flips_evened(skel, q, result, root, side, frames.time, held)
        frames.q = result
        for other in sides[k + 1 :]:
            inside[other] = depth_after(skel, inside[other], q, result, root, other)
    if handed is not None:  # for verify, via sample: what clearance changed is posed again
        ctx.cache[FramesPosed.KEY] = handed
    return ir


def swivel_planned(
    skel: Skeleton,
    q: FloatArray,
    root: tuple[FloatArray, FloatArray],
    side: str,
    keep: FloatArray,
    t: FloatArray,
    inside: FloatArray,
) -> tuple[FloatArray, FloatArray]:
    """Where the clearance solve of the ``side`` arm starts, and how deep it is there: for each
    run of frames where a held hand's arm is inside (``keep`` over ``FREE``), its elbow turned
    about the shoulder-wrist line as ``swivel_plan`` chooses over the whole run and as many
    frames on each side as the plan needs to turn the elbow by 180 degrees at
    ``SWIVEL_SPEED``; elsewhere ``q`` itself.

    A held hand leaves the arm one motion, the elbow's turn; solved frame by frame, each frame
    took the way out nearest its own pose, and the way round a thigh or the trunk flipped from
    one side to the other between two frames: the shoulder's rotation swung 50-130 deg in one
    output frame (issue 19, the rack module's low latch). Chosen over time, the turn starts
    early enough to be done in time and goes round one side."""
    held = (inside > 0.0) & (keep > FREE + EPS)
    if not held.any() or len(t) < 2:
        return q, inside
    dt = float(np.median(np.diff(t)))
    per_frame = max(1, int(SWIVEL_SPEED * dt / SWIVEL_STEP))
    margin = int(np.ceil(np.abs(SWIVEL_TURNS).max() / (per_frame * SWIVEL_STEP))) + 1
    rows = np.flatnonzero(held)
    breaks = np.flatnonzero(np.diff(rows) > 2 * margin)
    turns = np.zeros(len(t))
    for first, last in zip(
        np.concatenate([[0], breaks + 1]), np.concatenate([breaks, [len(rows) - 1]]), strict=True
    ):
        a, b = max(0, rows[first] - margin), min(len(t), rows[last] + margin + 1)
        if b - a > PLAN_FRAMES:  # a long hold inside: left to the frame-by-frame solve
            continue
        chunks = [slice(c, min(c + 256, b)) for c in range(a, b, 256)]  # memory: 256 x G
        measured = [
            swivel_clearance(skel, q[c], (root[0][c], root[1][c]), side, SWIVEL_TURNS)
            for c in chunks
        ]
        depth = np.concatenate([m[0] for m in measured])
        offset = np.concatenate([m[1] for m in measured])
        turns[a:b] = swivel_plan(depth, per_frame, a == 0, b == len(t), offset < STRAIGHT_ARM)
    if not turns.any():
        return q, inside
    start = swiveled(skel, q, root, side, turns, PINNED)
    # the hand exactly where it was (the turned elbow's solve weighs it, it does not fix it;
    # a turn past a joint's limit pulled it off), else the run of frames is not turned at all
    # (a frame of it alone left unturned would be a step)
    rows = np.flatnonzero(turns != 0.0)
    sub_root = (root[0][rows], root[1][rows])
    put, ok = hand_restored(skel, start[rows], q[rows], sub_root, side)
    start[rows] = put
    lost = np.zeros(len(t), dtype=bool)
    lost[rows[~ok]] = True
    for a, b in runs_of(turns != 0.0):
        if lost[a:b].any():
            start[a:b] = q[a:b]
    if np.array_equal(start, q):
        return q, inside
    return start, depth_after(skel, inside, q, start, root, side)


def swivel_plan(
    depth: FloatArray,
    per_frame: int,
    free_start: bool,
    free_end: bool,
    unturned: np.ndarray | None = None,
) -> FloatArray:
    """(W,) the elbow's turn per frame, one of ``SWIVEL_TURNS``, given how deep each turn
    leaves the forearm in each frame (W, G): the least total depth (plus ``SWIVEL_PRICE`` per
    radian turned) over the run, the turn changing by at most ``per_frame`` grid steps between
    two frames (a person's joint speed), and 0 at the run's ends unless they are the motion's
    own (dynamic programming, Viterbi: the best path through the grid, exact). ``unturned``
    (W,): frames that keep no turn (a straight arm: a turn there would be a twist of the whole
    arm, all at once where it bends)."""
    w, g = depth.shape
    zero = int(np.flatnonzero(SWIVEL_TURNS == 0.0)[0])
    cost = np.maximum(depth, 0.0) + SWIVEL_PRICE * np.abs(SWIVEL_TURNS)[None, :]
    if unturned is not None:
        cost[np.ix_(unturned, np.arange(g) != zero)] = np.inf
    # moves tried in this order: ties keep the turn it had, then the smaller change
    moves = [0] + [m for j in range(1, per_frame + 1) for m in (-j, j)]
    acc = cost[0].copy()
    if not free_start:
        acc[np.arange(g) != zero] = np.inf
    back = np.zeros((w, g), dtype=np.int64)
    cols = np.arange(g)
    for i in range(1, w):
        cand = np.full((len(moves), g), np.inf)
        for m_i, m in enumerate(moves):  # reached at column c from column c - m
            lo, hi = max(0, m), min(g, g + m)
            cand[m_i, lo:hi] = acc[lo - m : hi - m]
        pick = np.argmin(cand, axis=0)
        back[i] = cols - np.asarray(moves)[pick]
        acc = cand[pick, cols] + cost[i]
    j = zero if not free_end and np.isfinite(acc[zero]) else int(np.argmin(acc))
    path = np.empty(w, dtype=np.int64)
    for i in range(w - 1, -1, -1):
        path[i] = j
        j = back[i, j]
    return SWIVEL_TURNS[path]


def held_in_time(
    skel: Skeleton,
    q: FloatArray,
    solved: FloatArray,
    kept: FloatArray,
    root: tuple[FloatArray, FloatArray],
    side: str,
    t: FloatArray,
    held: np.ndarray,
) -> FloatArray:
    """``solved`` (the corrected frames ``q``) with the correction of a ``held`` (N,) hand's
    arm widened in time too, where it turns a joint faster than ``CORRECTED_JOINT_SPEED``:
    started earlier and let go later (``speed_limited``), and the hand then put back on the
    pose it has at ``kept`` (the solve's), the arm's own dofs solved from the widened pose
    (damped least squares: the least change from it, so the widening's continuity stays). A
    frame takes that where its hand comes back within ``HELD_TOL`` and ``HELD_TURN``, no dof
    turns ``HELD_SEED_TURN`` from the widened pose and its arm is not ``HELD_DEEPER`` deeper
    than at ``kept``; a run of frames that makes a faster step than before is given back
    (``worse_runs_undone``).

    The solve is frame by frame: where a carried part passes the trunk, its arm must swing
    out within a few frames, and the solve lands on one side of the arm's redundancy one
    frame and on the other the next. ``speed_limited`` leaves a held hand's correction as it
    is (moving it alone would take the hand off its goal): the fuel filter's bowl carried past
    the trunk turned the wrist and the shoulder 14-26 deg in an output frame (issue 19)."""
    correction = solved - q
    wide = speed_limited(q, correction, skel.lower, skel.upper, t, CORRECTED_JOINT_SPEED)
    changed = (wide != correction).any(axis=1)
    rows = np.flatnonzero(changed & held)
    if rows.size == 0:
        return solved
    out = np.array(solved, dtype=float)
    free = np.flatnonzero(changed & ~held)
    out[free] = q[free] + wide[free]
    sub_root = (root[0][rows], root[1][rows])
    seed = skel.clip(q[rows] + wide[rows])
    moved, ok = hand_restored(skel, seed, kept[rows], sub_root, side)
    deeper = penetration(skel, moved, sub_root, side) - np.maximum(
        penetration(skel, kept[rows], sub_root, side), 0.0
    )
    ok &= (deeper <= HELD_DEEPER) & (np.abs(moved - seed).max(axis=1) <= HELD_SEED_TURN)
    out[rows[ok]] = moved[ok]
    return worse_runs_undone(q, solved, out, t, CORRECTED_JOINT_SPEED)


def flips_evened(
    skel: Skeleton,
    q: FloatArray,
    solved: FloatArray,
    root: tuple[FloatArray, FloatArray],
    side: str,
    t: FloatArray,
    held: np.ndarray,
    slack: float = GIVE_BACK_SLACK,
) -> FloatArray:
    """``solved`` (the corrected frames ``q``) where each run of corrected frames with a
    ``held`` frame (N,) in it that steps more than ``slack`` (``GIVE_BACK_SLACK``) over
    ``CORRECTED_JOINT_SPEED`` (beyond the motion's own step: a flip between two ways out, not
    a fast turn) takes its correction widened in time (``speed_limited``: started earlier,
    let go later), or averaged over the run (``_averaged``: a ramp through it), or else the
    largest of ``FLIP_SHARES`` of it, the hand put back on its pose (``hand_restored``), the
    first that flips nowhere and goes no deeper than the run given back; else the run is given
    back (``q``: what it leaves inside, verify reports, MT0514)."""
    flipped = (
        worse_runs_undone(q, q, solved, t, CORRECTED_JOINT_SPEED, held, slack) != solved
    ).any(axis=1)
    flip: np.ndarray | None = None
    for a, b in runs_of(flipped) if slack < FLIP_SLACK else ():
        if b - a > LONG_RUN:  # evened out or given back only where it flips
            if flip is None:
                flip = (
                    worse_runs_undone(q, q, solved, t, CORRECTED_JOINT_SPEED, held, FLIP_SLACK)
                    != solved
                ).any(axis=1)
            flipped[a:b] = flip[a:b]
    if not flipped.any():
        return solved
    out = solved.copy()
    # the hands' sites to keep: where they are (the orientation the solve yielded flipped with
    # the arm: it follows the seed)
    kept = solved
    tries: list[list[tuple[slice, FloatArray]]] = []  # each run's seeds, in order
    for a, b in runs_of(flipped):
        correction = np.zeros_like(q)
        correction[a:b] = solved[a:b] - q[a:b]
        out[a:b] = q[a:b]  # given back, unless one of these evens it out
        wide = speed_limited(q, correction, skel.lower, skel.upper, t, CORRECTED_JOINT_SPEED)
        # within ``SPREAD`` of the run: where the motion itself turns as fast, the widening
        # need not fade, and 4758's stretched over 11,900 frames (0.2 s of posing a try)
        near = slice(max(a - SPREAD, 0), min(b + SPREAD, len(q)))
        spread = near.start + np.flatnonzero((wide[near] != 0.0).any(axis=1))
        seeds = []  # (frames, their correction)
        if spread.size:
            seeds.append((slice(spread[0], spread[-1] + 1), wide[spread[0] : spread[-1] + 1]))
        seeds.append((slice(a, b), _averaged(correction[a:b])))
        seeds += [(slice(a, b), share * correction[a:b]) for share in FLIP_SHARES]
        tries.append(seeds)
    # the runs' k-th seeds tried together, as many at once as neither overlap nor touch (each
    # would be judged as one run with its neighbour); one run at a time, each solve and measure
    # had a cost of its own: 4758's 12 runs took 5.7 s
    turn = [0] * len(tries)
    while True:
        batch: list[int] = []
        end = -1
        for r, seeds in enumerate(tries):
            if turn[r] < len(seeds) and seeds[turn[r]][0].start > end:
                batch.append(r)
                end = seeds[turn[r]][0].stop
        if not batch:
            return out
        spans = [tries[r][turn[r]][0] for r in batch]
        rows = np.concatenate([np.arange(sp.start, sp.stop) for sp in spans])
        sub_root = (root[0][rows], root[1][rows])
        seed_q = skel.clip(q[rows] + np.concatenate([tries[r][turn[r]][1] for r in batch]))
        put, ok = hand_restored(skel, seed_q, kept[rows], sub_root, side, turn=False)
        depth = np.maximum(penetration(skel, out[rows], sub_root, side), 0.0)
        ok &= penetration(skel, put, sub_root, side) <= depth + EPS
        candidate = out.copy()
        first, fine = 0, []
        for r, sp in zip(batch, spans, strict=True):
            part = slice(first, first + sp.stop - sp.start)
            first = part.stop
            turn[r] += 1
            if ok[part].all():
                candidate[sp] = put[part]
                fine.append((r, sp, part))
        if not fine:
            continue
        again = worse_runs_undone(q, q, candidate, t, CORRECTED_JOINT_SPEED, held, slack)
        for r, sp, part in fine:
            if np.array_equal(again[sp], put[part]):
                out[sp] = put[part]
                turn[r] = len(tries[r])  # evened out: no more seeds


def _averaged(run: FloatArray) -> FloatArray:
    """A run of corrections (n, D) averaged over ``SWING_SMOOTH`` frames each side, twice (a
    triangle: no corners), fading to nothing past its ends: a jump becomes a ramp."""
    width = 2 * SWING_SMOOTH + 1
    padded = np.pad(run, ((width, width), (0, 0)))
    kernel = np.ones(width) / width
    for _ in range(2):
        padded = np.apply_along_axis(np.convolve, 0, padded, kernel, mode="same")
    return padded[width:-width]


def hand_restored(
    skel: Skeleton,
    seed: FloatArray,
    kept: FloatArray,
    root: tuple[FloatArray, FloatArray],
    side: str,
    turn: bool = True,
) -> tuple[FloatArray, np.ndarray]:
    """The poses ``seed`` (N, D) with the ``side`` hand put back where it is at ``kept``
    (its site, and with ``turn`` its orientation) by the arm's own dofs, damped least squares
    from ``seed`` (the least change from it: the redundancy stays where ``seed`` has it), and
    (N,) whether the hand came back within ``HELD_TOL`` (and ``HELD_TURN``)."""
    site = f"{side}_hand"
    at = forward(skel, kept, *root)
    rotation = site_rotation(skel, at, site) if turn else None
    return hand_put(skel, seed, site_positions(skel, at, site), rotation, root, side)


def hand_put(
    skel: Skeleton,
    seed: FloatArray,
    position: FloatArray,
    rotation: FloatArray | None,
    root: tuple[FloatArray, FloatArray],
    side: str,
) -> tuple[FloatArray, np.ndarray]:
    """The poses ``seed`` (N, D) with the ``side`` hand at ``position`` (N, 3) and, given,
    turned to ``rotation`` (N, 3, 3), by the arm's own dofs with the least change from
    ``seed`` (``hand_restored``), and (N,) whether it got there within ``HELD_TOL`` (and
    ``HELD_TURN``)."""
    goal = [Goal(f"{side}_hand", position=position, orientation=rotation)]
    model = prepare(skel, goal, seed, dofs=arm_dofs(skel, side), root_position=root[0],
                    root_rotation=root[1])  # fmt: skip
    res = solve_ta(skel, goal, seed, model=model, restarts=0, null_gain=0.0, tol=HELD_TOL / 2,
                   orientation_tol=HELD_TURN / 2, max_iter=40)  # fmt: skip
    ok = (res.position_error <= HELD_TOL) & (res.orientation_error <= HELD_TURN)
    return res.q, ok


def reseeded(
    skel: Skeleton,
    q: FloatArray,
    solved: FloatArray,
    root: tuple[FloatArray, FloatArray],
    side: str,
    keep: FloatArray,
    t: FloatArray,
    inside: FloatArray,
) -> FloatArray:
    """``solved`` (``keep_clear`` of frames ``q``) with each frame of a kept hand (weight
    ``KEPT_HAND`` or more) it leaves ``LEFT_DEPTH`` or more inside solved again, started from its neighbours' correction: the corrections of the
    nearest frames it cleared within ``RESEED_REACH`` on each side, interpolated (or the one
    side's). Kept where that clears it and no dof ends ``RESEED_TURN`` from the neighbours'
    poses (less deep is not enough: a correction carried from one side into a run the arm
    cannot leave makes a taller cliff at the run's other end); up to ``RESEED_ROUNDS`` times,
    a run of such frames closing from its ends. The solve is frame by frame and, at the
    deepest frames of a pass through the trunk, stops in a local minimum its neighbours got
    past: a correction of +38 degrees on both sides and none between was a 38-degree step out
    and back (issue 19)."""
    need = np.flatnonzero(inside > 0.0)
    if need.size == 0:
        return solved
    dt = float(np.median(np.diff(t))) if len(t) > 1 else 1.0
    reach = max(1, round(RESEED_REACH / dt))
    # a frame takes part only as a kept hand's frame or as one's neighbour within ``reach``:
    # only those are measured (a 415 s walk's free arm by the thigh: 21,000 frames, 200 used);
    # the others count as deep, never a neighbour (none is within reach of a kept frame)
    near_kept = _within(np.flatnonzero(keep >= KEPT_HAND), reach, len(q))
    if not near_kept[need].any():
        return solved
    depth = np.full(len(q), np.inf)
    measured = need[near_kept[need]]
    depth[measured] = penetration(
        skel, solved[measured], (root[0][measured], root[1][measured]), side
    )
    out = solved.copy()
    for _ in range(RESEED_ROUNDS):
        # a held hand's frames only: a free hand's seed carries its neighbours' hand with it
        left = need[(depth[need] >= LEFT_DEPTH) & (keep[need] >= KEPT_HAND)]
        good = need[depth[need] < LEFT_DEPTH]
        if left.size == 0 or good.size == 0:
            break
        pos = np.searchsorted(good, left)
        before = good[np.clip(pos - 1, 0, good.size - 1)]
        after = good[np.clip(pos, 0, good.size - 1)]
        has_before = (pos > 0) & (left - before <= reach)
        has_after = (pos < good.size) & (after - left <= reach)
        near = has_before | has_after
        if not near.any():
            break
        rows = left[near]
        b = np.where(has_before, before, after)[near]
        a = np.where(has_after, after, before)[near]
        share = np.where(a > b, (rows - b) / np.maximum(a - b, 1), 0.0)[:, None]
        correction = out - q
        seed = skel.clip(q[rows] + (1.0 - share) * correction[b] + share * correction[a])
        sub_root = (root[0][rows], root[1][rows])
        again = keep_clear(skel, q[rows], sub_root, side, keep[rows], start=seed, firm=FIRM)
        new_depth = penetration(skel, again, sub_root, side)
        between = (1.0 - share) * out[b] + share * out[a]  # the neighbours' poses
        cleared = (new_depth < LEFT_DEPTH) & (np.abs(again - between).max(axis=1) <= RESEED_TURN)
        cleared &= hand_moved(skel, q[rows], again, sub_root, side) <= RESEED_HAND_TOL
        # the solve from the seed can fall back into the frame's own local minimum (the hand's
        # pose weighs much more than the depth, and the neighbours cleared by yielding its
        # orientation): the seed with only the hand's site put back, its redundancy and its
        # orientation where the neighbours have them (a male P99's right arm stuck 19 mm
        # inside the trunk between two frames 2-3 mm in, the fuel filter's bowl carried)
        rest = np.flatnonzero(~cleared)
        if rest.size:
            sub_rest = (sub_root[0][rest], sub_root[1][rest])
            put, ok = hand_restored(skel, seed[rest], q[rows[rest]], sub_rest, side, turn=False)
            put_depth = penetration(skel, put, sub_rest, side)
            ok &= (put_depth < LEFT_DEPTH) & (
                np.abs(put - between[rest]).max(axis=1) <= RESEED_TURN
            )
            again[rest[ok]] = put[ok]
            new_depth[rest[ok]] = put_depth[ok]
            cleared[rest[ok]] = True
        out[rows[cleared]] = again[cleared]
        depth[rows[cleared]] = new_depth[cleared]
        if not cleared.any():
            break
    return out


def _within(rows: np.ndarray, reach: int, n: int) -> np.ndarray:
    """(n,) the frames within ``reach`` frames of one of ``rows`` (sorted indices)."""
    mark = np.zeros(n + 1, dtype=np.int64)
    np.add.at(mark, np.maximum(rows - reach, 0), 1)
    np.add.at(mark, np.minimum(rows + reach + 1, n), -1)
    return np.cumsum(mark[:n]) > 0


def hand_moved(
    skel: Skeleton,
    q: FloatArray,
    moved: FloatArray,
    root: tuple[FloatArray, FloatArray],
    side: str,
) -> FloatArray:
    """(N,) how far (m) the ``side`` hand's site is at ``moved`` from where it is at ``q``."""
    site = f"{side}_hand"
    at = [site_positions(skel, forward(skel, c, *root, with_axes=False), site) for c in (q, moved)]
    return np.linalg.norm((at[1] - at[0]).reshape(len(q), -1), axis=1)


def depth_after(
    skel: Skeleton,
    depth: FloatArray,
    q: FloatArray,
    moved: FloatArray,
    root: tuple[FloatArray, FloatArray],
    side: str,
) -> FloatArray:
    """``penetration`` (N,) of the ``side`` arm at frames ``moved``, given its ``depth`` at
    frames ``q``: measured again only where a dof it depends on changed (the other arm's
    correction moves neither this arm nor the trunk and thighs)."""
    rows = np.flatnonzero((moved != q)[:, penetration_dofs(skel, side)].any(axis=1))
    out = depth.copy()
    if rows.size:
        out[rows] = penetration(skel, moved[rows], (root[0][rows], root[1][rows]), side)
    return out
