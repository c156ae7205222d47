"""Pass 9d: a walk with both hands free starts from a natural stand (issue 19).

A walk keys the legs and the root only; every other joint holds what the segment before it left.
After a reach that bent the trunk (a 14 kg battery set on a bench at 90 cm, vehicle_battery) and
a release, the manikin walked back 6.4 s with the trunk bent ~57 deg (lumbar 45, thorax 12) and
the elbows at 30 and 65 deg: the reach's pose, kept because nothing asked for another.

Here, on the dense frames of a walk on which neither hand holds anything (no grip closed, not
on a site, no arm segment during the walk), the trunk (lumbar and thorax) goes to its rest pose
and each arm to the comfort pose, on minimum-jerk ramps from the walk's start
(``ramp_length``). The trunk stays upright to the end unless a reach or posture follows, solved
on the trunk as it was: then it goes back before the walk ends (``_settle_trunk``). An arm stays
down until its next segment and is let go of over it (``keep_until_keyed``, which carry_pose
uses too), unless its way down goes deeper into the body (``_deeper``). A walk that carries a
part is left to carry_pose (its trunk too).
"""

from __future__ import annotations

import math
from collections.abc import Collection
from dataclasses import dataclass

import numpy as np

from mtlc.body import part_site_positions
from mtlc.body.ik.clearance import penetrations
from mtlc.body.skeleton import Skeleton
from mtlc.ir.model import FloatArray, Frames, MotionIR
from mtlc.passes.context import PassContext
from mtlc.passes.hold import ARM_HAND, _arm_dofs, closed_at, on_site
from mtlc.passes.profile import minimum_jerk, smooth_path

TRUNK = tuple(f"{j}_{a}" for j in ("lumbar", "thorax") for a in ("flex", "lat", "rot"))
NEAR = math.radians(2.0)  # rad: a group of joints this close to its rest pose is left alone
SPEED = math.radians(150.0)  # rad/s: a ramp's peak joint speed at most (mean 80 deg/s)
PEAK = 1.875  # a minimum-jerk ramp's peak speed over its mean
MIN_RAMP = 0.6  # s: the shortest ramp
MIN_PATH = 0.01  # m: a reach whose effector moves less is not re-timed (a turn in place)
PATH_POINTS = 121  # a re-timed reach's path, resampled at even steps of arc length
SMOOTH_SIGMA = 0.1  # of the path's arc length: pace's least smoothing
MIN_FADE = 0.3  # s: the shortest fade of a correction over the segment that keys its joint
DEEPER_TOL = 0.005  # m: how much deeper a let-down arm that was inside may go on a frame
EPS = 1e-9


def ramp_length(offset: FloatArray, room: float) -> float:
    """Seconds a minimum-jerk ramp of ``offset`` (rad) takes: at least ``MIN_RAMP``, no joint
    faster than ``SPEED`` on average, at most ``room``."""
    return min(room, max(MIN_RAMP, PEAK * float(np.abs(offset).max(initial=0.0)) / SPEED))


@dataclass(frozen=True)
class Keyed:
    """The first movement that keys a joint after a correction: its window, the effector whose
    reach it is (None: not a reach) and the dofs its segments key."""

    start: float
    end: float
    effector: str | None = None
    dofs: frozenset[str] = frozenset()


def next_movement(ir: MotionIR, names: Collection[str], after: float) -> Keyed | None:
    """The first movement starting at ``after`` or later whose keyframes move any of the dofs
    ``names``; None when none does. A TA runs on through the TO that continues it (same track,
    adjacent): pace times the two as one bell."""
    keyed = [
        s
        for s in ir.segments
        if s.start >= after - EPS
        and s.keyframes is not None
        and not names.isdisjoint(s.keyframes.dofs)
    ]
    if not keyed:
        return None
    first = min(keyed, key=lambda s: (s.start, s.end))
    if first.kind not in ("TA", "TO"):
        return Keyed(first.start, first.end)
    chain = [first]
    if first.kind == "TA":
        chain += [
            s for s in ir.on_track(first.track)
            if s.kind == "TO" and s.keyframes is not None and abs(s.start - first.end) < EPS
        ][:1]  # fmt: skip
    sites = {site.name for site in ir.skeleton.sites}
    effector = first.goal.effector if first.goal.effector in sites else None
    dofs = frozenset(n for s in chain for n in s.keyframes.dofs)
    return Keyed(first.start, chain[-1].end, effector, dofs)


