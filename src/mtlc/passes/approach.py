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

import itertools
from typing import Any

import numpy as np

from mtlc.body import forward, part_site_positions, site_positions
from mtlc.body.capsules import limbs_of_sides, self_intersection
from mtlc.body.ik import ChainModel, Goal, default_dofs, prepare, solve_ta
from mtlc.body.ik.clearance import keep_clear
from mtlc.ir.model import FloatArray, Keyframes, MotionIR, Segment
from mtlc.passes.context import PassContext
from mtlc.passes.state import PoseState, cached, mark, reanchor, solved

TOLERANCE = 1e-3  # m, the solvers' position tolerance; further than this is "short"
TWO_HAND_SPREAD = 0.20  # m between the hands on a two-handed site, across the body
ARM_TRACKS = ("l_arm", "r_arm")
HAND_NAMES = {"r_hand": "right hand", "l_hand": "left hand"}
FINGERTIPS = {"r_hand": "r_fingertip", "l_hand": "l_fingertip"}
GROUND_SLACK = 5e-4  # m a hand point may dip below the ground (half the 1 mm budget)
FLAT_CLEARANCE = 0.02  # m: a site this close to fingers pointing down at the floor is "low"
FLAT_NORMAL_UP = 0.5  # a low site is come down on (its normal this far up, or none)
SWEEP_CLEARANCE = 0.02  # m: an approach path whose hands come this near the floor is lifted
LIFTS = 3  # re-solves that raise an approach point whose pose puts the fingers in the floor
KEEP_GOAL = 30.0  # weight of the hand's pose against the body's volume (ik.clearance): kept
KEEP_PATH = 0.3  # ...on the way there: the hand may move out of the body's way
PATH_SAMPLES = 9  # poses checked on each stretch between two keyframes, ends included
CLEAR_KEYS = 1  # keyframes added at most to keep an approach's arms out of the body
CLEAR_GAIN = 0.005  # m a cleared keyframe must take off the path's depth to be kept


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
    """Goals that keep the other hand where it is, when it holds a site at the segments'
    start (``hold.holding``: from its contact until its next arm motion, a walk, or a release
    it does not take back): a reach that bends the trunk must not pull it off."""
    from mtlc.passes.hold import ARM_HAND, holding

    t0 = segs[0].start
    mine = {f"{s.goal.effector[0]}_hand" for s in segs}  # a tool's tip moves its hand too
    held = holding(state.ir, t0, state.memo)
    return [
        Goal(hand, position=state.site(hand, q0, root))
        for track, hand in ARM_HAND.items()
        if hand not in mine and track in held
    ]


def held_sites(
    state: PoseState, segs: list[Segment], pinned: list[Goal], root: tuple[FloatArray, FloatArray]
) -> list[Goal]:
    """``pinned`` with each hand at its contact's site (where the hold pass keeps it on the
    frames), for the solves that look for a pose when the first ones leave a reach short.

    The approaches are solved before the contacts, so at the start of the other hand's reach
    the keyframes leave a held hand at its approach point (8 cm off its handle): a trunk found
    around that point left the hold pass an arm that could not reach the handle (132 mm off
    on the frames, MT0511, tests/data/lean/l04 female P5). The first solves keep the point
    where the hand is (what main did, so what already reached is unchanged)."""
    from mtlc.passes.hold import ARM_HAND, hold_spans

    t0 = segs[0].start
    key = ("hold_spans", len(state.ir.segments))
    spans = state.memo.get(key)
    if spans is None:
        spans = state.memo[key] = hold_spans(state.ir)
    site: dict[str, FloatArray] = {}
    for seg, end in spans:
        hand = ARM_HAND[seg.track]
        if not seg.start - 1e-9 <= t0 < end - 1e-9 or seg.goal.effector != hand:
            continue
        short = float(seg.result.get("distance", 0.0)) > TOLERANCE
        if seg.goal.orientation is not None or short:
            continue  # a contact solved short holds where it stopped
        site[hand] = hand_target(state.ir, seg, root[1])
    return [Goal(g.effector, position=site.get(g.effector, g.position)) for g in pinned]


