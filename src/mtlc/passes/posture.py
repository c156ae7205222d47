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
* kneel(knees): the stepping kneel of ``mtlc.passes.kneel`` (the right foot steps back, the right
  knee goes down, then the left one beside it), solved frame by frame with the root's whole
  position keyed; a stand right after a kneel plays it backwards;
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
from mtlc.body.ik.clearance import penetration
from mtlc.ir.model import FloatArray, Keyframes, MotionIR, Segment
from mtlc.passes.context import INTERNAL_FPS, PassContext
from mtlc.passes.hold import carried_postures, holding
from mtlc.passes.interpolate import FOOT_POINTS, anchored_root
from mtlc.passes.kneel import (
    HALF_KNEEL_PHASES,
    PLANT_W,
    SPINE_VARS,
    TOE_VARS,
    KneelPlan,
    contact_points,
    phase_edges,
    plan_kneel,
    polish_frames,
    smoothstep,
    to_world,
)
from mtlc.passes.locomotion import LegModel, leg_fk, leg_ik, leg_model
from mtlc.passes.profile import minimum_jerk
from mtlc.passes.stance import WIDE_RESULT
from mtlc.passes.state import TRUNK_DOFS, PoseState, mark, reanchor, start_posture_from

LEG_DOFS = tuple(
    f"{s}_{d}"
    for s in ("r", "l")
    for d in ("hip_flex", "hip_abd", "hip_rot", "knee_flex", "ankle_dorsi", "ankle_inv")
)
KNEE_HEIGHT = 0.05  # m, knee joint centre above the ground when kneeling (half a knee's depth)
SQUAT_HIP_MAX = math.radians(110.0)  # deepest squat: hips 110°, ankles 20° dorsiflexed
SQUAT_ANKLE_MAX = math.radians(20.0)
# the ankles reach their dorsiflexion limit by this share of the squat: the knees go forward
# first, so the hips need not go as far back behind the heels
SQUAT_ANKLE_LEAD = 0.5
SQUAT_ARMS = math.radians(90.0)  # free arms held forward at the deepest squat (counterweight)
HEEL_MARGIN = 0.03  # m: a flat-footed posture keeps its CoM this far in front of the heels
TRANSITION_KEYS = 6  # keyframes of a flat-footed posture change, each one balanced
WIDE_KEYS = 41  # ...over feet set apart: leg IK at each key (11 keys slid them 5 cm/s)
ARM_FLEX = ("r_shoulder_flex", "l_shoulder_flex")
FINGER_CLEARANCE = 0.03  # m: free fingertips stay this far above the ground in a posture
FINGER_ARM_MAX = math.radians(120.0)  # ...raising the arm forward at most this far
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
    h, a = s * SQUAT_HIP_MAX, min(1.0, s / SQUAT_ANKLE_LEAD) * SQUAT_ANKLE_MAX
    vals = {}
    for side in ("r", "l"):
        vals |= {f"{side}_hip_flex": h, f"{side}_knee_flex": h + a, f"{side}_ankle_dorsi": a}
    return _deg(skel, vals, base)


def balanced_lean(skel: Any, q: FloatArray, margin: float = HEEL_MARGIN) -> FloatArray:
    """Lean the trunk forward until the centre of mass is ``margin`` in front of the heels.

    With the heels down, a squat puts the pelvis behind the feet (the base correction keeps the
    feet where they stood); people lean forward to stay balanced, and so does the manikin: the
    lean (added to the trunk's flexion, split 2:1 over lumbar and thorax as in `bend`) is found
    by bisection on the CoM's forward distance from the heels, in the body's own frame.
    """
    lum, tho = skel.dof_index("lumbar_flex"), skel.dof_index("thorax_flex")
    lum0, tho0 = float(q[lum]), float(q[tho])
    lum_max, tho_max = float(skel.upper[lum]), float(skel.upper[tho])

    def leaned(lean: float) -> FloatArray:
        return _deg(skel, {"lumbar_flex": min(lum0 + lean * 2 / 3, max(lum_max, lum0)),
                           "thorax_flex": min(tho0 + lean / 3, max(tho_max, tho0))}, q)  # fmt: skip

    def ahead(lean: float) -> float:
        pose = forward(skel, leaned(lean)[None])
        com = center_of_mass(skel, pose)[0]
        heels = site_positions(skel, pose, ["r_heel", "l_heel"])[0]
        return float(com[2] - heels[:, 2].max()) - margin  # the body faces +Z

    top = lum_max * 1.5
    if ahead(0.0) >= 0.0:
        return q
    if ahead(top) <= 0.0:
        return leaned(top)
    return leaned(_bisect(ahead, 0.0, top))


def flat_feet(skel: Any, q: FloatArray) -> FloatArray:
    """``q`` with each ankle dorsiflexed by knee − hip flexion, so an upright pelvis stands on
    level soles. The comfortable pose's knees are 1.7° more bent than its hips: standing up
    to it raised the heels 7 mm off the floor while the toes stayed on it, and a heel 7 mm up
    bears no weight (docs/metrics.md, "Support")."""
    vals = {
        f"{s}_ankle_dorsi": float(q[skel.dof_index(f"{s}_knee_flex")])
        - float(q[skel.dof_index(f"{s}_hip_flex")])
        for s in ("r", "l")
    }
    return _deg(skel, vals, q)


def fingertip_clearance(skel: Any, q: FloatArray, side: str) -> float:
    """Height (m) of a fingertip of pose ``q`` above the lowest foot point (the ground, once
    the root is placed by ``root_height``)."""
    pts = _points(skel, q, [f"{side}_fingertip", *FOOT_POINTS])
    return float(pts[0, 1] - pts[1:, 1].min())


def clear_fingertips(skel: Any, q: FloatArray, free_arms: tuple[str, ...]) -> FloatArray:
    """``q`` with each free arm raised forward (shoulder flexion, by bisection) until its
    fingertip is ``FINGER_CLEARANCE`` above the ground: a deep squat lowers the shoulders
    until hanging fingers would go through the floor (45-112 mm for a squat to a site 18 cm
    up, before). An arm already clear, or not free, is left as it is."""
    for dof in free_arms:
        side, k = dof[0], skel.dof_index(dof)
        if fingertip_clearance(skel, q, side) >= FINGER_CLEARANCE:
            continue
        lo, hi = float(q[k]), max(float(q[k]), min(float(skel.upper[k]), FINGER_ARM_MAX))

        def gap(a: float, k: int = k, side: str = side, q: FloatArray = q) -> float:
            qq = q.copy()
            qq[k] = a
            return fingertip_clearance(skel, qq, side) - FINGER_CLEARANCE

        if gap(hi) <= 0.0:
            q = _deg(skel, {dof: hi}, q)
            continue
        q = _deg(skel, {dof: _bisect(gap, lo, hi)}, q)
    return q


