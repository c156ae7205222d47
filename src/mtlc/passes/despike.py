"""Pass 11e: no arm leaves its own motion for a few frames faster than a person moves (issue 19).

The passes that move an arm after interpolation solve it frame by frame: balance restores a
hand's contact, smoothing re-pins it, clearance keeps the forearm out of the body. Where two
solutions of the arm's redundancy lie close, a frame or two land on the other one and come
back: the pump's low kneel (female P90) turned the right wrist 27° out and back within two
output frames as balance put its hand back on the filter. No pass that made it sees it: each
judges its own correction, and the spike is the difference between two of them.

Here, on the final dense frames, a short run of frames (``SPIKE_TIME`` at most) that the upper
body (spine, neck, clavicles, arms: ``upper_body``) enters and leaves faster than
``SPIKE_SPEED`` (issue 19's 360°/s) in some dof, where going straight from the frame before it
to the frame after it would not, is given that straight way: those dofs interpolated across
it, and each hand that has a goal there (``clearance.pinned``: a contact, a grip, a reach's
arrival) put on the straight way between its places in those two frames, by its arm's own
dofs with the least change from the interpolation (``hand_way``, ``clearance.hand_put``). A run takes it
where every such hand gets there (``HELD_TOL``, ``HELD_TURN``), no step into, within or out of
it is as large as the run's largest was, and neither arm goes deeper into the body than it was
(``DEEPER``); else it stays as it was, and verify measures it like any other frame.

Fastener turns are left as they are (a tool's strokes and a hand's turns: out and back by
design, and the straight way between two frames of a stroke's arc would take the tip off the
fastener). The legs and the root are left as they are: a run where they jump too (a balance
correction that a frame or two did not take) is not a spike of the arm, and stays.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from mtlc.body.ik.clearance import penetration
from mtlc.body.kinematics import (
    forward,
    matrix_to_quat,
    quat_to_matrix,
    site_positions,
    site_rotation,
)
from mtlc.body.skeleton import Skeleton
from mtlc.ir.model import FloatArray, MotionIR
from mtlc.passes.clearance import hand_put, pinned
from mtlc.passes.context import PassContext
from mtlc.passes.tool import is_stroke

SPIKE_SPEED = math.radians(360.0)  # rad/s: issue 19's fastest joint
SPIKE_TIME = 0.1  # s: the longest run of frames taken for a spike (6 frames at 60 fps)
DEEPER = 1e-3  # m the arm may go deeper into the body than the run had it
SIDES = ("r", "l")
UPPER_PARTS = ("lumbar", "thorax", "neck", "head", "clavicle", "shoulder", "elbow", "wrist")


def spikes(q: FloatArray, t: FloatArray, limit: float, longest: float) -> list[tuple[int, int]]:
    """(a, b): the frames before and after each run of frames ``a+1 .. b-1`` that ``q`` (N, C)
    enters and leaves faster than ``limit`` (rad/s) in some column, no longer than ``longest``
    (s), where the straight way from frame ``a`` to frame ``b`` is within ``limit``: the first
    such way out of each fast step, in time order, none overlapping."""
    n = len(t)
    if n < 3:
        return []
    dt = np.diff(t)
    fast = np.flatnonzero((np.abs(np.diff(q, axis=0)) > (limit * dt)[:, None] + 1e-9).any(axis=1))
    out: list[tuple[int, int]] = []
    done = -1
    for k, s in enumerate(fast):
        if s < done:
            continue
        for e in fast[k + 1 :]:
            if t[e] - t[s + 1] > longest + 1e-9:
                break
            a, b = int(s), int(e) + 1
            if np.all(np.abs(q[b] - q[a]) <= limit * (t[b] - t[a]) + 1e-9):
                out.append((a, b))
                done = b
                break
    return out


def straight(q: FloatArray, t: FloatArray, a: int, b: int) -> FloatArray:
    """(b - a - 1, C) the frames between ``a`` and ``b`` on the straight way from one to the
    other, in time."""
    w = ((t[a + 1 : b] - t[a]) / (t[b] - t[a]))[:, None]
    return (1.0 - w) * q[a] + w * q[b]


def turned_between(Ra: FloatArray, Rb: FloatArray, w: FloatArray) -> FloatArray:
    """(W, 3, 3) the rotations a share ``w`` (W,) of the way from ``Ra`` to ``Rb`` (3, 3),
    about one axis (spherical interpolation)."""
    qa, qb = matrix_to_quat(Ra), matrix_to_quat(Rb)
    if float(qa @ qb) < 0.0:
        qb = -qb
    angle = math.acos(min(1.0, float(qa @ qb)))
    if angle < 1e-9:
        return np.broadcast_to(Ra, (len(w), 3, 3)).copy()
    s = math.sin(angle)
    q = (np.sin((1.0 - w) * angle) / s)[:, None] * qa + (np.sin(w * angle) / s)[:, None] * qb
    return quat_to_matrix(q)


def hand_way(
    place: FloatArray, rot: FloatArray, t: FloatArray, a: int, b: int
) -> tuple[FloatArray, FloatArray]:
    """Where a hand goes over the frames between ``a`` and ``b``, given its ``place`` (2, 3)
    and orientation ``rot`` (2, 3, 3) in those two frames: straight, and about one axis. Not
    where the run had it: a frame one pass left alone between two it corrected has its hand
    where it was before the correction, 20 mm off its neighbours' way (a ceiling cassette,
    female P1)."""
    w = (t[a + 1 : b] - t[a]) / (t[b] - t[a])
    return (1.0 - w)[:, None] * place[0] + w[:, None] * place[1], turned_between(rot[0], rot[1], w)


def upper_body(skel: Skeleton) -> NDArray[np.intp]:
    """The dofs above the pelvis: spine, neck, head, clavicles and both arms, straightened
    together (the pump's two arms took their other branch in the same two frames, and an
    arm straightened alone under a trunk that moved with it cannot keep its hand)."""
    return np.array(
        [j for j, n in enumerate(skel.dof_names) if n.split("_")[-2] in UPPER_PARTS
         or n.split("_")[0] in UPPER_PARTS],
        dtype=np.intp,
    )  # fmt: skip


def fastener_turns(ir: MotionIR, t: FloatArray) -> NDArray[np.bool_]:
    """(N,) frames of a fastener turn (a tool's strokes, a hand's turns): their wrist and
    forearm go out and back by design (issue 19 allows them 20 deg a frame), and the straight
    way between two frames of a stroke's arc takes the tool's tip off the fastener."""
    out = np.zeros(len(t), dtype=bool)
    for seg in ir.segments:
        path = seg.provenance.path
        if is_stroke(seg) or (path and "turn_fastener" in path[-1]):
            out |= (t >= seg.start - 1e-9) & (t <= seg.end + 1e-9)
    return out


def run(ir: MotionIR, ctx: PassContext) -> MotionIR:
    frames = ir.frames
    skel = ir.skeleton
    if frames is None or skel is None or len(frames.time) < 3:
        return ir
    t = frames.time
    root = (frames.root_position, frames.root_rotation)
    cols = upper_body(skel)
    turning = fastener_turns(ir, t)
    runs = [
        (a, b) for a, b in spikes(frames.q[:, cols], t, SPIKE_SPEED, SPIKE_TIME)
        if not turning[a : b + 1].any()
    ]  # fmt: skip
    if not runs:
        return ir
    rows = np.concatenate([np.arange(a + 1, b) for a, b in runs])
    sub_root = (root[0][rows], root[1][rows])
    was = frames.q[rows]
    new = was.copy()
    new[:, cols] = np.concatenate([straight(frames.q[:, cols], t, a, b) for a, b in runs])
    ok = np.ones(len(rows), dtype=bool)
    ends = np.array([(a, b) for a, b in runs]).ravel()  # the frames around the runs, posed once
    around = forward(skel, frames.q[ends], root[0][ends], root[1][ends], with_axes=False)
    for side in SIDES:
        at = np.flatnonzero(pinned(ir, side, t)[rows])
        if not at.size:
            continue
        place = site_positions(skel, around, f"{side}_hand").reshape(-1, 2, 3)
        rot = site_rotation(skel, around, f"{side}_hand").reshape(-1, 2, 3, 3)
        targets = [hand_way(place[k], rot[k], t, a, b) for k, (a, b) in enumerate(runs)]
        site = np.concatenate([p for p, _ in targets])[at]
        turn = np.concatenate([r for _, r in targets])[at]
        at_root = (sub_root[0][at], sub_root[1][at])
        new[at], back = hand_put(skel, new[at], site, turn, at_root, side)
        ok[at] &= back
    for side in SIDES:
        ok &= (
            penetration(skel, new, sub_root, side)
            <= np.maximum(penetration(skel, was, sub_root, side), 0.0) + DEEPER
        )
    first = 0
    for a, b in runs:
        span = slice(first, first + b - a - 1)
        first += b - a - 1
        if not ok[span].all():
            continue
        before = frames.q[a : b + 1][:, cols]
        after = before.copy()
        after[1:-1] = new[span][:, cols]
        if np.abs(np.diff(after, axis=0)).max() < np.abs(np.diff(before, axis=0)).max():
            frames.q[a + 1 : b] = new[span]
    return ir
