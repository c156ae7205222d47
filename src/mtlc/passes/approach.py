"""Pass 2, TA (target approaching, seeds 000 and 001): bring each hand to its approach point.

For every TA segment, in time order, the body is taken as it is at the segment's start (the
joints from the keyframes so far, ``state.PoseState``) and the root where the plan puts it at
the segment's end (the hand arrives where the body then stands). The approach point is the site
moved out along its normal by the goal's ``approach`` distance, or, for a site without a normal,
that far short of the site on the line from the shoulder, so the TO phase comes in straight.

Seed 001's Jacobian IK (``solve_ta``: damped least squares with limits and restarts) moves the
arm chain (shoulder, elbow, wrist) first; if that leaves the hand more than the tolerance short,
it retries with the torso (lumbar, thorax, clavicle) and keeps the better pose. TA segments that
share a time window on both arms form one group: if the torso is needed they are solved together
so both hands agree on one trunk. A two-handed goal grips its site with the hands
``TWO_HAND_SPREAD`` apart across the body (the segment's goal position says where each hand
goes). When the best pose is still short the pass reports MT0501 at the task line that asked
for the goal and keeps the best pose.

Keyframes: the pose at the segment's start (held until then) and the solution at its end.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from mtlc.body.ik import ChainModel, Goal, default_dofs, prepare, solve_ta
from mtlc.ir.model import FloatArray, Keyframes, MotionIR, Segment
from mtlc.passes.context import PassContext
from mtlc.passes.state import PoseState, cached, mark, reanchor

TOLERANCE = 1e-3  # m, the solvers' position tolerance; further than this is "short"
TWO_HAND_SPREAD = 0.20  # m between the hands on a two-handed site, across the body
ARM_TRACKS = ("l_arm", "r_arm")
HAND_NAMES = {"r_hand": "right hand", "l_hand": "left hand"}
FINGERTIPS = {"r_hand": "r_fingertip", "l_hand": "l_fingertip"}
GROUND_SLACK = 5e-4  # m a hand point may dip below the ground (half the 1 mm budget)
FLAT_CLEARANCE = 0.02  # m: a site this close to fingers pointing down at the floor is "low"
FLAT_NORMAL_UP = 0.5  # a low site is come down on (its normal this far up, or none)
LIFTS = 3  # re-solves that raise an approach point whose pose puts the fingers in the floor


def model_for(
    ctx: PassContext,
    skel: Any,
    effectors: tuple[str, ...],
    reach: str,
    q: FloatArray,
    root: tuple[FloatArray, FloatArray],
) -> ChainModel:
    """A prepared chain model, reused while the frozen body and root are the same."""
    active = set(default_dofs(skel, list(effectors), reach))
    # only the dofs between the root and the effectors shape the frozen base
    base = sorted({d for e in effectors for d in skel.chain_dofs(e)} - active)
    key = (effectors, reach, root[0].tobytes(), root[1].tobytes(), q[base].round(12).tobytes())
    return cached(
        ctx.cache,
        key,
        lambda: prepare(
            skel, list(effectors), q, reach=reach, root_position=root[0], root_rotation=root[1]
        ),
    )


def site_position(ir: MotionIR, name: str | None) -> FloatArray | None:
    for s in ir.sites:
        if s["name"] == name:
            return np.asarray(s["position"], dtype=float)
    return None


def hand_target(ir: MotionIR, seg: Segment, heading_rot: FloatArray) -> FloatArray:
    """Where this hand grips: the site, or beside it for a two-handed goal."""
    goal = seg.goal
    base = site_position(ir, goal.site)
    if base is None:
        base = np.asarray(goal.position, dtype=float)
    if not goal.params.get("two_handed"):
        return base
    w, _, y, _ = heading_rot
    left = np.array([1.0 - 2.0 * y * y, 0.0, -2.0 * w * y])  # the body's +X, turned by heading
    n = goal.params.get("normal")
    if n is not None:
        nv = np.asarray(n, dtype=float) / np.linalg.norm(n)
        left = left - nv * float(left @ nv)
        if np.linalg.norm(left) < 1e-6:  # normal along the body's side: spread along +Z
            left = np.cross(nv, [0.0, 1.0, 0.0])
        left = left / np.linalg.norm(left)
    side = 1.0 if goal.effector.startswith("l") else -1.0
    return base + side * 0.5 * TWO_HAND_SPREAD * left


def approach_point(
    state: PoseState, seg: Segment, target: FloatArray, q: FloatArray, root: Any
) -> FloatArray:
    goal = seg.goal
    dist = float(goal.approach or 0.0)
    if dist <= 0.0:
        return target
    normal = goal.params.get("approach_normal") or goal.params.get("normal")
    if normal is not None:
        n = np.asarray(normal, dtype=float)
        return target + dist * n / np.linalg.norm(n)
    side = "r" if goal.effector.startswith("r") else "l"
    shoulder = state.site(f"joint:{side}_shoulder", q, root)
    d = target - shoulder
    norm = float(np.linalg.norm(d))
    return target if norm < 1e-9 else target - dist * d / norm


def effector_name(effector: str) -> str:
    """How a message names an effector: "right hand", or "wrench_10mm in the right hand" for
    a tool's working point (``r_tool_wrench_10mm``, docs/tools.md)."""
    side, _, rest = effector.partition("_")
    hand = HAND_NAMES.get(f"{side}_hand", effector)
    if rest.startswith("tool_"):
        return f"{rest[5:]} in the {hand}"
    return HAND_NAMES.get(effector, effector)


