"""Pass 5b: a hand that holds a site stays on it while the rest of the body moves.

The solving passes key each segment's own dofs at its own times; interpolation then blends every
dof separately. A hand that reached its site and holds it (a bowl it unscrews, a handle it
steadies) is therefore on the site only at the keyframes: while the other hand's reach bends the
trunk, or a kneel lowers the body, the held arm keeps its angles and the hand is dragged with
the shoulder (121 mm off the fuel filter's bowl for a P5 woman, 560 mm for a lever reached
behind the body before a kneel). Here, on the dense frames, a held hand is an IK goal at every
frame: its arm (shoulder, elbow flexion, wrist; not the forearm's twist, which a `turn` sets)
is re-solved from the interpolated pose onto the held point, warm-started frame by frame so the
motion stays as smooth as the body's.

A hold (``hold_windows``) runs from the end of a contact (TO) segment until the hand's next arm
segment starts, a walk starts (the part is carried from then on: it moves with the hand), a
posture starts through which the hand carries its part (``carried_postures``: a grip that
takes its part somewhere, by a move or a walk, before it opens; a part picked from the floor
rises with the hand as the body stands), a whole-body posture starts while the hand has no
grip closed (a hand that only touched a site
does not stay on it through a squat) or the hand lets go for good (its last grip event in that
time is a release: the hold ends with it).
The held point is the site (the segment's goal position) when the contact reached it, else
where the hand stopped. After a hold the correction fades out over ``FADE`` seconds or more, so
the arm does not jump when the hand is free again; after a hold that a walk ends, the part is
carried and the correction stays until the hand's next arm motion or release.

Where the arm cannot keep the hand there (the kneel takes the shoulder out of reach), the hand
stays as close as it can and lets go. This pass reports nothing: the verify pass measures the
hand on the output frames and reports it (MT0511 for a closed grip or a hand resting on the site
it reached; MT0520, which this pass used to raise for the same fault, is retired).
"""

from __future__ import annotations

from bisect import bisect_left
from dataclasses import dataclass
from typing import Any

import numpy as np

from mtlc.body import part_site_positions
from mtlc.body.ik import Goal, default_dofs, prepare, solve_ta
from mtlc.ir.model import FloatArray, Frames, MotionIR, Segment
from mtlc.passes.context import PassContext
from mtlc.passes.profile import minimum_jerk

ARM_HAND = {"r_arm": "r_hand", "l_arm": "l_hand"}
SOLVE_TOL = 2e-4  # m: the held point is restored this close
REPORT_TOL = 1e-3  # m: further than this on a frame, the hand has let go
FIX_FROM = 5e-5  # m: frames already this close are left alone
FADE = 0.25  # s over which a hold's correction fades out after it ends, at least...
FADE_RATE = 2.0  # rad/s: ...so that no dof fades faster than this
PEAK_RATE = 1.875  # a minimum-jerk ramp's fastest rate over its mean (Flash & Hogan 1985)
EPS = 1e-6
# s into a whole-body posture a free hand (no grip closed) stays on the site it touched: the
# frame a user receives at the end of its contact (the next output frame, up to 1/10 s later)
# still shows it there, and then the hand goes with the body
LET_GO = 0.1
MAX_SWING = 0.15  # rad a hold's correction may change in one dense frame (9 deg at 60 fps)


@dataclass
class Hold:
    """One hand holding one point from ``start`` until ``end`` (``seg``: the contact)."""

    seg: Segment
    effector: str
    start: float
    end: float
    point: FloatArray | None  # None: where the hand is at ``start``


def _is_open(seg: Segment) -> bool:
    return seg.kind == "grip" and seg.goal.params.get("state") == "open"


def closed_at(grips: list[Segment], t: float) -> bool:
    """Whether the hand's last grip event that starts before ``t`` closed it."""
    before = [g for g in grips if g.start < t - EPS]
    return bool(before) and not _is_open(before[-1])


def closed_during(grips: list[Segment], lo: float, hi: float) -> bool:
    """Whether the hand's grip (its ``grip`` segments, in time order) is closed at some time in
    ``[lo, hi)``: closed at ``lo``, or closing after it."""
    return closed_at(grips, lo) or any(
        not _is_open(g) for g in grips if lo - EPS <= g.start < hi - EPS
    )


def last_opening(grips: list[Segment], lo: float, hi: float) -> float:
    """When, in ``[lo, hi)``, the hand's grip opens for the last time after being closed in
    it (``hi`` if it is closed at ``hi`` or never closed in it): where a hand that holds a part
    short of its site lets go of it."""
    closed, out = closed_at(grips, lo), hi
    for g in grips:
        if not lo - EPS <= g.start < hi - EPS:
            continue
        if _is_open(g) and closed:
            out = g.start
        elif not _is_open(g):
            out = hi
        closed = not _is_open(g)
    return out