def next_keyed(ir: MotionIR, names: Collection[str], after: float) -> tuple[float, float] | None:
    """(start, end) of ``next_movement``."""
    m = next_movement(ir, names, after)
    return None if m is None else (m.start, m.end)


def repace(skel: Skeleton, frames: Frames, m: Keyed, dofs: list[int]) -> None:
    """Make the reach ``m``, with a correction let go of over it on ``dofs``, one movement
    again, in place: its joints' path (the reach's own dofs and ``dofs``) at even steps of the
    effector's arc length, low-passed as pace does (``SMOOTH_SIGMA``, both ends kept), then
    run on one minimum-jerk bell over the window. The correction's ramp added to the reach's
    made a second bell where the two pulled the hand different ways, and a corner where the
    reach turned onto its site (aircraft_panel_sideways' move after a carried stand: two
    speed peaks, LDLJ -7.0 -> -8.5)."""
    t = frames.time
    rows = np.flatnonzero((t >= m.start - EPS) & (t <= m.end + EPS))
    if m.effector is None or rows.size < 4 or m.end - m.start <= EPS:
        return
    cols = sorted({*dofs, *(skel.dof_index(n) for n in m.dofs)})
    q = frames.q[rows]
    p = part_site_positions(
        skel, q, frames.root_position[rows], frames.root_rotation[rows], [m.effector]
    )[:, 0]
    step = np.linalg.norm(np.diff(p, axis=0), axis=1)
    total = float(np.sum(step))
    if total <= MIN_PATH:
        return
    u = np.concatenate([[0.0], np.cumsum(step)]) / total
    u += np.arange(len(u)) * 1e-12  # strictly rising where the hand stood still
    even = np.linspace(0.0, 1.0, PATH_POINTS)
    path = np.stack([np.interp(even, u, q[:, d]) for d in cols], axis=1)
    path = smooth_path(path, SMOOTH_SIGMA * (PATH_POINTS - 1))
    s = minimum_jerk((t[rows] - m.start) / (m.end - m.start))
    for k, d in enumerate(cols):
        frames.q[rows, d] = np.interp(s, even, path[:, k])
    frames.q[np.ix_(rows, cols)] = np.clip(
        frames.q[np.ix_(rows, cols)], skel.lower[cols], skel.upper[cols]
    )


def keep_until_keyed(
    skel: Skeleton, ir: MotionIR, frames: Frames, dofs: list[int], offset: FloatArray,
    rise: tuple[float, float], until: Collection[str] | None = None,
) -> None:  # fmt: skip
    """Add ``offset`` (len(dofs),) to ``dofs`` in place: on a minimum-jerk ramp over ``rise``
    (start, end), then held until the next segment that keys one of the dofs ``until`` (the
    dofs themselves by default) starts (in ``rise`` or later), and faded out over that segment
    (at least ``MIN_FADE``), so the segment, solved from the pose before the correction, ends
    where it was solved to."""
    t = frames.time
    a, b = rise
    if b > a + EPS:
        up = minimum_jerk(np.clip((t - a) / (b - a), 0.0, 1.0)) * (t >= a - EPS)
    else:  # a step: the frames from ``a`` on
        up = (t >= a - EPS).astype(float)
    span = _let_go(skel, ir, dofs, a, until)
    down = np.ones_like(t)
    end = np.inf
    if span is not None:  # kept until that movement, let go of over it
        start, end = span.start, max(span.end, span.start + MIN_FADE)
        down = 1.0 - minimum_jerk(np.clip((t - start) / (end - start), 0.0, 1.0))
    rows = np.flatnonzero((t >= a - EPS) & (t < end))
    weight = np.minimum(up[rows], down[rows])
    moved = frames.q[np.ix_(rows, dofs)] + weight[:, None] * offset[None]
    frames.q[np.ix_(rows, dofs)] = np.clip(moved, skel.lower[dofs], skel.upper[dofs])
    if span is not None and span.start >= a + EPS:  # let go of over a reach: one bell again
        repace(skel, frames, span, dofs)


def _let_go(
    skel: Skeleton, ir: MotionIR, dofs: list[int], a: float, until: Collection[str] | None
) -> Keyed | None:
    """The movement over which ``keep_until_keyed`` lets go of its correction (None: none)."""
    names = set(until) if until is not None else {skel.dof_names[d] for d in dofs}
    return next_movement(ir, names, a)


