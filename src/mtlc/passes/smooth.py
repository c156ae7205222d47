"""Pass 7: blend out jumps at segment boundaries (seed 004, claim 6).

Claim 6: take the offset between the last frame of one step and the first frame of the next,
and subtract it from the frames of the next step, scaled by a factor that starts at 1 and falls
by 0.02 per frame until it reaches 0 (50 frames) or the motion ends. Here the boundaries are
the starts of walks, whole-body postures and holds and every footstep lift-off
(``result["steps"]``), in time order (not TA, TO, gaze or grip starts, which begin from the
current pose); the offset is taken on all joint angles and the root position.

On dense frames a boundary in smooth motion also shows the motion's own velocity between its
two frames, so the offset is the jump *beyond* that: ``x[i+1] − x[i] − v·dt``, with ``v`` the
mean velocity of the frames on either side. Only a jump above ``JUMP_Q`` (rad) or ``JUMP_ROOT``
(m) is blended. The root rotation is left alone (a quaternion has no offset to subtract and
the gait and the root plan keep it continuous).

After subtracting, angles are clipped into their limits, so smoothing never pushes a joint
past one. Subtracting offsets moves the limbs, so contacts are then restored on the frames it
changed: a foot that touched the ground keeps its leg's angles from before smoothing where the
root did not move (its foot is then exactly where it was); elsewhere feet that touched and hands
on their sites (TO and after, see ``balance.hand_pins``) are re-solved by IK back to where they
were before smoothing, with the same routine balance uses. Re-pinning (rather than skipping the pinned frames) keeps the
pelvis and trunk smooth through a contact window while the hand and feet stay put.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mtlc.body import Pose, forward, part_site_positions, site_positions, site_rotation
from mtlc.body.kinematics import forward_rows_changed
from mtlc.body.skeleton import Skeleton
from mtlc.ir.model import Frames, MotionIR
from mtlc.metrics import (
    balance_margin,
    contact_mask,
    foot_points,
    foot_stance,
    lowest_point,
    walking,
)
from mtlc.passes.balance import (
    CORRECTED_JOINT_SPEED,
    FEET_SITES,
    HANDS,
    MARGIN,
    arm_dofs,
    arms_in_time,
    balance_frames,
    hand_pins,
    pin_windows,
    restore_contacts,
)
from mtlc.passes.context import FramesPosed, PassContext
from mtlc.passes.joint_speed import worse_runs_undone

STEP = 0.02  # the claim's decrement per frame: 1, 0.98, …, 0.02, then 0
JUMP_Q = 1e-3  # rad: smaller offsets are the interpolation's own
JUMP_ROOT = 5e-4  # m
PIN_TOL = 1e-4  # m: a contact that moved less than this is left alone
PUT_BACK = 1e-3  # m: a re-pinned hand this close to its place is back on it
CHUNK_FRAMES = 4096  # changed frames measured at once


def blend_weights(n: int) -> np.ndarray:
    """The claim's factors for the frames after a boundary: 1, 0.98, … (at most n)."""
    steps = round(1.0 / STEP)
    return (1.0 - STEP * np.arange(steps))[:n]


# TA, TO, gaze and grip segments start from the pose the body is in (their first keyframe is
# that pose), so they have no offset to blend; blending there would only move a hand off its way
# to the site. Walks, footsteps and whole-body postures are where offsets arise.
BLENDED_KINDS = ("locomotion", "posture", "hold")


def boundaries(ir: MotionIR) -> list[float]:
    """Starts of walks, postures and holds, and footstep lift-offs, sorted, without duplicates."""
    times: set[float] = set()
    for seg in ir.segments:
        if seg.start > 1e-9 and seg.kind in BLENDED_KINDS and seg.track == "root":
            times.add(round(seg.start, 9))
        if seg.kind == "locomotion":
            for step in seg.result.get("steps", ()) or ():
                times.add(round(float(step["t_lift"]), 9))
    return sorted(times)


def jump(x: np.ndarray, i: int) -> np.ndarray:
    """The offset between frames i and i+1 beyond the motion's velocity around them."""
    before = x[i] - x[i - 1] if i >= 1 else np.zeros_like(x[i])
    after = x[i + 2] - x[i + 1] if i + 2 < len(x) else before
    return x[i + 1] - x[i] - 0.5 * (before + after)