def carried_postures(ir: MotionIR) -> dict[str, list[Segment]]:
    """Per arm track, the whole-body postures (squat, kneel, stand, bend; not a hand's twist)
    through which its hand carries the part it holds, so the part goes with the body.

    A closed grip *transports* its part when, before the hand opens, the hand takes it
    somewhere: an arm goal of that hand (a `move`: a reach or move while the grip is closed;
    not a wrench's stroke, which turns a fastener that stays) or a walk. Every posture that
    starts while such a grip is closed carries the part: picked from the floor, a part rises
    with the hand when the body stands up. A grip that nothing takes anywhere before it opens
    (a handle steadied through a kneel, a rail held) keeps its part where it is, and the hand
    on it (the hold pass; MT0511 when it cannot)."""
    walks = [s.start for s in ir.segments if s.kind == "locomotion"]
    postures = [
        s for s in ir.segments
        if s.kind == "posture" and s.goal.params.get("posture") != "twist"
    ]  # fmt: skip
    out: dict[str, list[Segment]] = {track: [] for track in ARM_HAND}
    for track, hand in ARM_HAND.items():
        grips = sorted((s for s in ir.on_track(hand) if s.kind == "grip"), key=lambda s: s.start)
        goals = [
            s.start for s in ir.on_track(track)
            if s.kind in ("TA", "TO") and "stroke" not in s.goal.params
        ]  # fmt: skip
        moves = sorted((*goals, *walks))  # a grip takes its part if one starts before it opens
        for closing in _closing_opens(grips):
            if closing is None:
                continue
            g, opens = closing
            first = bisect_left(moves, g.start - EPS)
            if first < len(moves) and moves[first] < opens - EPS:
                out[track] += [p for p in postures if g.start - EPS <= p.start < opens - EPS]
    return out


def _closing_opens(grips: list[Segment]) -> list[tuple[Segment, float] | None]:
    """Per grip of one hand (in time order): a closing grip and the start of the first release
    after it (inf: none), None for a release. One scan back instead of a scan of the later
    grips per grip (a long procedure has hundreds)."""
    out: list[tuple[Segment, float] | None] = [None] * len(grips)
    opens = np.inf
    for k in range(len(grips) - 1, -1, -1):
        g = grips[k]
        if _is_open(g):
            opens = g.start
        else:
            out[k] = (g, opens)
    return out


def hold_spans(ir: MotionIR) -> list[tuple[Segment, float]]:
    """Each contact (TO) segment with the time its hand stops holding: the hand's next arm
    segment, the next walk, a whole-body posture while the hand's grip is open or through which
    it carries its part (``carried_postures``), or the end of
    a release not followed by a new grasp, whichever comes first (the end of the motion when
    none does)."""
    by_track: dict[str, list[Segment]] = {}
    walks: list[float] = []
    postures: list[float] = []
    for seg in ir.segments:
        by_track.setdefault(seg.track, []).append(seg)
        if seg.kind == "locomotion":
            walks.append(seg.start)
        elif seg.kind == "posture" and seg.goal.params.get("posture") != "twist":
            postures.append(seg.start)
    out = []
    carried = carried_postures(ir)
    duration = ir.duration  # (a scan of every segment: once, not once per contact)
    walks_sorted = sorted(walks)
    for track, hand in ARM_HAND.items():
        arm = sorted(by_track.get(track, []), key=lambda s: s.start)
        grips = sorted(
            (s for s in by_track.get(hand, []) if s.kind == "grip"), key=lambda s: s.start
        )
        # each list sorted: the earliest of each kind after a contact is a bisection, not a scan
        # (a long procedure's hundreds of contacts each scanned every segment)
        arm_starts = [s.start for s in arm]
        grip_starts = [g.start for g in grips]
        carried_starts = sorted(p.start for p in carried[track])
        # a hand that only touched its site (no grip closed on it) lets go when the body
        # changes posture: holding an overhead latch through a squat would stretch the arm
        # to its limit and then drop it, and pin the trunk of the reaches after it
        free = sorted(t for t in postures if not closed_at(grips, t))
        for seg in arm:
            if seg.kind != "TO" or "stroke" in seg.goal.params:
                continue
            after = seg.end - EPS
            ends = []
            i = bisect_left(arm_starts, after)
            if i < len(arm) and arm[i] is seg:
                i += 1  # (the contact itself, when it ends where it starts)
            if i < len(arm):
                ends.append(arm_starts[i])
            for times in (walks_sorted, carried_starts):
                # a part the hand takes somewhere goes with the body through a posture, as
                # with a walk
                i = bisect_left(times, after)
                if i < len(times):
                    ends.append(times[i])
            i = bisect_left(free, after)
            if i < len(free):
                ends.append(free[i] + LET_GO)
            end = min(ends, default=duration)
            last = bisect_left(grip_starts, end - EPS) - 1  # the last grip event before the end
            if last >= 0 and grip_starts[last] >= after and _is_open(grips[last]):
                end = min(end, grips[last].end)  # let go and not taken again: the hold ends
            out.append((seg, end))
    return out