def pins_off(
    state: PoseState, pinned: list[Goal], q: FloatArray, root: tuple[FloatArray, FloatArray]
) -> float:
    """How far (m) the pinned hands are from where they rest, the worst over poses ``q``
    (K, D): a trunk pose that leaves one off its site is a hold let go."""
    if not pinned or not len(q):
        return 0.0
    k = len(q)
    pose = forward(
        state.skel, q, np.broadcast_to(root[0], (k, 3)), np.broadcast_to(root[1], (k, 4)),
        with_axes=False,
    )  # fmt: skip
    worst = 0.0
    for goal in pinned:
        at = np.asarray(site_positions(state.skel, pose, goal.effector))
        worst = max(worst, float(np.linalg.norm(at - np.asarray(goal.position), axis=-1).max()))
    return worst


def goals_off(
    state: PoseState, goals: list[Goal], q: FloatArray, root: tuple[FloatArray, FloatArray]
) -> float:
    """How far (m) the farthest of the position ``goals`` is from its effector in pose ``q``."""
    return max(
        (hand_distance(state, g.effector, q, root, g.position) for g in goals
         if g.position is not None),
        default=0.0,
    )  # fmt: skip


def held_pose(
    ctx: PassContext,
    state: PoseState,
    goals: list[Goal],
    q0: FloatArray,
    root: tuple[FloatArray, FloatArray],
    seeds: list[FloatArray],
) -> FloatArray:
    """The least trunk lean meeting every goal (the reaching hands' and the held ones'), from
    ``q0``, the upright trunk, ``seeds`` and random starts (``mtlc.body.ik.lean``), then the
    held hands put back on their sites by their arms alone; once per compile for one question.

    ``solve_ta``'s pull to upright fades as the error goes to 0, so its descent from the body
    as it is stopped at a deep lean where both hands could not be met: the reach was reported
    unreachable (MT0501) though poses that meet both goals exist."""
    from mtlc.body.ik.lean import solve_held

    if any(g.position is None or g.orientation is not None or g.aim is not None for g in goals):
        return seeds[0] if seeds else q0  # (a position solve only: a tool's axis is not one)
    store: dict[Any, FloatArray] = ctx.cache.setdefault("passes.approach.held", {})
    key = (
        tuple((g.effector, np.asarray(g.position, dtype=float).tobytes()) for g in goals),
        q0.tobytes(), root[0].tobytes(), root[1].tobytes(),
        tuple(np.asarray(s).tobytes() for s in seeds),
    )  # fmt: skip
    if key not in store:
        res = solve_held(
            state.skel, goals, q0, root_position=root[0], root_rotation=root[1], seeds=seeds
        )
        store[key] = res.q[0]
    return store[key].copy()