def report_short(ctx: PassContext, seg: Segment, short: float) -> None:
    """MT0501 once per goal (TA and TO of one goal share their origin)."""
    done: set[Any] = ctx.cache.setdefault("passes.unreachable", set())
    key = (seg.provenance.origin, seg.goal.site, seg.track)
    if key in done:
        return
    done.add(key)
    ctx.report(
        "MT0501",
        f"the {effector_name(seg.goal.effector)} cannot reach site `{seg.goal.site}`: "
        f"{short * 1000:.0f} mm short",
        seg.provenance.origin,
    )


def hand_distance(state: PoseState, effector: str, q: FloatArray, root: Any, p: Any) -> float:
    return float(np.linalg.norm(state.site(effector, q, root) - p))


def pinned_hands(
    state: PoseState, segs: list[Segment], q0: FloatArray, root: tuple[FloatArray, FloatArray]
) -> list[Goal]:
    """Goals that keep the other hand where it is, when it rests on a site at the segments'
    start (``balance.hand_pins``): a reach that bends the trunk must not pull it off."""
    from mtlc.passes.balance import hand_pins, pin_windows

    t0 = segs[0].start
    mine = {f"{s.goal.effector[0]}_hand" for s in segs}  # a tool's tip moves its hand too
    # the windows once per pass (a pass adds no arm segment), not once per reach
    key = ("pin_windows", len(state.ir.segments))
    if key not in state.memo:
        state.memo[key] = pin_windows(state.ir)
    pins = hand_pins(state.ir, np.array([t0]), state.memo[key])
    return [
        Goal(hand, position=state.site(hand, q0, root))
        for hand, pinned in pins.items()
        if hand not in mine and bool(pinned[0])
    ]


def with_pinned(
    skel: Any, names: tuple[str, ...], pinned: list[Goal], reach: str
) -> tuple[str, ...]:
    """A torso reach's keyframe dofs plus the arms of the hands it keeps on their sites."""
    if reach != "torso" or not pinned:
        return names
    extra = chain_names(skel, [g.effector for g in pinned], "arm")
    return names + tuple(n for n in extra if n not in names)


def repin(
    ctx: PassContext,
    skel: Any,
    q: FloatArray,
    pinned: list[Goal],
    root: tuple[FloatArray, FloatArray],
) -> FloatArray:
    """Poses ``q`` (B, D) with each pinned hand's arm re-solved onto where the hand rests.

    A reach that bends the trunk carries the other arm along; that arm alone (shoulder, elbow,
    wrist: dofs the reaching hand and the trunk do not use) then puts its hand back, so the
    reaching hand's pose is not traded against it.
    """
    out = np.array(q, dtype=float, copy=True)
    for goal in pinned:
        batch = Goal(goal.effector, position=np.tile(goal.position, (len(out), 1)))
        m = prepare(
            skel, [goal.effector], out, reach="arm",
            root_position=np.tile(root[0], (len(out), 1)),
            root_rotation=np.tile(root[1], (len(out), 1)),
        )  # fmt: skip
        out = solve_ta(skel, [batch], out, model=m, restarts=0, null_gain=0.0, tol=2e-4).q
    return out


def seg_goals(skel: Any, seg: Segment, target: FloatArray) -> list[Goal]:
    """The segment's goal at ``target``, then any goals that align its tool with the fastener
    (a screwdriver's axis on the screw's, ``tool.axis_goals``)."""
    from mtlc.passes.tool import axis_goals

    goal = Goal(seg.goal.effector, position=target, orientation=seg.goal.orientation)
    return [goal, *axis_goals(skel, seg, target)]