def holding(ir: MotionIR, t: float, memo: dict[Any, Any] | None = None) -> set[str]:
    """The arm tracks whose hand is on a site at ``t`` (from its contact's start until its
    hold ends): what a reach of the other hand must not pull away."""
    key = ("hold_spans", len(ir.segments))
    if memo is not None and key in memo:
        spans = memo[key]
    else:
        spans = hold_spans(ir)
        if memo is not None:
            memo[key] = spans
    return {seg.track for seg, end in spans if seg.start - EPS <= t < end - EPS}


def on_site(ir: MotionIR, time: FloatArray) -> dict[str, np.ndarray]:
    """(N,) per hand (``r_hand``, ``l_hand``): the frames where it is on a site, from the start
    of a contact until its hold ends (``hold_spans``: its next arm segment, a walk, or a release
    it does not take back). A hand that has let go is free, though no arm segment follows."""
    t = np.asarray(time, dtype=float)
    out = {hand: np.zeros(len(t), dtype=bool) for hand in ARM_HAND.values()}
    for seg, end in hold_spans(ir):
        out[ARM_HAND[seg.track]] |= (t >= seg.start - EPS) & (t < end - EPS)
    return out


def hold_windows(ir: MotionIR) -> list[Hold]:
    """Every hold of the motion, in time order (see the module docstring)."""
    holds = []
    for seg, end in hold_spans(ir):
        if seg.goal.position is None or end <= seg.end + EPS:
            continue
        reached = float(seg.result.get("distance", np.inf)) <= REPORT_TOL
        point = np.asarray(seg.goal.position, dtype=float) if reached else None
        holds.append(Hold(seg, seg.goal.effector, seg.end, end, point))
    return sorted(holds, key=lambda h: h.start)


def _arm_dofs(skel: Any, effector: str) -> list[int]:
    """The arm chain without the forearm's twist (a `turn` owns that dof)."""
    return [d for d in default_dofs(skel, [effector], "arm") if "_pro" not in skel.dof_names[d]]


def _site(skel: Any, frames: Frames, rows: np.ndarray, effector: str, q: FloatArray) -> FloatArray:
    root, rotation = frames.root_position[rows], frames.root_rotation[rows]
    return part_site_positions(skel, q, root, rotation, [effector])[:, 0]


def keep_hold(
    skel: Any, frames: Frames, hold: Hold
) -> tuple[np.ndarray, FloatArray, FloatArray] | None:
    """Re-solve the held arm on the hold's frames: (rows, corrected q, remaining distance)."""
    t = frames.time
    rows = np.flatnonzero((t >= hold.start - EPS) & (t < hold.end - EPS))
    if rows.size == 0:
        return None
    q = frames.q[rows].copy()
    here = _site(skel, frames, rows, hold.effector, q)
    point = here[0] if hold.point is None else hold.point
    dist = np.linalg.norm(here - point, axis=1)
    fix = dist > FIX_FROM
    if fix.any():
        sub = rows[fix]
        model = prepare(
            skel, [hold.effector], q[fix], dofs=_arm_dofs(skel, hold.effector),
            root_position=frames.root_position[sub], root_rotation=frames.root_rotation[sub],
        )  # fmt: skip
        goal = Goal(hold.effector, position=np.tile(point, (int(fix.sum()), 1)))
        res = solve_ta(skel, [goal], q[fix], model=model, restarts=0, null_gain=0.0, tol=SOLVE_TOL)
        better = res.position_error < dist[fix]
        idx = np.flatnonzero(fix)[better]
        q[idx] = res.q[better]
        dist[idx] = res.position_error[better]
    # a frame the arm reaches only by a sudden swing (near its limits the nearest pose may
    # change branch) is one the hand cannot follow smoothly: it is let go there as well
    swing = np.abs(np.diff(q - frames.q[rows], axis=0)).max(axis=1, initial=0.0)
    lost = np.union1d(np.flatnonzero(dist > REPORT_TOL), np.flatnonzero(swing > MAX_SWING) + 1)
    if lost.size:
        # out of the arm's reach from frame ``f`` on: the hand holds until then and lets go
        # there, the correction fading out at a bounded rate (a best-effort pose per frame
        # would jump between branches); what the hand then misses is measured and reported
        f = int(lost[0])
        delta = q[f - 1] - frames.q[rows[f - 1]] if f > 0 else np.zeros(skel.n_dofs)
        t = frames.time[rows[f:]]
        fade = max(FADE, float(np.abs(delta).max()) / FADE_RATE)
        w = np.clip(1.0 - (t - t[0]) / fade, 0.0, 1.0)
        q[f:] = frames.q[rows[f:]] + w[:, None] * delta[None]
        dist[f:] = np.linalg.norm(
            _site(skel, frames, rows[f:], hold.effector, skel.clip(q[f:])) - point, axis=1
        )
    return rows, q, dist


