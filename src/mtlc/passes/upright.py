"""Upright: the trunk a reach leaned comes back toward upright when no goal needs the lean.

A whole-body reach (approach, contact, pace) bends and turns the trunk; nothing but the next
segment that keys the trunk moved it again, so after a reach to the floor the body went on bent
double to the next task: a 3 s look at a gauge at head height was made with the trunk flexed
72 deg (male P50, tests/data/upright), and only a user-written ``stand()`` straightened it.

Here, after the keyframe passes that bend the trunk and before the gaze (whose neck and head
aim from the trunk they find), each gap between the segments that key the trunk (lumbar and
thorax) that follows a reach gets a ``rest`` segment on the ``spine`` track: the trunk goes to
its rest pose on a minimum-jerk ramp (``settle.ramp_length``: at least 0.6 s, 150 deg/s peak at
most) from the end of the reach, is held there, and, when a reach follows (solved from the
trunk as the last one left it), comes back to that pose before it starts; a posture that
follows starts from upright (``state.start_posture_from``). A hand still on a site (``hold``)
limits the return: the trunk comes back only as far as keeps its shoulder within
``PINNED_REACH`` of the held point (the hold pass then re-solves that arm on the dense frames,
and the balance pass keeps the centre of mass over the feet). Left as it is: a lean after a
squat, kneel, sit or a user's ``bend`` (the posture asked for it), a part carried in a closed
grip off any site (carry_pose owns that trunk), or a gap too short for the ramps.
"""

from __future__ import annotations

import itertools

import numpy as np

from mtlc.body import forward, site_positions
from mtlc.ir.model import FloatArray, GoalSpec, Keyframes, MotionIR, Segment
from mtlc.passes.context import PassContext
from mtlc.passes.hold import ARM_HAND, closed_at, hold_spans
from mtlc.passes.profile import minimum_jerk
from mtlc.passes.settle import NEAR, ramp_length
from mtlc.passes.state import TRUNK_DOFS, PoseState

REACHES = ("TA", "TO")  # the segments whose trunk lean is a means, not a goal
UPRIGHT_POSTURES = (None, "stand")  # a body in these (no posture yet, a stand) may straighten
PINNED_REACH = 0.95  # share of the arm's length a held point may be from its shoulder at most
RAMP_KEYS = 7  # keys along a ramp (the interpolation between two keys is not a profile)
BISECT_STEPS = 12
EPS = 1e-9


def trunk_gaps(ir: MotionIR) -> list[tuple[Segment, float, float, Segment | None]]:
    """(the segment that ends last, gap start, gap end, the next segment) for each gap between
    the segments whose keyframes move a trunk dof, and after the last one (to the end)."""
    trunk = set(TRUNK_DOFS)
    keyed = sorted(
        (s for s in ir.segments if s.keyframes is not None and trunk & set(s.keyframes.dofs)),
        key=lambda s: (s.start, s.end),
    )
    gaps: list[tuple[Segment, float, float, Segment | None]] = []
    last: Segment | None = None
    end = -np.inf
    for seg in keyed:
        if last is not None and seg.start > end + EPS:
            gaps.append((last, end, seg.start, seg))
        if seg.end >= end:
            end, last = seg.end, seg
    if last is not None and ir.duration > end + EPS:
        gaps.append((last, end, ir.duration, None))
    return gaps


def _posture_at(ir: MotionIR, t: float) -> str | None:
    """The whole-body posture the body is in at ``t`` (the last one started before it)."""
    started = [s for s in ir.on_track("root") if s.kind == "posture" and s.start < t - EPS]
    return max(started, key=lambda s: s.start).goal.params.get("posture") if started else None


def _carrying(ir: MotionIR, t: float, pinned: set[str]) -> bool:
    """A hand has a grip closed at ``t`` and is on no site: it carries a part."""
    for track, hand in ARM_HAND.items():
        grips = sorted((s for s in ir.on_track(hand) if s.kind == "grip"), key=lambda s: s.start)
        if track not in pinned and closed_at(grips, t + EPS):
            return True
    return False


def _arm_length(skel: object, side: str) -> float:
    """Shoulder to elbow to wrist to hand site, at the rest pose (segment lengths)."""
    q = np.asarray(skel.q_comfort, dtype=float)[None]  # type: ignore[attr-defined]
    pose = forward(skel, q, np.zeros((1, 3)), np.array([[1.0, 0.0, 0.0, 0.0]]), with_axes=False)
    joints = [skel.joint_index(f"{side}_{j}") for j in ("shoulder", "elbow", "wrist")]  # type: ignore[attr-defined]
    points = [*pose.p[0, joints], site_positions(skel, pose, f"{side}_hand")[0]]
    return float(sum(np.linalg.norm(b - a) for a, b in itertools.pairwise(points)))