def flat_hand(
    state: PoseState, seg: Segment, root: tuple[FloatArray, FloatArray]
) -> FloatArray | None:
    """The fingertip's offset from the hand (horizontal, away from the pelvis, the fingers'
    length) that lays the hand flat when it comes down on a site so low that fingers pointing
    down would reach the floor; None for any other site.

    The TA goal is a position only, so the hand arrives at the approach point in whatever
    orientation the solver found. Above a tray 5 cm up, fingers pointing down are already at
    the floor, and the last few centimetres (TO) are then cut off by it: the reach is reported
    short, and whether it is depends on the solver's path. Laying the hand flat at the
    approach point (a fingertip goal, ``seg_goals``) leaves TO a straight descent.
    """
    effector = seg.goal.effector
    site = seg.goal.position
    if effector not in FINGERTIPS or site is None:
        return None
    normal = seg.goal.params.get("approach_normal") or seg.goal.params.get("normal")
    if normal is not None and normal[1] < FLAT_NORMAL_UP * float(np.linalg.norm(normal)):
        return None
    skel = state.skel
    fingers = float(
        np.linalg.norm(
            np.subtract(skel.site(FINGERTIPS[effector]).offset, skel.site(effector).offset)
        )
    )
    if float(site[1]) - state.ir.ground > fingers + FLAT_CLEARANCE:
        return None
    away = np.asarray(site, dtype=float) - root[0]
    away[1] = 0.0
    norm = float(np.linalg.norm(away))
    return None if norm < 1e-6 else away * (fingers / norm)


def solve_group(
    ctx: PassContext,
    state: PoseState,
    segs: list[Segment],
    targets: list[FloatArray],
    q0: FloatArray,
    root: tuple[FloatArray, FloatArray],
    pinned: list[Goal] | None = None,
    flat: list[FloatArray | None] | None = None,
) -> tuple[FloatArray, str, list[float]]:
    """Best pose for one or two hands: arm chains first, then (together) with the torso; a
    torso pose puts the ``pinned`` hands back on their sites (``repin``). ``flat``: per
    segment, the fingers' offset from the hand that lays it flat (``flat_hand``), or None; a
    pose that lays the hands flat is kept only if it reaches as well as one that does not."""
    if flat is not None and any(f is not None for f in flat):
        laid = _solve_group(ctx, state, segs, targets, q0, root, pinned, flat)
        if max(laid[2]) <= TOLERANCE:
            return laid
        plain = _solve_group(ctx, state, segs, targets, q0, root, pinned, None)
        return laid if max(laid[2]) <= max(plain[2]) else plain
    return _solve_group(ctx, state, segs, targets, q0, root, pinned, None)


def _solve_group(
    ctx: PassContext,
    state: PoseState,
    segs: list[Segment],
    targets: list[FloatArray],
    q0: FloatArray,
    root: tuple[FloatArray, FloatArray],
    pinned: list[Goal] | None,
    flat: list[FloatArray | None] | None,
) -> tuple[FloatArray, str, list[float]]:
    skel = state.skel

    def goals_of(k: int, seg: Segment, p: FloatArray) -> list[Goal]:
        goals = seg_goals(skel, seg, p)
        if flat is not None and flat[k] is not None:
            goals.append(Goal(FINGERTIPS[seg.goal.effector], position=p + flat[k]))
        return goals

    q = q0.copy()
    for k, (seg, p) in enumerate(zip(segs, targets, strict=True)):
        arm_goals = goals_of(k, seg, p)
        m = model_for(ctx, skel, tuple(g.effector for g in arm_goals), "arm", q, root)
        q = solve_ta(skel, arm_goals, q, model=m).q[0]
    dist = [
        hand_distance(state, s.goal.effector, q, root, p)
        for s, p in zip(segs, targets, strict=True)
    ]
    if max(dist) <= TOLERANCE:
        return q, "arm", dist
    goals = [
        g for k, (s, p) in enumerate(zip(segs, targets, strict=True)) for g in goals_of(k, s, p)
    ]
    effs = tuple(g.effector for g in goals)
    m = model_for(ctx, skel, effs, "torso", q0, root)
    qt = solve_ta(skel, goals, q0, model=m).q[0]
    if pinned:
        qt = repin(ctx, skel, qt[None], pinned, root)[0]
    dt = [
        hand_distance(state, s.goal.effector, qt, root, p)
        for s, p in zip(segs, targets, strict=True)
    ]
    if max(dt) < max(dist):
        return qt, "torso", dt
    return q, "arm", dist