def kept_rows(
    skel: Skeleton, ir: MotionIR, frames: Frames, dofs: list[int], rise: tuple[float, float],
    until: Collection[str] | None = None,
) -> slice:  # fmt: skip
    """The frames ``keep_until_keyed`` may change (the ramp's, the hold's and the let-go
    movement's, which ``repace`` re-times): what a caller that may undo it keeps a copy of,
    instead of every frame of the motion for every walk."""
    t = frames.time
    lo = int(np.searchsorted(t, rise[0] - EPS))
    span = _let_go(skel, ir, dofs, rise[0], until)
    if span is None:
        return slice(lo, len(t))
    end = max(span.end, span.start + MIN_FADE)
    hi = max(int(np.searchsorted(t, end)), int(np.searchsorted(t, span.end + EPS, "right")))
    return slice(lo, max(lo, hi))


def free_arms(ir: MotionIR, start: float, end: float, held: dict[str, np.ndarray]) -> list[str]:
    """The arm tracks whose hand is free over ``start``..``end``: no grip closed at ``start``,
    not on a site (``held``: ``hold.on_site`` at ``start``), no segment of the arm in between."""
    out = []
    for track, hand in ARM_HAND.items():
        grips = sorted((s for s in ir.on_track(hand) if s.kind == "grip"), key=lambda s: s.start)
        busy = any(s.start < end - EPS and s.end > start + EPS for s in ir.on_track(track))
        if not busy and not closed_at(grips, start + EPS) and not bool(held[hand][0]):
            out.append(track)
    return out


def settle_walk(
    skel: Skeleton, ir: MotionIR, frames: Frames, start: float, end: float, tracks: list[str],
    trunk: bool = True,
) -> None:  # fmt: skip
    """Lead the trunk (``trunk``), and the arms of ``tracks``, to the rest pose from the walk's
    start."""
    t = frames.time
    i = int(np.searchsorted(t, start - EPS))
    if i >= len(t) or end - start <= EPS:
        return
    rest = np.asarray(skel.q_comfort, dtype=float)
    arms = [n for hand in ARM_HAND.values() for n in _names(skel, _arm_dofs(skel, hand))]
    way = trunk_offset(skel, frames.q[i]) if trunk else None
    if way is not None:
        _settle_trunk(skel, ir, frames, (start, end), *way, [*TRUNK, *arms])
    for track in tracks:  # a free arm hangs until its next segment, let go of over it
        dofs = _arm_dofs(skel, ARM_HAND[track])
        offset = rest[dofs] - frames.q[i, dofs]
        if float(np.abs(offset).max()) <= NEAR:
            continue
        rise = (start, start + ramp_length(offset, end - start))
        # a copy of the frames it may change (of every frame, per walk and arm, it was a fifth
        # of the pass on a long procedure)
        kept = kept_rows(skel, ir, frames, dofs, rise)
        before = frames.q[kept].copy()
        keep_until_keyed(skel, ir, frames, dofs, offset, rise)
        if _deeper(skel, frames, kept, before, track[0]):
            frames.q[kept] = before


def trunk_offset(skel: Skeleton, q: FloatArray) -> tuple[list[int], FloatArray] | None:
    """(the trunk's dofs, their way from ``q`` to the rest pose), or None where the trunk is
    within ``NEAR`` of it already: what a walk straightens (here, and in carry_pose)."""
    dofs = [skel.dof_index(n) for n in TRUNK]
    offset = np.asarray(skel.q_comfort, dtype=float)[dofs] - q[dofs]
    if float(np.abs(offset).max(initial=0.0)) <= NEAR:
        return None
    return dofs, offset