def _legs_zero(skel: Any, q: FloatArray) -> FloatArray:
    out = q.copy()
    for name in LEG_DOFS:
        out[skel.dof_index(name)] = 0.0
    return out


def target_posture(
    skel: Any, current: FloatArray, params: dict[str, Any], free_arms: tuple[str, ...] = ()
) -> FloatArray:
    """The joint angles of a whole-body posture (legs and trunk; head as it is).

    ``free_arms`` (shoulder flexion dofs of arms no segment uses): a squat holds them forward
    as a counterweight, standing lets them down; other arms stay as they are.
    """
    kind = params.get("posture", "stand")
    q = current.copy()
    if kind == "stand":
        for name in (*TRUNK_DOFS, *LEG_DOFS, *standing_arm_dofs(free_arms)):
            q[skel.dof_index(name)] = skel.q_comfort[skel.dof_index(name)]
        return flat_feet(skel, q)
    if kind == "bend":
        angle = float(params.get("angle", math.radians(45)))
        lum = min(angle * 2.0 / 3.0, skel.upper[skel.dof_index("lumbar_flex")])
        tho = min(angle - lum, skel.upper[skel.dof_index("thorax_flex")])
        return _deg(skel, {"lumbar_flex": lum, "thorax_flex": tho}, q)
    q = _legs_zero(skel, q)
    if kind == "squat":
        depth = float(params.get("depth", 0.0))
        stand = root_height(skel, _legs_zero(skel, skel.q_comfort), 0.0)
        s = 1.0
        if depth > 0.0:
            s = _bisect(
                lambda s: stand - root_height(skel, _squat_q(skel, q, s), 0.0) - depth, 0, 1
            )
        arms = {a: max(float(q[skel.dof_index(a)]), s * SQUAT_ARMS) for a in free_arms}
        low = balanced_lean(
            skel, clear_fingertips(skel, _deg(skel, arms, _squat_q(skel, q, s)), free_arms)
        )
        return clear_fingertips(skel, low, free_arms)
    if kind == "sit":
        vals = {f"{s}_{d}": math.pi / 2 for s in ("r", "l") for d in ("hip_flex", "knee_flex")}
        return _deg(skel, vals, q)
    if kind == "kneel":  # a kneeling pose; the pass kneels by stepping (mtlc.passes.kneel)
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


def standing_arm_dofs(free_arms: tuple[str, ...]) -> tuple[str, ...]:
    """The dofs a stand lets down to the comfort pose for each free arm (named by its shoulder
    flexion dof): the whole arm but the forearm's twist, which a `turn` owns. Only the shoulder's
    flexion went down before, and an arm that had reached down and out of a squat stood up with
    its shoulder turned and its elbow bent as it left the site."""
    return tuple(f"{dof[0]}_{part}" for dof in free_arms for part in KNEEL_ARM_PARTS)


def free_arms(ir: MotionIR, seg: Segment) -> tuple[str, ...]:
    """Shoulder flexion dofs of the arms free during ``seg``: no segment on the arm's track
    overlaps it, and the arm's last segment before it is not a contact (a hand that reached a
    site stays on it until its arm's next segment, see ``balance.hand_pins``) unless the hand
    opened its grip since (``released_arms``)."""
    return tuple(f"{side}_shoulder_flex" for side, how in _arm_states(ir, seg) if how != "held")


def released_arms(ir: MotionIR, seg: Segment) -> tuple[str, ...]:
    """Shoulder flexion dofs of the free arms whose hand let go of its site since its last
    contact: a released valve or a part set down leaves the hand free (the drain task stood up
    with the hand that had let go of the valve raised above the head)."""
    return tuple(f"{side}_shoulder_flex" for side, how in _arm_states(ir, seg) if how == "released")


def _arm_states(ir: MotionIR, seg: Segment) -> list[tuple[str, str]]:
    """(side, state) of each arm not busy during ``seg``: "free", "released" or "held"."""
    out = []
    for side in ("r", "l"):
        segs = ir.on_track(f"{side}_arm")
        if any(s.start < seg.end - 1e-9 and s.end > seg.start + 1e-9 for s in segs):
            continue
        before = [s for s in segs if s.end <= seg.start + 1e-9]
        last = max(before, key=lambda s: s.end, default=None)
        if last is None or last.kind != "TO":
            out.append((side, "free"))
        else:
            out.append((side, "released" if _let_go(ir, side, last.end, seg.start) else "held"))
    return out


LATE_START = 0.4  # share of a stand after which a released arm starts down (``late_share``)


def late_share(f: FloatArray) -> FloatArray:
    """How far a released arm has gone toward the stand's pose at share ``f`` of the stand: not
    at all until ``LATE_START``, then a smoothstep. Let down with the body, an arm that had
    reached low in a squat swept through the thigh while the thighs were still level."""
    return smoothstep((f - LATE_START) / (1.0 - LATE_START))


def _let_go(ir: MotionIR, side: str, after: float, before: float) -> bool:
    """Whether the hand's last grip event between ``after`` and ``before`` opened it."""
    grips = [s for s in ir.on_track(f"{side}_hand") if s.kind == "grip"]
    inside = [g for g in grips if after - 1e-9 <= g.start and g.end <= before + 1e-9]
    last = max(inside, key=lambda g: g.start, default=None)
    return last is not None and last.goal.params.get("state") == "open"


def transition(
    skel: Any,
    cur: FloatArray,
    target: FloatArray,
    n: int,
    free_arms: tuple[str, ...] = (),
    late: tuple[str, ...] = (),
) -> FloatArray:
    """``n`` poses from ``cur`` to ``target`` (n, D), each leaned until it is balanced.

    Interpolating the angles of two balanced flat-footed postures is not balanced on the way:
    half-way down a squat the hips are already back but the trunk only half leaned, so the CoM
    passes behind the heels. Each intermediate pose gets the lean it needs (``balanced_lean``).
    The ``late`` dofs move over the last ``1 - LATE_START`` of the change only (``late_share``).
    """
    f = np.linspace(0.0, 1.0, n)[:, None]
    share = np.repeat(f, len(cur), axis=1)
    if late:
        share[:, [skel.dof_index(name) for name in late]] = late_share(f)
    poses = cur[None] + share * (target - cur)[None]
    mid = (clear_fingertips(skel, balanced_lean(skel, p), free_arms) for p in poses[1:-1])
    return np.stack([poses[0], *mid, poses[-1]])


KNEEL_PLANS = "passes.posture.kneel_plans"  # ctx.cache: id(kneel segment) -> KneelPlan
STAND_SETTLE = 0.3  # s: a stand from a kneel first brings trunk and arms to the kneel's pose
SETTLE_PACE = math.radians(200.0)  # rad/s: their mean speed at most (peaks 1.5x: 10 deg a frame)
ARM_DOFS = tuple(
    f"{s}_{d}"
    for s in ("r", "l")
    for d in ("clavicle_elev", "clavicle_prot", "shoulder_flex", "shoulder_abd", "shoulder_rot",
              "elbow_flex", "elbow_pro", "wrist_flex", "wrist_dev")
)  # fmt: skip