def with_pinned(
    skel: Any, names: tuple[str, ...], pinned: list[Goal], reach: str
) -> tuple[str, ...]:
    """A torso reach's keyframe dofs plus the arms of the hands it keeps on their sites."""
    if reach != "torso" or not pinned:
        return names
    # the clavicle too: a solve that moves the trunk around a held hand may move it
    extra = chain_names(skel, [g.effector for g in pinned], "torso")
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
) -> tuple[FloatArray, str, list[float], bool]:
    """Best pose for one or two hands: arm chains first, then (together) with the torso; a
    torso pose puts the ``pinned`` hands back on their sites (``repin``). ``flat``: per
    segment, the fingers' offset from the hand that lays it flat (``flat_hand``), or None; a
    pose that lays the hands flat is kept only if it reaches as well as one that does not.
    Returns the pose, its reach, the hands' distances and whether the pose is the flat one."""
    if flat is not None and any(f is not None for f in flat):
        laid = _solve_group(ctx, state, segs, targets, q0, root, pinned, flat)
        if max(laid[2]) <= TOLERANCE:
            return (*laid, True)
        plain = _solve_group(ctx, state, segs, targets, q0, root, pinned, None)
        return (*laid, True) if max(laid[2]) <= max(plain[2]) else (*plain, False)
    return (*_solve_group(ctx, state, segs, targets, q0, root, pinned, None), False)


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
        q = solved(ctx.cache, solve_ta, skel, arm_goals, q, m).q[0]
    dist = [
        hand_distance(state, s.goal.effector, q, root, p)
        for s, p in zip(segs, targets, strict=True)
    ]
    if max(dist) <= TOLERANCE:
        return q, "arm", dist

    def torso_pose(goals: list[Goal]) -> FloatArray | None:
        """The goals solved with the trunk, the pinned hands put back; None when they cannot
        be (the trunk is then tried moving around them: they join the goals). When that
        leaves a goal short, the least lean that meets them all with the held hands on their
        sites (``held_pose``, ``held_sites``) is tried, and kept only if it meets them: a
        reach is short only when no solve meets it, and a short one is what it was."""
        m = model_for(ctx, skel, tuple(g.effector for g in goals), "torso", q0, root)
        qt = solved(ctx.cache, solve_ta, skel, goals, q0, m).q[0]
        if not pinned:
            return qt
        qt = repin(ctx, skel, qt[None], pinned, root)[0]
        choice: FloatArray | None = None
        if pins_off(state, pinned, qt[None], root) <= TOLERANCE:
            choice = qt
        else:
            both = goals + list(pinned)
            m = model_for(ctx, skel, tuple(g.effector for g in both), "torso", q0, root)
            qb = solved(ctx.cache, solve_ta, skel, both, q0, m).q[:1]
            qb = repin(ctx, skel, qb, pinned, root)[0]
            if pins_off(state, pinned, qb[None], root) <= TOLERANCE:
                choice = qb
        if choice is not None and goals_off(state, goals, choice, root) <= TOLERANCE:
            return choice
        # the descents stopped at a lean where the goals are not all met
        sites = held_sites(state, segs, pinned, root)
        seeds = [qt] if choice is None else [choice, qt]
        qh = held_pose(ctx, state, goals + sites, q0, root, seeds)
        qh = repin(ctx, skel, qh[None], sites, root)[0]
        if (
            pins_off(state, sites, qh[None], root) <= TOLERANCE
            and goals_off(state, goals, qh, root) <= TOLERANCE
        ):
            return qh
        return choice

    def distances(qc: FloatArray) -> list[float]:
        return [
            hand_distance(state, s.goal.effector, qc, root, p)
            for s, p in zip(segs, targets, strict=True)
        ]

    def score(d: list[float]) -> tuple[int, float]:
        return sum(x > TOLERANCE for x in d), sum(d)

    goals = [
        g for k, (s, p) in enumerate(zip(segs, targets, strict=True)) for g in goals_of(k, s, p)
    ]
    best: tuple[FloatArray, str, list[float]] = (q, "arm", dist)
    qt = torso_pose(goals)
    if qt is not None:
        dt = distances(qt)
        if max(dt) < max(dist):
            best = (qt, "torso", dt)
    if len(segs) > 1 and max(best[2]) > TOLERANCE:
        # one trunk for both hands that leaves one short: the trunk for one hand alone, the
        # other arm from there (a reachable site is not given up for an unreachable one)
        for k in sorted(range(len(segs)), key=lambda i: segs[i].end):
            qk = torso_pose(goals_of(k, segs[k], targets[k]))
            if qk is None:
                continue
            for j, (seg, p) in enumerate(zip(segs, targets, strict=True)):
                if j != k:
                    arm_goals = goals_of(j, seg, p)
                    m = model_for(ctx, skel, tuple(g.effector for g in arm_goals), "arm", qk, root)
                    qk = solved(ctx.cache, solve_ta, skel, arm_goals, qk, m).q[0]
            dk = distances(qk)
            if score(dk) < score(best[2]):
                best = (qk, "torso", dk)
    return best


def clear_of_body(
    state: PoseState,
    segs: list[Segment],
    q: FloatArray,
    root: tuple[FloatArray, FloatArray],
    keep: float = KEEP_GOAL,
    swivel: bool = True,
) -> FloatArray:
    """Pose ``q`` with each reaching arm swung clear of the trunk and thighs, its hand kept
    where it is (``mtlc.body.ik.clearance``: the body's volume is a constraint of the arm's
    IK; the solvers above know only the hand). A squat's forearm went through the thigh, a
    panel set down at the hip put the forearm through the trunk."""
    sides = sorted({s.goal.effector[0] for s in segs if s.goal.effector[:2] in ("r_", "l_")})
    rows = (root[0][None], root[1][None])
    out = q[None].copy()
    for side in sides:
        out = keep_clear(state.skel, out, rows, side, np.array([keep]), swivel=swivel)
    return out[0]


