"""No joint faster than a person's: where one would be, the clock stretches (issue 19).

The solvers place poses and the pace and gait passes time them; where the keys still ask a joint
for more than a person gives at this kind of work (an IK branch that flips between two keys, a
stroke's swing timed by the hand's path, an arm brought down from a reach in a posture's first
frames), the output would show a jump. Here the poses stay and the time between them grows: a
path-velocity decomposition, the time-scaling of Hollerbach (1984, "Dynamic scaling of
manipulator trajectories", J Dyn Sys Meas Control 106:102-106), with a joint-speed limit in
place of the torque limit. It runs on the keys, after ``pace`` and before ``interpolate``, so
every pass after it (the holds, balance, smoothing, the carry, the clearance) works on the
stretched clock and the frames the user receives are made on it.

* The keys are interpolated as ``interpolate`` does (``interpolate_naive``, 60 fps) and each
  interval's fastest joint is compared with ``LIMIT`` (``TURN_LIMIT`` for the wrist and
  forearm in a fastener turn: the tools' own pace). An interval over it is slowed to it, and
  the slowing fades in and out over ``RAMP`` seconds each side, so the joints that moved at a
  person's speed slow down smoothly with it and no velocity jumps.
* An interval more than ``JUMP`` times too fast is a jump, not a fast movement: it is given the
  time of a movement of its own at the limit, from rest to rest (minimum jerk, Flash & Hogan
  1985: peak speed 1.875 times the mean), and the interpolation shapes it.
* The gait is timed by its own model (cadence and swing from stature, docs/passes.md): the legs
  and the root's turn are not judged while a walk drives them.

Every time in the IR moves: segments, keyframes, the root plan and the times in segments'
results (``timewarp.warp_result``: gait steps and rolls, stroke phases), as the pace pass's
stretch of a reach moves them. A task that needs none of this keeps its bytes;
one that does takes longer, by what a person would need.

``speed_limited`` is the same rule for the passes that correct the frames after interpolation
(balance, clearance): where a correction blended in over a few frames would step a joint faster
than a person's (a kneel already at 300 deg/s, a free arm turned 21 deg out of the trunk), it is
widened in time, started earlier and let go later, never made smaller, so what it corrects is
not given back.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mtlc.ir.model import FloatArray, Frames, Keyframes, MotionIR, runs_of
from mtlc.passes.context import PassContext
from mtlc.passes.interpolate import interpolate_naive, walking_mask
from mtlc.passes.timewarp import warp_result

LIMIT = math.radians(340.0)  # rad/s: issue 19's 12 deg a frame at 30 fps is 360 deg/s
TURN_LIMIT = math.radians(570.0)  # the tool pass's screwdriver twist (passes/tool.py)
TURN_DOFS = ("wrist_flex", "wrist_dev", "elbow_pro")
GAIT_DOFS = ("hip_", "knee_", "ankle_", "toe_")  # the gait's own, while a walk drives them
RAMP = 0.15  # s each side over which a slowing fades in and out
JUMP = 2.0  # an interval this many times too fast is given a movement's time of its own
MOVEMENT_RATIO = 3.0  # a tool's movement at most this many times too fast is slowed as a whole
PEAK = 1.875  # minimum jerk's peak speed over its mean
ROUNDS = 6  # re-interpolated and judged again: the interpolation of stretched keys moves a little
EPS = 1e-9
ROOT = "root_turn"  # the root's rotation, judged as one more dof
IntArray = NDArray[np.intp]


def run(ir: MotionIR, ctx: PassContext) -> MotionIR:
    if ir.skeleton is None or not ir.segments:
        return ir
    names = [*ir.skeleton.dof_names, ROOT]
    for _ in range(ROUNDS):
        dense = interpolate_naive(ir)
        if len(dense.time) < 2:
            break
        limits = dof_limits(ir, dense)
        ratio = speed_ratio(dense, limits)
        if float(np.max(ratio)) <= 1.0 + EPS:
            break
        warp = stretch(ir, dense, ratio, fastest_dof(dense, limits), names, 1.0 / ctx.options.fps)
        retime_ir(ir, warp)
    return ir


def dof_limits(ir: MotionIR, frames: Frames) -> FloatArray:
    """(N - 1, D + 1) speed limit per interval and dof, the root's turn last (rad/s).

    A step belongs to a fastener turn, or to a walk, when either of its frames does (the rule of
    bench/human.py, which measures the output)."""
    t = frames.time
    names = list(ir.skeleton.dof_names)
    limits = np.full((len(t) - 1, len(names) + 1), LIMIT)
    turning = np.array([any(n.endswith(d) for d in TURN_DOFS) for n in names] + [False])
    on = np.zeros(len(t), dtype=bool)
    for seg in ir.segments:
        if seg.provenance.path and seg.provenance.path[-1] == "turn_fastener":
            on |= (t >= seg.start - EPS) & (t <= seg.end + EPS)
    limits[np.ix_(on[:-1] | on[1:], turning)] = TURN_LIMIT
    gait = np.array([any(d in n for d in GAIT_DOFS) for n in names] + [True])
    walking = walking_mask(ir, t)
    limits[np.ix_(walking[:-1] | walking[1:], gait)] = np.inf
    return limits


def root_turn(rotation: FloatArray) -> FloatArray:
    """(N - 1,) angle of the root's rotation between neighbouring frames."""
    dot = np.abs(np.sum(rotation[:-1] * rotation[1:], axis=1))
    return 2.0 * np.arccos(np.clip(dot, 0.0, 1.0))


