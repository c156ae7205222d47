"""Gaze: the neck and head keep the eyes on the work, within the neck's limits.

Runs after TA and TO, so the trunk is where the reaches left it. The damped least squares
solver aims the ``gaze`` site's direction (the head's forward axis) at a target (an ``aim``
goal) with the neck and head only (5 dofs); a target outside the neck's range gets the closest
direction the limits allow (``result["angle_error"]`` says by how much). No diagnostic: looking
is not a goal a task fails on; a site the head cannot bring into view is lint's MT0607.

Two kinds of head segments (track ``head``, kind ``gaze``):

* ``look`` segments, in time order, with the body at the segment's end (joints from the
  keyframes so far, root from the plan). Looks that share a time window aim at the middle of
  their targets. Keyframes: the head as it is at the start and the aimed head at the end.
* the work (``goal.params["implicit"]``), added here: wherever a hand reaches or works on a site
  (a TA or TO segment) and no ``look`` runs, the head follows the site, solved at every keyframe
  time of the reaches and at least every ``SAMPLE_STEP``, with the body as interpolation shows
  it then (the trunk moves during a reach). Two hands on different sites: the one making
  contact (TO) wins, otherwise their midpoint. A new target is reached after a turn of
  ``turn_time`` (0.2–0.4 s by angle); when the head is free before the reach the turn starts
  early and ends as the hand sets off (the eyes lead the hand). After the work the head holds
  until the next look or reach.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from mtlc.body import forward_part, site_direction, site_positions
from mtlc.body.ik import Goal, default_dofs, prepare, solve_ta
from mtlc.body.skeleton import Skeleton
from mtlc.ir.model import FloatArray, Frames, GoalSpec, Keyframes, MotionIR, Segment
from mtlc.passes.context import PassContext
from mtlc.passes.interpolate import correct_base, interpolate_joints, interpolate_root
from mtlc.passes.posture import RESTATERS
from mtlc.passes.state import PoseState, cached, mark, reanchor

GAZE_TOLERANCE = math.radians(1.0)
TRACK_TOLERANCE = math.radians(0.25)  # the solver's stop while following: well inside 1°
REACH_KINDS = ("TA", "TO")
SAMPLE_STEP = 0.05  # s: the longest gap between two solved head poses while following the work
TURN_MIN = 0.2  # s: a head turn to a target close by (docs/passes.md, gaze: sources)
TURN_MAX = 0.4  # s: a head turn of TURN_FULL or more
TURN_FULL = math.radians(60.0)
HEAD_PACE = math.radians(200.0)  # rad/s: a head's mean speed between keys (peaks ~1.5x)
HEAD_SPEED = math.radians(240.0)  # rad/s: faster than a head turn (60 deg in TURN_MAX)
NEAR_BRANCH = math.radians(10.0)  # aim given up to stay on the head's side of the neck
SAME_TARGET = 1e-3  # m: targets closer than this are one target
WORK_PAUSE = 0.5  # s: reaches closer than this in time are one stretch of work (a grasp between)
AHEAD_MIN = math.radians(2.0)  # a head this close to facing ahead is left where it is
EPS = 1e-9


def solve(ir: MotionIR, ctx: PassContext) -> MotionIR:
    state = PoseState(ir)
    looks = solve_looks(ir, ctx, state)
    follow_the_work(ir, ctx, state, looks)
    face_ahead(ir, ctx, state)
    keep_pace(ir, ctx, state)
    reanchor(ir, ctx.cache, RESTATERS)
    return ir


# -- explicit looks ----------------------------------------------------------------------------


def solve_looks(ir: MotionIR, ctx: PassContext, state: PoseState) -> list[tuple[float, float]]:
    """Aim the head at every ``look`` target; returns the windows the head turns in.

    A look lasts what MTM-1 gives the eyes (EF, 0.26 s); the head turns at a person's pace
    (``look_window``), so a look whose head has far to go ends its turn after its own end, the
    eyes already on the target (a gaze shift: the eyes land first, the head follows)."""
    skel = ir.skeleton
    dofs = default_dofs(skel, ["gaze"], "arm")
    names = tuple(skel.dof_names[d] for d in dofs)
    windows: dict[tuple[float, float], list[Segment]] = {}
    for s in ir.segments:
        if s.kind == "gaze" and s.goal.position is not None:
            windows.setdefault((round(s.start, 9), round(s.end, 9)), []).append(s)
    ordered = sorted(windows.items())
    turns: list[tuple[float, float]] = []
    for k, (_, segs) in enumerate(ordered):
        t0, t1 = segs[0].start, segs[0].end
        limit = ordered[k + 1][1][0].start if k + 1 < len(ordered) else ir.duration
        free = min(t0, max((end for _, end in turns), default=0.0))
        target = np.mean([np.asarray(s.goal.position, dtype=float) for s in segs], axis=0)
        before = state.q_at(t0)
        root = state.root_at(t1)
        q1 = aim_head(ir, ctx, state, before, target, t1, root)
        start, end = look_window(t0, t1, before[dofs], q1[dofs], free, max(limit, t1))
        # nothing is written between these reads: the same time gives the same pose and root
        q0 = before.copy() if start == t0 else state.q_at(start)
        if end != t1:
            root = state.root_at(end)
        if end > t1 + EPS:  # the body may have moved on by the time the head arrives
            q1 = aim_head(ir, ctx, state, q1, target, end, root)
        err = float(aim_errors(skel, q1[None], root[0][None], root[1][None], target[None])[0])
        for seg in segs:
            seg.start, seg.end = min(seg.start, start), max(seg.end, end)
            seg.keyframes = Keyframes(
                time=np.array([start, end]), dofs=names, q=np.stack([q0[dofs], q1[dofs]])
            )
            seg.result = {"angle_error": err, "success": err <= GAZE_TOLERANCE}
            state.add(seg)
            mark(ctx.cache, seg)
        turns.append((min(t0, start), max(t1, end)))
    return turns


def look_window(
    t0: float, t1: float, q0: FloatArray, q1: FloatArray, free: float, limit: float
) -> tuple[float, float]:
    """When the head turns from ``q0`` to ``q1`` for a look from ``t0`` to ``t1``: from ``t0``
    for a head turn's time (``turn_time``, and no joint faster than ``HEAD_PACE`` on average),
    ending by ``limit`` (the next look, the task's end); when that is too short, starting
    earlier, back to ``free`` (the head's last turn), for the time still missing."""
    move = float(np.abs(q1 - q0).max())
    need = max(t1 - t0, turn_time(move), move / HEAD_PACE)
    end = max(t1, min(limit, t0 + need))
    start = min(t0, max(free, end - need))
    return start, end


def aim_head(
    ir: MotionIR,
    ctx: PassContext,
    state: PoseState,
    q0: FloatArray,
    target: FloatArray,
    t: float,
    root: tuple[FloatArray, FloatArray] | None = None,
) -> FloatArray:
    """The whole pose with the neck and head aimed at ``target`` from the body at ``t`` (its
    root ``state.root_at(t)``, passed when the caller has it)."""
    skel = ir.skeleton
    dofs = default_dofs(skel, ["gaze"], "arm")
    root = state.root_at(t) if root is None else root
    body = state.q_at(t)
    body[dofs] = q0[dofs]
    base = sorted(set(skel.chain_dofs("gaze")) - set(dofs))
    key = ("gaze", root[0].tobytes(), root[1].tobytes(), body[base].round(12).tobytes())
    model = cached(
        ctx.cache,
        key,
        lambda: prepare(skel, ["gaze"], body, root_position=root[0], root_rotation=root[1]),
    )
    goal = [Goal("gaze", aim=target)]
    # the best of three starts, and the first start's own (what ``restarts=0`` gives), by one
    # solve: the restarts begin where the first attempt stops
    res = solve_ta(skel, goal, body, model=model, restarts=2, first_attempt=True)
    assert res.first is not None
    best, near = res.q[0], res.first[0]
    errors = aim_errors(skel, np.stack([best, near]), np.stack([root[0]] * 2),
                        np.stack([root[1]] * 2), np.stack([target] * 2))  # fmt: skip
    # a target past the neck's range is seen about as badly from either limit: stay on the
    # side the head is on rather than swing limit to limit (issue 19)
    return near if errors[1] <= errors[0] + NEAR_BRANCH else best


def aim_errors(
    skel: object,
    q: FloatArray,
    root_position: FloatArray,
    root_rotation: FloatArray,
    targets: FloatArray,
) -> FloatArray:
    """Per row, the angle (rad) between the head's forward axis and the line to its target."""
    # the gaze site's chain only (the head and what carries it): the same numbers as a whole pose
    pose = forward_part(skel, q, root_position, root_rotation, ["gaze"])  # type: ignore[arg-type]
    eye = np.asarray(site_positions(skel, pose, "gaze"))  # type: ignore[arg-type]
    look = np.asarray(site_direction(skel, pose, "gaze"))  # type: ignore[arg-type]
    want = targets - eye
    want = want / np.maximum(np.linalg.norm(want, axis=-1, keepdims=True), 1e-9)
    return np.arccos(np.clip(np.einsum("ij,ij->i", look, want), -1.0, 1.0))


# -- following the work ------------------------------------------------------------------------


@dataclass
class Stretch:
    """A time window in which some hand reaches or works on a site, and the reaches in it."""

    start: float
    end: float
    reaches: list[Segment]


def turn_time(angle: float) -> float:
    """How long the head takes to turn through ``angle`` (rad): 0.2 s, up to 0.4 s at 60°."""
    return TURN_MIN + (TURN_MAX - TURN_MIN) * min(angle / TURN_FULL, 1.0)


def reach_stretches(ir: MotionIR) -> list[Stretch]:
    """The TA and TO segments (with a site), in time order, merged where they overlap or follow
    within ``WORK_PAUSE`` (a grasp or a release between two reaches keeps the eyes on the work)."""
    reaches = sorted(
        (s for s in ir.segments if s.kind in REACH_KINDS and s.goal.position is not None),
        key=lambda s: (s.start, s.end),
    )
    out: list[Stretch] = []
    for seg in reaches:
        if out and seg.start <= out[-1].end + WORK_PAUSE:
            out[-1].end = max(out[-1].end, seg.end)
            out[-1].reaches.append(seg)
        else:
            out.append(Stretch(seg.start, seg.end, [seg]))
    return out


def outside_looks(stretch: Stretch, looks: list[tuple[float, float]]) -> list[Stretch]:
    """The parts of a stretch no ``look`` covers (an explicit look takes precedence)."""
    parts = [(stretch.start, stretch.end)]
    for ls, le in looks:
        cut: list[tuple[float, float]] = []
        for a, b in parts:
            if le <= a + EPS or ls >= b - EPS:
                cut.append((a, b))
                continue
            if ls > a + EPS:
                cut.append((a, ls))
            if le < b - EPS:
                cut.append((le, b))
        parts = cut
    return [
        Stretch(a, b, [s for s in stretch.reaches if s.end > a + EPS and s.start < b - EPS])
        for a, b in parts
        if b - a > EPS
    ]


def target_at(reaches: list[Segment], t: float) -> tuple[FloatArray, Segment] | None:
    """Where the eyes should be at ``t``: the site of a hand in contact (TO) if any, else of the
    reaching hands; the midpoint when two hands work on different sites. With one of the
    segments that asked for it (for provenance)."""
    return _target_of([s for s in reaches if s.start - EPS <= t <= s.end + EPS])


def targets_at(
    reaches: list[Segment], times: FloatArray
) -> list[tuple[FloatArray, Segment] | None]:
    """:func:`target_at` at each of ``times``: each set of active reaches is averaged once
    (a part's samples, 20 a second, see a few such sets; a call per sample was a tenth of a
    long task's gaze pass)."""
    starts = np.array([s.start for s in reaches]) - EPS
    ends = np.array([s.end for s in reaches]) + EPS
    t = np.asarray(times, dtype=float)[:, None]
    active = (starts[None, :] <= t) & (t <= ends[None, :])
    seen: dict[bytes, tuple[FloatArray, Segment] | None] = {}
    out = []
    for row in active:
        key = row.tobytes()
        if key not in seen:
            seen[key] = _target_of([s for s, a in zip(reaches, row, strict=True) if a])
        out.append(seen[key])
    return out


def _target_of(active: list[Segment]) -> tuple[FloatArray, Segment] | None:
    if not active:
        return None
    contact = [s for s in active if s.kind == "TO"]
    chosen = contact or active
    points = np.array([np.asarray(s.goal.position, dtype=float) for s in chosen])
    distinct = [p for i, p in enumerate(points) if not _seen(p, points[:i])]
    return np.mean(distinct, axis=0), chosen[-1]


def _seen(p: FloatArray, earlier: FloatArray) -> bool:
    return bool(len(earlier)) and bool((np.linalg.norm(earlier - p, axis=1) <= SAME_TARGET).any())


def held_targets(
    targets: list[tuple[FloatArray, Segment] | None],
) -> list[tuple[FloatArray, Segment]] | None:
    """Targets with the pauses between reaches filled by the last site worked on."""
    out: list[tuple[FloatArray, Segment]] = []
    for t in targets:
        if t is None and not out:
            return None  # a part starts with a reach: cannot happen
        out.append(out[-1] if t is None else t)
    return out


def sample_times(part: Stretch) -> FloatArray:
    """The reaches' keyframe times inside the part, its ends, and fill-ins at most SAMPLE_STEP
    apart (a TA has keyframes only at its ends while its trunk moves in between)."""
    times = [part.start, part.end]
    for seg in part.reaches:
        kf = seg.keyframes
        if kf is not None:
            times += [float(t) for t in kf.time if part.start - EPS <= t <= part.end + EPS]
    ts = np.unique(np.round(np.clip(times, part.start, part.end), 9))
    filled = [ts[0]]
    for a, b in itertools.pairwise(ts):
        n = math.ceil((b - a) / SAMPLE_STEP - 1e-9)
        filled += [a + (b - a) * k / n for k in range(1, n + 1)]
    return np.asarray(filled, dtype=float)


def body_at(ir: MotionIR, times: FloatArray) -> Frames:
    """The whole body at ``times`` as interpolation and the base correction will show it."""
    position, rotation = interpolate_root(ir, times)
    frames = Frames(0.0, times, position, rotation, interpolate_joints(ir, times))
    correct_base(ir, frames)
    return frames


@dataclass
class Aim:
    """One solved head pose: the row of the body samples, and the point the head looks at."""

    row: int
    target: FloatArray


def follow_the_work(
    ir: MotionIR, ctx: PassContext, state: PoseState, looks: list[tuple[float, float]]
) -> None:
    """Add a head segment for every part of the work no look covers (module docstring)."""
    parts = [p for s in reach_stretches(ir) for p in outside_looks(s, looks)]
    if not parts:
        return
    samples = [sample_times(p) for p in parts]
    body = body_at(ir, np.concatenate(samples))  # the head's own dofs are set per part below
    head_free = [end for _, end in looks]
    solved = HeadSolves(ir.skeleton)
    offset = 0
    for part, times in zip(parts, samples, strict=True):
        rows = slice(offset, offset + len(times))
        offset += len(times)
        seg = follow_part(ir, state, part, times, _rows(body, rows), head_free, solved)
        if seg is None:
            continue
        insert_in_time_order(ir.segments, seg)
        state.add(seg)
        mark(ctx.cache, seg)
        head_free.append(seg.end)


def face_ahead(ir: MotionIR, ctx: PassContext, state: PoseState) -> None:
    """Eyes ahead when the body sets off: at the start of a walk or of a stand, a head still
    turned to where the work was comes back to the body's front (the comfort pose) over a head
    turn's time (``turn_time``), unless a look or the work has the head then. Held, the head of
    the avionics unit's 5th-percentile woman walked 3.8 s at its flexion and lateral limits,
    and every example ended with the head still on its last site."""
    skel = ir.skeleton
    dofs = default_dofs(skel, ["gaze"], "arm")
    names = tuple(skel.dof_names[d] for d in dofs)
    rest = np.asarray(skel.q_comfort, dtype=float)[dofs]
    heads = [s for s in ir.segments if s.track == "head"]
    setting_off = [
        s
        for s in ir.segments
        if s.kind == "locomotion"
        or (s.kind == "posture" and s.goal.params.get("posture") == "stand")
    ]
    for seg in sorted(setting_off, key=lambda s: s.start):
        # a look still turning when the body sets off: the head comes back once it is done
        start = max((h.end for h in heads if h.start <= seg.start + EPS), default=seg.start)
        start = max(start, seg.start)
        if start >= seg.end - EPS:
            continue
        q = state.q_at(start)[dofs]
        angle = float(np.abs(q - rest).max())
        if angle < AHEAD_MIN:
            continue
        end = start + max(turn_time(angle), angle / HEAD_PACE)
        if any(h.start < end - EPS and h.end > start + EPS for h in heads):
            continue
        goal = GoalSpec("gaze", params={"implicit": True, "ahead": True})
        ahead = Segment("head", "gaze", start, end, goal, seg.provenance)
        ahead.keyframes = Keyframes(time=np.array([start, end]), dofs=names,
                                    q=np.stack([q, rest]))  # fmt: skip
        insert_in_time_order(ir.segments, ahead)
        state.add(ahead)
        mark(ctx.cache, ahead)
        heads.append(ahead)


def keep_pace(ir: MotionIR, ctx: PassContext, state: PoseState) -> None:
    """No head key further from the one before than the head turns at ``HEAD_PACE``.

    Looks are solved first, then the work is followed between them, each from the pose the
    earlier solve assumed; where they disagree (a follow ended at one neck limit, the next look
    starts from where the previous look left the head), or two parallel looks pull the head
    apart, the head swung limit to limit in a few frames (issue 19). One sweep over every head
    key in time order (at one instant in segment order, as interpolation takes them): a
    segment's first key is the pose the head is in, and a key the head cannot reach in time
    from the one before becomes the better aimed of two it can: part of the way there, or still
    where it was. Each changed segment's ``angle_error`` says how far off it then is.
    """
    heads = [s for s in ir.segments if s.track == "head" and s.keyframes is not None]
    keys = sorted(
        (round(float(t), 9), n, i)
        for n, s in enumerate(heads)
        for i, t in enumerate(s.keyframes.time)  # type: ignore[union-attr]
    )
    changed: set[int] = set()
    quiet = _quiet_keys(heads, keys)
    last_t, last_q = 0.0, None
    intact = False  # the key before is as it was (``quiet`` holds for this key)
    for k, (t, n, i) in enumerate(keys):
        q = heads[n].keyframes.q  # type: ignore[union-attr]
        if intact and quiet[k]:
            last_t, last_q = t, q[i].copy()
            continue
        before = q[i].copy()
        if last_q is not None:
            if i == 0:
                kept = last_q
            else:
                room = HEAD_PACE * max(t - last_t, 0.0)
                kept = np.clip(q[i], last_q - room, last_q + room)
                if np.abs(kept - q[i]).max() > 1e-12:
                    kept = _better_aimed(ir, state, heads[n], t, (kept, last_q))
            if np.abs(kept - q[i]).max() > 1e-12:
                q[i] = kept
                changed.add(n)
        last_t, last_q = t, q[i].copy()
        intact = bool(np.array_equal(before, q[i]))
    for n in sorted(changed):
        seg = heads[n]
        mark(ctx.cache, seg)
        if seg.goal.position is None:
            continue  # facing ahead: no target to miss
        kf = seg.keyframes
        errors = _key_errors(ir, state, seg, kf.time, kf.q)  # type: ignore[union-attr]
        worst = float(errors[1:].max() if seg.goal.params.get("implicit") else errors[-1])
        seg.result = {**seg.result, "angle_error": worst, "success": worst <= GAZE_TOLERANCE}


def _quiet_keys(heads: list[Segment], keys: list[tuple[float, int, int]]) -> np.ndarray:
    """Per key (in ``keep_pace``'s order), whether the sweep leaves it as it is when the key
    before it is as it was: the sweep's own test for all keys at once (elementwise the same
    arithmetic), so the sweep visits only the keys after a change or that need one."""
    quiet = np.zeros(len(keys), dtype=bool)
    rows = [heads[n].keyframes.q[i] for _, n, i in keys]  # type: ignore[union-attr]
    if len(keys) < 2 or len({len(r) for r in rows}) != 1:
        return quiet
    q = np.array(rows, dtype=float)
    t = np.array([k[0] for k in keys])
    first = np.array([k[2] == 0 for k in keys[1:]])
    room = (HEAD_PACE * np.maximum(t[1:] - t[:-1], 0.0))[:, None]
    kept = np.clip(q[1:], q[:-1] - room, q[:-1] + room)
    kept[first] = q[:-1][first]  # a segment's first key is the pose the head is in
    quiet[1:] = np.abs(kept - q[1:]).max(axis=1) <= 1e-12
    return quiet


def _key_errors(
    ir: MotionIR, state: PoseState, seg: Segment, times: FloatArray, heads: FloatArray
) -> FloatArray:
    """The aim error of head poses ``heads`` (the segment's dofs) at ``times``."""
    skel = ir.skeleton
    kf = seg.keyframes
    assert kf is not None and seg.goal.position is not None
    # the body and its root at every time in one batch (a call per time was most of the pass)
    body = state.q_at_many(times)
    cols = [skel.dof_index(name) for name in kf.dofs]
    body[:, cols] = heads
    root_position, root_rotation = state.root_at_many(times)
    target = np.asarray(seg.goal.position, dtype=float)
    return aim_errors(skel, body, root_position, root_rotation, np.tile(target, (len(body), 1)))


def _better_aimed(
    ir: MotionIR, state: PoseState, seg: Segment, t: float, options: tuple[FloatArray, ...]
) -> FloatArray:
    """Of ``options`` (head poses), the one that aims best at the segment's target at ``t``."""
    if seg.goal.position is None:
        return options[0]
    # one body and root for all options (``_key_errors`` at one time, asked once)
    skel = ir.skeleton
    kf = seg.keyframes
    assert kf is not None
    body = np.tile(state.q_at(t), (len(options), 1))
    body[:, [skel.dof_index(name) for name in kf.dofs]] = np.stack(options)
    root = state.root_at(t)
    target = np.asarray(seg.goal.position, dtype=float)
    errors = aim_errors(skel, body, np.tile(root[0], (len(options), 1)),
                        np.tile(root[1], (len(options), 1)), np.tile(target, (len(options), 1)))  # fmt: skip
    return options[int(np.argmin(errors))]


def insert_in_time_order(segments: list[Segment], seg: Segment) -> None:
    """Put ``seg`` after every segment that starts no later (the IR lists segments by start):
    after the last one from the end that does not start later (a scan in numpy: a walk back
    through a thousand segments per head segment was a tenth of a long task's gaze pass)."""
    starts = np.fromiter((s.start for s in segments), dtype=float, count=len(segments))
    stop = np.flatnonzero(~(starts > seg.start + EPS))
    segments.insert(int(stop[-1]) + 1 if len(stop) else 0, seg)


def _rows(frames: Frames, rows: slice) -> Frames:
    return Frames(
        frames.fps,
        frames.time[rows],
        frames.root_position[rows],
        frames.root_rotation[rows],
        frames.q[rows].copy(),
    )


def follow_part(
    ir: MotionIR,
    state: PoseState,
    part: Stretch,
    times: FloatArray,
    body: Frames,
    head_free: list[float],
    solved: HeadSolves | None = None,
) -> Segment | None:
    """The head segment that follows one part of the work: hold, turn, track (``solved``:
    the pass's row solves so far, see ``HeadSolves``)."""
    skel = ir.skeleton
    dofs = default_dofs(skel, ["gaze"], "arm")
    head0 = state.q_at(part.start)[dofs]
    body.q[:, dofs] = head0
    targets = held_targets(targets_at(part.reaches, times))
    if targets is None:
        return None
    points = np.array([t[0] for t in targets])
    pose = forward_part(skel, body.q, body.root_position, body.root_rotation, ["gaze"])
    eyes = np.asarray(site_positions(skel, pose, "gaze"))
    first = aim_errors(skel, body.q[:1], body.root_position[:1], body.root_rotation[:1],
                       points[:1])  # fmt: skip
    angle = float(first[0])
    turn = turn_time(angle) if angle > GAZE_TOLERANCE else 0.0
    free = max((e for e in head_free if e <= part.start + EPS), default=0.0)
    turn_start = max(free, part.start - turn) if turn else part.start
    plan = schedule(times, points, eyes, turn_start, turn_start + turn, bool(turn))
    if not plan:
        return None
    idx = [a.row for a in plan]
    aims = np.array([a.target for a in plan])
    q_rows = body.q[idx]
    roots = (body.root_position[idx], body.root_rotation[idx])
    q_head = aim_rows(skel, q_rows, roots, aims, times[idx], solved)
    errors = aim_errors(skel, q_head, roots[0], roots[1], aims)
    kf_time = np.concatenate([[turn_start], times[idx]])
    kf_q = np.vstack([head0[None], q_head[:, dofs]])
    kept = paced(kf_time, kf_q)
    kf_time, kf_q, errors = kf_time[kept], kf_q[kept], errors[kept[1:] - 1]
    last = targets[idx[-1]]
    return implicit_segment(ir, part, last, kf_time, kf_q, errors, turn_start)


def paced(kf_time: FloatArray, kf_q: FloatArray) -> FloatArray:
    """Indices of the head's keys to keep: the first, the last, and each one the head reaches
    from the last kept at no more than ``HEAD_PACE`` (issue 19).

    A turn is timed by the eyes' angle to the new target, but where two heads aim about as well
    the solved head may be on the other branch: the fuel filter's neck turned 62 deg in 0.05 s
    to look at the filter it already nearly saw. Leaving out the keys it cannot reach in time
    turns the head at a person's pace instead (it looks slightly off the work meanwhile)."""
    keep = [0]
    for i in range(1, len(kf_time)):
        dt = float(kf_time[i] - kf_time[keep[-1]])
        if i == len(kf_time) - 1 or np.abs(kf_q[i] - kf_q[keep[-1]]).max() <= HEAD_PACE * dt:
            keep.append(i)
    return np.asarray(keep)


def aim_rows(
    skel: object,
    q_rows: FloatArray,
    roots: tuple[FloatArray, FloatArray],
    aims: FloatArray,
    times: FloatArray,
    solved: HeadSolves | None = None,
) -> FloatArray:
    """Solve the head of every row for its aim, one batch per target.

    Each target's first row is solved with restarts (the best of several starts: from a head
    turned the other way a target far to the side has poor local minima) and its solution
    starts the target's other rows, which then follow the body smoothly from one basin. A row
    whose head is then further from the row before than a person turns it in that time is
    solved again from that row (``keep_branch``)."""
    out = np.array(q_rows, dtype=float, copy=True)
    gaze_dofs = default_dofs(skel, ["gaze"], "arm")  # type: ignore[arg-type]
    keys = [a.round(6).tobytes() for a in aims]
    for key in dict.fromkeys(keys):
        rows = np.array([k == key for k in keys])
        first = int(np.argmax(rows))
        seed = solve_rows(skel, out[first : first + 1], roots, aims, [first], restarts=2)
        start = out[rows].copy()
        start[:, gaze_dofs] = seed[0, gaze_dofs]
        out[rows] = solve_rows(skel, start, roots, aims, np.flatnonzero(rows), restarts=0)
        keep_branch(skel, out, roots, aims, np.flatnonzero(rows), times, solved)
    return out


def keep_branch(
    skel: object,
    out: FloatArray,
    roots: tuple[FloatArray, FloatArray],
    aims: FloatArray,
    rows: FloatArray,
    times: FloatArray,
    solved: HeadSolves | None = None,
) -> None:
    """Re-solve, from the row before, each row whose head jumped from it (issue 19).

    With the target near or past the neck's range several heads aim about as well, and rows
    solved from one seed fell on either (the neck swung 45 deg between two frames while a
    wrench swung on the access panel); from the row before, the solver stays on its branch.
    ``solved``: the solves asked before, reused where a row asks one again (``HeadSolves``)."""
    gaze_dofs = default_dofs(skel, ["gaze"], "arm")  # type: ignore[arg-type]
    if solved is None:
        solved = HeadSolves(skel)  # type: ignore[arg-type]
    rows = np.asarray(rows, dtype=np.intp)
    if len(rows) < 2:
        return
    # every step's test at once, from the rows as they are (elementwise the same arithmetic);
    # a step from a re-solved row is tested again in the loop
    head = out[rows][:, gaze_dofs]
    allowed_all = HEAD_SPEED * np.maximum(times[rows[1:]] - times[rows[:-1]], 0.0)
    slow = np.abs(head[1:] - head[:-1]).max(axis=1) <= allowed_all
    moved = False  # the row before was re-solved
    for k, (a, b) in enumerate(itertools.pairwise(rows.tolist())):
        if not moved and slow[k]:
            continue
        moved = False
        allowed = HEAD_SPEED * max(float(times[b] - times[a]), 0.0)
        if np.abs(out[b, gaze_dofs] - out[a, gaze_dofs]).max() <= allowed:
            continue
        moved = True
        start = out[b].copy()
        start[gaze_dofs] = out[a, gaze_dofs]
        out[b] = solved.solve(start, roots, aims, b)


class HeadSolves:
    """The one-row head solves (``restarts=0``) of a pass so far, by their exact inputs.

    ``keep_branch`` solves a row again from the head of the row before; where the trunk and
    the target hold still (a wrench turning on a bolt out of the neck's range: the arm moves,
    the head's chain does not), the solver returns its start, the row before's head, and the
    next row asks the same question again (1,157 of the 1,266 solves of fuzz case 4441's
    lint). A row's head is a function of the angles its model bakes in (the trunk under the
    neck), the head's start, the root and the target alone, bit for bit (the solver draws no
    random numbers without restarts): those bytes are the key, and a row asked again is its
    start with the head found the first time."""

    def __init__(self, skel: Skeleton) -> None:
        model = prepare(skel, ["gaze"])
        self.skel, self.baked, self.active = skel, model.baked, model.active
        self.found: dict[tuple[bytes, ...], FloatArray] = {}

    def solve(
        self, start: FloatArray, roots: tuple[FloatArray, FloatArray], aims: FloatArray, row: int
    ) -> FloatArray:
        """``solve_rows(skel, start[None], roots, aims, [row], restarts=0)[0]``."""
        key = (start[self.baked].tobytes(), start[self.active].tobytes(),
               roots[0][row].tobytes(), roots[1][row].tobytes(), aims[row].tobytes())  # fmt: skip
        head = self.found.get(key)
        if head is None:
            q = solve_rows(self.skel, start[None], roots, aims, [row], restarts=0)[0]
            self.found[key] = q[self.active].copy()
            return q
        q = start.copy()  # the solver returns its start's other dofs as they are
        q[self.active] = head
        return q


def solve_rows(
    skel: object,
    q_start: FloatArray,
    roots: tuple[FloatArray, FloatArray],
    aims: FloatArray,
    rows: list[int] | np.ndarray,
    restarts: int,
) -> FloatArray:
    """The damped least squares head (neck and head dofs) for some rows, from ``q_start``."""
    model = prepare(skel, ["gaze"], q_start, root_position=roots[0][rows],
                    root_rotation=roots[1][rows])  # fmt: skip
    res = solve_ta(skel, [Goal("gaze", aim=aims[rows])], q_start, model=model,
                   restarts=restarts, orientation_tol=TRACK_TOLERANCE)  # fmt: skip
    return res.q


def schedule(
    times: FloatArray,
    points: FloatArray,
    eyes: FloatArray,
    turn_start: float,
    arrival: float,
    turning: bool,
) -> list[Aim]:
    """Which samples get a solved head pose, aimed where.

    The head holds from ``turn_start`` and is on its first target from the first sample at or
    after ``arrival`` (without a turn, from the first sample after the start). When the target
    changes later, the sample where it changes still looks at the old one and the head arrives
    at the new one ``turn_time`` later; samples in between are left to interpolation.
    """
    start = arrival - EPS if turning else turn_start + EPS
    first = int(np.searchsorted(times, start, side="left" if turning else "right"))
    if first >= len(times):
        first = len(times) - 1
        if times[first] <= turn_start + EPS:
            return []
    plan = [Aim(first, points[first])]
    i = first + 1
    while i < len(times):
        current = plan[-1].target
        if np.linalg.norm(points[i] - current) <= SAME_TARGET:
            plan.append(Aim(i, points[i]))
            i += 1
            continue
        plan.append(Aim(i, current))  # the change starts here, the head still on the old site
        done = times[i] + turn_time(_angle_between(eyes[i], current, points[i]))
        j = min(int(np.searchsorted(times, done - EPS, side="left")), len(times) - 1)
        if j > i:
            plan.append(Aim(j, points[j]))
        i = j + 1
    return plan


def _angle_between(eye: FloatArray, a: FloatArray, b: FloatArray) -> float:
    """The angle (rad) between the lines of sight from ``eye`` to ``a`` and to ``b``."""
    u, v = a - eye, b - eye
    cos = float(u @ v) / max(float(np.linalg.norm(u) * np.linalg.norm(v)), 1e-12)
    return math.acos(max(-1.0, min(1.0, cos)))


def implicit_segment(
    ir: MotionIR,
    part: Stretch,
    last: tuple[FloatArray, Segment],
    kf_time: FloatArray,
    kf_q: FloatArray,
    errors: FloatArray,
    turn_start: float,
) -> Segment:
    """The head segment of one part of the work; its goal is the site the head ends on."""
    skel = ir.skeleton
    names = tuple(skel.dof_names[d] for d in default_dofs(skel, ["gaze"], "arm"))
    point, source = last
    worst = float(errors.max())
    goal = GoalSpec("gaze", source.goal.site, np.asarray(point, dtype=float),
                    params={"implicit": True})  # fmt: skip
    seg = Segment("head", "gaze", turn_start, max(part.end, float(kf_time[-1])), goal,
                  source.provenance)  # fmt: skip
    seg.keyframes = Keyframes(time=kf_time, dofs=names, q=kf_q)
    seg.result = {"angle_error": worst, "success": worst <= GAZE_TOLERANCE}
    return seg