def clear_path(
    state: PoseState,
    segs: list[Segment],
    poses: list[FloatArray],
    root: tuple[FloatArray, FloatArray],
    fracs: list[float],
) -> tuple[list[FloatArray], list[float]]:
    """Keyframes (poses at fractions of the segment) whose joint-space path keeps the arms out
    of the trunk and thighs: where the straight line between two keyframes takes a limb's
    surface into them (an arm swung down past a squatting knee), the deepest pose on it is cleared, its
    hand free to move (``KEEP_PATH``), and becomes a keyframe between them if the path is
    then less deep (``CLEAR_KEYS`` at most). ``fracs``: the poses' fractions of the window;
    returns the poses and their fractions."""
    fracs, poses = list(fracs), list(poses)
    sides = sorted({s.goal.effector[0] for s in segs if s.goal.effector[:2] in ("r_", "l_")})
    limbs = limbs_of_sides(sides)  # the moving arms' (the other arm's depth was dropped)
    steps = np.linspace(0.0, 1.0, PATH_SAMPLES)[1:-1]

    def deepest(keys: list[FloatArray]) -> tuple[float, FloatArray, int, float]:
        """The path's deepest sample: (how deep a limb's surface goes in, pose, stretch, fraction
        in it). Only a path that truly goes in is changed, not one inside the clearance."""
        qs = np.array([a + f * (b - a) for a, b in itertools.pairwise(keys) for f in steps])
        pose = forward(
            state.skel, qs, np.broadcast_to(root[0], (len(qs), 3)),
            np.broadcast_to(root[1], (len(qs), 4)), with_axes=False,
        )  # fmt: skip
        deep = self_intersection(state.skel, pose, limbs)[0].max(axis=1)  # (no dof axes)
        i = int(np.argmax(deep))
        return float(deep[i]), qs[i], i // len(steps), float(steps[i % len(steps)])

    for _ in range(CLEAR_KEYS):
        depth, pose, k, f = deepest(poses)
        if depth <= 0.0:
            break
        trial = [
            *poses[: k + 1],
            clear_of_body(state, segs, pose, root, KEEP_PATH),
            *poses[k + 1 :],
        ]
        if deepest(trial)[0] >= depth - CLEAR_GAIN:
            break
        poses = trial
        fracs.insert(k + 1, fracs[k] + f * (fracs[k + 1] - fracs[k]))
    return poses, fracs


def lowest_hand_point(
    state: PoseState, segs: list[Segment], q: FloatArray, root: tuple[FloatArray, FloatArray]
) -> float:
    """Height of the lowest hand or fingertip of the segments' effectors in pose ``q``."""
    names = [n for s in segs for n in (s.goal.effector, FINGERTIPS.get(s.goal.effector, ""))]
    return min(float(state.site(n, q, root)[1]) for n in names if n)


def lowest_hand_points(
    state: PoseState, segs: list[Segment], qs: FloatArray, root: tuple[FloatArray, FloatArray]
) -> FloatArray:
    """``lowest_hand_point`` of each of the poses ``qs`` (K, D), from one forward kinematics
    of them all (the same numbers: a batch of up to ``CHAIN_BATCH`` poses is placed with the
    same products as one)."""
    names = [n for s in segs for n in (s.goal.effector, FINGERTIPS.get(s.goal.effector, "")) if n]
    k = len(qs)
    return part_site_positions(
        state.skel, qs, np.broadcast_to(root[0], (k, 3)), np.broadcast_to(root[1], (k, 4)),
        names,
    )[..., 1].min(axis=1)  # fmt: skip


def chain_names(skel: Any, effectors: list[str], reach: str) -> tuple[str, ...]:
    return tuple(skel.dof_names[d] for d in default_dofs(skel, effectors, reach))


def groups(ir: MotionIR, kind: str) -> list[list[Segment]]:
    """Segments of ``kind`` on the arms whose time windows overlap, grouped, in time order (a
    wrench's strokes are the tool pass's). Two hands that move at once share one trunk, so
    they are solved together whatever their durations: two reaches of different MTM lengths
    solved one after the other gave the trunk two poses, and the later one pulled the first
    hand 250-380 mm off its site."""
    segs = sorted(
        (s for s in ir.segments
         if s.kind == kind and s.track in ARM_TRACKS and "stroke" not in s.goal.params),
        key=lambda s: (s.start, s.end),
    )  # fmt: skip
    out: list[list[Segment]] = []
    end = -np.inf
    for s in segs:
        if out and s.start < end - 1e-9 and all(o.track != s.track for o in out[-1]):
            out[-1].append(s)
            end = max(end, s.end)
        else:
            out.append([s])
            end = s.end
    return [sorted(g, key=lambda s: s.track) for g in out]