TRUNK_TURN = ("lumbar_rot", "thorax_rot")  # the trunk dofs a kneel's plan holds as they were


def _heading(rotation: FloatArray) -> float:
    """Heading about +Y of a yaw-only root rotation (w, x, y, z)."""
    return 2.0 * math.atan2(float(rotation[2]), float(rotation[0]))


# Free arms while the body kneels or stands up from a kneel: the comfort pose's arm turned out
# at the shoulder and abducted by the least of these angles that keeps forearm and hand out of
# the thighs (and trunk) on every frame of the kneel's plan. The comfort pose's forearm points
# forward and in, where a thigh comes up as its knee goes forward (issue 18: 49 mm on the fuel
# filter, female P5); flexion and elbow stay as they are, so the arms' mass stays where the
# kneel's plan had it balanced
KNEEL_ARM_ABDUCTIONS = np.radians(np.arange(7.5, 45.0, 2.5))
KNEEL_ARM_ROTATION = math.radians(-20.0)  # the shoulder turned out: the forearm beside the thigh
KNEEL_ARM_SPARE = 0.01  # m the chosen pose keeps beyond the clearance on the plan's frames
KNEEL_ARM_RAMP = 0.3  # s over which a free arm goes to that pose at the kneel's start
KNEEL_ARM_PARTS = ("clavicle_elev", "clavicle_prot", "shoulder_flex", "shoulder_abd",
                   "shoulder_rot", "elbow_flex", "wrist_flex", "wrist_dev")  # fmt: skip


def hanging_arm(skel: Any, side: str, abduction: float) -> dict[str, float]:
    """The ``side`` arm as in the comfort pose (the forearm's twist left alone), the shoulder
    turned out by ``KNEEL_ARM_ROTATION`` and abducted by ``abduction``."""
    values = {f"{side}_{d}": float(skel.q_comfort[skel.dof_index(f"{side}_{d}")])
              for d in KNEEL_ARM_PARTS}  # fmt: skip
    values[f"{side}_shoulder_abd"] = abduction
    values[f"{side}_shoulder_rot"] = KNEEL_ARM_ROTATION
    return {n: float(np.clip(v, *_limits(skel, n))) for n, v in values.items()}


def _limits(skel: Any, name: str) -> tuple[float, float]:
    d = skel.dof_index(name)
    return float(skel.lower[d]), float(skel.upper[d])


def clear_arms(
    skel: Any, frames: FloatArray, roots: FloatArray, sides: tuple[str, ...],
    share: FloatArray | None = None,
) -> tuple[dict[str, float], float]:  # fmt: skip
    """Arm poses for the ``sides`` arms while the body goes through configurations ``frames``
    (N, D) with root positions ``roots`` (N, 3) (the pelvis upright: the heading does not
    change what is inside what): nothing when every arm as it is stays clear (they are left
    alone), else ``hanging_arm`` for each, with the least abduction that keeps them all clear
    with ``KNEEL_ARM_SPARE`` to spare (the balance pass moves the pelvis a little after the
    plan; the clearance pass would then flick a wrist to find the millimetres) or, if none does, the one that goes least deep; and how deep (m) they go with it. The same for both arms: one arm held out
    alone would move the centre of mass sideways over a narrow kneeling support. ``share``
    (N,): how far each frame has blended from its own arm to that pose (a kneel's start)."""
    rot = np.tile([1.0, 0.0, 0.0, 0.0], (len(frames), 1))

    def deepest(q: FloatArray) -> float:
        return max(float(penetration(skel, q, (roots, rot), side).max()) for side in sides)

    if not sides or (depth := deepest(frames)) <= 0.0:
        return {}, 0.0 if not sides else depth
    w = np.ones(len(frames)) if share is None else share
    best: tuple[float, dict[str, float]] | None = None
    for abduction in KNEEL_ARM_ABDUCTIONS:
        arms: dict[str, float] = {}
        for side in sides:
            arms.update(hanging_arm(skel, side, float(abduction)))
        q = frames.copy()
        for name, v in arms.items():
            d = skel.dof_index(name)
            q[:, d] += w * (v - q[:, d])
        depth = deepest(q)
        if depth <= -KNEEL_ARM_SPARE:
            return arms, depth
        if best is None or depth < best[0]:
            best = (depth, arms)
    assert best is not None
    return best[1], best[0]


def _plan_frames(plan: KneelPlan, q0: FloatArray, x: FloatArray) -> FloatArray:
    """(N, D) whole-body configurations of a plan's states ``x``, the rest of the body as in
    ``q0``."""
    q = np.tile(q0, (len(x), 1))
    q[:, plan.body.idx] = x[:, 3:]
    return q


def kneel_arm_share(times: FloatArray, start: float, end: float, back: bool) -> FloatArray:
    """(N,) how far the free arms are from their own pose toward the kneel's: there over the
    first ``KNEEL_ARM_RAMP`` seconds, and (``back``) home again over the last ones."""
    share = smoothstep((times - start) / KNEEL_ARM_RAMP)
    if back:
        share = share * smoothstep((end - times) / KNEEL_ARM_RAMP)
    return np.asarray(share, dtype=float)


def _kneel_arms(
    seg: Segment, plan: KneelPlan, q0: FloatArray, sides: tuple[str, ...], skel: Any
) -> None:
    """Free arms (``sides``) to a ``clear_arms`` pose over the kneel's first
    ``KNEEL_ARM_RAMP`` seconds, keyed on the kneel's own frames. They go back to where they
    were as the kneel ends if that keeps them clear (the reaches that follow then start from
    the pose they would have without this), else they stay. ``restate_kneel_arms`` restarts
    the ramps from wherever the arm really is when later passes have moved it."""
    kf = seg.keyframes
    assert kf is not None and kf.root_position is not None
    x = np.concatenate([np.zeros((len(kf.time), 3)), kf.q], axis=1)
    frames = _plan_frames(plan, q0, x)
    arms: dict[str, float] = {}
    for back in (True, False):
        share = kneel_arm_share(kf.time, seg.start, seg.end, back)
        arms, depth = clear_arms(skel, frames, kf.root_position, sides, share)
        if depth <= 0.0:
            break
    if not arms:
        return
    names = tuple(arms)
    idx = [skel.dof_index(n) for n in names]
    start, target = q0[idx], np.array([arms[n] for n in names])
    ramp = start[None] + share[:, None] * (target - start)[None]
    kf.q = np.hstack([kf.q, ramp])
    kf.dofs = (*kf.dofs, *names)


