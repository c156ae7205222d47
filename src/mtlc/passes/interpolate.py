"""Pass 5: merge every segment's keyframes into dense whole-body frames, then correct the base.

Joint angles: each degree of freedom follows a shape-preserving cubic (PCHIP: no overshoot past
a keyframe, so no joint limit is crossed between two keyframes within limits) through all the
keyframes that set it, holding its value before the first (from the rest pose) and after the
last. The root follows the root plan (ground position and heading), lowered or raised by the
postures' root keyframes, and replaced by the gait's own root keyframes while walking.

Base-coordinate correction (seed 001): interpolating angles and root height separately does not
keep the feet on the ground (the legs' height is not linear in the angles: a half-way squat
pose stands taller than half-way between the poses, so the feet sink). After interpolation the
root is moved by h = L − x, L the ground height and x the lowest foot point: onto the ground
while both feet stand, only upward (never below the ground) while walking.
"""

from __future__ import annotations

from bisect import bisect_right
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from mtlc.body import part_site_positions
from mtlc.body.kinematics import bits_differ
from mtlc.ir.model import FloatArray, Frames, MotionIR, yaw_quaternion
from mtlc.ir.pchip import pchip
from mtlc.passes.context import INTERNAL_FPS, PassContext

FOOT_POINTS = (
    "r_heel",
    "r_toe",
    "r_ball_med",
    "r_ball_lat",
    "l_heel",
    "l_toe",
    "l_ball_med",
    "l_ball_lat",
)


def time_grid(duration: float, fps: float) -> np.ndarray:
    n = int(np.floor(duration * fps + 1e-9))
    grid = np.arange(n + 1) / fps
    return grid if grid[-1] >= duration - 1e-9 else np.append(grid, duration)


def track(times: ArrayLike, values: ArrayLike, grid: np.ndarray) -> np.ndarray:
    """Values on ``grid`` through keyframes, holding before the first and after the last."""
    t = np.asarray(times)
    v = np.asarray(values)
    order = np.argsort(t, kind="stable")
    t, v = t[order], v[order]
    keep = np.append(np.diff(t) > 1e-9, True)  # at equal times the later keyframe wins
    t, v = t[keep], v[keep]
    if len(t) == 1:
        return np.broadcast_to(v[0], (len(grid), *v.shape[1:])).copy()
    curve = pchip(t, v, extrapolate=False)
    at = np.clip(grid, t[0], t[-1])
    if len(at) <= EVAL_CHUNK:
        return curve(at)
    # a long grid a chunk at a time: each value is its own sample's arithmetic, so the same
    # numbers, and the pieces' temporaries stay in the cache (5x faster on 170,000 samples)
    out = np.empty((len(at), *v.shape[1:]))
    for a in range(0, len(at), EVAL_CHUNK):
        out[a : a + EVAL_CHUNK] = curve(at[a : a + EVAL_CHUNK])
    return out


EVAL_CHUNK = 4096  # samples of a curve evaluated at once
CHUNK_FRAMES = 4096  # frames whose pose is computed at once by the base correction
HOLD_EPS = 1e-3  # seconds: a held value turns into the next segment's first keyframe this fast
SAME_INSTANT = 1e-6  # seconds: keys of two segments closer than this are at one instant


