"""Whole-body postures (stand, bend, squat, kneel, sit) and wrist turns, as keyframes.

Each posture segment gets two keyframes: the pose the body is in at its start (so nothing moves
before it) and the target posture at its end, with the root height that puts the body on the
ground. Heights come from forward kinematics, not from a table: the root is placed so the lowest
foot point (heel, toe or ball) is on the ground, the same rule the base correction applies
(seed 001, h = L − x), so correction leaves a posture's end pose where it is.

The pelvis stays upright (interpolation turns the root about Y only), so trunk flexion is
lumbar + thorax and the legs fold under an upright pelvis:

* bend(angle): trunk flexion split 2:1 over lumbar and thorax (their ranges are 60° and 30°);
* squat(depth): hips, knees and ankles flexed with the feet flat (knee = hip + ankle
  dorsiflexion keeps the sole level), the root lowered by ``depth`` (0: the deepest the limits
  allow), heels on the ground;
* kneel(knees): the kneeling leg's thigh vertical, foot plantar-flexed, knee ``KNEE_HEIGHT`` above
  the ground with the toes on it; on one knee (the right) the left foot stands flat in front;
* sit: hips and knees at 90°, feet flat on the ground (on a seat the scene does not model).

A twist turns the forearm (``*_elbow_pro``, positive = pronation) by its angle from where it is,
clamped to the limits; a forearm already at the limit in that direction turns back instead (the
return stroke of a ratchet), so repeated turns stay visible instead of stalling at the stop.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from mtlc.body import center_of_mass, forward, site_positions
from mtlc.ir.model import FloatArray, Keyframes, MotionIR, Segment
from mtlc.passes.context import PassContext
from mtlc.passes.interpolate import FOOT_POINTS
from mtlc.passes.state import PoseState, mark, reanchor

TRUNK_DOFS = tuple(f"{j}_{a}" for j in ("lumbar", "thorax") for a in ("flex", "lat", "rot"))
LEG_DOFS = tuple(
    f"{s}_{d}"
    for s in ("r", "l")
    for d in ("hip_flex", "hip_abd", "hip_rot", "knee_flex", "ankle_dorsi", "ankle_inv")
)
KNEE_HEIGHT = 0.05  # m, knee joint centre above the ground when kneeling (half a knee's depth)
SQUAT_HIP_MAX = math.radians(110.0)  # deepest squat: hips 110°, ankles 20° dorsiflexed
SQUAT_ANKLE_MAX = math.radians(20.0)
TWIST_MIN_FRACTION = 0.25  # less than this share of a turn left before the stop: turn back


def _deg(skel: Any, values: dict[str, float], base: FloatArray) -> FloatArray:
    q = base.copy()
    for name, v in values.items():
        q[skel.dof_index(name)] = v
    return np.clip(q, skel.lower, skel.upper)


def _points(skel: Any, q: FloatArray, names: list[str]) -> FloatArray:
    """Body points with the root at the origin, facing +Z."""
    pose = forward(skel, q[None], np.zeros((1, 3)), np.array([[1.0, 0.0, 0.0, 0.0]]))
    return np.asarray(site_positions(skel, pose, names)[0])


def _knee_y(skel: Any, q: FloatArray, side: str) -> float:
    pose = forward(skel, q[None], np.zeros((1, 3)), np.array([[1.0, 0.0, 0.0, 0.0]]))
    return float(pose.p[0, skel.joint_index(f"{side}_knee"), 1])


def root_height(skel: Any, q: FloatArray, ground: float) -> float:
    """Root height that puts the lowest foot point of pose ``q`` on the ground."""
    return ground - float(_points(skel, q, list(FOOT_POINTS))[:, 1].min())


def _bisect(f: Any, lo: float, hi: float, n: int = 40) -> float:
    """Root of a monotone ``f`` on [lo, hi] (the end nearest to it if it has none)."""
    flo, fhi = f(lo), f(hi)
    if flo * fhi > 0:
        return lo if abs(flo) < abs(fhi) else hi
    for _ in range(n):
        mid = 0.5 * (lo + hi)
        fm = f(mid)
        if (fm > 0) == (flo > 0):
            lo, flo = mid, fm
        else:
            hi = mid
    return 0.5 * (lo + hi)


def _squat_q(skel: Any, base: FloatArray, s: float) -> FloatArray:
    h, a = s * SQUAT_HIP_MAX, s * SQUAT_ANKLE_MAX
    vals = {}
    for side in ("r", "l"):
        vals |= {f"{side}_hip_flex": h, f"{side}_knee_flex": h + a, f"{side}_ankle_dorsi": a}
    return _deg(skel, vals, base)


def balanced_lean(skel: Any, q: FloatArray, margin: float = 0.01) -> FloatArray:
    """Lean the trunk forward until the centre of mass is over the middle of the feet.

    With the heels down, a squat puts the pelvis behind the feet (the base correction keeps the
    feet where they stood); people lean forward to stay balanced, and so does the manikin: the
    lean (split 2:1 over lumbar and thorax, as in `bend`) is found by bisection on the CoM's
    forward distance from the feet's centre, in the body's own frame.
    """
    lum_max = float(skel.upper[skel.dof_index("lumbar_flex")])
    tho_max = float(skel.upper[skel.dof_index("thorax_flex")])

    def leaned(lean: float) -> FloatArray:
        return _deg(skel, {"lumbar_flex": min(lean * 2 / 3, lum_max),
                           "thorax_flex": min(lean / 3, tho_max)}, q)  # fmt: skip

    def ahead(lean: float) -> float:
        pose = forward(skel, leaned(lean)[None])
        com = center_of_mass(skel, pose)[0]
        feet = site_positions(skel, pose, list(FOOT_POINTS))[0]
        return float(com[2] - feet[:, 2].mean()) - margin  # the body faces +Z

    top = lum_max * 1.5
    if ahead(0.0) >= 0.0:
        return q
    if ahead(top) <= 0.0:
        return leaned(top)
    return leaned(_bisect(ahead, 0.0, top))


def _legs_zero(skel: Any, q: FloatArray) -> FloatArray:
    out = q.copy()
    for name in LEG_DOFS:
        out[skel.dof_index(name)] = 0.0
    return out


def target_posture(skel: Any, current: FloatArray, params: dict[str, Any]) -> FloatArray:
    """The joint angles of a whole-body posture (legs and trunk; arms and head as they are)."""
    kind = params.get("posture", "stand")
    q = current.copy()
    if kind == "stand":
        for name in (*TRUNK_DOFS, *LEG_DOFS):
            q[skel.dof_index(name)] = skel.q_comfort[skel.dof_index(name)]
        return q
    if kind == "bend":
        angle = float(params.get("angle", math.radians(45)))
        lum = min(angle * 2.0 / 3.0, skel.upper[skel.dof_index("lumbar_flex")])
        tho = min(angle - lum, skel.upper[skel.dof_index("thorax_flex")])
        return _deg(skel, {"lumbar_flex": lum, "thorax_flex": tho}, q)
    q = _legs_zero(skel, q)
    if kind == "squat":
        depth = float(params.get("depth", 0.0))
        stand = root_height(skel, _legs_zero(skel, skel.q_comfort), 0.0)
        if depth <= 0.0:
            return balanced_lean(skel, _squat_q(skel, q, 1.0))
        s = _bisect(lambda s: stand - root_height(skel, _squat_q(skel, q, s), 0.0) - depth, 0, 1)
        return balanced_lean(skel, _squat_q(skel, q, s))
    if kind == "sit":
        vals = {f"{s}_{d}": math.pi / 2 for s in ("r", "l") for d in ("hip_flex", "knee_flex")}
        return _deg(skel, vals, q)
    if kind == "kneel":
        down = ("r", "l") if int(params.get("knees", 2)) == 2 else ("r",)
        for side in down:
            q = _deg(skel, {f"{side}_ankle_dorsi": skel.lower[skel.dof_index(f"{side}_ankle_dorsi")]},
                     q)  # fmt: skip
            feet = [f"{side}_{p}" for p in ("heel", "toe", "ball_med", "ball_lat")]

            def gap(k: float, side: str = side, feet: list[str] = feet, q: FloatArray = q) -> float:
                qq = _deg(skel, {f"{side}_knee_flex": k}, q)
                return _knee_y(skel, qq, side) - _points(skel, qq, feet)[:, 1].min() - KNEE_HEIGHT

            q = _deg(skel, {f"{side}_knee_flex": _bisect(gap, math.radians(45), math.radians(135))},
                     q)  # fmt: skip
        if len(down) == 1:  # left foot flat in front, shank vertical, sole as low as the toes
            low = float(_points(skel, q, ["r_toe", "r_ball_med", "r_ball_lat"])[:, 1].min())

            def front(a: float) -> float:
                qq = _deg(skel, {"l_hip_flex": a, "l_knee_flex": a}, q)
                return float(_points(skel, qq, ["l_heel"])[0, 1]) - low

            a = _bisect(front, 0.0, math.radians(125))
            q = _deg(skel, {"l_hip_flex": a, "l_knee_flex": a}, q)
        return q
    raise ValueError(f"unknown posture {kind!r}")


def _posture_segment(seg: Segment, state: PoseState, ctx: PassContext) -> None:
    skel, ir = state.skel, state.ir
    cur = state.q_at(seg.start, skip=seg)
    target = target_posture(skel, cur, seg.goal.params)
    kind = seg.goal.params.get("posture", "stand")
    dofs = (
        TRUNK_DOFS
        if kind == "bend"
        else (TRUNK_DOFS + LEG_DOFS if kind in ("stand", "squat") else LEG_DOFS)
    )
    idx = [skel.dof_index(n) for n in dofs]
    kf = Keyframes(
        time=np.array([seg.start, seg.end]), dofs=dofs, q=np.stack([cur[idx], target[idx]])
    )
    if kind != "bend":
        p0, _ = state.root_at(seg.start, skip=seg)
        p1, _ = state.root_at(seg.end, skip=seg)
        p1[1] = root_height(skel, target, ir.ground)
        kf.root_position = np.stack([p0, p1])
        seg.result = {"root_height": float(p1[1] - ir.ground)}
    seg.keyframes = kf
    state.add(seg)
    mark(ctx.cache, seg)


def twist_target(skel: Any, dof: str, current: float, angle: float) -> float:
    """Forearm angle after a turn by ``angle`` from ``current``, within the limits (see module)."""
    d = skel.dof_index(dof)
    lo, hi = float(skel.lower[d]), float(skel.upper[d])
    target = min(max(current + angle, lo), hi)
    if abs(target - current) < TWIST_MIN_FRACTION * abs(angle):
        target = min(max(current - angle, lo), hi)
    return target


def restate_twist(seg: Segment, state: PoseState) -> None:
    """Recompute a twist from the forearm angle just before it (after the arm was solved)."""
    kf = seg.keyframes
    assert kf is not None
    d = state.skel.dof_index(kf.dofs[0])
    cur = float(state.q_at(seg.start, skip=seg)[d])
    kf.q[0, 0] = cur
    kf.q[1, 0] = twist_target(state.skel, kf.dofs[0], cur, float(seg.goal.params["angle"]))


def _twist_segment(seg: Segment, state: PoseState, ctx: PassContext) -> None:
    side = "r" if seg.goal.effector.startswith("r") else "l"
    dof = f"{side}_elbow_pro"
    seg.keyframes = Keyframes(time=np.array([seg.start, seg.end]), dofs=(dof,), q=np.zeros((2, 1)))
    restate_twist(seg, state)
    seg.result = {"angle": float(seg.keyframes.q[1, 0] - seg.keyframes.q[0, 0])}
    state.add(seg)
    mark(ctx.cache, seg, "twist")


RESTATERS = {"twist": restate_twist}


def solve(ir: MotionIR, ctx: PassContext) -> MotionIR:
    """Keyframes for every posture segment, in time order (each starts where the last left)."""
    state = PoseState(ir)
    for seg in sorted(ir.segments, key=lambda s: s.start):
        if seg.kind != "posture":
            continue
        if seg.goal.params.get("posture") == "twist":
            _twist_segment(seg, state, ctx)
        else:
            _posture_segment(seg, state, ctx)
    reanchor(ir, ctx.cache, RESTATERS)
    return ir