def restate_kneel_arms(seg: Segment, state: PoseState) -> None:
    """The kneel's arm ramps from the arm's pose just before the kneel (the legs, spine and
    root are the plan's, which started from the pose the posture pass saw)."""
    kf = seg.keyframes
    assert kf is not None
    arms = [k for k, n in enumerate(kf.dofs) if n.split("_", 1)[1] in KNEEL_ARM_PARTS]
    if not arms:
        return
    back = bool(np.allclose(kf.q[-1, arms], kf.q[0, arms]))
    share = kneel_arm_share(kf.time, seg.start, seg.end, back)
    target = kf.q[int(np.argmax(share)), arms]
    q = state.q_at(seg.start, skip=seg)
    start = q[[state.skel.dof_index(kf.dofs[k]) for k in arms]]
    kf.q[:, arms] = start[None] + share[:, None] * (target - start)[None]


def _knees_of(seg: Segment) -> int:
    return 2 if int(seg.goal.params.get("knees", 2)) == 2 else 1


def _kneel_segment(seg: Segment, state: PoseState, ctx: PassContext) -> None:
    """The stepping kneel (``mtlc.passes.kneel``): dense keyframes of legs, spine and root, and
    of the free arms (``_kneel_arms``). A kneel while the body kneels already does not start
    from standing: it holds that kneel or goes on to (or back from) the other one
    (``_kneel_from_kneel``)."""
    knees = _knees_of(seg)
    before = _last_posture(state.ir, seg)
    kneel = _kneel_before(state.ir, seg, ctx)
    if before is not None and kneel is not None and _knees_down(state, seg, before):
        _kneel_from_kneel(seg, kneel, _knees_of(before), knees, state, ctx)
        return
    q0 = state.q_at(seg.start, skip=seg)
    root, rot = state.root_at(seg.start, skip=seg)
    ground = state.ir.ground
    plan = plan_kneel(state.skel, q0, root, ground, knees, seg.end - seg.start)
    frame = (root.copy(), _heading(rot), ground)
    _key_kneel(seg, plan, q0, frame, plan, state, ctx)


KNEELING_TOL = 0.02  # m: knees this close to where the last kneel left them are still there
KNEELING_HIGH = 0.05  # m: and a knee this far above ``KNEE_HEIGHT`` does not kneel at all


def _knees_down(state: PoseState, seg: Segment, last: Segment) -> bool:
    """Whether the body, as ``seg`` starts, still kneels as the kneel ``last`` left it: each of
    its kneeling knees (the right; both for two) within ``KNEELING_TOL`` of where it was as
    ``last`` ended, and not ``KNEELING_HIGH`` above ``KNEE_HEIGHT`` (the plan of a large
    manikin's half kneel leaves its knee 3.6 cm above it, male P95)."""
    skel = state.skel
    sides = ("r", "l")[: _knees_of(last)]

    def heights(t: float) -> np.ndarray:
        q = state.q_at(t, skip=seg)
        root, rot = state.root_at(t, skip=seg)
        pose = forward(skel, q[None], root[None], rot[None], with_axes=False)
        return np.array([pose.p[0, skel.joint_index(f"{s}_knee"), 1] for s in sides])

    now, then = heights(seg.start), heights(last.end)
    return bool(np.all(np.abs(now - then) <= KNEELING_TOL)
                and np.all(now - state.ir.ground <= KNEE_HEIGHT + KNEELING_HIGH))  # fmt: skip


def _kneel_from_kneel(
    seg: Segment, kneel: tuple[KneelPlan, tuple[FloatArray, float, float]], had: int,
    knees: int, state: PoseState, ctx: PassContext,
) -> None:  # fmt: skip
    """A kneel on ``knees`` while the body kneels on ``had`` by the plan ``kneel`` (from
    standing): the same knees hold the kneel (``_hold_kneel``); both from the right knee go
    on with the two-knee kneel's last phases, the right knee from both undo them
    (``_kneel_between``). The plan recorded for a stand after it is always one from standing
    to where this segment leaves the body."""
    if knees == had:
        _hold_kneel(seg, kneel, state, ctx)
        return
    plan, frame = kneel
    duration = seg.end - seg.start
    half = float(phase_edges()[HALF_KNEEL_PHASES])  # share of kneel(2) that is kneel(1)
    if knees == 2:  # the whole two-knee kneel from the same standing start, its tail played;
        # its first four phases timed as the one-knee kneel's, so both reach the same half kneel
        full_time = float(plan.time[-1]) / half
        root = np.array([0.0, frame[2] + float(plan.x[0, 1]), 0.0])
        full = plan_kneel(state.skel, plan.body.q_base, root, frame[2], 2, full_time)
        piece = full.window(half * full_time, full_time, duration)
        # from where the one-knee kneel really left the body: the two solves' half kneels
        # differ a little (their frames are not at the same instants), which fades out over
        # the first phase
        piece.x = _faded_in(piece, plan.x[-1])
        standing = full
    else:  # the left knee comes up: the two-knee kneel's last phases backwards
        whole = float(plan.time[-1])
        cut = float(plan.time[np.searchsorted(plan.time, half * whole - 1e-9)])  # a solved frame
        piece = plan.window(cut, whole).reversed(duration)
        standing = plan.window(0.0, cut)
    q0 = state.q_at(seg.start, skip=seg)
    _key_kneel(seg, piece, q0, frame, standing, state, ctx)


def _key_kneel(
    seg: Segment, played: KneelPlan, q0: FloatArray, frame: tuple[FloatArray, float, float],
    standing: KneelPlan, state: PoseState, ctx: PassContext,
) -> None:  # fmt: skip
    """Key the ``played`` plan and the free arms on ``seg``, and record ``standing`` (the plan
    from standing to where ``seg`` leaves the body, for a later stand or kneel), marked for
    ``restate_kneel``."""
    _keyed(seg, played, seg.start, frame)
    sides = tuple(a[0] for a in free_arms(state.ir, seg))
    _kneel_arms(seg, played, q0, sides, state.skel)
    ctx.cache.setdefault(KNEEL_PLANS, {})[id(seg)] = (standing, frame)
    state.add(seg)
    mark(ctx.cache, seg, "kneel")


def _faded_in(piece: KneelPlan, start: FloatArray) -> FloatArray:
    """States of ``piece`` that start at ``start`` instead of its own first state, the
    difference fading out over its first phase; the faded frames are polished so that soles
    and knees go straight from where ``start`` has them to where the piece does (blending the
    angles of two poses put the front toe 34 mm into the floor, male P95)."""
    fade = 1.0 - smoothstep(piece.time / max(float(piece.phases[0]["end"]), 1e-9))
    x = piece.x + fade[:, None] * (start - piece.x[0])[None]
    rows = np.flatnonzero((fade > 1e-9) & (fade < 1.0 - 1e-9))
    if rows.size:
        a = contact_points(piece.body, start[None])
        b = contact_points(piece.body, piece.x[rows])
        target = b + fade[rows, None, None] * (a - b)
        weight = np.full(target.shape[:2], PLANT_W)
        x[rows] = polish_frames(piece.body, x[rows], target, weight)
    return x