def interpolate_joints(ir: MotionIR, grid: np.ndarray) -> np.ndarray:
    """Each dof through its keyframes; between two segments' keyframes it holds its value.

    Within a segment the curve is PCHIP. Between segments a dof keeps the last segment's final
    value until the next segment's first keyframe, exactly what the solving passes assume
    ("a segment starts from the pose the body is in", mtlc.passes.state); a jump that a pass
    leaves there is blended out by the smoothing pass (seed 004 claim 6), not spread over the gap.
    Only a segment's *first* keyframe holds: another segment's keyframe at the same instant (a
    walk's last keyframe at a posture's start) must not freeze the rest of the posture.
    """
    skel = ir.skeleton
    rest = np.asarray(skel.q_comfort, dtype=float)
    # per dof, its keyframe columns: (times, segment order, values)
    columns: dict[int, list[tuple[FloatArray, int, FloatArray]]] = {}
    for order, seg in enumerate(ir.segments):
        kf = seg.keyframes
        if kf is None or not kf.dofs:
            continue
        t = np.asarray(kf.time, dtype=float)
        for j, name in enumerate(kf.dofs):
            columns.setdefault(skel.dof_index(name), []).append((t, order, kf.q[:, j]))
    q = np.tile(rest, (len(grid), 1))
    curves: dict[bytes, tuple[FloatArray, list[int], list[FloatArray]]] = {}
    for d, parts in columns.items():
        ts, vs = _held_curve(parts, float(rest[d]))
        _, dofs, values = curves.setdefault(ts.tobytes(), (ts, [], []))
        dofs.append(d)
        values.append(vs)
    for ts, dofs, values in curves.values():  # dofs keyed at the same times: one spline
        q[:, dofs] = track(ts, np.stack(values, axis=1), grid)
    return q


def _held_curve(
    parts: list[tuple[FloatArray, int, FloatArray]], rest: float
) -> tuple[FloatArray, FloatArray]:
    """One dof's knots: from ``rest`` at 0 through its keyframes in time order (at equal times
    in segment order), with a hold just before each segment's first keyframe and after the
    last keyframe (so the dof comes to rest there)."""
    # to the nanosecond: two segments' keys at one instant, computed two ways (a gaze part's
    # end, rounded, and the next look's start), must sort by segment, not by a 4e-10 s
    # difference that put a hold of the older value just before the later key (issue 19)
    # Rounding alone is not enough: two times 4e-10 s apart can round to two neighbouring
    # nanoseconds (a reach's first key, which the pace pass rounds, and the posture's last key
    # before it, both warped by the joint-speed pass), and the reach's first key then sorted
    # first and held the posture's *previous* key: the trunk of a squat jumped 20 deg at the
    # reach's start and the hand made two movements (bench/procedures shelf_latches_valve, male
    # P95). Keys closer than ``SAME_INSTANT`` are one instant, ordered by segment.
    t = np.round(np.concatenate([p[0] for p in parts]), 9)
    order = np.concatenate([np.full(len(p[0]), p[1]) for p in parts])
    v = np.concatenate([np.asarray(p[2], dtype=float) for p in parts])
    first = np.concatenate([np.arange(len(p[0])) == 0 for p in parts])
    by = np.argsort(t, kind="stable")
    t, order, v, first = t[by], order[by], v[by], first[by]
    instant = np.concatenate([[0], np.cumsum(np.diff(t) > SAME_INSTANT)])
    by = np.lexsort((order, instant))
    t, v, first = t[by], v[by], first[by]
    t = np.maximum.accumulate(t)  # one instant's keys at its latest time
    before_t = np.concatenate([[0.0], t[:-1]])
    before_v = np.concatenate([[rest], v[:-1]])
    hold = first & (t - before_t > 2 * HOLD_EPS)  # hold until the next segment takes over
    # knot 2k is entry k's hold (if any), knot 2k + 1 the entry itself
    slot = np.concatenate([[-1], np.flatnonzero(hold) * 2, np.arange(len(t)) * 2 + 1])
    knots_t = np.concatenate([[0.0], t[hold] - HOLD_EPS, t])
    knots_v = np.concatenate([[rest], before_v[hold], v])
    by = np.argsort(slot, kind="stable")
    # and a hold just after the last: PCHIP's end slope is extrapolated from the last two
    # intervals, so a dof would stop at speed there (a forearm twist ended at 400 deg/s)
    return np.append(knots_t[by], t[-1] + HOLD_EPS), np.append(knots_v[by], v[-1])


