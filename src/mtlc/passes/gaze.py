"""Gaze: turn the neck and head so the eyes look at a site, within the neck's limits.

Runs after TA and TO, so the trunk is where the reaches left it. For each gaze segment (track
``head``), in time order, the body is taken at the segment's end (joints from the keyframes so
far, root from the plan) and the damped least squares solver aims the ``gaze`` site's direction
at the target (an ``aim`` goal) with the neck and head only (5 dofs). Gazes that share a time
window (``look`` at two latches at once) aim at the middle of their targets. A target outside the
neck's range gets the closest direction the limits allow (``result["angle_error"]`` says by how
much); no diagnostic, looking is not a goal a task fails on.

Keyframes: the head as it is at the start and the aimed head at the end.
"""

from __future__ import annotations

import math

import numpy as np

from mtlc.body import forward, site_direction, site_positions
from mtlc.body.ik import Goal, default_dofs, prepare, solve_ta
from mtlc.ir.model import Keyframes, MotionIR, Segment
from mtlc.passes.context import PassContext
from mtlc.passes.posture import RESTATERS
from mtlc.passes.state import PoseState, cached, mark, reanchor

GAZE_TOLERANCE = math.radians(1.0)


def solve(ir: MotionIR, ctx: PassContext) -> MotionIR:
    state = PoseState(ir)
    skel = ir.skeleton
    dofs = default_dofs(skel, ["gaze"], "arm")
    names = tuple(skel.dof_names[d] for d in dofs)
    windows: dict[tuple[float, float], list[Segment]] = {}
    for s in ir.segments:
        if s.kind == "gaze" and s.goal.position is not None:
            windows.setdefault((round(s.start, 9), round(s.end, 9)), []).append(s)
    for _, segs in sorted(windows.items()):
        t0, t1 = segs[0].start, segs[0].end
        target = np.mean([np.asarray(s.goal.position, dtype=float) for s in segs], axis=0)
        q0 = state.q_at(t0)
        root = state.root_at(t1)
        base = sorted(set(skel.chain_dofs("gaze")) - set(dofs))
        key = ("gaze", root[0].tobytes(), root[1].tobytes(), q0[base].round(12).tobytes())
        model = cached(
            ctx.cache,
            key,
            lambda q0=q0, root=root: prepare(
                skel, ["gaze"], q0, root_position=root[0], root_rotation=root[1]
            ),
        )
        res = solve_ta(skel, [Goal("gaze", aim=target)], q0, model=model, restarts=2)
        q1 = res.q[0]
        pose = forward(skel, q1[None], root[0][None], root[1][None])
        eye = np.asarray(site_positions(skel, pose, "gaze")[0])
        look = np.asarray(site_direction(skel, pose, "gaze")[0])
        want = (target - eye) / max(float(np.linalg.norm(target - eye)), 1e-9)
        err = float(np.arccos(np.clip(look @ want, -1.0, 1.0)))
        for seg in segs:
            seg.keyframes = Keyframes(
                time=np.array([t0, t1]), dofs=names, q=np.stack([q0[dofs], q1[dofs]])
            )
            seg.result = {"angle_error": err, "success": err <= GAZE_TOLERANCE}
            state.add(seg)
            mark(ctx.cache, seg)
    reanchor(ir, ctx.cache, RESTATERS)
    return ir