def speed_ratio(frames: Frames, limits: FloatArray) -> FloatArray:
    """(N - 1,) how many times faster than its limit the fastest joint crosses each interval."""
    dt = np.maximum(np.diff(frames.time), EPS)
    steps = np.concatenate(
        [np.abs(np.diff(frames.q, axis=0)), root_turn(frames.root_rotation)[:, None]], axis=1
    )
    return np.max(steps / limits, axis=1) / dt


def spread(rate: FloatArray, time: FloatArray) -> FloatArray:
    """The slowing faded in and out: each interval at least ``1 + (r - 1) w(d)`` for every
    interval's rate ``r`` at distance ``d``, ``w`` a raised cosine of half-width ``RAMP``."""
    centre = 0.5 * (time[:-1] + time[1:])
    out = rate.copy()
    slow = np.flatnonzero(rate > 1.0 + EPS)
    lo = np.searchsorted(centre, centre[slow] - RAMP, side="left")
    hi = np.searchsorted(centre, centre[slow] + RAMP, side="right")
    for j, a, b in zip(slow, lo, hi, strict=True):
        d = np.abs(centre[a:b] - centre[j])
        w = 0.5 * (1.0 + np.cos(np.pi * np.minimum(d / RAMP, 1.0)))
        np.maximum(out[a:b], 1.0 + (rate[j] - 1.0) * w, out=out[a:b])
    return out


def fastest_dof(frames: Frames, limits: FloatArray) -> IntArray:
    """(N - 1,) the index of the dof that sets each interval's ratio (the root's turn last)."""
    steps = np.concatenate(
        [np.abs(np.diff(frames.q, axis=0)), root_turn(frames.root_rotation)[:, None]], axis=1
    )
    return np.argmax(steps / limits, axis=1)


def keyed_starts(ir: MotionIR, name: str) -> FloatArray:
    """Sorted start times of the segments whose keys set dof ``name`` (``ROOT``: the root)."""
    starts = [
        s.start
        for s in ir.segments
        if s.keyframes is not None
        and len(s.keyframes.time)
        and (s.keyframes.root_rotation is not None if name == ROOT else name in s.keyframes.dofs)
    ]
    return np.sort(np.asarray(starts, dtype=float))