def _deeper(skel: Skeleton, frames: Frames, kept: slice, before: FloatArray, side: str) -> bool:
    """Whether the frames ``kept`` changed from ``before`` (the others did not change) take the
    arm of ``side`` deeper into the body's clearance than it was: an arm let down from where a
    place left it swept a forearm 103 mm through a thigh (vehicle_battery female P95), and the
    clearance pass, pushing it out, moved the place before it off its site.

    An arm that was inside already (a hand put on a site inside the trunk, then a walk away) is
    judged over the frames as a whole: let down, it went 3 mm deeper on 22 frames and came
    clear on the other 2,600; kept, it stayed 100 mm in the trunk for the 20 m walk (and the
    clearance pass solved every one of those frames). It is let down where no frame goes more
    than ``DEEPER_TOL`` deeper than the deepest it was and the depth summed over the frames
    shrinks."""
    changed = np.flatnonzero(np.abs(frames.q[kept] - before).max(axis=1) > 0.0)
    if changed.size == 0:
        return False
    rows = kept.start + changed
    root = (frames.root_position[rows], frames.root_rotation[rows])
    now = penetrations(skel, frames.q[rows], root, (side,))[side]
    # only a frame with the arm inside can be deeper than before: the frames before measured
    # there alone (a frame's figure does not depend on the frames measured with it; an arm let
    # down over a long walk is clear of the body on nearly every frame)
    inside = np.flatnonzero(now > 0.0)
    if inside.size == 0:
        return False
    was = np.full(len(rows), -np.inf)
    was[inside] = penetrations(skel, before[changed[inside]], _rows(root, inside), (side,))[side]
    if not (now[inside] > np.maximum(was[inside], 0.0)).any():
        return False
    # the others too, for the whole: each frame's figure is its own
    out = np.flatnonzero(now <= 0.0)
    if out.size:
        was[out] = penetrations(skel, before[changed[out]], _rows(root, out), (side,))[side]
    worst = float(np.max(was, initial=0.0))
    if worst <= 0.0 or float(now.max()) > worst + DEEPER_TOL:
        return True
    return float(np.maximum(now, 0.0).sum()) >= float(np.maximum(was, 0.0).sum())


def _rows(root: tuple[FloatArray, FloatArray], rows: np.ndarray) -> tuple[FloatArray, FloatArray]:
    return root[0][rows], root[1][rows]


def _settle_trunk(
    skel: Skeleton, ir: MotionIR, frames: Frames, walk: tuple[float, float], trunk: list[int],
    offset: FloatArray, until: list[str],
) -> None:  # fmt: skip
    """The trunk upright over the walk. Where a segment that moves the trunk or an arm follows
    (a reach, solved on the trunk as it was), the trunk goes back before the walk ends, so the
    reach starts from the pose it was solved from: let go of over the reach, the bent trunk
    came back under arms keyed for it, and a 14 kg battery's hands went 94 mm into a thigh
    (vehicle_battery female P95); kept upright through an arm-only place, the access panel's
    hands ended 84-116 mm off the bench. With none, it stays upright to the end. A walk too
    short for both ramps, or with such a segment during it, is left as it was."""
    start, end = walk
    names = set(until)
    later = next_keyed(ir, names, start)
    length = ramp_length(offset, end - start)
    if later is None:
        keep_until_keyed(skel, ir, frames, trunk, offset, (start, start + length), until)
        return
    if later[0] < end - EPS or 2.0 * length > end - start:
        return
    t = frames.time
    rows = np.flatnonzero((t > start + EPS) & (t < end - EPS))  # the walk's ends as they were
    rise = minimum_jerk(np.clip((t[rows] - start) / length, 0.0, 1.0))
    fall = minimum_jerk(np.clip((end - t[rows]) / length, 0.0, 1.0))
    moved = frames.q[np.ix_(rows, trunk)] + np.minimum(rise, fall)[:, None] * offset[None]
    frames.q[np.ix_(rows, trunk)] = np.clip(moved, skel.lower[trunk], skel.upper[trunk])


def _names(skel: Skeleton, dofs: list[int]) -> list[str]:
    return [skel.dof_names[d] for d in dofs]


def run(ir: MotionIR, ctx: PassContext) -> MotionIR:
    frames = ir.frames
    skel = ir.skeleton
    if frames is None or not len(frames.time) or skel is None:
        return ir
    walks = sorted((s.start, s.end) for s in ir.on_track("root") if s.kind == "locomotion")
    for start, end in walks:
        held = on_site(ir, np.array([start + EPS]))
        free = free_arms(ir, start, end, held)
        # a walk that carries a part: carry_pose straightens its trunk with the arms solved
        # on it (straightened here, under arms solved for the lean, a 14 kg battery's hands
        # went 94 mm into a thigh on the place after, female P95)
        settle_walk(skel, ir, frames, start, end, free, trunk=len(free) == len(ARM_HAND))
    return ir