def _hold_kneel(
    seg: Segment, kneel: tuple[KneelPlan, tuple[FloatArray, float, float]], state: PoseState,
    ctx: PassContext,
) -> None:  # fmt: skip
    """The body kneels as the last kneel left it: legs, toes and root keyed where its plan
    ended, for the whole segment; the spine and arms are left to the reaches around it (kneel,
    pick, kneel, place: the author restates the posture, nothing steps)."""
    plan, frame = kneel
    held = (*LEG_DOFS, *TOE_VARS)
    cols = [plan.dofs.index(n) for n in held]
    last = plan.x[-1]
    root = to_world(last[None], *frame)[0]
    seg.keyframes = Keyframes(
        time=np.array([seg.start, seg.end]), dofs=held,
        q=np.tile(last[3:][cols], (2, 1)), root_position=np.stack([root, root]),
    )  # fmt: skip
    seg.result = {
        "root": "keyed",
        "root_height": float(last[1]),
        "phases": [{"name": "hold the kneel", "start": seg.start, "end": seg.end}],
        "steps": [],
        "rolls": [],
    }
    ctx.cache.setdefault(KNEEL_PLANS, {})[id(seg)] = kneel
    state.add(seg)


def _keyed(
    seg: Segment, plan: KneelPlan, t0: float, frame: tuple[FloatArray, float, float]
) -> None:
    """Write a plan's keyframes (on the interpolation grid, placed in the world by ``frame``:
    the starting root, heading and ground) and what it records (phases, steps, rolls)."""
    times, x = plan.on_grid(t0, INTERNAL_FPS)
    seg.keyframes = Keyframes(
        time=times, dofs=plan.dofs, q=x[:, 3:].copy(), root_position=to_world(x, *frame)
    )

    def shift(d: dict[str, Any]) -> dict[str, Any]:
        return {k: (v + t0 if isinstance(v, float) else v) for k, v in d.items()}

    seg.result = {
        "root": "keyed",
        "root_height": float(x[-1, 1]),
        "phases": [shift(p) for p in plan.phases],
        "steps": [shift(p) for p in plan.steps],
        "rolls": [shift(p) for p in plan.rolls],
    }


def _last_posture(ir: MotionIR, seg: Segment) -> Segment | None:
    """The last whole-body posture that ended by the time ``seg`` starts."""
    before = [s for s in ir.on_track("root") if s.kind == "posture" and s.end <= seg.start + 1e-9]
    return max(before, key=lambda s: s.end, default=None)


def _kneel_before(
    ir: MotionIR, seg: Segment, ctx: PassContext
) -> tuple[KneelPlan, tuple[FloatArray, float, float]] | None:
    """The plan of the kneel the body is in when ``seg`` starts (the last whole-body posture
    before it was a kneel), else None."""
    last = _last_posture(ir, seg)
    if last is None or last.goal.params.get("posture") != "kneel":
        return None
    found: tuple[KneelPlan, tuple[FloatArray, float, float]] | None
    found = ctx.cache.get(KNEEL_PLANS, {}).get(id(last))
    return found


def _stand_from_kneel(
    seg: Segment, kneel: tuple[KneelPlan, tuple[FloatArray, float, float]], state: PoseState,
    ctx: PassContext,
) -> None:  # fmt: skip
    """Rise by the kneel played backwards; first, for ``STAND_SETTLE``, trunk and arms go back
    to where the kneel left them (the reaches in between leaned, turned and moved them; the
    trunk's turn too, which the plan does not key: a trunk left turned by a reach swung the
    thigh into a hand the plan had clear): the arms to
    the comfort pose, or where that would pass through a thigh on the way up, beside the body
    (``clear_arms``)."""
    skel = state.skel
    plan, frame = kneel
    back = plan.reversed(seg.end - seg.start - STAND_SETTLE)
    _keyed(seg, back, seg.start + STAND_SETTLE, frame)
    kf = seg.keyframes
    assert kf is not None and kf.root_position is not None
    settled = (*ARM_DOFS, *TRUNK_TURN)
    arm_idx = [skel.dof_index(n) for n in settled]
    # the body as the kneel's plan had it (its balance was solved so), the arms in the comfort
    # pose; on the plan's own frames, where a thigh comes up through them, the arms hang
    # beside it instead (``clear_arms``)
    standing = plan.body.q_base.copy()
    standing[arm_idx[: len(ARM_DOFS)]] = np.asarray(skel.q_comfort)[arm_idx[: len(ARM_DOFS)]]
    frames = _plan_frames(plan, standing, np.concatenate([np.zeros((len(kf.q), 3)), kf.q], 1))
    for name, v in clear_arms(skel, frames, kf.root_position, ("r", "l"))[0].items():
        standing[skel.dof_index(name)] = v
    arms = standing[arm_idx]
    now = state.q_at(seg.start, skip=seg)
    first = np.concatenate([kf.q[0], now[arm_idx]])
    kf.q = np.concatenate([first[None], np.hstack([kf.q, np.tile(arms, (len(kf.time), 1))])])
    kf.time = np.concatenate([[seg.start], kf.time])
    kf.dofs = (*kf.dofs, *settled)
    kf.root_position = np.concatenate([kf.root_position[:1], kf.root_position])
    seg.result["arms_settled"] = [float(v) for v in arms]  # what the restater ramps to, each time
    state.add(seg)
    mark(ctx.cache, seg, "stand_from_kneel")  # its first keyframe: the pose the reaches left


def restate_stand_from_kneel(seg: Segment, state: PoseState) -> None:
    """A stand from a kneel starts from the pose the reaches left (its first keyframe), and its
    arms and trunk turn come back from there at a person's pace: over ``STAND_SETTLE``, or
    over the rise's first part when that is too short for them (``SETTLE_PACE``). Brought up
    100 deg in 0.3 s, a shoulder stepped 16-22 deg in one frame (issue 19)."""
    kf = seg.keyframes
    assert kf is not None
    # the kneel's plan sets the pace of the trunk and legs from the first key on
    _start_from(seg, state, state.q_at(seg.start, skip=seg), fade=False)
    cols = [kf.dofs.index(n) for n in (*ARM_DOFS, *TRUNK_TURN)]
    start, target = kf.q[0, cols].copy(), np.asarray(seg.result["arms_settled"], dtype=float)
    need = float(np.abs(target - start).max()) / SETTLE_PACE
    span = min(max(STAND_SETTLE, need), seg.end - seg.start)
    share = smoothstep(np.clip((kf.time - seg.start) / span, 0.0, 1.0))
    kf.q[:, cols] = start[None] + share[:, None] * (target - start)[None]