def stretch(
    ir: MotionIR,
    dense: Frames,
    ratio: FloatArray,
    fastest: IntArray,
    names: list[str],
    period: float,
) -> Warp:
    """The stretched clock: each interval slowed to its limit; a jump given a minimum-jerk
    movement's time at the limit (``PEAK`` times its time at the mean speed), as a pause opened
    where a segment starts on the jumping dof when one does (keys at one time with two poses:
    stretching time cannot part them) or as the interval's own time otherwise. Each stretch adds
    whole output frames (``period``): what comes after it stays on the output grid, so a goal's
    last key is still an output frame."""
    time = dense.time
    dt = np.diff(time)
    ratio = ratio.copy()
    jump = ratio > JUMP
    movements = movement_spans(ir, time, ratio)
    for span in movements:  # a tool's bell is a movement, not a jump
        jump[span] = False
    need = PEAK * ratio * dt  # a jump's time at the limit
    cuts: dict[float, tuple[float, int]] = {}  # cut -> (pause, the dense frame before it)
    starts_of: dict[str, FloatArray] = {}  # per dof, once: a procedure may jump hundreds of times
    for i in np.flatnonzero(jump):
        name = names[int(fastest[i])]
        if name not in starts_of:
            starts_of[name] = keyed_starts(ir, name)
        starts = starts_of[name]
        inside = starts[(starts > time[i] + EPS) & (starts <= time[i + 1] + EPS)]
        if len(inside):
            cut = float(inside[-1])
            pause = max(cuts.get(cut, (0.0, 0))[0], float(need[i] - dt[i]))
            cuts[cut] = (pause, int(i))
            jump[i] = False  # the pause is its time; the interval keeps its own
            ratio[i] = 1.0
    rate = spread(np.where(jump, 1.0, np.maximum(ratio, 1.0)), time)
    for span in movements:
        # slowed where it is fastest, a stroke's bell became a plateau with a bump at each end,
        # two speed peaks (a still trunk's ratchet returns, pump_low_kneel female P10: 30 of
        # 36); slowed evenly it stays one bell. It starts and ends at rest: its clock may
        # change there
        rate[span] = np.maximum(rate[span], float(ratio[span].max()))
    new_dt = whole_frames(dt, np.where(jump, need, dt * rate), period)
    new = np.concatenate([[time[0]], time[0] + np.cumsum(new_dt)])
    cuts = {c: (math.ceil(p / period - 1e-6) * period, i) for c, (p, i) in cuts.items()}
    at = sorted(cuts)
    return Warp(
        time,
        new,
        np.array(at, dtype=float),
        np.array([cuts[c][0] for c in at], dtype=float),
        Frames(
            dense.fps,
            np.array(at, dtype=float),
            dense.root_position[[cuts[c][1] for c in at]],
            dense.root_rotation[[cuts[c][1] for c in at]],
            dense.q[[cuts[c][1] for c in at]],
        ),
    )


def movement_windows(ir: MotionIR) -> list[tuple[float, float]]:
    """(start, end) of each movement from rest to rest that the tool pass timed on one bell:
    every stroke's seat, swing and return (``result["phases"]``)."""
    out = []
    for seg in ir.segments:
        phases = (seg.result or {}).get("phases") if isinstance(seg.result, dict) else None
        if isinstance(phases, dict):
            out += [(float(a), float(b)) for a, b in phases.values() if b > a + EPS]
    return out


def movement_spans(ir: MotionIR, time: FloatArray, ratio: FloatArray) -> list[slice]:
    """The intervals (slices of the dense frames' (N - 1,)) of each of the
    ``movement_windows`` whose fastest joint is at most ``MOVEMENT_RATIO`` times too fast: a
    movement to slow as a whole. One faster holds a branch flip, a jump the old rule times."""
    centre = 0.5 * (time[:-1] + time[1:])
    out = []
    for a, b in movement_windows(ir):
        lo, hi = (int(k) for k in np.searchsorted(centre, [a, b]))
        if hi > lo and float(ratio[lo:hi].max()) <= MOVEMENT_RATIO:
            out.append(slice(lo, hi))
    return out