def smooth_frames(
    frames: Frames, times: list[float], lower: np.ndarray, upper: np.ndarray
) -> np.ndarray:
    """Blend the jumps at ``times`` in place; returns the mask of frames changed."""
    t = frames.time
    n = len(t)
    changed = np.zeros(n, dtype=bool)
    for tb in times:
        i = int(np.searchsorted(t, tb - 1e-9)) - 1  # t[i] < tb <= t[i+1]: a frame at tb is new
        if i < 0 or i + 1 >= n:
            continue
        dq = jump(frames.q, i)
        dr = jump(frames.root_position, i)
        dq[np.abs(dq) <= JUMP_Q] = 0.0
        dr[np.abs(dr) <= JUMP_ROOT] = 0.0
        if not (dq.any() or dr.any()):
            continue
        w = blend_weights(n - i - 1)
        span = slice(i + 1, i + 1 + len(w))
        frames.q[span] = np.clip(frames.q[span] - w[:, None] * dq, lower, upper)
        frames.root_position[span] -= w[:, None] * dr
        changed[span] = True
    return changed


@dataclass
class Contacts:
    """What the re-pin needs of the pose before smoothing, on the frames it re-pins: measured
    while that pose is at hand, so it is posed once (a long walk re-pins nearly every frame)."""

    touching: np.ndarray  # (B, 2) the feet (r, l) on the ground
    feet: dict[str, tuple[np.ndarray, np.ndarray]]  # FEET_SITES: position (B, 3), rotation
    hands: dict[str, np.ndarray]  # HANDS: position (B, 3)
    lowest: np.ndarray  # (B,) the lowest body point

    @staticmethod
    def of(skel: Skeleton, pose: Pose, contact: np.ndarray, lowest: np.ndarray) -> Contacts:
        """Those of the rows of ``pose`` (its sole points on the ground: ``contact``)."""
        return Contacts(
            contact.reshape(len(contact), 2, -1).any(axis=2),
            {n: (site_positions(skel, pose, n), site_rotation(skel, pose, n)) for n in FEET_SITES},
            {h: site_positions(skel, pose, h) for h in HANDS},
            lowest,
        )

    @staticmethod
    def join(parts: list[Contacts]) -> Contacts:
        return Contacts(
            np.concatenate([c.touching for c in parts]),
            {
                n: tuple(np.concatenate([c.feet[n][i] for c in parts]) for i in range(2))  # type: ignore[misc]
                for n in FEET_SITES
            },
            {h: np.concatenate([c.hands[h] for c in parts]) for h in HANDS},
            np.concatenate([c.lowest for c in parts]),
        )