def trunk_carrier(segs: list[Segment]) -> int:
    """The segment of a group that keys the shared trunk: the one that ends first, so the
    trunk is still from then on and the hand that arrives first is not moved again."""
    return min(range(len(segs)), key=lambda k: (segs[k].end, k))


def own_names(
    skel: Any, segs: list[Segment], k: int, reach: str, pinned: list[Goal]
) -> tuple[str, ...]:
    """The dofs segment ``k`` of a group keys: its chain (with the pinned arms, for the
    trunk's carrier), without the trunk dofs the carrier keys."""
    carrier = trunk_carrier(segs)
    names = chain_names(skel, [segs[k].goal.effector], reach)
    if k == carrier:
        return with_pinned(skel, names, pinned, reach)
    if abs(segs[k].start - segs[carrier].start) + abs(segs[k].end - segs[carrier].end) < 1e-9:
        return names  # the same window: the same trunk keyframes, at the same times
    shared = set(chain_names(skel, [segs[carrier].goal.effector], reach))
    return tuple(n for n in names if n not in shared)


def sweep_mid(
    ctx: PassContext,
    state: PoseState,
    segs: list[Segment],
    targets: list[FloatArray],
    q0: FloatArray,
    q1: FloatArray,
    root: tuple[FloatArray, FloatArray],
    pinned: list[Goal] | None,
) -> FloatArray | None:
    """A pose half-way that lifts the hands over the floor, when the joint-space path from
    ``q0`` to ``q1`` sweeps a hand or fingertip within ``SWEEP_CLEARANCE`` of it; else None.
    ``pinned``: ``pinned_hands`` at ``q0``, or None to find them only if a lift is solved."""
    fs = np.linspace(0.0, 1.0, 9)[1:-1]
    lows = lowest_hand_points(state, segs, q0 + fs[:, None] * (q1 - q0), root)
    sink = state.ir.ground + SWEEP_CLEARANCE - float(lows.min())
    if sink <= 0.0:
        return None
    here = [state.site(s.goal.effector, q0, root) for s in segs]
    mids = [0.5 * (a + b) + np.array([0.0, sink, 0.0]) for a, b in zip(here, targets, strict=True)]
    if pinned is None:
        pinned = pinned_hands(state, segs, q0, root)
    mid, _, _, _ = solve_group(ctx, state, segs, mids, 0.5 * (q0 + q1), root, pinned)
    return mid


def relift(ir: MotionIR, ctx: PassContext) -> None:
    """``sweep_mid`` and ``clear_path`` for the approaches, once the contacts before them are
    solved (the first keyframe is then the pose the approach truly starts from).

    An approach starts from the pose the body is in, and the contact pass moves that pose
    (onto the site the hand reached before) after the approach was solved: from a spares box
    10 cm up, the path to the next site then swept the fingertips 12 mm into the floor.
    """
    state = PoseState(ir)
    skel = ir.skeleton
    for segs in groups(ir, "TA"):
        if any(s.keyframes is None for s in segs):
            continue
        t0, t1 = min(s.start for s in segs), max(s.end for s in segs)
        q0, q1 = state.q_at(t0), state.q_at(t1)
        root = state.root_at(t1)
        if all(len(s.keyframes.time) == 2 for s in segs):  # type: ignore[union-attr]
            targets = [
                np.asarray(s.result.get("approach_point", s.goal.position), dtype=float)
                for s in segs
            ]
            mid = sweep_mid(ctx, state, segs, targets, q0, q1, root, None)
            if mid is not None:
                _rekey(skel, segs, [q0, mid, q1], [0.0, 0.5, 1.0])
        if any(abs(s.start - t0) + abs(s.end - t1) > 1e-9 for s in segs):
            continue  # hands of different windows: their keyframes are not one path
        kf = segs[0].keyframes
        assert kf is not None
        fracs = list((kf.time - t0) / max(t1 - t0, 1e-9))
        poses = [_pose_at(skel, state.q_at(t), segs, k) for k, t in enumerate(kf.time)]
        poses, new_fracs = clear_path(state, segs, poses, root, fracs)
        if len(poses) != len(fracs):
            _rekey(skel, segs, poses, new_fracs)


def _pose_at(skel: Any, q: FloatArray, segs: list[Segment], k: int) -> FloatArray:
    """The whole body at keyframe ``k`` of the segments: ``q`` with their own keyed dofs."""
    out = q.copy()
    for seg in segs:
        kf = seg.keyframes
        assert kf is not None
        out[[skel.dof_index(n) for n in kf.dofs]] = kf.q[k]
    return out