def pinned_share(
    state: PoseState, t: float, q: FloatArray, offset: FloatArray, trunk: list[int],
    pinned: list[str],
) -> float:  # fmt: skip
    """How much of the trunk's way back (0..1) keeps every pinned hand's held point (where the
    hand is at ``t``) within ``PINNED_REACH`` of the arm's length from its shoulder, or no
    further than it is now (bisection: the distance grows as the trunk rises from the site)."""
    if not pinned:
        return 1.0
    skel = state.skel
    root = state.root_at(t)
    limits = []
    for track in pinned:
        side = track[0]
        held = state.site(f"{side}_hand", q, root)
        now = float(np.linalg.norm(held - state.site(f"joint:{side}_shoulder", q, root)))
        limits.append((side, held, max(now, PINNED_REACH * _arm_length(skel, side))))

    def fits(share: float) -> bool:
        moved = q.copy()
        moved[trunk] += share * offset
        for side, held, limit in limits:
            shoulder = state.site(f"joint:{side}_shoulder", moved, root)
            if float(np.linalg.norm(held - shoulder)) > limit + 1e-6:
                return False
        return True

    if fits(1.0):
        return 1.0
    lo, hi = 0.0, 1.0
    for _ in range(BISECT_STEPS):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if fits(mid) else (lo, mid)
    return lo


def _ramp_keys(
    start: float, length: float, q_from: FloatArray, q_to: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """``RAMP_KEYS`` keys of a minimum-jerk ramp from ``q_from`` to ``q_to`` over ``length``."""
    f = np.linspace(0.0, 1.0, RAMP_KEYS)
    share = minimum_jerk(f)
    return start + f * length, q_from[None] + share[:, None] * (q_to - q_from)[None]


def upright_segment(
    ir: MotionIR, state: PoseState, last: Segment, gap: tuple[float, float],
    after: Segment | None,
) -> Segment | None:  # fmt: skip
    """The ``rest`` segment that straightens the trunk over ``gap``, or None (see module)."""
    a, b = gap
    if last.kind not in REACHES or _posture_at(ir, a) not in UPRIGHT_POSTURES:
        return None
    # a reach that keys the arms only (a two-handed part's lift) is solved on the lean too
    arm_only = [s for s in ir.segments if s.kind in REACHES and a - EPS <= s.start < b - EPS]
    if arm_only:
        after = min(arm_only, key=lambda s: s.start)
        b = after.start
    skel = state.skel
    trunk = [skel.dof_index(n) for n in TRUNK_DOFS]
    spans = [(seg.track, end) for seg, end in hold_spans(ir) if seg.start - EPS <= a < end - EPS]
    # a hand that lets go during the gap frees the trunk from then on, when room is left
    start = max([a, *(end for _, end in spans if end < b - EPS)])
    pinned = sorted({track for track, end in spans if end >= b - EPS})
    if _carrying(ir, start, set(pinned)):
        return None
    q = state.q_at(start)
    offset = state.rest[trunk] - q[trunk]
    offset *= pinned_share(state, start, q, offset, trunk, pinned)
    if float(np.abs(offset).max(initial=0.0)) <= NEAR:
        return None
    back = after is not None and after.kind != "posture"  # a reach solved from the lean
    room = (b - start) / (2.0 if back else 1.0)
    length = ramp_length(offset, room)
    if length < ramp_length(offset, np.inf) - EPS:
        return None  # too short a gap for a ramp at a person's speed
    lean, upright = q[trunk], q[trunk] + offset
    times, keys = _ramp_keys(start, length, lean, upright)
    if back:
        fall_t, fall_q = _ramp_keys(b - length, length, upright, lean)
        times, keys = np.r_[times, fall_t], np.vstack([keys, fall_q])
    clipped = np.clip(keys, skel.lower[trunk], skel.upper[trunk])
    return Segment(
        track="spine",
        kind="rest",
        start=float(start),
        end=float(b if back else start + length),
        goal=GoalSpec(effector="body", params={"upright": [float(v) for v in offset]}),
        provenance=last.provenance,
        keyframes=Keyframes(time=times, dofs=TRUNK_DOFS, q=clipped),
    )


def run(ir: MotionIR, ctx: PassContext) -> MotionIR:
    """A ``rest`` segment on the spine for each gap after a reach that left the trunk leaned."""
    if ir.skeleton is None:
        return ir
    state = PoseState(ir)
    for last, a, b, after in trunk_gaps(ir):
        seg = upright_segment(ir, state, last, (a, b), after)
        if seg is not None:
            ir.segments.append(seg)
            state.add(seg)
    return ir