def wide_stand_arms(ir: MotionIR, seg: Segment, free: tuple[str, ...]) -> tuple[str, ...]:
    """``free`` and the arms that let go of their site before ``seg`` and do nothing during it:
    standing up from between the knees, an arm left where it worked goes into a rising thigh
    (the right forearm 10-12 mm on the drain valve, women P90-P99)."""
    held = holding(ir, seg.start)
    # an arm carrying its part through the stand keeps it (``hold.carried_postures``)
    held |= {t for t, segs in carried_postures(ir).items() if any(s is seg for s in segs)}
    out = list(free)
    for side in ("r", "l"):
        track, dof = f"{side}_arm", f"{side}_shoulder_flex"
        busy = any(s.start < seg.end - 1e-9 and s.end > seg.start + 1e-9
                   for s in ir.on_track(track))  # fmt: skip
        if dof not in out and track not in held and not busy:
            out.append(dof)
    return tuple(sorted(out, key=lambda d: d[0] != "r"))


def wide_stance(ir: MotionIR, seg: Segment) -> FloatArray | None:
    """The standing legs (``LEG_DOFS``) of a wide stance the body is in when ``seg`` starts: the
    last walk before it landed its feet apart and turned out (``mtlc.passes.stance``). None
    when the feet stand as the rest pose has them."""
    walks = [s for s in ir.on_track("root") if s.kind == "locomotion" and s.end <= seg.start + 1e-9]
    last = max(walks, key=lambda s: s.end, default=None)
    if last is None or WIDE_RESULT not in last.result or last.keyframes is None:
        return None
    kf = last.keyframes
    return np.array([kf.q[-1, kf.dofs.index(name)] for name in LEG_DOFS])


def _feet_in_root(legs: LegModel, q_legs: FloatArray) -> dict[str, tuple[FloatArray, float]]:
    """Each foot's ankle (root frame, root at the origin facing +Z) and heading, legs ``q_legs``
    in ``LEG_DOFS`` order."""
    out = {}
    for k, side in enumerate(("r", "l")):
        row = q_legs[None, 6 * k : 6 * k + 6]
        ankle, toe = leg_fk(legs, side, np.zeros((1, 3)), np.zeros(1), row)
        d = toe[0] - ankle[0]  # a level foot: its toe turned about +Y by the heading
        heading = math.atan2(float(d[0]), float(d[2])) - math.atan2(legs.toe[0], legs.toe[2])
        out[side] = ankle[0], heading
    return out


def legs_over_feet(legs: LegModel, stance: FloatArray, drop: FloatArray) -> FloatArray:
    """Legs (``LEG_DOFS``) that keep the feet of the standing legs ``stance`` where they are
    while the pelvis (upright, facing as before) moves by ``-drop`` (so the feet move by
    ``drop`` in its frame): the leg IK is exact, each leg's six dofs for its foot's six."""
    out = []
    for side, (ankle, heading) in _feet_in_root(legs, stance).items():
        out.append(leg_ik(legs, side, np.zeros((1, 3)), np.zeros(1), (ankle + drop)[None],
                          np.array([heading]))[0])  # fmt: skip
    return np.concatenate(out)


def _ankle_drop(legs: LegModel, q_legs: FloatArray, stance: FloatArray) -> FloatArray:
    """How far the right ankle of legs ``q_legs`` is from where the legs ``stance`` put it, in
    the root's frame."""
    return _feet_in_root(legs, q_legs)["r"][0] - _feet_in_root(legs, stance)["r"][0]


def _narrow_drop(skel: Any, legs: LegModel, s: float) -> FloatArray:
    """Where the ankle of the feet-together squat ``s`` (0 standing, 1 the deepest) is, seen
    from the pelvis, against the legs straight."""
    idx = [skel.dof_index(name) for name in LEG_DOFS]
    q = _squat_q(skel, np.zeros(len(skel.lower)), s)
    return _ankle_drop(legs, q[idx], np.zeros(len(idx)))


def stand_arms(f: float | FloatArray, squat: bool) -> Any:
    """How far (0-1) the free arms have gone to their end pose at fraction ``f`` of a posture
    over feet apart: with the body going down (a squat), or, standing up, only over the second
    half, once the knees have come up past the hands between them (let down at once, a forearm
    went 50-70 mm into the rising thigh)."""
    return f if squat else smoothstep(2.0 * np.asarray(f) - 1.0)


def wide_transition(
    skel: Any, cur: FloatArray, target: FloatArray, n: int, free: tuple[str, ...],
    stance: FloatArray, squat: bool,
) -> FloatArray:  # fmt: skip
    """``transition`` over feet set apart. The feet-together squat says how far the pelvis
    goes down and back on the way (its ankle seen from the pelvis: the ankles dorsiflex by half
    the depth, so the heels stay down); the wide stance's legs are solved to do the same over
    their own feet at every keyframe, so the feet stay planted; then each pose is leaned until
    it is balanced. A squat goes to the depth of ``target``, a stand back to the stance."""
    legs = leg_model(skel)
    idx = [skel.dof_index(name) for name in LEG_DOFS]
    if not squat:  # standing up, the free arms hang again as they do at rest
        abd = [skel.dof_index(f"{a[0]}_shoulder_abd") for a in free]
        target = target.copy()
        target[abd] = skel.q_comfort[abd]
    start = _ankle_drop(legs, cur[idx], stance)
    s0 = _bisect(lambda s: float(_narrow_drop(skel, legs, s)[1] - start[1]), 0.0, 1.0)
    s1 = float(target[skel.dof_index("r_hip_flex")]) / SQUAT_HIP_MAX if squat else 0.0
    rest = start - _narrow_drop(skel, legs, s0)  # what the start has beside the squat's path
    # legs apart already stand the pelvis lower (3.5 mm, male P50): a squat's depth is from
    # the legs straight, as with the feet together
    apart = _ankle_drop(legs, stance, np.zeros(len(idx))) * np.array([0.0, 1.0, 0.0])
    if not squat:
        apart[:] = 0.0
    arm_cols = [skel.dof_index(f"{a[0]}_shoulder_{d}") for a in free for d in ("flex", "abd")]
    poses = []
    for f in np.linspace(0.0, 1.0, n):
        q = cur + f * (target - cur)
        q[arm_cols] = cur[arm_cols] + stand_arms(f, squat) * (target - cur)[arm_cols]
        drop = _narrow_drop(skel, legs, s0 + f * (s1 - s0)) + (1.0 - f) * rest - f * apart
        q[idx] = legs_over_feet(legs, stance, drop)
        poses.append(q if f == 0.0 else clear_fingertips(skel, balanced_lean(skel, q), free))
    fracs = np.linspace(0.0, 1.0, n)
    share = fracs if squat else 4.0 * fracs * (1.0 - fracs)  # a stand ends where arms hang
    spare = WIDE_ARM_SPARE if squat else KNEEL_ARM_SPARE  # nothing follows a stand's arms
    sides = tuple(a[0] for a in free)
    return arms_between_knees(skel, np.stack(poses), sides, share, spare, between=squat)