def interpolate_root(ir: MotionIR, grid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    skel = ir.skeleton
    stand = float(np.asarray(skel.root_position)[1])
    plan = ir.root_plan
    assert plan is not None
    position, heading = plan.at(grid)
    position = position.copy()
    position[:, 1] = ir.ground + stand
    # postures move the root up and down: their keyframes give heights, held until the next
    ts, ys = [0.0], [0.0]
    for seg in ir.segments:
        kf = seg.keyframes
        if seg.kind == "posture" and kf is not None and kf.root_position is not None:
            ts += [float(t) for t in kf.time]
            ys += [float(y) - (ir.ground + stand) for y in kf.root_position[:, 1]]
    position[:, 1] += track(ts, [np.array(y) for y in ys], grid)
    rotation = yaw_quaternion(heading)
    keyed, keyed_position = keyed_root(ir, grid)  # a stepping kneel places the root itself
    position[keyed] = keyed_position[keyed]
    # the gait sets the whole root while walking, including its closing step
    for seg in ir.segments:
        kf = seg.keyframes
        if seg.kind != "locomotion" or kf is None or kf.root_position is None:
            continue
        start, end = gait_window(seg)
        inside = (grid >= start) & (grid <= end)
        if not inside.any():
            continue
        position[inside] = track(list(kf.time), list(kf.root_position), grid[inside])
        if kf.root_rotation is not None:
            quats = track(list(kf.time), list(kf.root_rotation), grid[inside])
            rotation[inside] = quats / np.linalg.norm(quats, axis=1, keepdims=True)
    return position, rotation


def keyed_windows(ir: MotionIR) -> list[tuple[Any, float, float]]:
    """Postures that place the root themselves (``result["root"] == "keyed"``: the stepping
    kneel and the stand from it), with when they do: from the segment's start until the next
    walk or root-placing posture starts (the root holds the last keyframe until then)."""
    movers = sorted(
        (s for s in ir.segments if s.kind == "locomotion"
         or (s.kind == "posture" and s.keyframes is not None
             and s.keyframes.root_position is not None)),
        key=lambda s: s.start,
    )  # fmt: skip
    starts = [m.start for m in movers]
    out = []
    for i, seg in enumerate(movers):
        if seg.kind == "posture" and seg.result.get("root") == "keyed":
            # the first later start past this one is the soonest (the starts are sorted)
            j = bisect_right(starts, seg.start + 1e-9, lo=i + 1)
            out.append((seg, seg.start, starts[j] if j < len(starts) else np.inf))
    return out


def keyed_root(ir: MotionIR, grid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(mask (N,), positions (N, 3)) of the frames whose root a keyed posture sets."""
    mask = np.zeros(len(grid), dtype=bool)
    pos = np.zeros((len(grid), 3))
    for seg, start, end in keyed_windows(ir):
        kf = seg.keyframes
        inside = (grid > start + 1e-9) & (grid <= end + 1e-9)
        if kf is None or kf.root_position is None or not inside.any():
            continue
        mask |= inside
        pos[inside] = track(list(kf.time), list(kf.root_position), grid[inside])
    return mask, pos


def gait_window(seg: Any) -> tuple[float, float]:
    """When a walk's gait drives the body: its segment, and its closing step if that runs on
    (the gait holds the feet until its last keyframe, ``result["feet_held_until"]``)."""
    kf = seg.keyframes
    last = float(kf.time[-1]) if kf is not None and len(kf.time) else seg.end
    return seg.start, max(seg.end, last)


def walking_mask(ir: MotionIR, grid: np.ndarray) -> np.ndarray:
    mask = np.zeros(len(grid), dtype=bool)
    for seg in ir.segments:
        if seg.kind == "locomotion":
            start, end = gait_window(seg)
            mask |= (grid >= start) & (grid <= end)
    return mask


def lowest_foot_point(ir: MotionIR, frames: Frames) -> np.ndarray:
    feet = part_site_positions(
        ir.skeleton, frames.q, frames.root_position, frames.root_rotation, list(FOOT_POINTS)
    )
    return feet[..., 1].min(axis=-1)


def _feet_in_root_frame(skel: Any, q: np.ndarray, rotation: np.ndarray) -> np.ndarray:
    """Foot points (N, P, 3) relative to the root position, for joint angles and root rotation."""
    # the legs' joints only (9 of 21): the same numbers as a whole pose, for every frame
    return part_site_positions(skel, q, np.zeros((len(q), 3)), rotation, list(FOOT_POINTS))


_FOOT_DOFS: dict[int, tuple[Any, np.ndarray]] = {}


def foot_chain_dofs(skel: Any) -> np.ndarray:
    """The dofs that move the foot points relative to the root: those of the joints carrying
    them and of every joint above (what ``part_site_positions`` reads). Cached per skeleton."""
    hit = _FOOT_DOFS.get(id(skel))
    if hit is not None and hit[0] is skel:
        return hit[1]
    carriers = sorted({skel.joint_index(skel.site(name).joint) for name in FOOT_POINTS})
    chain = np.asarray(skel.ancestor)[carriers].any(axis=0)  # ancestor[j, k]: k is j or above
    dofs = np.flatnonzero(chain[np.asarray(skel.dof_joint)])
    if len(_FOOT_DOFS) > 16:
        _FOOT_DOFS.clear()
    _FOOT_DOFS[id(skel)] = (skel, dofs)
    return dofs


def feet_summary_rows(
    skel: Any, q: np.ndarray, rotation: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Of many frames, the foot points' centre (N, 3) and lowest height (N,) relative to the
    root: what the base correction needs of ``_feet_in_root_frame``. Each run of frames whose
    legs and heading are unchanged (to the bit) is computed once: a reach or a hold keeps the
    legs still for thousands of frames, and each frame's numbers are its own arithmetic, so
    the copies are the numbers those frames would give."""
    if len(q) == 0:
        return np.zeros((0, 3)), np.zeros(0)
    legs = np.concatenate([q[:, foot_chain_dofs(skel)], rotation], axis=1)
    new = np.ones(len(q), dtype=bool)
    new[1:] = bits_differ(legs[1:], legs[:-1]).any(axis=1)  # -0.0 is not 0.0 here
    rows = np.flatnonzero(new)
    centre, lowest = np.empty((len(rows), 3)), np.empty(len(rows))
    for a in range(0, len(rows), CHUNK_FRAMES):  # a chunk's feet are 96 bytes a frame
        take = rows[a : a + CHUNK_FRAMES]
        feet = _feet_in_root_frame(skel, q[take], rotation[take])
        centre[a : a + CHUNK_FRAMES], lowest[a : a + CHUNK_FRAMES] = _feet_summary(feet)
    if len(rows) == len(q):
        return centre, lowest
    run = np.cumsum(new) - 1
    return centre[run], lowest[run]


def _feet_summary(feet: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The centre (N, 3) and lowest height (N,) of foot points (N, P, 3)."""
    return feet.mean(axis=1), feet[..., 1].min(axis=1)


_REST_CENTRES: dict[int, tuple[Any, np.ndarray]] = {}


def _rest_feet_centre(skel: Any) -> np.ndarray:
    """Where the feet's centre lies from the root when standing at rest, heading 0 (body frame).

    Cached per skeleton (the solving passes ask for every root they place); the entry keeps
    the skeleton alive so its id cannot be reused by another one.
    """
    hit = _REST_CENTRES.get(id(skel))
    if hit is not None and hit[0] is skel:
        return hit[1]
    rest = np.asarray(skel.q_comfort, dtype=float)[None]
    centre = _feet_in_root_frame(skel, rest, np.array([[1.0, 0.0, 0.0, 0.0]]))[0].mean(axis=0)
    if len(_REST_CENTRES) > 16:
        _REST_CENTRES.clear()
    _REST_CENTRES[id(skel)] = (skel, centre)
    return centre


def anchored_root(
    skel: Any, q: np.ndarray, plan_position: np.ndarray, rotation: np.ndarray, ground: float
) -> np.ndarray:
    """Root positions (N, 3) that stand the legs' pose on the ground where the plan stands them.

    Vertically this is seed 001's correction h = L − x (L the ground, x the lowest foot point);
    horizontally the feet's centre is kept where it is at rest under the planned root, so a squat
    moves the pelvis back instead of sliding the feet forward. Used by the solving passes (where
    is the body when the hand must reach) and by interpolation alike, so they agree.
    """
    centre, lowest = _feet_summary(_feet_in_root_frame(skel, q, rotation))
    return _anchor(skel, centre, lowest, plan_position, rotation, ground)


def _anchor(
    skel: Any,
    centre: np.ndarray,
    lowest: np.ndarray,
    plan_position: np.ndarray,
    rotation: np.ndarray,
    ground: float,
) -> np.ndarray:
    """``anchored_root`` from the foot points' centre (N, 3) and lowest height (N,) relative
    to the root, already known."""
    w, x, y, z = rotation.T
    yaw = np.arctan2(2 * (w * y + x * z), 1 - 2 * (y * y + x * x))  # heading about +Y
    rest = _rest_feet_centre(skel)
    rest_world = np.stack(
        [np.cos(yaw) * rest[0] + np.sin(yaw) * rest[2], np.zeros_like(yaw),
         -np.sin(yaw) * rest[0] + np.cos(yaw) * rest[2]], axis=1,
    )  # fmt: skip
    out = np.array(plan_position, dtype=float, copy=True)
    out[:, 0] += rest_world[:, 0] - centre[:, 0]
    out[:, 2] += rest_world[:, 2] - centre[:, 2]
    out[:, 1] = ground - lowest
    return out


def correct_base(ir: MotionIR, frames: Frames) -> np.ndarray:
    """Seed 001's h = L − x on every frame; returns the vertical correction applied (per frame).

    While both feet stand, the root is re-anchored (``anchored_root``): feet on the ground, where
    the plan stands them. While walking the gait places the feet; a swing foot may lift, and the
    correction only raises the root so that nothing sinks.
    """
    walking = walking_mask(ir, frames.time)
    before = frames.root_position[:, 1].copy()
    standing = ~walking & ~keyed_root(ir, frames.time)[0]  # a keyed root is already exact
    centre, lowest = np.zeros((len(frames.time), 3)), np.zeros(len(frames.time))
    moved = standing | walking
    if moved.all():
        centre, lowest = feet_summary_rows(ir.skeleton, frames.q, frames.root_rotation)
    elif moved.any():
        centre[moved], lowest[moved] = feet_summary_rows(
            ir.skeleton, frames.q[moved], frames.root_rotation[moved]
        )
    if standing.any():
        plan_position, _ = ir.root_plan.at(frames.time[standing])  # type: ignore[union-attr]
        frames.root_position[standing] = _anchor(
            ir.skeleton, centre[standing], lowest[standing], plan_position,
            frames.root_rotation[standing], ir.ground,
        )  # fmt: skip
    if walking.any():
        low = frames.root_position[walking, 1] + lowest[walking]
        frames.root_position[walking, 1] += np.maximum(ir.ground - low, 0.0)
    return frames.root_position[:, 1] - before


def interpolate_naive(ir: MotionIR, fps: float = INTERNAL_FPS) -> Frames:
    grid = time_grid(ir.duration, fps)
    q = interpolate_joints(ir, grid)
    position, rotation = interpolate_root(ir, grid)
    return Frames(fps=fps, time=grid, root_position=position, root_rotation=rotation, q=q)


def run(ir: MotionIR, ctx: PassContext) -> MotionIR:
    frames = interpolate_naive(ir)
    correct_base(ir, frames)
    ir.frames = frames
    return ir