def lowest_hand_point(
    state: PoseState, segs: list[Segment], q: FloatArray, root: tuple[FloatArray, FloatArray]
) -> float:
    """Height of the lowest hand or fingertip of the segments' effectors in pose ``q``."""
    names = [n for s in segs for n in (s.goal.effector, FINGERTIPS.get(s.goal.effector, ""))]
    return min(float(state.site(n, q, root)[1]) for n in names if n)


def chain_names(skel: Any, effectors: list[str], reach: str) -> tuple[str, ...]:
    return tuple(skel.dof_names[d] for d in default_dofs(skel, effectors, reach))


def groups(ir: MotionIR, kind: str) -> list[list[Segment]]:
    """Segments of ``kind`` on the arms, grouped by shared time window, in time order (a
    wrench's strokes are the tool pass's)."""
    by: dict[tuple[float, float], list[Segment]] = {}
    for s in ir.segments:
        if s.kind == kind and s.track in ARM_TRACKS and "stroke" not in s.goal.params:
            by.setdefault((round(s.start, 9), round(s.end, 9)), []).append(s)
    return [sorted(v, key=lambda s: s.track) for _, v in sorted(by.items())]


def solve(ir: MotionIR, ctx: PassContext) -> MotionIR:
    state = PoseState(ir)
    skel = ir.skeleton
    for segs in groups(ir, "TA"):
        t0, t1 = segs[0].start, segs[0].end
        q0 = state.q_at(t0)
        root = state.root_at(t1)
        targets = []
        for seg in segs:
            seg.goal.position = hand_target(ir, seg, root[1])
            targets.append(approach_point(state, seg, seg.goal.position, q0, root))
        pinned = pinned_hands(state, segs, q0, root)
        flat = [flat_hand(state, seg, root) for seg in segs]
        q1, reach, dist = solve_group(ctx, state, segs, targets, q0, root, pinned, flat)
        for _ in range(LIFTS):
            sink = ir.ground - GROUND_SLACK - lowest_hand_point(state, segs, q1, root)
            if sink <= 0.0:
                break
            # the hand arrives fingers first: raise its approach point by what they sink
            targets = [p + np.array([0.0, sink + GROUND_SLACK, 0.0]) for p in targets]
            q1, reach, dist = solve_group(ctx, state, segs, targets, q0, root, pinned, flat)
        # the joint-space path from q0 to q1 may sweep the hand through the floor: lift it
        mid = None
        fs = np.linspace(0.0, 1.0, 9)[1:-1]
        lows = [lowest_hand_point(state, segs, q0 + f * (q1 - q0), root) for f in fs]
        sink = ir.ground + 0.02 - min(lows)
        if sink > 0.0:
            here = [state.site(s.goal.effector, q0, root) for s in segs]
            mids = [
                0.5 * (a + b) + np.array([0.0, sink, 0.0])
                for a, b in zip(here, targets, strict=True)
            ]
            mid, _, _ = solve_group(ctx, state, segs, mids, 0.5 * (q0 + q1), root, pinned)
        for k, (seg, p, d) in enumerate(zip(segs, targets, dist, strict=True)):
            names = chain_names(skel, [seg.goal.effector], reach)
            if k == 0:  # one segment of the group carries the pinned arms
                names = with_pinned(skel, names, pinned, reach)
            idx = [skel.dof_index(n) for n in names]
            if mid is None:
                seg.keyframes = Keyframes(
                    time=np.array([t0, t1]), dofs=names, q=np.stack([q0[idx], q1[idx]])
                )
            else:
                seg.keyframes = Keyframes(
                    time=np.array([t0, 0.5 * (t0 + t1), t1]),
                    dofs=names,
                    q=np.stack([q0[idx], mid[idx], q1[idx]]),
                )
            ok = d <= TOLERANCE
            seg.result = {
                "distance": d,
                "success": bool(ok and skel.within_limits(q1)),
                "reach": reach,
                "approach_point": [float(v) for v in p],
            }
            if not ok:
                report_short(ctx, seg, d)
            state.add(seg)
            mark(ctx.cache, seg)
    reanchor(ir, ctx.cache, _restaters())
    return ir


def _restaters() -> dict[str, Any]:
    from mtlc.passes.posture import RESTATERS

    return RESTATERS
