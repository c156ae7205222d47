"""Pass 3, TO (target overlapping, seed 000): the hand's last stretch onto the site, as a path.

From the pose the TA phase left (the keyframes so far at the segment's start), seed 000's
gradient path (``solve_to``: steps down the gradient of the end-effector distance, adaptive step
after seed 004 claim 5, every accepted step lowers the distance) moves the same chain TA used
(the arm, or the arm with the torso when TA needed it) onto the site. The path itself becomes
the keyframes, so the final approach is continuous and the hand never backs away:

* at most ``MAX_KEYFRAMES`` configurations are kept, chosen at even steps of progress
  (distance covered / distance to cover), first and last always;
* each keyframe's time is the segment's start plus its share of the progress, so the distance
  to the target falls monotonically over time and the hand moves at a steady pace.

Hands that share a time window and needed the torso are solved together (one trunk for both).
A hand still more than 1 mm from its site reports MT0501 at the task line (once per goal: a
goal TA already found short is not reported again) and keeps its best pose.
"""

from __future__ import annotations

import numpy as np

from mtlc.body import part_site_positions
from mtlc.body.ik import Goal, solve_ta, solve_to
from mtlc.ir.model import FloatArray, Keyframes, MotionIR, Segment
from mtlc.passes.approach import (
    TOLERANCE,
    _restaters,
    chain_names,
    groups,
    hand_target,
    held_pose,
    held_sites,
    model_for,
    own_names,
    pinned_hands,
    pins_off,
    relift,
    repin,
    report_short,
    seg_goals,
    solve_ta_group,
    stale_approach,
)
from mtlc.passes.context import PassContext
from mtlc.passes.state import TRUNK_DOFS, PoseState, reanchor, solved

MAX_KEYFRAMES = 12
MAX_ITER = 400
NEAR_RATIO = 2.0  # a pose near the start is kept unless a restart's ends this many times closer
GROUND_SLACK = 5e-4  # m a hand point may dip below the ground (half the 1 mm budget)
FINGERTIPS = {"r_hand": "r_fingertip", "l_hand": "l_fingertip"}


def _ta_of(ir: MotionIR) -> dict[tuple[object, ...], list[Segment]]:
    """TA segments by (track, origin, site): the TA phase of each TO's goal."""
    out: dict[tuple[object, ...], list[Segment]] = {}
    for s in ir.segments:
        if s.kind == "TA":
            out.setdefault((s.track, s.provenance.origin, s.goal.site), []).append(s)
    return out


def _ta_for(tas: dict[tuple[object, ...], list[Segment]], seg: Segment) -> Segment | None:
    """The latest TA of the same goal that ends by the time this TO starts."""
    best = None
    for s in tas.get((seg.track, seg.provenance.origin, seg.goal.site), []):
        if s.end <= seg.start + 1e-9 and (best is None or s.end >= best.end):
            best = s
    return best


def _distances(
    skel: object, configs: FloatArray, effectors: list[str], targets: list[FloatArray], root: tuple
) -> FloatArray:
    """(K, H) distance of each hand to its target for K configurations."""
    k = configs.shape[0]
    # the hands' chains only (``part_site_positions``: the whole body's numbers)
    pts = part_site_positions(
        skel, configs, np.broadcast_to(root[0], (k, 3)), np.broadcast_to(root[1], (k, 4)),
        effectors,
    ).reshape(k, len(effectors), 3)  # fmt: skip
    return np.linalg.norm(pts - np.stack(targets)[None], axis=-1)


def select_keys(dist: FloatArray, n_max: int = MAX_KEYFRAMES) -> tuple[list[int], FloatArray]:
    """Path indices to keep and their progress in [0, 1], non-decreasing distance drop.

    ``dist`` (T, H): per path sample, each hand's distance. A sample is kept only if no hand is
    further than at the last kept sample, so the kept distances never rise."""
    total = dist.sum(axis=1)
    span = total[0] - total[-1]
    if span <= 1e-12 or len(total) < 2:
        return [0, len(total) - 1], np.array([0.0, 1.0])
    progress = np.clip((total[0] - total) / span, 0.0, 1.0)
    keep = [0]
    for level in np.linspace(0.0, 1.0, n_max)[1:]:
        i = int(np.argmax(progress >= level - 1e-12))
        if i > keep[-1] and np.all(dist[i] <= dist[keep[-1]] + 1e-12):
            keep.append(i)
    last = len(total) - 1
    if keep[-1] != last:
        if np.all(dist[last] <= dist[keep[-1]] + 1e-12):
            keep.append(last)
        else:  # a hand would move away at the end: hold the last sample kept
            keep.append(keep[-1])
    prog = np.maximum.accumulate(progress[keep])
    prog[0], prog[-1] = 0.0, 1.0
    return keep, prog