def run(ir: MotionIR, ctx: PassContext) -> MotionIR:
    frames = ir.frames
    skel = ir.skeleton
    if frames is None or skel is None or len(frames.time) < 3:
        return ir
    t = frames.time
    q0, root0 = frames.q.copy(), frames.root_position.copy()
    handed = FramesPosed.take(ctx.cache, frames)  # the balance pass's pose of these frames
    changed = smooth_frames(frames, boundaries(ir), skel.lower, skel.upper)
    rows = np.flatnonzero(changed)
    if rows.size == 0:
        if handed is not None:
            ctx.cache[FramesPosed.KEY] = handed
        return ir
    stance_all, pins = foot_stance(ir, t), hand_pins(ir, t, pin_windows(ir, reached_only=True))
    # contacts before and after, on the changed frames only (forward kinematics is the cost),
    # a chunk of frames at a time: a long walk changes most of its frames (~16 KB each here).
    # Each frame is posed before and after the blend once; the frames re-pinned once more at
    # the end (forward kinematics is computed frame by frame: a frame's numbers are the same
    # in any batch)
    moved = np.zeros(rows.size, dtype=bool)
    held: list[Contacts] = []  # of the frames to re-pin, chunk by chunk
    legs = [skel.dofs_of_joints([f"{s}_hip", f"{s}_knee", f"{s}_ankle", f"{s}_toes"]) for s in "rl"]
    for a in range(0, rows.size, CHUNK_FRAMES):
        r = rows[a : a + CHUNK_FRAMES]
        rot = frames.root_rotation[r]
        if handed is None:
            pose = forward(skel, q0[r], root0[r], rot, with_axes=False)
        else:  # where balance changed them, posed again
            pose = handed.now(skel, r, q0[r], root0[r], rot)
        soles_before = foot_points(skel, pose)
        contact = contact_mask(soles_before, stance_all[r], ir.ground)
        _stance_legs_kept(frames, q0, root0, r, contact, legs)
        after = forward_rows_changed(
            skel, pose, q0[r], root0[r], frames.q[r], frames.root_position[r], rot
        )
        if handed is not None:
            handed.update(r, after, frames)
        # re-pin only the frames where a touching foot or a pinned hand actually moved
        soles = np.linalg.norm(foot_points(skel, after) - soles_before, axis=-1)
        m = (np.where(contact, soles, 0.0) > PIN_TOL).any(axis=1)
        # and where anything went deeper below the ground (a swinging toe just before it set
        # down, which no contact pins: the gait's walks went 3.6 mm through the floor)
        low = lowest_point(skel, pose)
        m |= lowest_point(skel, after) < np.minimum(low, ir.ground) - 1e-9
        for h in HANDS:
            off = np.linalg.norm(
                site_positions(skel, after, h) - site_positions(skel, pose, h), axis=-1
            )
            m |= pins[h][r] & (off > PIN_TOL)
        moved[a : a + CHUNK_FRAMES] = m
        fix = np.flatnonzero(m)
        if fix.size:
            held.append(Contacts.of(skel, _pose_rows(pose, fix), contact[fix], low[fix]))
    at = np.flatnonzero(moved)
    if at.size:  # one batch: the solver's last bits depend on the batch it runs in
        back = _repin(ir, frames, rows[at], Contacts.join(held), pins)
        # the arms, blended and re-pinned frame by frame, made continuous in time: a hand on
        # its place keeps its arm, the others' corrections turn in no faster than a person's
        kept = {h: np.zeros(len(t), dtype=bool) for h in HANDS}
        for h in HANDS:
            kept[h][rows[at]] = back[h]
            kept[h] |= pins[h] & ~np.isin(np.arange(len(t)), rows[at])
        frames.q[:] = arms_in_time(skel, q0, frames.q, t, kept)
    worse = _worse_standing_runs(ir, frames, rows, q0, root0)
    if worse.size:
        q1, root1 = frames.q.copy(), frames.root_position.copy()
        balance_frames(ir, frames, worse)
        # a run the balance makes step faster than a person moves is given back, root too (a
        # trunk leaned to its limit in one frame: the lumbar 25 -> -30 deg, a squat after a
        # kneel, tests/data/pose/p01, female P5); what it leaves outside, verify reports
        kept = worse_runs_undone(q1, q1, frames.q, t, CORRECTED_JOINT_SPEED)
        back = np.flatnonzero((kept != frames.q).any(axis=1))
        frames.q[back], frames.root_position[back] = q1[back], root1[back]
    if handed is not None:  # for clearance: what changed since is posed again there
        ctx.cache[FramesPosed.KEY] = handed
    return ir


def _stance_legs_kept(
    frames: Frames,
    q0: np.ndarray,
    root0: np.ndarray,
    rows: np.ndarray,
    contact: np.ndarray,
    legs: list[list[int]],
) -> None:
    """A touching foot's leg keeps its angles from before the blend on the frames ``rows``
    where the blend left the root where it was: its foot then stays exactly where it was, what
    re-pinning it by IK would find (to the solver's tolerance) at the cost of a solve. A long
    walk's lift-offs blend nearly every frame's legs (the gait's own acceleration at each
    lift-off is over the jump threshold) and rarely its root: their re-pin was a quarter of a
    lint. ``contact``: the sole points touching before the blend ((len(rows), 8), r then l)."""
    still = (frames.root_position[rows] == root0[rows]).all(axis=1)
    touching = contact.reshape(len(rows), 2, -1).any(axis=2)
    for k, dofs in enumerate(legs):
        keep = rows[still & touching[:, k]]
        frames.q[np.ix_(keep, dofs)] = q0[np.ix_(keep, dofs)]