def _inside_knee(skel: Any, q: FloatArray, side: str) -> bool:
    """Whether the ``side`` wrist of pose ``q`` is nearer the midline than its knee: the arm
    hangs between the knees, where a reach down in front of them starts without crossing a
    thigh (from outside the knee, the way to a site between them was over it)."""
    pose = forward(skel, q[None])
    wrist = pose.p[0, skel.joint_index(f"{side}_wrist"), 0]
    knee = pose.p[0, skel.joint_index(f"{side}_knee"), 0]
    return bool(abs(wrist) < abs(knee))


WIDE_ARM_TURNS = np.radians(np.arange(-40.0, 41.0, 5.0))  # shoulder abduction tried
WIDE_ARM_RAISES = np.radians([0.0, 15.0, 30.0, 45.0, 60.0])  # more shoulder flexion tried
# m beyond the clearance the chosen pose keeps: the reach that follows turns and bends the trunk
# (a hand 10 cm above the floor: 11° of turn), and the free arm goes with it
WIDE_ARM_SPARE = 0.03


def arms_between_knees(
    skel: Any, poses: FloatArray, sides: tuple[str, ...], share: FloatArray,
    spare: float = WIDE_ARM_SPARE, between: bool = True,
) -> FloatArray:  # fmt: skip
    """``poses`` with each free arm whose forearm or hand would come within the clearance of a
    thigh (the knees go out over the turned-out feet, where arms held forward hang) raised
    forward and moved in at the shoulder: the least change (raise plus turn, from
    ``WIDE_ARM_RAISES`` and ``WIDE_ARM_TURNS``) that keeps it ``spare`` beyond the
    clearance on every pose with the wrist between the knees (``_inside_knee``; unless not
    ``between``: a stand ends with the arms hanging at the sides), or the least deep;
    ``share`` (N,) how much of the change each pose takes (0 where it must stay)."""
    out = poses.copy()
    roots = (np.zeros((len(poses), 3)), np.tile([1.0, 0.0, 0.0, 0.0], (len(poses), 1)))
    tries = sorted(((float(r), float(t)) for r in WIDE_ARM_RAISES for t in WIDE_ARM_TURNS),
                   key=lambda rt: (abs(rt[0]) + abs(rt[1]), rt))  # fmt: skip
    for side in sides:
        if float(penetration(skel, out, roots, side).max()) <= -spare:
            continue
        flex, abd = (skel.dof_index(f"{side}_shoulder_{d}") for d in ("flex", "abd"))
        best: tuple[float, FloatArray] | None = None
        for raise_, turn in tries:
            q = out.copy()
            q[:, flex] = np.clip(q[:, flex] + share * raise_, skel.lower[flex], skel.upper[flex])
            q[:, abd] = np.clip(q[:, abd] + share * turn, skel.lower[abd], skel.upper[abd])
            depth = float(penetration(skel, q, roots, side).max())
            if depth <= -spare and (not between or _inside_knee(skel, q[-1], side)):
                best = (depth, q)
                break
            if best is None or depth < best[0]:
                best = (depth, q)
        assert best is not None
        out = best[1]
    return out


def _posture_segment(seg: Segment, state: PoseState, ctx: PassContext) -> None:
    skel, ir = state.skel, state.ir
    kind = seg.goal.params.get("posture", "stand")
    if kind == "kneel":
        _kneel_segment(seg, state, ctx)
        return
    if kind == "stand" and (kneel := _kneel_before(ir, seg, ctx)) is not None:
        _stand_from_kneel(seg, kneel, state, ctx)
        return
    cur = state.q_at(seg.start, skip=seg)
    flat = kind in ("stand", "squat")
    arms = free_arms(ir, seg) if flat else ()
    target = target_posture(skel, cur, seg.goal.params, arms)
    moved_arms = standing_arm_dofs(arms) if kind == "stand" else arms
    dofs = (
        TRUNK_DOFS if kind == "bend" else (TRUNK_DOFS + LEG_DOFS + moved_arms if flat else LEG_DOFS)
    )
    idx = [skel.dof_index(n) for n in dofs]
    stance = wide_stance(ir, seg) if flat else None
    if stance is not None and kind == "stand":
        arms = wide_stand_arms(ir, seg, arms)
        target = target_posture(skel, cur, seg.goal.params, arms)
        # over feet apart the arms' flexion and abduction come down between the knees
        # (``restate_wide_stand``); the rest of each arm stays as the reach left it
        kept = [skel.dof_index(n) for n in standing_arm_dofs(arms) if n[2:] != "shoulder_flex"]
        target[kept] = cur[kept]
        dofs = TRUNK_DOFS + LEG_DOFS + arms
    from_kneel = kind != "bend" and _kneel_before(ir, seg, ctx) is not None
    # from a kneel the root is keyed (below): a key a frame's worth keeps the feet on the floor
    keys = (WIDE_KEYS if from_kneel else TRANSITION_KEYS) if flat else 2
    times = np.linspace(seg.start, seg.end, keys)
    late = standing_arm_dofs(released_arms(ir, seg)) if kind == "stand" else ()
    if stance is not None:  # the feet stand apart: the legs fold over them
        times = np.linspace(seg.start, seg.end, WIDE_KEYS)
        poses = wide_transition(skel, cur, target, len(times), arms, stance, kind == "squat")
        dofs = (*dofs, *(f"{a[0]}_shoulder_abd" for a in arms))
        idx = [skel.dof_index(n) for n in dofs]
        late = ()
    elif flat:
        poses = transition(skel, cur, target, len(times), arms, late)
    else:
        poses = np.stack([cur, target])
    kf = Keyframes(time=times, dofs=dofs, q=poses[:, idx])
    if kind != "bend":
        p0, _ = state.root_at(seg.start, skip=seg)
        p1, rot1 = state.root_at(seg.end, skip=seg)
        if from_kneel:  # where the posture's own pose stands on the plan's feet
            plan_at, _ = ir.root_plan.at(seg.end)
            p1 = anchored_root(skel, poses[-1][None], np.asarray(plan_at, float)[None],
                               rot1[None], ir.ground)[0]  # fmt: skip
        rows = [p0 + f * (p1 - p0) for f in np.linspace(0.0, 1.0, len(times))]
        for row, pose in zip(rows[1:], poses[1:], strict=True):
            row[1] = root_height(skel, pose, ir.ground)
        kf.root_position = np.stack(rows)
        seg.result = {"root_height": float(rows[-1][1] - ir.ground)}
        if from_kneel:
            # from a kneel the pelvis goes from where the kneel's plan left it to where the
            # posture stands on the plan's feet, over the posture: the feet under it, anchored
            # from the first frame, moved it there in one (25 cm at a squat's start, issue 19)
            seg.result["root"] = "keyed"
    seg.keyframes = kf
    state.add(seg)
    if stance is not None and kind == "stand":
        mark(ctx.cache, seg, "wide_stand")
    elif late:
        seg.result["arms_let_down"] = list(late)
        mark(ctx.cache, seg, "stand_arms")
    else:
        mark(ctx.cache, seg)