def _gradient(
    ctx: PassContext,
    state: PoseState,
    goals: list[Goal],
    q0: FloatArray,
    root: tuple[FloatArray, FloatArray],
    reach: str,
    max_iter: int,
) -> FloatArray:
    """Seed 000's gradient path (T, n_dofs) for these goals, on one prepared model."""
    effs = tuple(g.effector for g in goals)
    model = model_for(ctx, state.skel, effs, reach, q0, root)
    res = solved(
        ctx.cache, solve_to, state.skel, goals, q0, model, tol=0.5 * TOLERANCE, max_iter=max_iter
    )
    assert res.path is not None
    return np.asarray(res.path[:, 0])


def best_path(
    ctx: PassContext,
    state: PoseState,
    segs: list[Segment],
    targets: list[FloatArray],
    q0: FloatArray,
    root: tuple[FloatArray, FloatArray],
    reach: str,
    hopeless: bool,
    pinned: list[Goal] | None = None,
    seeds: list[FloatArray] | None = None,
) -> tuple[FloatArray, str, FloatArray]:
    """The path onto the sites: the gradient path on TA's chain; if it stalls short of a
    reachable site (a local minimum at a limit), the gradient path with the torso, then the
    straight joint-space line to a DLS solution (kept samples still never move away).
    Each is judged as it will be used: a torso path with the other hand put back (``pinned``),
    every path cut where a hand meets the floor (``above_ground``). Returns the path, the
    reach used and the (T, H) distances along it. ``seeds``: poses near the goals (the hands
    solved one after the other) the torso solve starts from too (``nearest_solution``)."""
    skel = state.skel
    goals = [g for s, p in zip(segs, targets, strict=True) for g in seg_goals(skel, s, p)]
    effs = [s.goal.effector for s in segs]

    def finished(p: FloatArray, r: str) -> tuple[FloatArray, FloatArray]:
        if r == "torso" and pinned:  # the trunk carried the other arm: put its hand back
            p = repin(ctx, skel, p, pinned, root)
            if pins_off(state, pinned, p, root) > TOLERANCE:
                # a trunk the held arm cannot follow lets go of the hold: never chosen
                p, d = above_ground(state, p, _distances(skel, p, effs, targets, root), effs, root)
                return p, np.full_like(d, np.inf)
        return above_ground(state, p, _distances(skel, p, effs, targets, root), effs, root)

    path = _gradient(ctx, state, goals, q0, root, reach, MAX_ITER // 4 if hopeless else MAX_ITER)
    path, dist = finished(path, reach)
    if not np.isfinite(dist).all():  # the trunk would let go of a hold: the arm alone
        reach = "arm"
        path, dist = finished(_gradient(ctx, state, goals, q0, root, reach, MAX_ITER), reach)
    if hopeless or dist[-1].max() <= TOLERANCE:
        return path, reach, dist
    tries = []
    if reach != "torso":
        tries.append(("torso", _gradient(ctx, state, goals, q0, root, "torso", MAX_ITER)))
    near = [path[-1], *(seeds or [])]
    q_star = nearest_solution(ctx, state, goals, q0, root, near)
    steps = np.linspace(0.0, 1.0, 2 * MAX_KEYFRAMES)[:, None]
    tries.append(("torso", q0[None] + steps * (q_star - q0)[None]))
    if pinned:  # a trunk that moves around the held hands: they are goals of the solve too
        both = goals + list(pinned)
        q_held = nearest_solution(ctx, state, both, q0, root, near)
        tries.append(("torso", q0[None] + steps * (q_held - q0)[None]))
    for r, p in tries:
        p, d = finished(p, r)
        if d[-1].max() < dist[-1].max():
            path, reach, dist = p, r, d
        if dist[-1].max() <= TOLERANCE:
            break
    if pinned and dist[-1].max() > TOLERANCE:
        # every descent stopped short at a deep lean: the least lean that meets the site and
        # the held hands on their sites (``approach.held_pose``, ``held_sites``), before the
        # reach is called unreachable
        sites = held_sites(state, segs, pinned, root)
        q_least = held_pose(ctx, state, goals + sites, q0, root, [q_held, path[-1]])
        p = repin(ctx, skel, q0[None] + steps * (q_least - q0)[None], sites, root)
        if pins_off(state, sites, p, root) <= TOLERANCE:
            p, d = above_ground(state, p, _distances(skel, p, effs, targets, root), effs, root)
            if d[-1].max() <= TOLERANCE:  # kept only when it meets them: else as it was
                path, reach, dist = p, "torso", d
    return path, reach, dist


def nearest_solution(
    ctx: PassContext,
    state: PoseState,
    goals: list[Goal],
    q0: FloatArray,
    root: tuple[FloatArray, FloatArray],
    seeds: list[FloatArray],
) -> FloatArray:
    """A torso pose that meets ``goals``, found near ``q0`` first (issue 19).

    The straight joint-space line to it is the contact's path. ``solve_ta`` restarts from
    random poses when its descent from ``q0`` stalls, and the pose a restart finds may be on
    another branch of the arm: the avionics unit's handle, 22 cm from the latches, was reached
    with the shoulder turned 124 degrees the other way in 0.14 s. The descent from each of
    ``seeds`` (where the gradient path stalled) is tried first, without restarts; the solver's
    restarts when none reaches, and their pose is kept if it ends ``NEAR_RATIO`` times closer
    (both are then short: MT0501)."""
    model = model_for(ctx, state.skel, tuple(g.effector for g in goals), "torso", q0, root)
    best = None
    for seed in seeds:
        res = solved(ctx.cache, solve_ta, state.skel, goals, seed, model, restarts=0)
        if best is None or res.position_error[0] < best.position_error[0]:
            best = res
    if best is not None and best.position_error[0] <= TOLERANCE:
        return best.q[0]
    res = solved(ctx.cache, solve_ta, state.skel, goals, q0, model)
    if best is None or res.position_error[0] * NEAR_RATIO < best.position_error[0]:
        best = res
    return best.q[0]


def above_ground(
    state: PoseState,
    path: FloatArray,
    dist: FloatArray,
    effectors: list[str],
    root: tuple[FloatArray, FloatArray],
) -> tuple[FloatArray, FloatArray]:
    """The path up to the sample before a hand or fingertip goes through the ground.

    The gradient path knows only the distance to the site: toward a site near the floor (a
    tray 5 cm up, reached fingers first) it pushes the fingertips through it. A hand stops
    where it touches the floor instead, short of the site (reported like any short reach).
    """
    names = [n for e in effectors for n in (e, FINGERTIPS.get(e, e))]
    k = len(path)
    low = part_site_positions(
        state.skel, path, np.broadcast_to(root[0], (k, 3)), np.broadcast_to(root[1], (k, 4)),
        names,
    )[..., 1].min(axis=-1)  # fmt: skip
    below = np.flatnonzero(low < state.ir.ground - GROUND_SLACK)
    if below.size == 0 or below[0] == 0:  # nothing below, or already below where TA left it
        return path, dist
    return path[: below[0]], dist[: below[0]]


_Part = tuple[list[Segment], list[FloatArray], str, bool]


def _solve_parts(
    ctx: PassContext,
    state: PoseState,
    parts: list[_Part],
    q0: FloatArray,
    root: tuple[FloatArray, FloatArray],
    pinned: list[Goal] | None = None,
    seeds: list[FloatArray] | None = None,
) -> list[tuple[FloatArray, list[Segment], str, FloatArray, list[int], FloatArray]]:
    """Paths for each part of a time window, each hand starting where the one before left;
    with the kept samples and their progress (``select_keys``)."""
    out = []
    for psegs, ptargets, reach, hopeless in parts:
        path, used, dist = best_path(
            ctx, state, psegs, ptargets, q0, root, reach, hopeless, pinned, seeds
        )
        keep, prog = select_keys(dist)
        q0 = path[keep[-1]].copy()
        out.append((path, psegs, used, dist, keep, prog))
    return out


def _approach_again(
    ctx: PassContext, state: PoseState, segs: list[Segment], followed: set[int]
) -> PoseState:
    """Solve a group of approaches again when it ends its goal (no contact phase follows it:
    ``goal ... approach 0 cm``, so the frames' claim rests on it) and the contacts solved
    since (before it in time) moved the body under it (``approach.stale_approach``); the
    state, indexed again if so. An approach that a contact phase follows is left as it is:
    that phase is solved from the body as it is and makes the claim."""
    if all(id(s) in followed for s in segs) or not stale_approach(state, segs):
        return state
    solve_ta_group(ctx, state, segs, skip=segs)
    return PoseState(state.ir)  # the group's keyframes were replaced


def own_starts(state: PoseState, segs: list[Segment], q0: FloatArray) -> FloatArray:
    """The group's start pose ``q0`` (the body when its first contact starts) with each later
    hand's arm (and clavicle) where that hand is when its own contact starts. Each hand's
    keyframes are laid on its own window, so its path must start where its approach ended: at
    the group's start a hand still on its way is at its approach's first keyframe (the state
    holds a dof's latest keyframe), and a press whose other hand started first began from the
    hip, 1.2 m below the cover its approach had nearly reached."""
    skel = state.skel
    first = min(s.start for s in segs)
    for seg in segs:
        if seg.start > first + 1e-9:
            arm = chain_names(skel, [seg.goal.effector], "torso")
            idx = [skel.dof_index(n) for n in arm if n not in TRUNK_DOFS]
            q0[idx] = state.q_at(seg.start)[idx]
    return q0


def solve(ir: MotionIR, ctx: PassContext) -> MotionIR:
    state = PoseState(ir)
    skel = ir.skeleton
    ta_of = _ta_of(ir)
    # the approaches were solved before any contact: each is checked, in time order, once the
    # contacts before it are solved, and before the contact that starts where it ends
    approaches, checked = groups(ir, "TA"), 0
    contacts = groups(ir, "TO")
    followed = {id(ta) for segs in contacts for s in segs if (ta := _ta_for(ta_of, s)) is not None}
    for segs in contacts:
        t0, t1 = min(s.start for s in segs), max(s.end for s in segs)
        while checked < len(approaches) and (min(s.end for s in approaches[checked]) <= t0 + 1e-9):
            state = _approach_again(ctx, state, approaches[checked], followed)
            checked += 1
        q0 = own_starts(state, segs, state.q_at(t0))
        root = state.root_at(t1)
        targets = []
        for seg in segs:
            seg.goal.position = hand_target(ir, seg, root[1])
            targets.append(seg.goal.position)
        tas = [_ta_for(ta_of, s) for s in segs]
        reaches = [("arm" if ta is None else ta.result.get("reach", "arm")) for ta in tas]
        # TA already well short: TO cannot reach either, so it spends less on trying
        hopeless_all = [ta is not None and ta.result.get("distance", 0.0) > 0.01 for ta in tas]
        if "torso" in reaches and len(segs) > 1:
            parts = [(segs, targets, "torso", any(hopeless_all))]
        else:
            parts = [
                ([s], [p], r, h)
                for s, p, r, h in zip(segs, targets, reaches, hopeless_all, strict=True)
            ]
        pinned = pinned_hands(state, segs, q0, root)
        solved = _solve_parts(ctx, state, parts, q0, root, pinned)
        if len(parts) > 1 and any(x[2] == "torso" for x in solved):
            # one hand needed the trunk: that would move the other hand, so solve them together,
            # from where the hands solved one after the other ended too (near both goals)
            ends = [x[0][x[4][-1]] for x in solved]
            solved = _solve_parts(
                ctx, state, [(segs, targets, "torso", any(hopeless_all))], q0, root, pinned,
                ends,
            )  # fmt: skip
        for path, psegs, reach, dist, keep, prog in solved:
            for h, seg in enumerate(psegs):
                # each hand keeps its own window; the trunk is keyed by the one ending first
                names = own_names(skel, psegs, h, reach, pinned)
                idx = [skel.dof_index(n) for n in names]
                times = seg.start + (seg.end - seg.start) * prog
                seg.keyframes = Keyframes(time=times, dofs=names, q=path[keep][:, idx])
                d = float(dist[keep[-1], h])
                ok = d <= TOLERANCE
                seg.result = {
                    "distance": d,
                    "success": bool(ok and skel.within_limits(path[keep[-1]])),
                    "reach": reach,
                    "path_samples": len(path),
                    "keyframes": len(keep),
                }
                if not ok:
                    report_short(ctx, seg, d)
                state.add(seg)
    for segs in approaches[checked:]:
        state = _approach_again(ctx, state, segs, followed)
    reanchor(ir, ctx.cache, _restaters())
    relift(ir, ctx)
    return ir