def whole_frames(dt: FloatArray, new_dt: FloatArray, period: float) -> FloatArray:
    """``new_dt`` with each run of stretched intervals stretched a little more, to add a whole
    number of ``period``s."""
    grown = new_dt > dt * (1.0 + 1e-12)
    out = new_dt.copy()
    for a, b in runs_of(grown):
        added = float(np.sum(new_dt[a:b] - dt[a:b]))
        whole = math.ceil(added / period - 1e-6) * period
        out[a:b] = dt[a:b] + (new_dt[a:b] - dt[a:b]) * (whole / added)
    return out


@dataclass(frozen=True)
class Warp:
    """Old time -> new time: through the dense frames' knots (at the old pace outside them),
    and later by each pause for what comes after its cut."""

    old: FloatArray
    new: FloatArray
    cuts: FloatArray  # sorted times where a pause opens
    pauses: FloatArray  # its length (s)
    before: Frames  # the pose at each cut (the dense frame before its jump)

    def __call__(self, time: Any, at_cut_after: bool = False) -> Any:
        """``at_cut_after``: a time at a cut belongs to what starts there (it moves with it)."""
        tt = np.asarray(time, dtype=float)
        old, new = self.old, self.new
        out = np.interp(tt, old, new) + np.maximum(tt - old[-1], 0.0)
        out = out + np.minimum(tt - old[0], 0.0)
        if len(self.cuts):
            shifted = np.concatenate([[0.0], np.cumsum(self.pauses)])
            if at_cut_after:
                n = np.searchsorted(self.cuts, tt + EPS, side="right")
            else:
                n = np.searchsorted(self.cuts, tt - EPS, side="left")
            out = out + shifted[n]
        return float(out) if out.ndim == 0 else out


def retime_ir(ir: MotionIR, warp: Warp) -> None:
    """Every time the IR holds, moved onto the stretched clock. A segment that starts at a cut
    starts there still, from the pose before the jump (a key added at its start), and its own
    keys come after the pause: the interpolation carries the body across it."""
    for seg in ir.segments:
        kf = seg.keyframes
        cut = np.flatnonzero(np.abs(warp.cuts - seg.start) <= EPS) if len(warp.cuts) else []
        if kf is not None and len(kf.time):
            first = np.abs(kf.time - seg.start) <= EPS  # keys at its start move with the segment
            kf.time = np.where(first, warp(kf.time, True), warp(kf.time))
            if len(cut):
                from_pose(ir, kf, warp.before, int(cut[0]), warp(seg.start))
        seg.start, seg.end = warp(seg.start), warp(seg.end)
        seg.result = warp_result(seg.result, warp)
    if ir.root_plan is not None:
        ir.root_plan.time = warp(ir.root_plan.time)


def from_pose(ir: MotionIR, kf: Keyframes, before: Frames, k: int, at: float) -> None:
    """A first key at ``at`` holding the pose ``before`` gives at cut ``k``."""
    cols = [ir.skeleton.dof_index(n) for n in kf.dofs]
    kf.time = np.concatenate([[at], kf.time])
    kf.q = np.concatenate([before.q[k, cols][None, :], kf.q])
    if kf.root_position is not None:
        kf.root_position = np.concatenate([before.root_position[k][None, :], kf.root_position])
    if kf.root_rotation is not None:
        kf.root_rotation = np.concatenate([before.root_rotation[k][None, :], kf.root_rotation])


