"""Pass 7a: a part held in both hands is rigid: the part's pose drives both hands (MT0511).

Each hand's reach or move is solved, keyed and interpolated on its own arm, so between the
keyframes the two hands follow two unrelated joint-space paths: a panel carried to the bench
was squeezed 11-36 mm and an avionics unit 146-196 mm while the verify pass held it rigid. Here,
on the dense frames where both hands are closed on one two-handed part (``carries``), the part
is one body: its centre follows the hands' mid-point and its axis the line between them, as the
solved motion has them, and its length is what it was when the second hand closed. Each hand's
goal on every such frame is its end of that part, and each arm (shoulder, elbow, wrist; not the
forearm's twist) is re-solved onto it, warm-started from the frame's own pose. At the keyframes
where both hands reach their goals the two agree already and nothing changes.

A frame an arm cannot follow keeps its best pose; verify measures the hands' distance on the
output frames and reports what is left (MT0511).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from mtlc.body import forward_part, site_positions
from mtlc.body.ik import Goal, SerialRows, prepare, solve_ta, solve_ta_row
from mtlc.ir.model import FloatArray, Frames, MotionIR, Segment
from mtlc.passes.context import PassContext
from mtlc.passes.hold import _arm_dofs
from mtlc.passes.profile import minimum_jerk, smooth_path

ARM_TRACK = {"r": "r_arm", "l": "l_arm"}
HAND_TRACK = {"r": "r_hand", "l": "l_hand"}
REACHED = 1e-3  # m: a hand further than this from the part at its grasp does not hold it
# rad/s: the correction left at a carry's end is let go of at most this fast at its bell's peak
# (a minimum-jerk fade; the output frames' 12 deg at 30 fps is 360 deg/s, issue 19)
FADE_SPEED = float(np.radians(240.0))
MIN_FADE = 0.2  # s: the shortest fade
FIX_FROM = 5e-5  # m: frames whose hands are already this close to the part's ends stay
SOLVE_TOL = 1e-4  # m
HOLD_TOL = 1e-3  # m: a hand this close to its end of the part holds it (solve_along)
MAX_ADVANCE = 2.0  # points of its path a part moved in both hands goes on at most per point
STALL_STEPS = 4  # bisections of how far the part goes where the arms cannot take it further
RESOLVE_SIGMA = 3.0  # dense frames (50 ms at 60 fps): the Gaussian that smooths a correction
# rad: the correction changing more than this between two dense frames has changed IK branch
# (issue 19: a shoulder's abduction 40 -> 141 deg in one frame near the overhead singularity)
BRANCH_STEP = float(np.radians(3.0))
EPS = 1e-9


@dataclass(frozen=True)
class Carry:
    """Both hands closed on one two-handed part from ``start`` until ``end``."""

    site: str
    start: float
    end: float


def _grasps(ir: MotionIR, side: str) -> list[tuple[float, float, Segment | None]]:
    """(closes, opens, the contact the hand closed on) for each closed grip of one hand."""
    grips = sorted(
        (s for s in ir.on_track(HAND_TRACK[side]) if s.kind == "grip"), key=lambda s: s.start
    )
    out = []
    contacts = [r for r in ir.on_track(ARM_TRACK[side]) if r.kind == "TO"]
    duration = ir.duration  # (each a scan of every segment: once, not once per grip)
    for k, g in enumerate(grips):
        if g.goal.params.get("state") != "closed":
            continue
        opens = [o.start for o in grips[k + 1 :] if o.goal.params.get("state") == "open"]
        reach = max(
            (r for r in contacts if r.end <= g.start + EPS), key=lambda r: r.end, default=None
        )
        out.append((g.start, min(opens, default=duration), reach))
    return out


def _holds_part(reach: Segment | None) -> str:
    """The two-handed part a contact closes on ("" when none, or the hand fell short of it)."""
    if reach is None or not reach.goal.params.get("two_handed"):
        return ""
    return reach.goal.site if _on_its_site(reach) else ""


def _on_its_site(reach: Segment | None) -> bool:
    """Whether a contact put its hand on a site (within ``REACHED``)."""
    return (
        reach is not None
        and bool(reach.goal.site)
        and float(reach.result.get("distance", np.inf)) <= REACHED
    )


def _one_hand_leaves(ir: MotionIR, start: float, end: float) -> float:
    """When one hand first goes somewhere on its own between ``start`` and ``end`` (a reach,
    move or stroke that is not the two hands' goal): from then the part is no longer held by
    both (a generated procedure picked a part with both hands, then reached with the right one
    and turned a screw before `release(both)`: keeping the part rigid pulled the right arm back
    to it, and its elbow jumped 136 deg in one frame where the grip opened)."""
    first = end
    for s in ir.segments:
        if (
            s.kind in ("TA", "TO")
            and s.track in ARM_TRACK.values()
            and not s.goal.params.get("two_handed")
            and start - EPS <= s.start < first
        ):
            first = s.start
    return first


def hold_nothing(ir: MotionIR, start: float, end: float) -> bool:
    """Whether both hands are closed from ``start`` to ``end`` on grips whose contacts fell
    short of their sites (or had none): the hands hold no part (the avionics unit out of
    reach of the smaller manikins: they closed in the air, MT0501), so nothing sets how far
    apart they must stay (``carry_pose``)."""
    for side in ("r", "l"):
        spans = [g for g in _grasps(ir, side) if g[0] <= start + EPS and g[1] >= end - EPS]
        if not spans:
            return False
        if _on_its_site(spans[-1][2]):
            return False
    return True


def carries(ir: MotionIR) -> list[Carry]:
    """Every span where both hands hold the same two-handed part (as verify's rigid check),
    until either hand goes somewhere on its own."""
    out = []
    for r0, r1, r_reach in _grasps(ir, "r"):
        site = _holds_part(r_reach)
        if not site:
            continue
        for l0, l1, l_reach in _grasps(ir, "l"):
            if _holds_part(l_reach) != site:
                continue
            start, end = max(r0, l0), min(r1, l1)
            end = _one_hand_leaves(ir, start, end)
            if end > start + EPS:
                out.append(Carry(site, start, end))
    return sorted(out, key=lambda c: c.start)


HANDS = ("r_hand", "l_hand")


def hand_pair(skel: object, frames: Frames, rows: np.ndarray, q: FloatArray) -> FloatArray:
    """(N, 2, 3) the right and the left hand on the rows of ``frames`` with joints ``q``
    (``forward_part``: the hands' chains alone, ``forward``'s numbers; the carry's
    continuation asks for them at every point of a path)."""
    pose = forward_part(skel, q, frames.root_position[rows], frames.root_rotation[rows], HANDS)  # type: ignore[arg-type]
    return np.asarray(site_positions(skel, pose, list(HANDS)))  # type: ignore[arg-type]


def part_ends(hands: FloatArray, length: float) -> FloatArray:
    """(N, 2, 3) where the two hands hold a rigid part of ``length`` whose centre and axis are
    those of the hands' positions ``hands`` (N, 2, 3): the part's pose drives both goals.

    The axis is the line between the hands, kept pointing one way from frame to frame: a part
    does not turn end over end between two frames. Where the hands come closer than half the
    part's length its direction says little (two arms interpolated apart brought a 20 cm box's
    hands within 1 cm of each other), and it is interpolated between the frames around."""
    mid = hands.mean(axis=1)
    axis = hands[:, 0] - hands[:, 1]
    apart = np.linalg.norm(axis, axis=1)
    axis /= np.maximum(apart, 1e-12)[:, None]
    good = np.flatnonzero(apart >= 0.5 * length)
    if good.size:
        for a, b in itertools.pairwise(good):  # one way along the part
            if axis[b] @ axis[a] < 0.0:
                axis[b] = -axis[b]
        if good.size < len(axis):
            at = np.arange(len(axis))
            axis = np.stack([np.interp(at, good, axis[good, i]) for i in range(3)], axis=1)
            axis /= np.maximum(np.linalg.norm(axis, axis=1, keepdims=True), 1e-12)
    half = 0.5 * length * axis
    return np.stack([mid + half, mid - half], axis=1)


def part_path(hands: FloatArray, length: float) -> FloatArray:
    """(P, 2, 3) the two ends of a part moved in both hands along a path whose hands, each
    arm on its own path, are ``hands`` (P, 2, 3): the part's centre follows the hands'
    mid-point, its axis turns from the start's to the end's on the minimum-jerk clock of the
    path's progress (a rotation about one axis, not the line between two hands that each went
    their own way: the hood's hands were 20 to 48 cm apart between its two keys), and its
    length goes on the same clock from the start's to ``length``, the hands' distance where
    they closed on it (a part turned in both hands before it is moved may start the move
    squeezed: the pump's filter at 17 of 20 cm). Both hands' goals are rigid by construction."""
    mid = hands.mean(axis=1)
    ends = hands[[0, -1], 0] - hands[[0, -1], 1]
    start = float(np.linalg.norm(ends[0]))
    a0, a1 = (e / max(float(np.linalg.norm(e)), 1e-12) for e in ends)
    w = minimum_jerk(np.linspace(0.0, 1.0, len(hands)))
    angle = float(np.arccos(np.clip(a0 @ a1, -1.0, 1.0)))
    if angle < 1e-6:
        axis = np.broadcast_to(a0, mid.shape)
    else:  # slerp
        s = np.sin(angle)
        axis = (np.sin((1.0 - w) * angle)[:, None] * a0 + np.sin(w * angle)[:, None] * a1) / s
    half = 0.5 * (start + (length - start) * w)[:, None] * axis
    return np.stack([mid + half, mid - half], axis=1)


def solve_along(
    skel: object,
    frames: Frames,
    goal: FloatArray,
    dofs: dict[str, list[int]] | None = None,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Both arms (``dofs`` per hand; default the arm chains) solved onto the part's path
    ``goal`` (P, 2, 3) point after point, each from the one before moved by the path's own step
    (continuation): solved each on its own from the path's pose, two neighbouring points near
    the shoulder's overhead singularity landed on two IK branches (issue 19: a shoulder 100 deg
    apart). Where a hand cannot reach its end of the part, it leads: the other holds the part's
    other end where that hand is (the part lags or tilts a little). Where even that fails (the
    other hand further than ``HOLD_TOL`` from it), the part goes as far along its path as the
    arms can take it (bisection, ``STALL_STEPS``) and no further: it stops short of a goal out of reach, held, instead of
    one hand reaching on and the other falling behind (the hood edge stretched by 30 cm).
    It never goes further than ``MAX_ADVANCE`` points ahead of the point before, so it catches
    up gradually where the path comes back into reach. Returns the poses (P, D), each point's
    error (P,: the worse hand's distance from its end of the part, or the follower's from the
    leader's other end) and how far along the part's path each point took it (P,)."""
    q = frames.q.copy()
    error = np.zeros(len(q))
    along = np.zeros(len(q))
    arms = dofs or {hand: _arm_dofs(skel, hand) for hand in ("r_hand", "l_hand")}
    start = hand_pair(skel, frames, np.array([0]), q[:1])[0]
    error[0] = float(np.linalg.norm(start - goal[0], axis=-1).max())
    last = len(q) - 1

    def ends_at(s: float) -> FloatArray:
        k = min(int(s), last - 1)
        w = s - k
        return (1.0 - w) * goal[k] + w * goal[k + 1]

    def solve_at(k: int, seed: FloatArray, s: float) -> tuple[FloatArray, float]:
        pose = seed.copy()
        target = ends_at(s)
        for i, hand in enumerate(arms):
            pose = solve_hand(k, pose, hand, target[i])
        hands = hands_at(k, pose)
        off = np.linalg.norm(hands - target, axis=-1)
        if off.max() <= HOLD_TOL:
            return pose, float(off.max())
        # the hand that falls shorter leads: the other holds the part's other end where that
        # hand is (the part tilts or lags a little instead of stopping)
        lead = int(np.argmax(off))
        other = 1 - lead
        held = hands[lead] + target[other] - target[lead]
        pose = solve_hand(k, pose, list(arms)[other], held)
        hands = hands_at(k, pose)
        return pose, float(np.linalg.norm(hands[other] - held))

    paths = {hand: _rows_of(skel, frames, hand, chain) for hand, chain in arms.items()}

    def hands_at(k: int, pose: FloatArray) -> FloatArray:
        """(2, 3) both hands at row ``k`` with joints ``pose``: on the rows' scalar chains
        where they describe its body (``hand_pair``'s numbers to rounding, 1e-16 m), else
        ``hand_pair``."""
        rows = [paths.get(h) for h in HANDS]
        if any(r is None or not r.describes(k, pose) for r in rows):
            return hand_pair(skel, frames, np.array([k]), pose[None])[0]
        return np.array([r.site(k, pose) for r in rows])  # type: ignore[union-attr]

    def solve_hand(k: int, pose: FloatArray, hand: str, target: FloatArray) -> FloatArray:
        chain = arms[hand]
        rows = paths[hand]
        fast = None if rows is None else solve_ta_row(
            rows, k, pose, target, null_gain=0.0, tol=SOLVE_TOL)  # fmt: skip
        if fast is not None:
            return fast[0]
        # only the angles are read (``measure=False``): the hands are measured after
        res = solve_ta(
            skel, [Goal(hand, position=target)], pose, dofs=chain,  # type: ignore[arg-type]
            root_position=frames.root_position[k], root_rotation=frames.root_rotation[k],
            restarts=0, null_gain=0.0, tol=SOLVE_TOL, measure=False,
        )  # fmt: skip
        out = pose.copy()
        out[chain] = res.q[0, chain]
        return out

    for k in range(1, len(q)):
        seed = frames.q[k].copy()
        for chain in arms.values():
            seed[chain] = q[k - 1, chain] + frames.q[k, chain] - frames.q[k - 1, chain]
        s = min(float(k), along[k - 1] + MAX_ADVANCE)
        pose, err = solve_at(k, seed, s)
        if err > HOLD_TOL:
            lo, hi = along[k - 1], s
            pose, err = solve_at(k, seed, lo)
            s = lo
            for _ in range(STALL_STEPS if err <= HOLD_TOL else 0):
                mid = 0.5 * (lo + hi)
                p_mid, e_mid = solve_at(k, seed, mid)
                if e_mid <= HOLD_TOL:
                    lo, pose, err, s = mid, p_mid, e_mid, mid
                else:
                    hi = mid
        q[k], error[k], along[k] = pose, err, s
    return q, error, along


def _rows_of(skel: object, frames: Frames, hand: str, chain: list[int]) -> SerialRows | None:
    """``hand``'s arm ``chain`` prepared once for every row of ``frames`` (its poses and
    roots): ``solve_along``'s solves of that arm, hundreds a path, without a model each;
    None where the chain is not one serial chain (each solve then prepares its own)."""
    model = prepare(skel, [hand], frames.q, dofs=chain, root_position=frames.root_position,
                    root_rotation=frames.root_rotation)  # type: ignore[arg-type]  # fmt: skip
    try:
        return SerialRows(model)
    except ValueError:
        return None


def keep_rigid(
    skel: object,
    frames: Frames,
    carry: Carry,
    sigma: float = RESOLVE_SIGMA,
    held: float | None = 0.0,
) -> None:
    """Re-solve both arms on the carry's frames so the hands hold the part's two ends
    (``sigma``: the Gaussian, in frames, that smooths the correction before the second solve);
    after the carry the correction stays ``held`` s more (the hands opening on the part), then
    fades out (``_fade_out``; None: the frames after are left as they are, as the pace pass
    wants its path's end pose, the solver's, kept)."""
    t = frames.time
    rows = np.flatnonzero((t >= carry.start - EPS) & (t < carry.end - EPS))
    if rows.size < 2:
        return
    q = frames.q[rows].copy()
    hands = hand_pair(skel, frames, rows, q)
    length = float(np.linalg.norm(hands[0, 0] - hands[0, 1]))
    goal = part_ends(hands, length)
    off = np.linalg.norm(hands - goal, axis=-1).max(axis=1)
    fix = np.flatnonzero(off > FIX_FROM)
    if fix.size == 0:
        return
    q = solve_smoothed(skel, frames, rows, fix, q, hands, goal, sigma)
    arms = _both_arms(skel)
    if held is not None:
        keyed = frames.q[rows][:, arms]
        let_go = _let_go_at_branch_jumps(t[rows], q[:, arms] - keyed)
        if let_go is not None:  # no jump: the solved frames stay as they are, to the bit
            q[:, arms] = keyed + let_go
    if held is not None:
        _fade_out(frames, rows[-1], q[-1] - frames.q[rows[-1]], carry.end + held)
    # the solver's steps end up to 0.04 deg past a limit (MT0513 on the avionics unit's walk)
    frames.q[rows] = np.clip(q, skel.lower, skel.upper)  # type: ignore[attr-defined]


def solve_smoothed(
    skel: object, frames: Frames, rows: np.ndarray, fix: np.ndarray, q: FloatArray,
    hands: FloatArray, goal: FloatArray, sigma: float, dofs: dict[str, list[int]] | None = None,
) -> FloatArray:  # fmt: skip
    """``q`` (on ``rows``) with both arms on ``goal``: each frame of ``fix`` solved from its own
    pose, the correction smoothed in time (a Gaussian of ``sigma`` frames, its ends kept) and
    solved again from there. Each frame's solve converges where it will: the correction
    jumped from frame to frame (the avionics unit's elbow 18 deg in one output frame);
    solved again from the smoothed correction, each frame lands near its neighbours."""
    solved = solve_arms(skel, frames, rows, fix, q, hands, goal, dofs)
    arms = sorted({i for chain in dofs.values() for i in chain}) if dofs else _both_arms(skel)
    smooth = q.copy()
    smooth[:, arms] += smooth_path(solved[:, arms] - q[:, arms], sigma)
    hands2 = hand_pair(skel, frames, rows, smooth)
    fix2 = np.flatnonzero(np.linalg.norm(hands2 - goal, axis=-1).max(axis=1) > FIX_FROM)
    if not fix2.size:
        return smooth
    return solve_arms(skel, frames, rows, fix2, smooth, hands2, goal, dofs)


def _fade_out(frames: Frames, last: int, offset: FloatArray, start: float) -> None:
    """The correction at the carry's last frame (``offset``) kept until ``start`` and let go of
    over the frames after it on a minimum-jerk clock, not dropped at once: the hands open or
    one leaves, and the arms go on from where the part held them (a squat with a 15 kg part
    ended with a shoulder 67 deg away from its keyed pose, and it jumped there in one frame).
    The hands stay on the part while they open (the grip's time): contact is still made at
    rest."""
    largest = float(np.abs(offset).max(initial=0.0))
    if largest <= 1e-9 or last + 1 >= len(frames.time):
        return
    fade = max(MIN_FADE, 1.875 * largest / FADE_SPEED)
    t = frames.time[last + 1 :] - max(start, float(frames.time[last]))
    n = int(np.searchsorted(t, fade, side="right"))
    weight = 1.0 - minimum_jerk(np.maximum(t[:n], 0.0) / fade)
    frames.q[last + 1 : last + 1 + n] += weight[:, None] * offset[None, :]


def _let_go_at_branch_jumps(t: FloatArray, correction: FloatArray) -> FloatArray | None:
    """``correction`` (N, D) faded to nothing around each frame where it jumps: each frame is
    solved on its own, and near the shoulder's singularity two poses a few degrees apart
    converge to two IK branches (a shoulder 100 deg apart in one frame, issue 19). Solving each
    frame on from the previous one's pose instead held the part but drove the arms into their
    limits (a shoulder at 180 deg abduction, a wrist at 0) and jumped where the carry ended. So
    the arms let go of the correction on a minimum-jerk clock no faster than ``FADE_SPEED`` at its peak and pass the
    jump on the solved motion's own pose; the hands' distance there is what verify reports
    (MT0511). None where it does not jump."""
    step = np.abs(np.diff(correction, axis=0)).max(axis=1)
    jumps = np.flatnonzero(step > BRANCH_STEP)
    if jumps.size == 0:
        return None
    weight = np.ones(len(t))
    for j in jumps:
        largest = float(np.abs(correction[j : j + 2]).max())
        width = max(MIN_FADE, 1.875 * largest / FADE_SPEED)
        mid = 0.5 * (t[j] + t[j + 1])
        weight = np.minimum(weight, minimum_jerk(np.clip(np.abs(t - mid) / width, 0.0, 1.0)))
    return weight[:, None] * correction


def opening(ir: MotionIR, carry: Carry) -> float:
    """How long (s) the hands take to open on the part where the carry ends (0: one hand left
    it, or nothing opens then)."""
    ends = [
        s.end - carry.end
        for s in ir.segments
        if s.kind == "grip"
        and s.goal.params.get("state") == "open"
        and abs(s.start - carry.end) <= EPS
    ]
    return max(ends, default=0.0)


def solve_arms(
    skel: object, frames: Frames, rows: np.ndarray, fix: np.ndarray, q: FloatArray,
    hands: FloatArray, goal: FloatArray, dofs: dict[str, list[int]] | None = None,
) -> FloatArray:  # fmt: skip
    """``q`` with both arms (``dofs`` per hand; default the arm chains) of the rows ``fix``
    solved onto their ends of the part, where that brings the hand closer."""
    q = q.copy()
    sub = rows[fix]
    for k, hand in enumerate(("r_hand", "l_hand")):
        chain = dofs[hand] if dofs else _arm_dofs(skel, hand)
        model = prepare(
            skel, [hand], q[fix], dofs=chain,  # type: ignore[arg-type]
            root_position=frames.root_position[sub], root_rotation=frames.root_rotation[sub],
        )  # fmt: skip
        res = solve_ta(
            skel, [Goal(hand, position=goal[fix, k])], q[fix], model=model,  # type: ignore[arg-type]
            restarts=0, null_gain=0.0, tol=SOLVE_TOL,
        )  # fmt: skip
        before = np.linalg.norm(hands[fix, k] - goal[fix, k], axis=1)
        better = res.position_error < before
        q[fix[better]] = res.q[better]
    return q


def _both_arms(skel: object) -> list[int]:
    return sorted({i for hand in ("r_hand", "l_hand") for i in _arm_dofs(skel, hand)})


def run(ir: MotionIR, ctx: PassContext) -> MotionIR:
    frames = ir.frames
    if frames is None or not len(frames.time):
        return ir
    for carry in carries(ir):
        keep_rigid(ir.skeleton, frames, carry, held=opening(ir, carry))
    return ir