def carried_until(ir: MotionIR, hold: Hold, carried: dict[str, list[Segment]]) -> float:
    """When a hold ends because a walk or a carried posture (``carried``, the motion's
    ``carried_postures``) starts, the part is carried: the hand keeps its grip on the body (its
    arm's correction stays as it was) until the hand's next arm segment or a release; otherwise
    the hold's end."""
    if not any(
        s.kind == "locomotion" and abs(s.start - hold.end) <= EPS for s in ir.segments
    ) and not any(abs(p.start - hold.end) <= EPS for p in carried[hold.seg.track]):
        return hold.end
    hand = ARM_HAND.get(hold.seg.track, "")
    later = [
        s.start
        for s in ir.segments
        if s.start >= hold.end - EPS
        and (s.track == hold.seg.track or (s.track == hand and _is_open(s)))
    ]
    return min(later, default=ir.duration + 1.0)


def _fade(
    skel: Any, frames: Frames, start: float, carry: float, delta: FloatArray, until: float
) -> None:
    """Keep the last frame's correction ``delta`` (n_dofs,) from ``start`` until ``carry``
    (a carried part), then blend it out on a minimum-jerk ramp at a bounded rate, stopping at
    ``until``. A linear ramp set the arm moving at its full rate in the frame the hold ended:
    where a move takes the hand away from rest there, its first frame went 18 cm/s (the fuel
    filter's cartridge, male P1, issue 19)."""
    if not np.any(delta):
        return
    t = frames.time
    # the ramp's fastest rate is PEAK_RATE times its mean
    fade = max(FADE, PEAK_RATE * float(np.abs(delta).max()) / FADE_RATE)
    if carry < until < carry + fade:  # done by the next hold, not cut off by it
        fade = until - carry
    stop = min(carry + fade, until)
    rows = np.flatnonzero((t >= start - EPS) & (t < stop - EPS))
    if rows.size == 0:
        return
    w = 1.0 - minimum_jerk(np.clip((t[rows] - carry) / fade, 0.0, 1.0))
    frames.q[rows] = skel.clip(frames.q[rows] + w[:, None] * delta[None])


def _ease_in(skel: Any, frames: Frames, contact: Segment, delta: FloatArray) -> None:
    """Add the hold's first correction ``delta`` (n_dofs,) over the contact segment that leads
    into it, on a minimum-jerk ramp that ends at rest on the hold. The contact stops within
    1 mm of its site and the hold puts the hand on it: as a step on the hold's first frame,
    0.3 mm in 1/60 s was the largest jerk of a slow 14 cm move (aircraft_panel_sideways male
    P99, LDLJ -9.6)."""
    if not np.any(delta):
        return
    t = frames.time
    rows = np.flatnonzero((t > contact.start + EPS) & (t < contact.end - EPS))
    if rows.size == 0:
        return
    w = minimum_jerk((t[rows] - contact.start) / (contact.end - contact.start))
    frames.q[rows] = skel.clip(frames.q[rows] + w[:, None] * delta[None])


def run(ir: MotionIR, ctx: PassContext) -> MotionIR:
    frames = ir.frames
    skel = ir.skeleton
    if frames is None or not len(frames.time):
        return ir
    holds = hold_windows(ir)
    carried = carried_postures(ir)  # once: the segments do not change in this pass
    for k, hold in enumerate(holds):
        kept = keep_hold(skel, frames, hold)
        if kept is None:
            continue
        rows, q, _ = kept
        delta = q[-1] - frames.q[rows[-1]]
        _ease_in(skel, frames, hold.seg, q[0] - frames.q[rows[0]])
        frames.q[rows] = skel.clip(q)
        # the next hold of the same hand takes over where it starts
        nxt = [h.start for h in holds[k + 1 :] if h.seg.track == hold.seg.track]
        carry = carried_until(ir, hold, carried)
        _fade(skel, frames, hold.end, carry, delta, min(nxt, default=np.inf))
    return ir