def speed_limited(
    q: FloatArray, dq: FloatArray, lower: FloatArray, upper: FloatArray, t: FloatArray,
    speed: float, fixed: np.ndarray | None = None,
) -> FloatArray:  # fmt: skip
    """The corrections ``dq`` (N, D) of frames ``q`` (times ``t``) widened in time so that no
    corrected dof turns faster than ``speed`` (rad/s) where the motion itself did not. Per
    dof the positive and the negative parts each take their smallest envelope with the
    allowed slopes (one pass back in time, one forward); ``fixed`` (N,) frames keep their own
    correction (a hand held on its goal). Returned within the joint limits; unchanged where
    nothing is too fast."""
    if len(q) < 2:
        return dq
    done = np.clip(q + dq, lower, upper) - q  # what the correction does within the limits
    step = np.diff(q, axis=0)
    room = np.maximum(np.abs(step), speed * np.diff(t)[:, None]) + 1e-9
    lo, hi = -room - step, room - step  # allowed change of the correction between frames
    change = np.diff(done, axis=0)
    if not ((change < lo).any() or (change > hi).any()):
        return dq
    cols = np.flatnonzero(np.abs(done).max(axis=0) > 0.0)  # the dofs corrected at all
    up, down = np.maximum(done[:, cols], 0.0), np.minimum(done[:, cols], 0.0)
    lo, hi = lo[:, cols], hi[:, cols]
    keep = np.zeros(len(q), dtype=bool) if fixed is None else np.asarray(fixed, dtype=bool)
    envelopes(up, down, lo, hi, keep)
    both = up + down
    # each part keeps its slope, their sum need not: a correction that changes sign within a
    # ramp's reach (a per-frame solve, +9 deg one frame, -1 the next) took both, 6.5 deg a
    # dense frame where 5.5 were allowed (the fuel filter male P99's left shoulder, issue 19)
    clamped(both, lo, hi, keep)  # (returns at once where the sum keeps the speed)
    out = done.copy()
    out[:, cols] = np.clip(q[:, cols] + both, lower[cols], upper[cols]) - q[:, cols]
    return out


def worse_runs_undone(
    q: FloatArray,
    before: FloatArray,
    after: FloatArray,
    t: FloatArray,
    speed: float,
    only: np.ndarray | None = None,
    slack: float = 0.0,
) -> FloatArray:
    """``after`` (a correction of the frames ``q``) with each run of frames it changed from
    ``before`` given back where its fastest step over ``speed`` (rad/s, and over the motion
    ``q``'s own), from the frame before the run to the frame after it, is larger than
    ``before``'s: a correction may not make a step a person would not. ``only`` (N,): the runs
    with a frame in it alone (the others stay ``after``'s); ``slack``: the share of ``speed``
    a run's step may go over its room before it is given back."""
    changed = (after != before).any(axis=1)
    if not changed.any():
        return after
    room = np.maximum(np.abs(np.diff(q, axis=0)), (speed * np.diff(t))[:, None])
    over = slack * speed * np.diff(t)  # (N - 1,)

    def excess(poses: FloatArray) -> FloatArray:
        return (np.abs(np.diff(poses, axis=0)) - room).max(axis=1)  # (N - 1,)

    was, now = excess(before), excess(after)
    out = after.copy()
    for a, b in runs_of(changed):
        if only is not None and not only[a:b].any():
            continue
        span = slice(max(a - 1, 0), min(b, len(was)))  # the steps into, within and out of it
        if (now[span] - over[span]).max() > max(was[span].max(), 0.0) + 1e-9:
            out[a:b] = before[a:b]
    return out