def restate_stand_arms(seg: Segment, state: PoseState) -> None:
    """A stand that lets released arms down: its first keyframe from the pose before it (as any
    posture's) and the arms' ramps (``late_share``) from where the reach left them, which the
    posture pass, solved before the reaches, could not know."""
    kf = seg.keyframes
    assert kf is not None
    _start_from(seg, state, state.q_at(seg.start, skip=seg))
    cols = [kf.dofs.index(n) for n in seg.result["arms_let_down"]]
    share = late_share((kf.time - seg.start) / max(seg.end - seg.start, 1e-9))
    start, target = kf.q[0, cols], kf.q[-1, cols]
    kf.q[:, cols] = start[None] + share[:, None] * (target - start)[None]


def _start_from(seg: Segment, state: PoseState, q0: FloatArray, fade: bool = True) -> None:
    """A posture's first keyframe at ``q0``, the pose before it, and its root at the height
    the body has then: what the default restater (``state.reanchor``) does for any posture
    (``fade``: what ``q0`` has that the keys did not see is let go over the whole posture,
    ``state.start_posture_from``; else the first key alone changes)."""
    kf = seg.keyframes
    assert kf is not None
    first = q0[[state.skel.dof_index(n) for n in kf.dofs]]
    if fade:
        start_posture_from(seg, first, state.standing_before(seg))
    else:
        kf.q[0] = first
    if kf.root_position is not None:
        kf.root_position[0, 1] = state.height_at(seg.start, skip=seg)


WIDE_STAND_SETTLE = 0.5  # share of a stand over feet apart that brings the trunk to its own


def restate_wide_stand(seg: Segment, state: PoseState) -> None:
    """A stand over feet apart starts from the pose the reaches left (the first keyframe), and
    its arms go from there, not from where the posture pass saw them before the reaches: a
    hand that let go of a site between the knees (two hands on a cap) was keyed from the free
    arms' pose of the squat and swung 43° in one frame, through a thigh. Then between the
    knees again (``arms_between_knees``).

    The trunk the reaches left (turned and leaned toward the site) goes to the stand's own over
    the first ``WIDE_STAND_SETTLE`` of it, as a kneel's spine does (``restate_kneel``):
    restated at the first keyframe only, it turned back 12° in the first 29 ms of the stand
    (the drain valve), and smoothing that jump with the hand still pinned swung the arm into
    the rising thigh."""
    kf = seg.keyframes
    assert kf is not None
    skel = state.skel
    q0 = state.q_at(seg.start, skip=seg)
    idx = [skel.dof_index(n) for n in kf.dofs]
    trunk = [k for k, n in enumerate(kf.dofs) if n in TRUNK_DOFS]
    if trunk:
        dofs = [idx[k] for k in trunk]
        span = max(WIDE_STAND_SETTLE * (seg.end - seg.start), 1e-9)
        fade = 1.0 - smoothstep((kf.time - seg.start) / span)
        shifted = kf.q[:, trunk] + fade[:, None] * (q0[dofs] - kf.q[0, trunk])[None]
        kf.q[:, trunk] = np.clip(shifted, skel.lower[dofs], skel.upper[dofs])
    _start_from(seg, state, q0)
    arms = [k for k, n in enumerate(kf.dofs) if n[2:] in ("shoulder_flex", "shoulder_abd")]
    if not arms:
        return
    f = np.linspace(0.0, 1.0, len(kf.time))
    poses = np.repeat(q0[None], len(f), axis=0)
    poses[:, idx] = kf.q
    cols = [idx[k] for k in arms]
    blend = stand_arms(f, False)[:, None]
    poses[:, cols] = q0[cols][None] + blend * (kf.q[-1, arms] - q0[cols])[None]
    sides = tuple(sorted({kf.dofs[k][0] for k in arms}, key=lambda side: side != "r"))
    poses = arms_between_knees(skel, poses, sides, 4.0 * f * (1.0 - f), KNEEL_ARM_SPARE, False)
    kf.q[:, arms] = poses[:, cols]


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


def restate_kneel(seg: Segment, state: PoseState) -> None:
    """A kneel's arm ramps (``restate_kneel_arms``), and its spine starting where the body
    really is and going to the plan's over the first phase, before a knee moves (within the
    limits): the plan starts from the pose the posture pass saw, and the passes after it move
    the trunk before the kneel. A kneel from another kneel: a trunk leaning to a part on the
    floor stood up in one frame and tore the held hand off it (1.2 m); a kneel after a walk
    that carried a picked part with the trunk bent: the lumbar went 14.7 -> 0 deg in one
    frame (issue 19, the rack module's spare). The plan's own trunk keeps the swing balanced
    as the phase ends."""
    restate_kneel_arms(seg, state)
    kf = seg.keyframes
    assert kf is not None
    skel = state.skel
    cols = [kf.dofs.index(n) for n in SPINE_VARS]
    dofs = [skel.dof_index(n) for n in SPINE_VARS]
    q = state.q_at(seg.start, skip=seg)
    settled = float(seg.result["phases"][0]["end"])
    fade = 1.0 - smoothstep((kf.time - seg.start) / max(settled - seg.start, 1e-9))
    shifted = kf.q[:, cols] + fade[:, None] * (q[dofs] - kf.q[0, cols])[None]
    kf.q[:, cols] = np.clip(shifted, skel.lower[dofs], skel.upper[dofs])


# rad: a trunk leaned further than this (flexion, side bend or turn, lumbar and thorax summed)
# keeps an idle arm where it is: let down beside a trunk a reach left bent and turned, the
# forearm went into the thigh (16 mm, the tutorial's lamp)
REST_TRUNK_LEAN = math.radians(20.0)


def restate_rest(seg: Segment, state: PoseState) -> None:
    """An idle arm's way down (``passes.rest``) from where the arm really is when it starts
    (the release's pose, known only once the reaches and contacts are solved) to the rest pose;
    no way down, the arm kept, where the trunk is leaned (``REST_TRUNK_LEAN``)."""
    kf = seg.keyframes
    assert kf is not None
    skel = state.skel
    q = state.q_at(seg.start, skip=seg)
    idx = [skel.dof_index(n) for n in kf.dofs]
    start, rest = q[idx], np.asarray(skel.q_comfort, dtype=float)[idx]
    lean = max(
        abs(sum(float(q[skel.dof_index(f"{j}_{axis}")]) for j in ("lumbar", "thorax")))
        for axis in ("flex", "lat", "rot")
    )
    share = minimum_jerk((kf.time - seg.start) / max(seg.end - seg.start, 1e-9))
    if lean > REST_TRUNK_LEAN:
        share = np.zeros_like(share)
    kf.q = start[None] + share[:, None] * (rest - start)[None]


RESTATERS = {
    "rest": restate_rest,
    "twist": restate_twist,
    "kneel": restate_kneel,
    "stand_arms": restate_stand_arms,
    "stand_from_kneel": restate_stand_from_kneel,
    "wide_stand": restate_wide_stand,
}


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