def _repin(
    ir: MotionIR,
    frames: Frames,
    fix: np.ndarray,
    before: Contacts,
    pins: dict[str, np.ndarray],
) -> dict[str, np.ndarray]:
    """Put the touching feet and pinned hands of the frames ``fix`` back where they were
    before the blend (``before``), never sinking anything deeper. Returns, per hand, the rows
    of ``fix`` where it was pinned and put back (``_hands_put_back``)."""
    rot = frames.root_rotation[fix]
    feet = {name: (*before.feet[name], before.touching[:, k]) for k, name in enumerate(FEET_SITES)}
    hands = {h: (pins[h][fix], before.hands[h]) for h in HANDS}
    q, root, _ = restore_contacts(ir, frames.q[fix], frames.root_position[fix], rot, feet, hands)
    # smoothing must not sink anything deeper (a swing toe near the ground when the pelvis
    # came down): raise the root by what it added below the ground, h = L − x
    low_after = _lowest(ir, q, root, rot)
    lift = np.maximum(np.minimum(before.lowest, ir.ground) - low_after, 0.0)
    root[:, 1] += lift
    up = np.flatnonzero(lift > 0.0)
    if up.size:  # the raise took the standing feet up with it: put them back down, legs bent
        q[up], root[up], _ = restore_contacts(
            ir, q[up], root[up], rot[up],
            {n: (p[up], r[up], touch[up]) for n, (p, r, touch) in feet.items()},
            {h: (mask[up], at[up]) for h, (mask, at) in hands.items()},
        )  # fmt: skip
    reached = _hands_put_back(ir, frames.q[fix], q, root, rot, hands)
    for hand, ok in reached.items():  # a hand that could not be put back keeps the blend's arm
        lost = np.flatnonzero(hands[hand][0] & ~ok)
        cols = arm_dofs(ir.skeleton, hand)
        q[np.ix_(lost, cols)] = frames.q[fix][np.ix_(lost, cols)]
    frames.q[fix] = q
    frames.root_position[fix] = root
    return {h: hands[h][0] & ok for h, ok in reached.items()}


def _hands_put_back(
    ir: MotionIR,
    seed: np.ndarray,
    q: np.ndarray,
    root: np.ndarray,
    rot: np.ndarray,
    hands: dict[str, tuple[np.ndarray, np.ndarray]],
) -> dict[str, np.ndarray]:
    """Per hand, (B,) whether re-pinning brought it back: within ``PUT_BACK`` of its place, or
    at least halfway from where the blend took it (``seed``). A blend that moved the body far
    from a pinned hand (a kneel's pelvis 25 cm from the squat's after it) left it out of reach,
    and the solve, failing, turned the arm 108 deg in a frame (issue 19). Measured on the rows
    where the hand is pinned (False elsewhere: the callers ask of those alone), by the arm's
    chain (``part_site_positions``: ``forward``'s numbers; a long walk pins no hand, and two
    whole-body poses of its every frame were a third of the pass)."""
    skel = ir.skeleton
    out = {}
    for hand, (pinned, target) in hands.items():
        rows = np.flatnonzero(pinned)
        ok = np.zeros(len(q), dtype=bool)
        if rows.size:
            r, rr = root[rows], rot[rows]
            was = part_site_positions(skel, seed[rows], r, rr, [hand])[:, 0]
            now = part_site_positions(skel, q[rows], r, rr, [hand])[:, 0]
            was = np.linalg.norm(was - target[rows], axis=-1)
            now = np.linalg.norm(now - target[rows], axis=-1)
            ok[rows] = (now <= PUT_BACK) | (now <= 0.5 * was)
        out[hand] = ok
    return out


def _lowest(ir: MotionIR, q: np.ndarray, root: np.ndarray, rot: np.ndarray) -> np.ndarray:
    """The lowest body point of each frame, a chunk at a time."""
    low = np.empty(len(q))
    for a in range(0, len(q), CHUNK_FRAMES):
        c = slice(a, a + CHUNK_FRAMES)
        low[c] = lowest_point(ir.skeleton, forward(ir.skeleton, q[c], root[c], rot[c],
                                                   with_axes=False))  # fmt: skip
    return low


