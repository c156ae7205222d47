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
What the arm cannot clear is measured and reported by verify (MT0514).

It runs after smoothing and the two-handed carry (``carry``), on the frames ``sample`` turns
into the output: nothing after it moves the arms.
"""

from __future__ import annotations

import numpy as np

from mtlc.body.ik.clearance import keep_clear
from mtlc.ir.model import FloatArray, MotionIR
from mtlc.passes.context import PassContext

PINNED = 30.0  # weight of the hand's pose where it has a goal (per metre of the clearance)
FREE = 0.3  # ...and where it is free
RAMP = 0.2  # s over which the weight changes between the two
GOAL_LEAD = 0.15  # s before a reach's end the hand counts as arriving at its goal
ARM_TRACK = {"r": "r_arm", "l": "l_arm"}
HAND_TRACK = {"r": "r_hand", "l": "l_hand"}
EPS = 1e-9


def pinned(ir: MotionIR, side: str, t: FloatArray) -> np.ndarray:
    """(N,) frames where the ``side`` hand's pose is a goal: the last ``GOAL_LEAD`` seconds of
    each reach or move and its contact phase (TO), a wrench's strokes, and while its grip is
    closed (it holds a site or carries a part)."""
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


def run(ir: MotionIR, ctx: PassContext) -> MotionIR:
    frames = ir.frames
    if frames is None or not len(frames.time):
        return ir
    root = (frames.root_position, frames.root_rotation)
    for side in ("r", "l"):
        keep = pinned_weights(ir, side, frames.time)
        frames.q = keep_clear(ir.skeleton, frames.q, root, side, keep)
    return ir