def _rekey(skel: Any, segs: list[Segment], poses: list[FloatArray], fracs: list[float]) -> None:
    """Each segment's keyframes at ``fracs`` of its window, from the whole-body ``poses``."""
    for seg in segs:
        kf = seg.keyframes
        assert kf is not None
        idx = [skel.dof_index(n) for n in kf.dofs]
        seg.keyframes = Keyframes(
            time=seg.start + (seg.end - seg.start) * np.asarray(fracs),
            dofs=kf.dofs,
            q=np.stack([pose[idx] for pose in poses]),
        )


def solve(ir: MotionIR, ctx: PassContext) -> MotionIR:
    state = PoseState(ir)
    for segs in groups(ir, "TA"):
        solve_ta_group(ctx, state, segs)
        for seg in segs:
            state.add(seg)
            mark(ctx.cache, seg)
    reanchor(ir, ctx.cache, _restaters())
    return ir


def solve_ta_group(
    ctx: PassContext, state: PoseState, segs: list[Segment], skip: list[Segment] | None = None
) -> None:
    """Key one group of TA segments: from the body at the group's start (``skip``: segments
    whose keyframes there are not evidence of it, the group's own when solved again) to the
    approach points, with the root where the plan puts it at the group's end."""
    ir, skel = state.ir, state.skel
    t0, t1 = min(s.start for s in segs), max(s.end for s in segs)
    q0 = state.q_at(t0, skip=skip)
    root = state.root_at(t1)
    targets = []
    for seg in segs:
        seg.goal.position = hand_target(ir, seg, root[1])
        targets.append(approach_point(state, seg, seg.goal.position, q0, root))
    pinned = pinned_hands(state, segs, q0, root)
    flat = [flat_hand(state, seg, root) for seg in segs]
    q1, reach, dist, laid = solve_group(ctx, state, segs, targets, q0, root, pinned, flat)
    if not laid:
        # the lifts raise the pose that was chosen, the plain one: the flat one, which lost
        # at the approach point, is not tried again at each raised point (each try of a
        # flat pose that cannot reach costs every restart of up to five solves)
        flat = None
    for _ in range(LIFTS):
        sink = ir.ground - GROUND_SLACK - lowest_hand_point(state, segs, q1, root)
        if sink <= 0.0:
            break
        # the hand arrives fingers first: raise its approach point by what they sink
        targets = [p + np.array([0.0, sink + GROUND_SLACK, 0.0]) for p in targets]
        q1, reach, dist, _ = solve_group(ctx, state, segs, targets, q0, root, pinned, flat)
    q1 = clear_of_body(state, segs, q1, root)
    dist = [
        hand_distance(state, s.goal.effector, q1, root, p)
        for s, p in zip(segs, targets, strict=True)
    ]
    mid = sweep_mid(ctx, state, segs, targets, q0, q1, root, pinned)
    for k, (seg, p, d) in enumerate(zip(segs, targets, dist, strict=True)):
        names = own_names(skel, segs, k, reach, pinned)
        idx = [skel.dof_index(n) for n in names]
        s0, s1 = seg.start, seg.end
        if mid is None:
            seg.keyframes = Keyframes(
                time=np.array([s0, s1]), dofs=names, q=np.stack([q0[idx], q1[idx]])
            )
        else:
            seg.keyframes = Keyframes(
                time=np.array([s0, 0.5 * (s0 + s1), s1]),
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


def stale_approach(state: PoseState, segs: list[Segment]) -> bool:
    """A hand of the group that its solver put on its approach point is no longer there at
    the segment's end, in the body as keyed now: the approaches are solved before the
    contacts, and a contact before this approach that bent the trunk (a torso reach) moved the
    shoulders under the arm's solved angles (the avionics unit's slide: 157 and 208 mm)."""
    skel = state.skel
    for seg in segs:
        point = seg.result.get("approach_point")
        if point is None or seg.keyframes is None or seg.result.get("distance", 1.0) > TOLERANCE:
            continue
        q = _pose_at(skel, state.q_at(seg.end), segs, -1)
        if hand_distance(state, seg.goal.effector, q, state.root_at(seg.end), point) > TOLERANCE:
            return True
    return False


def _restaters() -> dict[str, Any]:
    from mtlc.passes.posture import RESTATERS

    return RESTATERS