def _margins(
    ir: MotionIR, q: np.ndarray, root: np.ndarray, rot: np.ndarray, t: np.ndarray
) -> np.ndarray:
    """``balance_margin`` of each frame, a chunk at a time."""
    out = np.empty(len(q))
    for a in range(0, len(q), CHUNK_FRAMES):
        c = slice(a, a + CHUNK_FRAMES)
        pose = forward(ir.skeleton, q[c], root[c], rot[c], with_axes=False)
        out[c] = balance_margin(ir, pose, t[c])
    return out


def _pose_rows(pose: Pose, rows: np.ndarray | slice) -> Pose:
    """Some frames of a batch of poses, copied (forward kinematics solves frame by frame, so
    they are the numbers ``forward`` gives those frames alone)."""
    return Pose(R=pose.R[rows].copy(), p=pose.p[rows].copy(), axes=pose.axes[rows].copy(),
                root=pose.root[rows].copy())  # fmt: skip


def _worse_standing_runs(
    ir: MotionIR, frames: Frames, rows: np.ndarray, q0: np.ndarray, root0: np.ndarray
) -> np.ndarray:
    """The changed frames ``rows`` to balance again: blending toward the frames before a
    boundary can undo the balance pass's correction of the frames after it, so the frames
    smoothing made less balanced (``_worse``), in the runs of consecutive such frames that hold
    a standing frame (``balance_frames`` balances each run by itself and moves no walking frame
    unless a standing one of its run is corrected: the others are left as they are; a long
    walk's gait gave ~1,700 such runs, each measured for nothing, 9 s).

    Measured outward from the standing frames only: a run is followed frame by frame (in
    blocks that double) while its frames are worse, so a long walk's frames are not measured
    (the margins were a sixth of the pass). The frames returned are those runs of
    ``rows[_worse(every row)]``."""
    n = rows.size
    link = np.r_[np.diff(rows) == 1, False]  # position i and i + 1 are neighbouring frames
    standing = ~walking(ir, frames.time[rows])
    known = np.zeros(n, dtype=bool)
    worse = np.zeros(n, dtype=bool)

    def measure(pos: np.ndarray) -> None:
        pos = pos[~known[pos]]
        if pos.size:
            worse[pos] = _worse(ir, frames, rows[pos], q0, root0)
            known[pos] = True

    measure(np.flatnonzero(standing))
    width = 16
    while True:
        runs = _live_runs(worse, link, standing)
        ahead: list[np.ndarray] = []
        for a, b in runs:  # positions a..b, worse, holding a standing frame
            if a > 0 and link[a - 1] and not known[a - 1]:
                lo = a - 1
                while lo > max(a - width, 0) and link[lo - 1]:
                    lo -= 1
                ahead.append(np.arange(lo, a))
            if b + 1 < n and link[b] and not known[b + 1]:
                hi = b + 1
                while hi < min(b + width, n - 1) and link[hi]:
                    hi += 1
                ahead.append(np.arange(b + 1, hi + 1))
        if not ahead:
            return rows[np.concatenate([np.arange(a, b + 1) for a, b in runs] or [[]]).astype(int)]
        # two runs' ranges can meet in the frames between them: each frame measured once
        measure(np.unique(np.concatenate(ahead)))
        width *= 2


def _live_runs(worse: np.ndarray, link: np.ndarray, standing: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) positions of the runs of neighbouring worse frames holding a standing one."""
    start = worse & ~np.r_[False, link[:-1] & worse[:-1]]
    run = np.cumsum(start) - 1
    out = []
    for k in np.unique(run[worse & standing]):
        pos = np.flatnonzero(worse & (run == k))
        out.append((int(pos[0]), int(pos[-1])))
    return out


def _worse(
    ir: MotionIR, frames: Frames, r: np.ndarray, q0: np.ndarray, root0: np.ndarray
) -> np.ndarray:
    """Which frames ``r`` smoothing made less balanced than before (``q0``, ``root0``) and
    less than ``MARGIN``."""
    t, rot = frames.time[r], frames.root_rotation[r]
    before = _margins(ir, q0[r], root0[r], rot, t)
    after = _margins(ir, frames.q[r], frames.root_position[r], rot, t)
    return np.nan_to_num(after, nan=1.0) < np.minimum(np.nan_to_num(before, nan=1.0), MARGIN) - 1e-4