def clamped(c: FloatArray, lo: FloatArray, hi: FloatArray, keep: np.ndarray) -> None:
    """``c`` (N, D) with each change between frames brought within ``[lo, hi]``, in place:
    forward, a frame not ``keep`` goes at most the allowed change from its predecessor; then
    back, a frame not ``keep`` at most the allowed change from its successor; a step into or out
    of a ``keep`` frame is left as it is (the held hand's own: the correction before it is not
    made smaller for it). For the rows where ``speed_limited``'s two envelopes overlap with
    opposite signs: the correction gives back there what the other sign would
    take, no more. Only the rows from the first violation on are visited, until nothing
    changes past the last one."""
    n = len(c)
    free = ~(keep[:-1] | keep[1:])

    def violations() -> IntArray:
        change = np.diff(c, axis=0)
        bad = ((change < lo - 1e-9) | (change > hi + 1e-9)).any(axis=1)
        return np.flatnonzero(bad & free)

    bad = violations()
    if bad.size == 0:
        return
    for i in range(int(bad[0]), n - 1):  # forward: row i + 1 from row i
        if keep[i + 1]:
            continue
        new = np.clip(c[i + 1], c[i] + lo[i], c[i] + hi[i])
        if i > bad[-1] and np.array_equal(new, c[i + 1]):
            break
        c[i + 1] = new
    bad = violations()
    if bad.size == 0:
        return
    for i in range(int(bad[-1]), -1, -1):  # back: row i from row i + 1
        if keep[i] or keep[i + 1]:
            continue
        new = np.clip(c[i], c[i + 1] - hi[i], c[i + 1] - lo[i])
        if i < bad[0] and np.array_equal(new, c[i]):
            break
        c[i] = new


def envelopes(
    up: FloatArray, down: FloatArray, lo: FloatArray, hi: FloatArray, keep: np.ndarray
) -> None:
    """``speed_limited``'s two sweeps, in place: back in time (a correction starts earlier)
    ``up[i] = max(up[i], up[i+1] - hi[i])`` and ``down[i] = min(down[i], down[i+1] - lo[i])``,
    then forward (it lets go later) ``up[i+1] = max(up[i+1], up[i] + lo[i])`` and
    ``down[i+1] = min(down[i+1], down[i] + hi[i])``; rows ``keep`` are left as they are.

    Each sweep is solved for all rows at once and then again only where the row it reads
    changed (``hi > 0 > lo``: a row next to an untouched one never changes, and most rows of a
    long motion are untouched): every row ends as the sweep's fixed point, which is the
    frame-by-frame loop's result to the bit, the same operation on the same values (``max``
    only grows a row, and a row is solved again whenever the one it reads grows). A loop over
    every frame was half a second of a 48,000-frame balance pass (``sweeps_reference``)."""
    n = len(up)
    if n < 2:
        return
    rows = np.flatnonzero(~keep[:-1])  # back: row i reads row i + 1
    for _ in range(n):
        if rows.size == 0:
            break
        new_up = np.maximum(up[rows], up[rows + 1] - hi[rows])
        new_down = np.minimum(down[rows], down[rows + 1] - lo[rows])
        grown = (new_up != up[rows]).any(axis=1) | (new_down != down[rows]).any(axis=1)
        up[rows], down[rows] = new_up, new_down
        rows = rows[grown] - 1
        rows = rows[(rows >= 0) & ~keep[np.maximum(rows, 0)]]
    rows = np.flatnonzero(~keep[1:]) + 1  # forward: row i reads row i - 1
    for _ in range(n):
        if rows.size == 0:
            break
        new_up = np.maximum(up[rows], up[rows - 1] + lo[rows - 1])
        new_down = np.minimum(down[rows], down[rows - 1] + hi[rows - 1])
        grown = (new_up != up[rows]).any(axis=1) | (new_down != down[rows]).any(axis=1)
        up[rows], down[rows] = new_up, new_down
        rows = rows[grown] + 1
        rows = rows[(rows < n) & ~keep[np.minimum(rows, n - 1)]]


def sweeps_reference(
    up: FloatArray, down: FloatArray, lo: FloatArray, hi: FloatArray, keep: np.ndarray
) -> None:
    """``envelopes`` frame by frame, as ``speed_limited`` did it (the tests' reference)."""
    for i in range(len(up) - 2, -1, -1):  # started earlier
        if not keep[i]:
            up[i] = np.maximum(up[i], up[i + 1] - hi[i])
            down[i] = np.minimum(down[i], down[i + 1] - lo[i])
    for i in range(len(up) - 1):  # let go later
        if not keep[i + 1]:
            up[i + 1] = np.maximum(up[i + 1], up[i] + lo[i])
            down[i + 1] = np.minimum(down[i + 1], down[i] + hi[i])
