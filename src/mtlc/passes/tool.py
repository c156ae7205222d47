"""Tool operation (seed 000's tool-operation actions, ``jsaToolMotion``): tools in the hand.

Two passes (docs/tools.md):

* ``equip``, after the manikin: every tool a goal is made with becomes a site on that hand, its
  working point (``r_tool_wrench_10mm``), so TA and TO solve for the tip on the site and metrics
  measure the tip. A held tool's mass counts in the centre of mass (balance, metrics) while it
  is held, a point at the middle of grip and tip (``mtlc.loads.carried_com``).
* ``solve``, after contact: a wrench's strokes (TO segments with a ``stroke`` number). The hand
  holds the handle at the arc's radius ``r`` (the grip's distance from the fastener's axis) and
  swings about the fastener's axis (its site's normal) through the stroke's angle, the tip on the
  fastener, then is lifted off along the axis, swings back and re-engages; a ratchet swings back
  engaged. Every keyframe is solved by damped least squares for two goals: the grip on the arc
  and the tip on the fastener (lifted by ``LIFT`` while off).

A screwdriver's or pliers' reach (TA and TO) is solved with the tool's axis on the fastener's axis
(``axis_goals``: the grip on the site's normal line behind the tip), and its twists are re-solved
here so the hand turns about that axis with the tip on the fastener, re-gripping where the
wrist's range is short of the turn (``solve_axial_twist``).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from typing import Any

import numpy as np

from mtlc.body import forward, part_site_positions, site_positions, site_rotation
from mtlc.body.ik import ChainModel, Goal, prepare, solve_ta
from mtlc.body.kinematics import bits_differ
from mtlc.body.skeleton import Site, Skeleton
from mtlc.ir.model import FloatArray, Keyframes, MotionIR, Segment
from mtlc.ir.pchip import pchip
from mtlc.loads import AXIAL_KINDS, tool_site
from mtlc.loads import carried_com as carried_com  # re-exported: it lives below the passes
from mtlc.loads import held_spans as held_spans
from mtlc.passes.approach import TOLERANCE, _restaters, chain_names, report_short
from mtlc.passes.chain_ik import ChainSolve, RowChain, ScalarChain, solve_rows
from mtlc.passes.context import INTERNAL_FPS, PassContext
from mtlc.passes.profile import minimum_jerk, placing_clock
from mtlc.passes.state import PoseState, array_key, memo, reanchor, remembered

LIFT = 0.03  # m the tool is lifted off the fastener to swing back
SEAT_SHARE = 0.1  # share of a stroke's time the wrench rests on the fastener before swinging
SWING_SHARE = 0.6  # share of a stroke's time spent turning; the rest re-positions
KEY_STEP = math.radians(5.0)  # at most this much arc between keyframes
HAND_FRAME_AXIS = (0.0, -1.0, 0.0)  # a tool's default `axis`: back along the hand


def hand_to_joint(v: Any, side: str) -> FloatArray:
    """A point of the hand's frame (x thumb, y toward the fingers, z palm normal) in the wrist
    joint's frame. At the neutral pose the right palm faces +X (the thigh), the thumb +Z and the
    fingers -Y (docs/body.md); the left hand is its mirror image."""
    x, y, z = (float(c) for c in v)
    return np.array([z if side == "r" else -z, -y, x])


def tool_tip(tool: dict[str, Any]) -> FloatArray:
    """A tool's working point in the hand's frame; a tool that declares no `tip` works at its
    grip (docs/language.md, "Tools"), as the expansion's stroke times take it."""
    return np.asarray(tool.get("tip", tool.get("grip", (0.0, 0.0, 0.0))), float)


def radius(tool: dict[str, Any]) -> float:
    """Distance from the fastener's axis (through the tip, along ``axis``) to the grip (m)."""
    d = np.asarray(tool.get("grip", (0.0, 0.0, 0.0)), float) - tool_tip(tool)
    a = np.asarray(tool.get("axis", HAND_FRAME_AXIS), float)
    a = a / np.linalg.norm(a)
    return float(np.linalg.norm(d - (d @ a) * a))


def axial_offset(tool: dict[str, Any]) -> float:
    """How far the grip sits out along the fastener's axis from the tip (m; a cranked ring)."""
    d = np.asarray(tool.get("grip", (0.0, 0.0, 0.0)), float) - tool_tip(tool)
    a = np.asarray(tool.get("axis", HAND_FRAME_AXIS), float)
    return float(d @ (a / np.linalg.norm(a)))


# ------------------------------------------------------------------ equip
def held_tools(ir: MotionIR) -> dict[str, dict[str, Any]]:
    """Tool sites the segments address, with their tool, by site name (a forearm twist with a
    screwdriver names the tool but addresses the hand: not a tool site)."""
    out: dict[str, dict[str, Any]] = {}
    for seg in ir.segments:
        tool, eff = seg.goal.params.get("tool"), seg.goal.effector
        if isinstance(tool, dict) and _is_tool_site(eff, tool):
            out.setdefault(eff, tool)
    return dict(sorted(out.items()))


def _is_tool_site(effector: str, tool: dict[str, Any]) -> bool:
    """Whether a goal addresses the tool's working point (not the hand holding it)."""
    return effector[:2] in ("r_", "l_") and effector == tool_site(effector, tool)


def with_tools(skel: Skeleton, tools: dict[str, dict[str, Any]]) -> Skeleton:
    """The skeleton with a site at each tool's tip. The tool's mass is not the skeleton's: it
    counts only while the tool is held (``mtlc.loads.carried_com``)."""
    sites = list(skel.sites)
    for name, tool in tools.items():
        side = name[0]
        hand = skel.site(f"{side}_hand")
        grip = np.asarray(tool.get("grip", (0.0, 0.0, 0.0)), float)
        tip = np.asarray(hand.offset) + hand_to_joint(tool_tip(tool) - grip, side)
        sites.append(Site(name, hand.joint, tuple(float(c) for c in tip), "effector"))
    return dataclasses.replace(skel, sites=tuple(sites))


def axis_goals(skel: Skeleton, seg: Segment, tip_target: FloatArray) -> list[Goal]:
    """An extra goal that puts a screwdriver's (or pliers') axis on the fastener's axis: the grip
    on the site's normal line behind ``tip_target``, at the tool's grip-to-tip distance. Empty for
    other tools, bare hands and sites without a normal.

    (Putting the elbow on that line too, so the forearm is in line and its twist keeps the axis,
    left the reach 0.6 m short for a screw in front of the chest: see docs/tools.md, limits.)"""
    g = seg.goal
    tool, normal = g.params.get("tool"), g.params.get("normal")
    if tool is None or tool.get("kind") not in AXIAL_KINDS or normal is None:
        return []
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    hand = f"{g.effector[0]}_hand"
    tip = np.asarray(skel.site(g.effector).offset)
    grip_back = float(np.linalg.norm(tip - np.asarray(skel.site(hand).offset)))
    return [Goal(hand, position=tip_target + grip_back * n)]


def axis_angle(skel: Skeleton, pose: Any, effector: str, normal: Any) -> FloatArray:
    """(K,) angle (rad) between a tool's axis (tip to grip) and the fastener's normal."""
    pts = np.asarray(site_positions(skel, pose, [effector, f"{effector[0]}_hand"]))
    axis = pts[..., 1, :] - pts[..., 0, :]
    axis = axis / np.linalg.norm(axis, axis=-1, keepdims=True)
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    return np.arccos(np.clip(axis @ n, -1.0, 1.0)).reshape(-1)


def equip(ir: MotionIR, ctx: PassContext) -> MotionIR:
    tools = held_tools(ir)
    if tools and ir.skeleton is not None:
        ir.skeleton = with_tools(ir.skeleton, tools)
    return ir


# ------------------------------------------------------------------ strokes
def plane_basis(normal: Any) -> tuple[FloatArray, FloatArray, FloatArray]:
    """(n, u, v): the unit axis and two unit vectors across it, right-handed (u × v = n)."""
    n = np.asarray(normal, float)
    n = n / np.linalg.norm(n)
    helper = np.array([0.0, 1.0, 0.0]) if abs(n[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
    u = np.cross(helper, n)
    u /= np.linalg.norm(u)
    return n, u, np.cross(n, u)


def arc_points(
    centre: FloatArray, normal: Any, r: float, theta: FloatArray, out: float = 0.0
) -> FloatArray:
    """(K, 3) points at radius ``r`` about the axis through ``centre``, ``out`` along it."""
    n, u, v = plane_basis(normal)
    th = np.asarray(theta, float)[:, None]
    return centre + out * n + r * (np.cos(th) * u + np.sin(th) * v)


def arc_angle(centre: FloatArray, normal: Any, point: FloatArray) -> float:
    """The angle about the axis at which ``point`` lies (0 along ``u``)."""
    _, u, v = plane_basis(normal)
    d = np.asarray(point, float) - centre
    return math.atan2(float(d @ v), float(d @ u))


RETURN_KEYS = 12  # keyframes of a wrench's return (lift, swing back, re-seat)
BACK_SHARE = (0.1, 0.9)  # of the return's parameter: swinging back above the fastener


def _return_path(a0: float, a1: float) -> tuple[FloatArray, FloatArray]:
    """(K,) arc angles and lifts of a wrench's return from ``a1`` (engaged) to ``a0`` (engaged)
    at ``RETURN_KEYS`` even steps of its parameter: one arch, the lift a smooth bump
    ``(4 phi (1 - phi))^3`` (flat at both ends: it leaves and meets the fastener along its
    axis) and the swing back a minimum-jerk move inside it (``BACK_SHARE``), so the hand's
    path has no corner and its speed one bell."""
    phi = np.linspace(0.0, 1.0, RETURN_KEYS + 1)[1:]
    lo, hi = BACK_SHARE
    theta = a1 + (a0 - a1) * minimum_jerk((phi - lo) / (hi - lo))
    return theta, (4.0 * phi * (1.0 - phi)) ** 3


def _shares(points: FloatArray, a: float, b: float) -> FloatArray:
    """Times in [a, b] of a phase's keys in proportion to the hand's path between them."""
    step = np.linalg.norm(np.diff(points, axis=0), axis=1)
    along = np.concatenate([[0.0], np.cumsum(step)])
    if along[-1] <= 1e-12:
        return np.linspace(a, b, len(points))
    return a + (b - a) * along / along[-1]


def stroke_plan(
    theta_start: float, turn: float, ratchet: bool, arm: float = 0.1
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Keyframe fractions of the stroke's time, arc angles and lift (0/1) for one stroke.

    Three phases, each a movement from rest to rest: the seat (``SEAT_SHARE`` of the time: the
    pose the motion before left, settled on the fastener), the swing (to ``SWING_SHARE``) from
    ``theta_start`` (where the reach left the hand) to ``theta_start + turn`` (``turn`` signed,
    about the fastener's normal) in steps of at most ``KEY_STEP``, and the return: a wrench is
    lifted, swung back above the fastener and re-seated (``_return_path``), a ratchet swings
    back engaged. Inside the seat, the swing and a ratchet's return a key's fraction is in
    proportion to the hand's path up to it (a hand at ``arm`` from the axis), so
    ``paced_stroke`` can time the path by its length; a wrench's return keys are even steps
    of the arch's own parameter."""
    steps = max(2, math.ceil(abs(turn) / KEY_STEP - 1e-9))  # 60 deg is 12 steps, not 13
    a0, a1 = theta_start, theta_start + turn
    swing = np.linspace(a0, a1, steps + 1)
    if ratchet:
        back, back_lift = swing[::-1][1:], np.zeros(steps)
    else:
        back, back_lift = _return_path(a0, a1)
    theta = np.concatenate([[a0], swing, back])
    lift = np.concatenate([np.zeros(steps + 2), back_lift])
    hand = np.stack([arm * np.cos(theta), arm * np.sin(theta), LIFT * lift], axis=1)
    swing_frac = _shares(hand[1 : steps + 2], SEAT_SHARE, SWING_SHARE)
    back_frac = (
        _shares(hand[-steps - 1 :], SWING_SHARE, 1.0)[1:]
        if ratchet
        else np.linspace(SWING_SHARE, 1.0, RETURN_KEYS + 1)[1:]
    )
    return np.concatenate([[0.0], swing_frac, back_frac]), theta, lift


PHASES = ((0.0, SEAT_SHARE), (SEAT_SHARE, SWING_SHARE), (SWING_SHARE, 1.0))
# rad/s: the fastest a joint turns in a stroke. Issue 19 allows 360 deg/s (12 deg a frame at
# 30 fps), the wrist and the forearm's roll in a fastener turn 600 deg/s (20 deg a frame); a
# little under each, as the output frames sample a path keyed at the internal rate
STROKE_JOINT_SPEED = math.radians(330.0)
STROKE_TURN_SPEED = math.radians(540.0)
TURNING_DOFS = ("wrist_", "elbow_pro")  # the dofs that turn the tool (the looser limit)
NEED_SAMPLES = 241  # points of each phase's path at which its joint speed is measured


def _phase_path(
    frac: FloatArray, q: FloatArray, k: int, lifted: bool, tau: FloatArray,
    curves: dict[Any, Any] | None = None,
) -> FloatArray:  # fmt: skip
    """(len(tau), D) poses of phase ``k`` at its normalised times ``tau``: its keys joined by
    PCHIP in the phase's progress (minimum jerk; a wrench's lifted return on a placing clock).
    ``curves``: the PCHIP curves built so far, by their exact keys (the strokes of a series
    repeat them)."""
    a, b = PHASES[k]
    keys = np.flatnonzero((frac >= a - 1e-9) & (frac <= b + 1e-9))
    u = (placing_clock if lifted and k == len(PHASES) - 1 else minimum_jerk)(tau)
    along = (frac[keys] - a) / (b - a)
    if len(keys) > 2:
        if curves is None:
            return pchip(along, q[keys])(u)
        curve = memo(curves, (k, array_key(frac), array_key(q)),
                     lambda: pchip(along, q[keys]), SHARES_KEPT)  # fmt: skip
        return curve(u)  # type: ignore[no-any-return]
    return q[keys[0]] + u[:, None] * (q[keys[-1]] - q[keys[0]])


def phase_shares(
    frac: FloatArray, q: FloatArray, lifted: bool, speed: FloatArray
) -> tuple[tuple[float, float], ...]:
    """Each phase's window (shares of the stroke's time) so that no joint turns faster than
    ``speed`` (per dof, rad/s times the stroke's time: a share's least length) where the
    stroke's time allows it. Each phase first gets the time its fastest joint needs, and the
    time left over is shared as ``PHASES`` share it; short of time, the needs are scaled down
    together. With MTM's 0.54 s for a 60 deg stroke and fixed shares (swing 50 %, return 40 %),
    a small woman's return (lift, swing back, re-seat) bent the elbow 33 deg in 3 frames while
    the swing's joints went at half that speed."""
    tau = np.linspace(0.0, 1.0, NEED_SAMPLES)
    need = np.empty(len(PHASES))
    for k in range(len(PHASES)):
        path = _phase_path(frac, q, k, lifted, tau)
        rate = np.abs(np.diff(path, axis=0)) / np.diff(tau)[:, None]  # rad per unit of tau
        need[k] = float((rate / speed).max()) if len(rate) else 0.0
    nominal = np.array([b - a for a, b in PHASES])
    spare = 1.0 - need.sum()
    shares = need + spare * nominal if spare >= 0.0 else need / need.sum()
    edges = np.concatenate([[0.0], np.cumsum(shares)])
    edges[-1] = 1.0
    return tuple((float(edges[k]), float(edges[k + 1])) for k in range(len(PHASES)))


SHARES_KEPT = 4096  # strokes' phase windows a compile remembers


def _stroke_shares(
    cache: dict[str, Any], frac: FloatArray, q: FloatArray, lifted: bool, speed: FloatArray
) -> tuple[tuple[float, float], ...]:
    """``phase_shares``, once per compile for the exact same stroke: the middle strokes of a
    series repeat their keys and time (a 90 rad turn is 86 strokes of one solved stroke)."""
    return memo(  # type: ignore[no-any-return]
        cache.setdefault("passes.tool.shares", {}),
        (array_key(frac), array_key(q), lifted, array_key(speed)),
        lambda: phase_shares(frac, q, lifted, speed), SHARES_KEPT,
    )  # fmt: skip


def paced_stroke(
    frac: FloatArray,
    q: FloatArray,
    start: float,
    end: float,
    lifted: bool,
    windows: tuple[tuple[float, float], ...] = PHASES,
    curves: dict[Any, Any] | None = None,
) -> tuple[FloatArray, FloatArray]:
    """Dense keyframes (times, (N, D) poses) of a stroke whose keys ``q`` sit at ``frac``: each
    phase (seat, swing, return) one movement from rest to rest, in its window of the stroke's
    time (``windows``, shares; ``phase_shares``). The seat, the swing and a ratchet's return
    progress along the hand's path (the keys' fractions inside the phase) by the minimum-jerk
    profile; a wrench's ``lifted`` return runs its arch (already a bell in its own parameter)
    on a placing clock (``mtlc.passes.profile.placing_clock``), so the tool comes back onto the
    fastener slowly. Keys every internal frame: interpolation cannot undo that. ``curves``:
    the phases' PCHIP curves built so far (``_phase_path``)."""
    times, poses = [np.array([start])], [q[:1]]
    for k, (a, b) in enumerate(windows):
        t0, t1 = start + (end - start) * a, start + (end - start) * b
        grid = np.arange(np.ceil(t0 * INTERNAL_FPS - 1e-9), np.floor(t1 * INTERNAL_FPS + 1e-9) + 1)
        t = np.unique(np.round(np.r_[grid / INTERNAL_FPS, t1], 9))
        t = t[t > t0 + 1e-9]
        times.append(t)
        poses.append(_phase_path(frac, q, k, lifted, (t - t0) / (t1 - t0), curves))
    return np.concatenate(times), np.concatenate(poses)


def key_times(frac: FloatArray, lifted: bool) -> FloatArray:
    """(K,) share of the stroke's time at which ``paced_stroke`` passes each key: the inverse
    of each phase's progress profile at the key's place in the phase."""
    out = np.zeros(len(frac))
    grid = np.linspace(0.0, 1.0, 2001)
    for k, (a, b) in enumerate(PHASES):
        keys = np.flatnonzero((frac >= a - 1e-9) & (frac <= b + 1e-9))
        u = (placing_clock if lifted and k == len(PHASES) - 1 else minimum_jerk)(grid)
        out[keys] = a + (b - a) * np.interp((frac[keys] - a) / (b - a), u, grid)
    return out


def _solve_keys(
    state: PoseState,
    seg: Segment,
    hands: FloatArray,
    tips: FloatArray,
    q0: FloatArray,
    root: tuple[FloatArray, FloatArray],
    clock: FloatArray,
    first: str = "arm",
    trunk: FloatArray | None = None,
    solves: Solves | None = None,
) -> tuple[FloatArray, str, FloatArray, FloatArray | None]:
    """(K, D) poses putting the grip on ``hands`` and the tip on ``tips``, solved as a chain
    (``_chain``) and evened out in time (``_even_out``; ``clock`` the keys' times); the arm
    first, else on one still trunk (``_frozen_trunk``, reach ``girdle``: a mechanic keeps the
    trunk still and swings the wrench with the arm; solved with the torso at every key, the
    trunk pumped 15 deg with every stroke) where the clavicle and arm on it reach every key,
    else the torso at every key (``first``: the series' strokes so far went with the torso,
    so this one starts and ends on their pose; ``trunk``: the still trunk its strokes share).
    Also the reach, the tip's distance per keyframe and the series' still trunk."""
    sites = [f"{seg.goal.effector[0]}_hand", seg.goal.effector]

    def solved(start: FloatArray, reach: str) -> tuple[FloatArray, FloatArray]:
        q = _chain(state, sites, hands, tips, start, root, reach, solves=solves)
        assert q is not None  # (only a chain ``until_short`` stops)
        q[-1] = q[1]  # the stroke ends on the pose it swings from: the same goals
        q[1:] = _even_out(state, sites, hands[1:], tips[1:], q[1:], root, reach, clock[1:],
                          solves)  # fmt: skip
        return q, _errors(state, q, root, sites, [hands, tips])

    def girdle(start: FloatArray) -> FloatArray | None:
        """The keys solved on the still trunk of ``start``, if every key may be reached: a
        key beyond the girdle chain's reach cannot be (its solution would be dropped)."""
        if _beyond_girdle(state, sites, hands, tips, start, root):
            return None
        q, err = solved(start, "girdle")
        return q if err.max() <= TOLERANCE else None

    if trunk is not None:
        q = girdle(_with_trunk(state, q0, trunk))
        if q is not None:
            return _answer(state, seg, tips, root, q, "girdle", trunk)
    tried: dict[str, tuple[FloatArray, FloatArray]] = {}
    best, reach = None, "arm"
    for r in (first, "torso" if first == "arm" else "arm"):
        q, err = tried[r] = solved(q0, r)
        if best is None or err.max() < best[1].max() - 1e-6:
            best, reach = (q, err), r
        if best[1].max() <= TOLERANCE:
            break
    assert best is not None
    if trunk is None and reach == "torso" and "arm" in tried:
        idx = state.skel.dofs_of_joints(TRUNK_JOINTS)

        def reaches(t: FloatArray) -> bool:
            q = _chain(state, sites, hands, tips, _with_trunk(state, q0, t), root, "girdle",
                       until_short=True, solves=solves)  # fmt: skip
            if q is None:
                return False
            reached = _errors(state, q, root, sites, [hands, tips]).max() <= TOLERANCE
            return bool(reached and _off_stops(state, q, seg.goal.effector[0]))

        lean = tried["torso"][0][int(np.argmax(tried["arm"][1])), idx]
        still = _frozen_trunk(reaches, q0, idx, lean)
        q = girdle(_with_trunk(state, q0, still))
        if q is not None:
            return _answer(state, seg, tips, root, q, "girdle", still)
    return _answer(state, seg, tips, root, best[0], reach, None)


BEYOND_MARGIN = 1e-6  # m past the tolerance: the trunk's last bits moving in ``_even_out``


def _beyond_girdle(
    state: PoseState, sites: list[str], hands: FloatArray, tips: FloatArray, start: FloatArray,
    root: tuple[FloatArray, FloatArray],
) -> bool:  # fmt: skip
    """Whether some key's grip or tip is further from the clavicle than the arm and the tool
    laid end to end, past ``TOLERANCE``: no pose on ``start``'s still trunk reaches it, so the
    girdle's solve (a chain and ``EVEN_ROUNDS`` rounds, a quarter of a stroke's solve on a
    fastener out of reach) would be dropped. False where the scalar chain does not apply."""
    model = prepare(state.skel, sites, start[None], reach="girdle", root_position=root[0][None],
                    root_rotation=root[1][None])  # fmt: skip
    scalar = _scalar_chain(state.skel, model, root)
    if scalar is None:
        return False
    targets = np.concatenate([hands, tips], axis=1)
    return any(scalar.beyond(t, TOLERANCE + BEYOND_MARGIN) for t in targets)


def _answer(
    state: PoseState, seg: Segment, tips: FloatArray, root: Any, q: FloatArray, reach: str,
    trunk: FloatArray | None,
) -> tuple[FloatArray, str, FloatArray, FloatArray | None]:  # fmt: skip
    """A solution as ``_solve_keys`` returns it, with the tip's distance per keyframe."""
    return q, reach, _errors(state, q, root, [seg.goal.effector], [tips]), trunk


TRUNK_JOINTS = ("lumbar", "thorax")  # held still through a fastener's strokes


def _with_trunk(state: PoseState, q: FloatArray, trunk: FloatArray) -> FloatArray:
    """``q`` with the trunk's dofs set to ``trunk``."""
    out = q.copy()
    out[state.skel.dofs_of_joints(TRUNK_JOINTS)] = trunk
    return out


TRUNK_HALVINGS = 3  # bisections of the way from the reach pose's trunk to the leaning one


STOP_MARGIN = math.radians(2.0)  # a reaching arm's girdle, shoulder and elbow this off stops


def _off_stops(state: PoseState, q: FloatArray, side: str) -> bool:
    """Whether keys ``q`` keep the clavicle, shoulder and elbow off their stops (the wrist
    turns to its stops: the forearm's roll takes the rest). Leaned in just enough for the tip to
    reach, the arm swung at its stops and the tip left the bolt by 11 mm between the keys."""
    skel = state.skel
    idx = skel.dofs_of_joints([f"{side}_clavicle", f"{side}_shoulder", f"{side}_elbow"])
    lo, hi = skel.lower[idx] + STOP_MARGIN, skel.upper[idx] - STOP_MARGIN
    return bool(np.all((q[:, idx] >= lo) & (q[:, idx] <= hi)))


def _frozen_trunk(
    reaches: Callable[[FloatArray], bool], q0: FloatArray, idx: list[int], lean: FloatArray
) -> FloatArray:
    """The trunk a series of strokes keeps still: the least part of the way from the reach
    pose's trunk to ``lean`` (the torso-chained solution's trunk at the key the arm alone misses
    most) with which the arm reaches every key (``reaches``), found by bisection; so the trunk
    leans in once, no further than it must, and stays."""
    lo, hi = 0.0, 1.0
    for _ in range(TRUNK_HALVINGS):
        mid = 0.5 * (lo + hi)
        if reaches(q0[idx] + mid * (lean - q0[idx])):
            hi = mid
        else:
            lo = mid
    return q0[idx] + hi * (lean - q0[idx])


REMEMBER_SOLVES = True  # tests turn it off to check the remembered solves equal fresh ones
SOLVES_REMEMBERED = 20_000  # keys' and rows' solves a compile remembers (~1 KB each)


@dataclasses.dataclass
class Solves:
    """The key and row solves of a compile's strokes by their exact question (``_chain``'s
    keys, ``_even_out``'s rows). A loop that turns the same fastener again after the other
    hand moved (``for x in [s0, s1] { carry(right, x) turn_fastener(left, ...) }``) asks
    every question again with another pose of the other arm, which no solve reads: a key's
    or a row's solve reads only the dofs of the joints from the root to its sites (the
    chain's frames, ``forward_part``) and its own arguments, and each row's solve is its own
    arithmetic (the same numbers alone or in a batch). What it does not read (the other
    limbs' angles) is carried over from the question's pose, as the solvers carry it."""

    skel: Skeleton  # kept alive: the keys hold its id
    keys: dict[Any, tuple[ChainSolve, dict[int, tuple[list[float], float]]]] = dataclasses.field(
        default_factory=dict
    )
    rows: dict[Any, FloatArray] = dataclasses.field(default_factory=dict)

    paths: dict[tuple[str, ...], list[int]] = dataclasses.field(default_factory=dict)

    def path_dofs(self, sites: list[str]) -> list[int]:
        """The dofs of the joints from the root to the sites' joints (all a solve reads)."""
        found = self.paths.get(tuple(sites))
        if found is None:
            found = self.paths[tuple(sites)] = self._path_dofs(sites)
        return found

    def _path_dofs(self, sites: list[str]) -> list[int]:
        skel, dofs = self.skel, set()
        for site in sites:
            j = skel.joint_index(skel.site(site).joint)
            while j >= 0:
                s = int(skel.joint_dof_start[j])
                dofs.update(range(s, s + int(skel.joint_dof_count[j])))
                j = int(skel.parent[j])
        return sorted(dofs)

    def keep(self, store: dict[Any, Any]) -> dict[Any, Any]:
        if len(store) >= SOLVES_REMEMBERED:
            store.clear()
        return store


def _solves(cache: dict[str, Any], skel: Skeleton) -> Solves:
    """The compile's ``Solves`` for this skeleton."""
    found: dict[int, Solves] = cache.setdefault("passes.tool.solves", {})
    if id(skel) not in found:
        found[id(skel)] = Solves(skel)
    return found[id(skel)]


def _problem_key(
    reach: str, sites: list[str], root: tuple[FloatArray, FloatArray], model: ChainModel,
    q_path: FloatArray, lower: Any, upper: Any, comfort: Any, *rest: Any,
) -> tuple[Any, ...]:  # fmt: skip
    """The exact key of a chain solve: everything its arithmetic reads."""
    return (
        reach, tuple(sites), tuple(model.sites), array_key(root[0]), array_key(root[1]),
        array_key(model.active), array_key(q_path), array_key(lower), array_key(upper),
        array_key(comfort), *rest,
    )  # fmt: skip


def _chain(
    state: PoseState,
    sites: list[str],
    hands: FloatArray,
    tips: FloatArray,
    q0: FloatArray,
    root: tuple[FloatArray, FloatArray],
    reach: str,
    until_short: bool = False,
    solves: Solves | None = None,
) -> FloatArray | None:
    """(K, D) keyframes solved one after the other, each from the one before (the first from
    ``q0``): a continuation along the stroke's path, so neighbouring keys keep one branch of
    the arm (solved each from the reach pose, a lifted key sometimes took another forearm roll:
    a 40 deg step between two frames). Random restarts are used only where a warm start
    stalls short of the goal, and kept only when they reach it: on a fastener out of reach every
    key is short, and the restarts' slightly nearer poses flipped the shoulder by 175 deg
    between neighbouring keys. ``until_short``: None as soon as a key is short (a question of
    whether every key is reached need not solve the keys after the first that is not)."""
    skel = state.skel
    k = len(hands)
    model = prepare(skel, sites, q0[None], reach=reach, root_position=root[0][None],
                    root_rotation=root[1][None])  # fmt: skip
    out = np.empty((k, len(q0)))
    prev = q0
    scalar = _scalar_chain(skel, model, root)
    for i in range(k):
        goals = [
            Goal(sites[0], position=hands[i : i + 1]),
            Goal(sites[1], position=tips[i : i + 1]),
        ]
        kw = dict(root_position=root[0][None], root_rotation=root[1][None], tol=2e-4)
        targets = np.concatenate([hands[i], tips[i]])
        solve = _key_solver(skel, model, scalar, goals, targets, prev, (solves, reach, root), **kw)
        key_goals = [hands[i : i + 1], tips[i : i + 1]]
        q, fast = solve(0)
        if _short(fast, state, q, root, sites, key_goals):
            reached = False
            # restarts are kept only where they reach: not tried where no pose of the chain
            # can (a fastener metres away: two restarts were 80 % of a stroke's solve)
            if not _out_of_reach(scalar, model, prev, targets):
                q2, fast2 = solve(2)  # goes on from the warm start's stall (the same iterates)
                # most restarts find nothing nearer: the same pose is as short, not measured
                # (a restart short too is no better: another branch)
                if not np.array_equal(q2, q) and not _short(
                    fast2, state, q2, root, sites, key_goals
                ):
                    q, reached = q2, True
            if until_short and not reached:
                return None
        out[i] = prev = q[0]
    return out


SHORT_MARGIN = 1e-7  # m: the scalar chain's distance decides "short" this far from the tolerance


def _short(
    fast: float | None, state: PoseState, q: FloatArray, root: Any, sites: list[str],
    goals: list[FloatArray],
) -> bool:  # fmt: skip
    """Whether a key's pose ``q`` (1, D) is further than ``TOLERANCE`` from its ``goals``: by
    the scalar chain's own distance at the pose (``fast``; Python floats, within 1e-15 m of
    forward kinematics) unless that is within ``SHORT_MARGIN`` of the tolerance, else by
    ``_errors`` (a forward kinematics a key was a tenth of the tool pass's time)."""
    if fast is not None and abs(fast - TOLERANCE) > SHORT_MARGIN:
        return fast > TOLERANCE
    return bool(_errors(state, q, root, sites, goals)[0] > TOLERANCE)


def _scalar_chain(
    skel: Skeleton, model: ChainModel, root: tuple[FloatArray, FloatArray]
) -> ScalarChain | None:
    """``chain_ik``'s scalar chain of a key's problem, or None where it does not apply."""
    try:
        return ScalarChain(skel, model, root)
    except ValueError:
        return None


def _out_of_reach(
    scalar: ScalarChain | None, model: ChainModel, prev: FloatArray, targets: FloatArray
) -> bool:
    """Whether no pose of the key's chain reaches ``targets`` within ``TOLERANCE``: known where
    the scalar chain describes ``prev``'s body (``_key_solver``'s condition), else not."""
    if scalar is None or not np.array_equal(prev[model.baked], model.q_base[0, model.baked]):
        return False
    return scalar.beyond(targets, TOLERANCE)


def _row_chain(
    skel: Skeleton, model: ChainModel, root: tuple[FloatArray, FloatArray]
) -> RowChain | None:
    """``chain_ik``'s row chain of the keys' problem, or None where it does not apply."""
    try:
        return RowChain(skel, model, root)
    except ValueError:
        return None


def _key_solver(
    skel: Skeleton, model: ChainModel, scalar: ScalarChain | None, goals: list[Goal],
    targets: FloatArray, prev: FloatArray, asked: tuple[Solves | None, str, Any] | None = None,
    **kw: Any,
) -> Callable[[int], tuple[FloatArray, float | None]]:  # fmt: skip
    """A key's solve as a function of its restarts: (1, D) ``solve_ta(skel, goals, prev[None],
    restarts=restarts, **kw).q``, by the scalar chain when the model describes ``prev``'s body
    (``solve_ta`` would rebuild it otherwise), which a call with more restarts resumes where
    the last one stopped instead of repeating its warm-started attempt; and the scalar
    chain's largest distance of the sites to their goals there (None on the general path)."""
    if scalar is None or not np.array_equal(prev[model.baked], model.q_base[0, model.baked]):
        return lambda restarts: (solve_ta(skel, goals, prev[None], model=model,
                                          restarts=restarts, **kw).q, None)  # fmt: skip
    act = model.active

    def fresh() -> ChainSolve:
        return ChainSolve(scalar, targets.tolist(), prev[act], model.lower, model.upper,
                          skel.q_comfort[act], tol=kw["tol"])  # fmt: skip

    solves, reach, root = asked if asked is not None else (None, "", None)
    if solves is None:
        solver = fresh()
        runs: dict[int, tuple[list[float], float]] = {}
    else:  # the scalar chain reads the base pose's path, the key's start its active angles
        path = solves.path_dofs(list(model.sites))
        key = _problem_key(reach, list(model.sites), root, model, model.q_base[0, path],
                           model.lower, model.upper, skel.q_comfort[act], array_key(targets),
                           array_key(prev[act]), kw["tol"])  # fmt: skip
        solver, runs = memo(solves.keys, key, lambda: (fresh(), {}), SOLVES_REMEMBERED)

    def solve(restarts: int) -> tuple[FloatArray, float | None]:
        nonlocal solver
        if restarts not in runs:
            if any(r > restarts for r in runs):  # a run resumes: it cannot go back
                solver = fresh()
            runs[restarts] = (list(solver.run(restarts)), solver.best_err)
        q = prev[None].copy()
        q[0, act] = runs[restarts][0]
        return q, runs[restarts][1]

    return solve


EVEN_ROUNDS = 24  # rounds of smoothing the chained keys' joint path and putting them back


def _even_out(
    state: PoseState,
    sites: list[str],
    hands: FloatArray,
    tips: FloatArray,
    q: FloatArray,
    root: tuple[FloatArray, FloatArray],
    reach: str,
    clock: FloatArray,
    solves: Solves | None = None,
) -> FloatArray:
    """The chained keys with their joint path evened out in time: each round moves every
    inner key halfway to where its neighbours would put it at its time (``clock``: moving at
    one speed from one to the other) and solves it back onto its goals from there (the arm's
    spare freedom), so the joints tend to one speed over the stroke (the least integral of
    squared joint speed). A chain takes the nearest solution at each key, so a wrist that meets its
    stop hands the rest of the turn to the forearm's roll in one or two keys (15 deg between
    keys 5 deg of arc apart, 29 deg between frames at the swing's peak speed); evened out, the
    roll is spread over the swing. A key that would end further from its goals than before
    (or than the tolerance) keeps its pose. The first and last keys stay. A round that moves
    no key ends the rounds: those left would repeat it (the same guesses, the same poses)."""
    skel, k = state.skel, len(q)
    if k < 3:
        return q
    inner = slice(1, k - 1)
    goals = [Goal(sites[0], position=hands[inner]), Goal(sites[1], position=tips[inner])]
    rp, rr = np.tile(root[0], (k - 2, 1)), np.tile(root[1], (k - 2, 1))
    model = prepare(skel, sites, q[inner], reach=reach, root_position=rp, root_rotation=rr)
    rows = _row_chain(skel, model, root)
    targets = np.concatenate([hands[inner], tips[inner]], axis=1)
    err = _errors(state, q[inner], root, sites, [hands[inner], tips[inner]])
    q = q.copy()
    gap = np.maximum(np.diff(clock), 1e-9)
    after = (gap[:-1] / (gap[:-1] + gap[1:]))[:, None]  # share of the way from key i-1 to i+1
    last: tuple[FloatArray, FloatArray, FloatArray] | None = None  # guess, moved, new_err
    for _ in range(EVEN_ROUNDS):
        guess = 0.5 * q[inner] + 0.5 * ((1.0 - after) * q[:-2] + after * q[2:])
        if rows is None:
            moved = solve_ta(skel, goals, guess, model=model, restarts=0, null_gain=0.0,
                             tol=2e-4, root_position=rp, root_rotation=rr).q  # fmt: skip
            new_err = _errors(state, moved, root, sites, [hands[inner], tips[inner]])
        else:  # the same poses (``chain_ik``), without the general path's overhead
            # a key whose guess is the last round's, to the bit, is solved as it was then
            # (each row's solve is its own arithmetic): only the keys whose neighbourhood
            # moved are solved again (a key out of reach is never taken: its guess repeats)
            ask = np.arange(k - 2) if last is None else np.flatnonzero(
                bits_differ(guess, last[0]).any(axis=1))  # fmt: skip
            moved = np.empty_like(guess) if last is None else last[1].copy()
            new_err = np.empty(k - 2) if last is None else last[2].copy()
            if ask.size:
                moved[ask] = _rows_solved(solves, rows, targets[ask], guess[ask], model,
                                          (reach, sites, root))  # fmt: skip
                new_err[ask] = _errors(state, moved[ask], root, sites,
                                       [hands[inner][ask], tips[inner][ask]])  # fmt: skip
            last = (guess, moved.copy(), new_err.copy())
        ok = (new_err <= np.maximum(err, TOLERANCE) + 1e-9) & skel.within_limits(moved)
        was_q, was_err = q[inner].copy(), err
        q[inner][ok] = moved[ok]
        err = np.where(ok, new_err, err)
        if _unmoved(was_q, q[inner], was_err, err):
            break  # a fixed point: every round left would start from this one's poses again
    return q


def _rows_solved(
    solves: Solves | None, chain: RowChain, targets: FloatArray, guess: FloatArray,
    model: ChainModel, problem: tuple[str, list[str], tuple[FloatArray, FloatArray]],
) -> FloatArray:  # fmt: skip
    """``solve_rows`` of ``_even_out``'s rows, each row asked once per compile (``Solves``):
    the rows solved before are looked up, the others solved together."""
    comfort = model.skel.q_comfort[model.active]

    def solve(idx: Any) -> FloatArray:
        return solve_rows(chain, targets[idx], guess[idx], model.lower, model.upper, comfort,
                          tol=2e-4, null_gain=0.0)  # fmt: skip

    if solves is None:
        return solve(slice(None))
    reach, sites, root = problem
    act, path = model.active, solves.path_dofs(sites)
    base = _problem_key(reach, sites, root, model, None, model.lower, model.upper, comfort)
    keys = [(base, array_key(t), array_key(g[path])) for t, g in zip(targets, guess, strict=True)]
    out = guess.copy()
    miss = [i for i, k in enumerate(keys) if k not in solves.rows]
    hit = [i for i, k in enumerate(keys) if k in solves.rows]
    for i in hit:
        out[i, act] = solves.rows[keys[i]]
    if miss:
        out[miss] = solve(miss)
        store = solves.keep(solves.rows)
        for i in miss:
            store[keys[i]] = out[i, act].copy()
    return out


def _unmoved(q0: FloatArray, q1: FloatArray, err0: FloatArray, err1: FloatArray) -> bool:
    """Whether a round of ``_even_out`` left its keys' poses and errors as they were."""
    return bool(np.array_equal(q0, q1) and np.array_equal(err0, err1))


def _errors(
    state: PoseState, q: FloatArray, root: Any, sites: list[str], targets: list[FloatArray]
) -> FloatArray:
    """(K,) largest distance of the sites to their targets for each pose (the chains to the
    sites alone: ``forward_part``'s numbers are ``forward``'s)."""
    k = len(q)
    rp, rr = np.tile(root[0], (k, 1)), np.tile(root[1], (k, 1))
    pts = part_site_positions(state.skel, q, rp, rr, sites).reshape(k, len(sites), 3)
    return np.linalg.norm(pts - np.stack(targets, axis=1), axis=-1).max(axis=1)


@dataclasses.dataclass(frozen=True)
class StrokeSolution:
    """One stroke's solved keyframes (a chain from the series' reach pose), shared
    by the strokes of a series that repeat it: same fastener, tool, angle, reach pose and root."""

    q: FloatArray  # (K, D)
    reach: str
    tip_error: FloatArray  # (K,) m
    frac: FloatArray  # (K,) share of the stroke's time
    lift: FloatArray  # (K,) 0 engaged, 1 lifted off
    tips: FloatArray  # (K, 3) where the tip is put


@dataclasses.dataclass
class Series:
    """A fastener's strokes so far: the arc angle and pose the reach left, and the solved
    strokes by their key (so the 18 strokes of 3 turns at 60 deg cost one solve)."""

    theta_start: float
    q_reached: FloatArray
    root: tuple[FloatArray, FloatArray]  # the strokes' root: the arms and trunk leave it put
    solved: dict[tuple[Any, ...], StrokeSolution] = dataclasses.field(default_factory=dict)
    previous: Segment | None = None  # the stroke before, whose last keyframe this one starts at
    tip_errors: dict[bytes, float] = dataclasses.field(default_factory=dict)  # by pose
    trunk: FloatArray | None = None  # the lumbar and thorax dofs its strokes keep still


def _start_pose(state: PoseState, seg: Segment, run: Series) -> FloatArray:
    """The pose a stroke starts from: the state's, the stroke before ending where it starts.
    (The strokes are not added to the state one by one: indexing 18 strokes' keyframes cost
    more than solving them.)"""
    q = state.q_at(seg.start)
    prev = run.previous
    if prev is not None and prev.keyframes is not None and abs(prev.end - seg.start) <= 1e-9:
        q[[state.skel.dof_index(n) for n in prev.keyframes.dofs]] = prev.keyframes.q[-1]
    return q


def _tip_error(state: PoseState, run: Series, seg: Segment, q: FloatArray) -> float:
    """The tip's distance to the fastener in pose ``q`` (remembered: the poses repeat)."""
    key = q.tobytes()
    if key not in run.tip_errors:
        tip = np.asarray(seg.goal.position, float)[None]
        run.tip_errors[key] = float(
            _errors(state, q[None], run.root, [seg.goal.effector], [tip])[0]
        )
    return run.tip_errors[key]


REUSE_STROKES = True  # tests turn it off to check the reused strokes equal the solved ones


def _series(state: PoseState, seg: Segment, series: dict[Any, Series]) -> Series:
    """The stroke's series, started at its first stroke from the pose the reach left."""
    g = seg.goal
    key = (seg.track, g.site, seg.provenance.origin)
    if g.params["stroke"] == 1 or key not in series:
        q0 = state.q_at(seg.start)
        root = state.root_at(seg.start)
        hand_now = state.site(f"{g.effector[0]}_hand", q0, root)
        theta = arc_angle(np.asarray(g.position, float), g.params["normal"], hand_now)
        series[key] = Series(theta, q0, root)
    return series[key]


def _solve_stroke_keys(
    cache: dict[str, Any], state: PoseState, seg: Segment, run: Series
) -> StrokeSolution:
    """Solve a stroke's keyframes (the grip on the arc, the tip on the fastener) as a chain
    from the series' reach pose, or reuse the solution of an identical stroke of the series."""
    g = seg.goal
    tool = g.params["tool"]
    turn = -float(g.params["angle"])  # twist angles loosen when negative: positive about n
    key = (g.effector, round(turn, 9))  # the last stroke takes the rest: float noise
    if REUSE_STROKES and key in run.solved:
        return run.solved[key]
    site = np.asarray(g.position, float)
    normal = g.params["normal"]
    frac, theta, lift = stroke_plan(
        run.theta_start, turn, tool.get("kind") == "ratchet", radius(tool)
    )
    n = plane_basis(normal)[0]
    hands = arc_points(site, normal, radius(tool), theta, axial_offset(tool))
    hands = hands + LIFT * lift[:, None] * n
    tips = site + LIFT * lift[:, None] * n
    clock = key_times(frac, bool(lift.max() > 0))
    first = "arm" if next((s.reach for s in run.solved.values()), "arm") == "arm" else "torso"
    args = (hands, tips, run.q_reached, run.root, clock, first, run.trunk)
    q, reach, tip_err, trunk = _keys_solved(cache, state, seg, *args)
    run.trunk = run.trunk if trunk is None else trunk
    q, tip_err = _closed(q, tip_err, frac, lift)
    run.solved[key] = StrokeSolution(q, reach, tip_err, frac, lift, tips)
    return run.solved[key]


def _keys_solved(
    cache: dict[str, Any], state: PoseState, seg: Segment, hands: FloatArray, tips: FloatArray,
    q0: FloatArray, root: tuple[FloatArray, FloatArray], clock: FloatArray, first: str,
    trunk: FloatArray | None,
) -> tuple[FloatArray, str, FloatArray, FloatArray | None]:  # fmt: skip
    """``_solve_keys``, solved once per compile: a loop that screws the same fastener again
    from the same reach pose (``for x in [s1, s1]``, ``repeat 3``) starts a new series with the
    same question, and the solve is deterministic (fuzz cases spent 0.7 s on each of four
    identical series). The key is exact: every input's bytes, the skeleton's identity (the
    entry keeps it alive) and the effector, all ``_solve_keys`` reads of ``state`` and ``seg``."""
    key = (
        id(state.skel), seg.goal.effector, array_key(hands), array_key(tips), array_key(q0),
        array_key(root[0]), array_key(root[1]), array_key(clock), first, array_key(trunk),
    )  # fmt: skip
    return remembered(  # type: ignore[no-any-return]
        cache, "passes.tool.keys", key,
        lambda: _solve_keys(state, seg, hands, tips, q0, root, clock, first, trunk,
                            _solves(cache, state.skel) if REMEMBER_SOLVES else None),
        state.skel,
    )  # fmt: skip


def _closed(
    q: FloatArray, tip_err: FloatArray, frac: FloatArray, lift: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """A ratchet's return is its swing's keys reversed (the chain closes the loop on its own:
    its last key is the swing's first)."""
    if lift.max() > 0:
        return q, tip_err
    q, tip_err = q.copy(), tip_err.copy()
    back = np.flatnonzero(frac > SWING_SHARE + 1e-9)
    swing = np.flatnonzero((frac >= SEAT_SHARE - 1e-9) & (frac <= SWING_SHARE + 1e-9))
    q[back], tip_err[back] = q[swing[::-1][1:]], tip_err[swing[::-1][1:]]
    return q, tip_err


def _bent(
    state: PoseState,
    seg: Segment,
    run: Series,
    sol: StrokeSolution,
    delta: FloatArray,
    keys: FloatArray,
    weight: FloatArray,
) -> tuple[FloatArray, FloatArray]:
    """The solved ``keys`` moved by ``weight`` × ``delta`` (a difference of poses) and solved
    back onto their tip positions from there (the hand free): the blend to or from another
    pose with the tip kept on its path. Blended in joint angles alone, the tip left the
    fastener by 3 mm as the last return came down (contact 5.7 cm/s). (len(keys), D) poses
    and the tip's distances."""
    skel = state.skel
    k = len(keys)
    if k == 0:
        return sol.q[keys], sol.tip_error[keys]
    guess = np.clip(sol.q[keys] + weight[:, None] * delta, skel.lower, skel.upper)
    tips = sol.tips[keys]
    rp, rr = np.tile(run.root[0], (k, 1)), np.tile(run.root[1], (k, 1))
    eff = seg.goal.effector
    # a still trunk's stroke blends from or to the reach pose's trunk: the arm alone on the
    # trunk half-way left the tip 11 mm off the bolt; the torso corrects it
    reach = "torso" if sol.reach == "girdle" else sol.reach
    q = solve_ta(skel, [Goal(eff, position=tips)], guess, reach=reach, restarts=0,
                 null_gain=0.0, tol=2e-4, root_position=rp, root_rotation=rr).q  # fmt: skip
    return q, _errors(state, q, run.root, [eff], [tips])


def solve_stroke(ctx: PassContext, state: PoseState, seg: Segment, series: dict) -> None:
    """Keyframes of one stroke (see the module). The first keyframe is the pose the stroke
    starts from (the motion before it is continuous), the last stroke ends at the reach pose
    (the motion after it was solved from there); the rest are the series' solved stroke, timed
    by ``paced_stroke``."""
    g = seg.goal
    run = _series(state, seg, series)
    sol = _solve_stroke_keys(ctx.cache, state, seg, run)
    q = sol.q.copy()
    q[0] = _start_pose(state, seg, run)
    tip_err = sol.tip_error.copy()
    if g.params["stroke"] == 1:
        # from the reach pose (the wrench tilted off the fastener's plane) into the seated
        # one over the seat and the swing: in the seat alone (54 ms) the wrist turned 24 deg
        out = np.flatnonzero((sol.frac > 1e-9) & (sol.frac < SWING_SHARE - 1e-9))
        w = 1.0 - minimum_jerk(sol.frac[out] / SWING_SHARE)
        q[out], tip_err[out] = _bent(state, seg, run, sol, q[0] - sol.q[1], out, w)
    if g.params["stroke"] == g.params["strokes"]:
        # back to the reach pose (the motion after was solved from it), blended in over the
        # return: a jump in its last stretch would be a second movement at the re-seat
        back = np.flatnonzero(sol.frac > SWING_SHARE + 1e-9)
        w = minimum_jerk((sol.frac[back] - SWING_SHARE) / (1.0 - SWING_SHARE))
        q[back[:-1]], tip_err[back[:-1]] = _bent(
            state, seg, run, sol, run.q_reached - sol.q[-1], back[:-1], w[:-1]
        )
        q[-1] = run.q_reached
    tip_err[0], tip_err[-1] = _tip_error(state, run, seg, q[0]), _tip_error(state, run, seg, q[-1])
    # every stroke keys the trunk too, so no trunk angle holds across strokes solved differently
    names = chain_names(state.skel, [g.effector], "torso")
    idx = [state.skel.dof_index(nm) for nm in names]
    lifted = bool(sol.lift.max() > 0)
    speed = np.array([STROKE_TURN_SPEED if any(d in nm for d in TURNING_DOFS)
                      else STROKE_JOINT_SPEED for nm in names]) * (seg.end - seg.start)  # fmt: skip
    windows = _stroke_shares(ctx.cache, sol.frac, q[:, idx], lifted, speed)
    curves = ctx.cache.setdefault("passes.tool.curves", {})
    times, poses = paced_stroke(sol.frac, q[:, idx], seg.start, seg.end, lifted, windows, curves)
    # a dof at its stop stays there (the last stroke's blend to the reach pose pushed one past)
    poses = np.clip(poses, state.skel.lower[idx], state.skel.upper[idx])
    seg.keyframes = Keyframes(time=times, dofs=names, q=poses)
    worst = float(tip_err[sol.lift == 0].max())
    seg.result = {
        "distance": float(tip_err[-1]),
        "success": bool(worst <= TOLERANCE and state.skel.within_limits(q[-1])),
        "reach": sol.reach,
        "radius": radius(g.params["tool"]),
        "swing": abs(float(g.params["angle"])),
        "keyframes": len(sol.frac),
        "tip_error_max": worst,
        # the stroke's movements (bench/human.py judges each): settle, swing, return
        "phases": {
            name: [seg.start + (seg.end - seg.start) * a, seg.start + (seg.end - seg.start) * b]
            for name, (a, b) in zip(("seat", "swing", "return"), windows, strict=True)
        },
    }
    if worst > TOLERANCE:
        report_short(ctx, seg, worst)
    run.previous = seg


# ------------------------------------------------------------------ axial twists
TWIST_STEP = math.radians(5.0)  # at most this much turn between a twist's keyframes


def is_axial_twist(seg: Segment) -> bool:
    """A forearm twist made with a screwdriver or pliers."""
    tool = seg.goal.params.get("tool")
    return (
        seg.goal.params.get("posture") == "twist"
        and isinstance(tool, dict)
        and tool.get("kind") in AXIAL_KINDS
    )


def _reach_before(ir: MotionIR, seg: Segment) -> Segment | None:
    """The TO that put this twist's tool on its fastener: the hand's latest before the twist."""
    side = seg.goal.effector[0]
    tos = [
        s
        for s in ir.segments
        if s.kind == "TO"
        and s.goal.effector[:1] == side
        and s.end <= seg.start + 1e-9
        and axis_goals(ir.skeleton, s, np.asarray(s.goal.position, float))  # type: ignore[arg-type]
    ]
    return max(tos, key=lambda s: s.end, default=None)


def rotation_about(axis: FloatArray, angle: FloatArray) -> FloatArray:
    """(K, 3, 3) rotations by ``angle`` (K,) about the unit ``axis`` (Rodrigues)."""
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    a = np.asarray(angle, float)[:, None, None]
    return np.eye(3) + np.sin(a) * k + (1.0 - np.cos(a)) * (k @ k)


@dataclasses.dataclass(frozen=True)
class RollPath:
    """The arm's poses that keep a screwdriver on its screw while the hand rolls about the
    screw's axis, from one stop to the other: ``roll`` (P,) rad about the axis from the reach
    pose, increasing; ``q`` (P, D) the poses. A twist moves along it (``regrip_plan``)."""

    roll: FloatArray
    q: FloatArray

    def at(self, theta: FloatArray) -> FloatArray:
        """(K, D) poses at rolls ``theta`` (K,), interpolated between the solved ones."""
        th = np.clip(np.asarray(theta, float), self.roll[0], self.roll[-1])
        i = np.clip(np.searchsorted(self.roll, th) - 1, 0, max(len(self.roll) - 2, 0))
        j = np.minimum(i + 1, len(self.roll) - 1)
        span = np.where(j > i, self.roll[j] - self.roll[i], 1.0)
        w = np.where(j > i, (th - self.roll[i]) / span, 0.0)[:, None]
        return (1.0 - w) * self.q[i] + w * self.q[j]


ROLL_STALL = math.radians(1.0)  # a step that rolls the hand less than this: the joints' stop
AXIS_TOLERANCE = math.radians(2.0)  # the tool's axis may leave the screw's by this much
MAX_ROLL = math.pi  # the hand is not rolled further than this either way
MIN_BITE = math.radians(30.0)  # a smaller turn than this is made after winding the wrist back
MAX_GRIPS = 4  # grips per twist at most: a hand that rolls < 22.5 deg is reported short
RETURN_PACE = 2.0  # the released hand rolls back this many times faster than it turns
MID_TIP_ERROR = 5e-4  # m: a path step whose middle leaves the screw by more is halved


def _twist_problem(skel: Skeleton, reach: Segment) -> tuple[str, str, FloatArray, FloatArray, Goal]:
    """(hand, tool tip site, screw position, unit screw normal, grip-on-axis goal)."""
    side = reach.goal.effector[0]
    site = np.asarray(reach.goal.position, float)
    n = np.asarray(reach.goal.params["normal"], float)
    return (
        f"{side}_hand",
        reach.goal.effector,
        site,
        n / np.linalg.norm(n),
        axis_goals(skel, reach, site)[0],
    )


def _roll_solve(
    skel: Skeleton, reach: Segment, q: FloatArray, root: Any, rot0: FloatArray, theta: FloatArray
) -> FloatArray:
    """(K, D) poses from ``q`` (K, D): tip on the screw, grip on its axis, hand frame rolled by
    ``theta`` (K,) about the axis from ``rot0``."""
    hand, tip_site, site, n, grip = _twist_problem(skel, reach)
    k = len(q)
    goals = [
        Goal(tip_site, position=np.tile(site, (k, 1))),
        Goal(hand, position=np.tile(grip.position, (k, 1)),
             orientation=rotation_about(n, theta) @ rot0, orientation_weight=0.1),
    ]  # fmt: skip
    rp, rr = np.tile(root[0], (k, 1)), np.tile(root[1], (k, 1))
    model = prepare(skel, [tip_site, hand], q, reach="arm", root_position=rp, root_rotation=rr)
    return solve_ta(skel, goals, q, model=model, restarts=0, tol=2e-4).q


def _roll_fit(
    skel: Skeleton, reach: Segment, q: FloatArray, root: Any, rot0: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """(K,) roll about the screw's axis, tip distance to the screw and tool-axis angle of the
    poses ``q`` (K, D)."""
    hand, tip_site, site, n, _ = _twist_problem(skel, reach)
    k = len(q)
    pose = forward(skel, q, np.tile(root[0], (k, 1)), np.tile(root[1], (k, 1)), with_axes=False)
    roll = roll_about(site_rotation(skel, pose, hand) @ rot0.T, n)
    tip = np.asarray(site_positions(skel, pose, tip_site)).reshape(k, 3)
    axis = axis_angle(skel, pose, tip_site, n)
    return roll, np.linalg.norm(tip - site, axis=1), axis


def _roll_walk(
    skel: Skeleton, reach: Segment, q0: FloatArray, root: Any, rot0: FloatArray, sign: float
) -> list[tuple[float, FloatArray]]:
    """Poses rolling the hand one way (``sign``) about the axis in ``TWIST_STEP`` steps, each
    solved from the one before, up to the joints' stop: where a step stalls or lets the tip
    or the tool's axis off the screw."""
    out: list[tuple[float, FloatArray]] = []
    q, roll = q0, 0.0
    while abs(roll) < MAX_ROLL - 1e-9:
        target = roll + sign * min(TWIST_STEP, MAX_ROLL - abs(roll))
        nxt = _roll_solve(skel, reach, q[None], root, rot0, np.array([target]))[0]
        got, tip, axis = (float(v[0]) for v in _roll_fit(skel, reach, nxt[None], root, rot0))
        if sign * (got - roll) < ROLL_STALL or tip > TOLERANCE or axis > AXIS_TOLERANCE:
            break
        if not skel.within_limits(nxt):
            break
        out.append((got, nxt))
        q, roll = nxt, got
    return out


def _refine(
    skel: Skeleton, reach: Segment, path: RollPath, root: Any, rot0: FloatArray
) -> RollPath:
    """The path with a solved pose at the middle of every step whose interpolated middle lets
    the tip off the screw by more than ``MID_TIP_ERROR`` (joint-space interpolation between
    poses 5 deg apart drifted 2.5 mm)."""
    if len(path.roll) < 2:
        return path
    mid_q = 0.5 * (path.q[:-1] + path.q[1:])
    mid_roll = 0.5 * (path.roll[:-1] + path.roll[1:])
    _, tip, _ = _roll_fit(skel, reach, mid_q, root, rot0)
    bad = np.flatnonzero(tip > MID_TIP_ERROR)
    if not len(bad):
        return path
    solved = _roll_solve(skel, reach, mid_q[bad], root, rot0, mid_roll[bad])
    got, tip_s, _ = _roll_fit(skel, reach, solved, root, rot0)
    ok = (tip_s <= TOLERANCE) & (got > path.roll[bad]) & (got < path.roll[bad + 1])
    roll = np.concatenate([path.roll, got[ok]])
    order = np.argsort(roll, kind="stable")
    return RollPath(roll[order], np.concatenate([path.q, solved[ok]])[order])


def roll_path(
    skel: Skeleton, reach: Segment, q0: FloatArray, root: Any, rot0: FloatArray
) -> RollPath:
    """The hand's roll about the screw's axis both ways from ``q0`` to the joints' stops."""
    down = _roll_walk(skel, reach, q0, root, rot0, -1.0)[::-1]
    up = _roll_walk(skel, reach, q0, root, rot0, 1.0)
    rolls = np.array([r for r, _ in down] + [0.0] + [r for r, _ in up])
    qs = np.stack([q for _, q in down] + [q0] + [q for _, q in up])
    return _refine(skel, reach, RollPath(rolls, qs), root, rot0)


def regrip_plan(lo: float, hi: float, start: float, turn: float) -> tuple[list[float], list[bool]]:
    """Rolls the hand passes through to turn the screw by ``turn`` (signed) from ``start``,
    within the wrist's range [lo, hi], and for each leg between them whether the hand grips
    (turning the screw) or has let go (rolling back to wind the wrist up again).

    A turn the wrist has room for is made at once; otherwise the hand first rolls back to the
    far stop (people wind the wrist before turning), then turns as far as it can, lets go, rolls
    back and grips again, at most ``MAX_GRIPS`` times (the turn made may fall short)."""
    d = 1.0 if turn >= 0 else -1.0
    end, back = (hi, lo) if d > 0 else (lo, hi)
    points, grips, left = [start], [], abs(turn)
    while left > 1e-9 and sum(grips) < MAX_GRIPS:
        cur = points[-1]
        room = max(d * (end - cur), 0.0)
        wound = abs(cur - back) <= 1e-9
        if room < min(left, MIN_BITE, hi - lo) - 1e-9 and not wound:
            points.append(back)
            grips.append(False)
            continue
        bite = min(room, left)
        if bite <= 1e-9:
            break
        points.append(cur + d * bite)
        grips.append(True)
        left -= bite
    return points, grips


def twist_keys(
    path: RollPath, points: list[float], grips: list[bool]
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """(K,) time fractions, (K,) rolls and (K,) grip flags (1 while the key's leg grips) of a
    twist's keyframes: the plan's turning points and every path pose between them, timed by the
    roll (a released hand rolls back ``RETURN_PACE`` times faster)."""
    rolls, held = [points[0]], [1.0]
    for a, b, grip in zip(points[:-1], points[1:], grips, strict=True):
        lo, hi = min(a, b), max(a, b)
        inner = path.roll[(path.roll > lo + 1e-9) & (path.roll < hi - 1e-9)]
        for r in [*(inner if b > a else inner[::-1]), b]:
            rolls.append(float(r))
            held.append(1.0 if grip else 0.0)
    th = np.asarray(rolls)
    pace = np.where(np.asarray(held[1:]) > 0, 1.0, RETURN_PACE)
    cost = np.concatenate([[0.0], np.cumsum(np.abs(np.diff(th)) / pace)])
    if len(th) < 2 or cost[-1] <= 1e-12:
        return np.array([0.0, 1.0]), np.array([th[0], th[0]]), np.array([1.0, 1.0])
    return cost / cost[-1], th, np.asarray(held)


@dataclasses.dataclass
class TwistRun:
    """A screw's twists so far: the roll path and the roll the last twist left the hand at."""

    path: RollPath
    rot0: FloatArray
    roll: float = 0.0


def _twist_run(state: PoseState, seg: Segment, reach: Segment, runs: dict) -> TwistRun:
    """The screw's path, solved at its first twist from the pose the reach left."""
    skel = state.skel
    key = id(reach)
    if key not in runs:
        q = state.q_at(seg.start, skip=seg)
        root = state.root_at(seg.start)
        hand = f"{reach.goal.effector[0]}_hand"
        rot0 = site_rotation(skel, forward(skel, q[None], root[0][None], root[1][None]), hand)[0]
        runs[key] = TwistRun(roll_path(skel, reach, q, root, rot0), rot0)
    return runs[key]


def solve_axial_twist(ctx: PassContext, state: PoseState, seg: Segment, reach: Segment,
                      runs: dict) -> None:  # fmt: skip
    """Re-solve a screwdriver's twist so the tool turns about the screw's axis by the twist's
    angle (loosening, a negative angle, turns counter-clockwise seen from the front, like a
    wrench): along the screw's roll path (``roll_path``), re-gripping where the wrist's range
    is short of the turn (``regrip_plan``); a turn still short after ``MAX_GRIPS`` grips is
    reported (MT0501)."""
    skel = state.skel
    run = _twist_run(state, seg, reach, runs)
    turn = -float(seg.goal.params["angle"])
    points, grips = regrip_plan(float(run.path.roll[0]), float(run.path.roll[-1]), run.roll, turn)
    frac, rolls, _ = twist_keys(run.path, points, grips)
    qs = run.path.at(rolls)
    names = chain_names(skel, [reach.goal.effector], "arm")
    idx = [skel.dof_index(nm) for nm in names]
    seg.keyframes = Keyframes(time=seg.start + (seg.end - seg.start) * frac, dofs=names,
                              q=qs[:, idx])  # fmt: skip
    turned = float(sum(b - a for a, b, g in zip(points[:-1], points[1:], grips, strict=True) if g))
    run.roll = float(rolls[-1])
    seg.result = {**(seg.result or {}), "angle": turn, "turned": turned,
                  "grips": int(sum(grips))}  # fmt: skip
    if abs(turned - turn) > math.radians(5.0):
        _report_short_turn(ctx, seg, reach, turn, turned)


def _report_short_turn(
    ctx: PassContext, seg: Segment, reach: Segment, turn: float, turned: float
) -> None:
    """MT0501 once per screw: the wrist's range (``MAX_GRIPS`` grips) cannot make the twist's
    turn (the first short twist's numbers; a screw's quarter turns repeat)."""
    done: set[Any] = ctx.cache.setdefault("passes.tool.short_turns", set())
    if id(reach) in done:
        return
    done.add(id(reach))
    tool = seg.goal.params["tool"]["name"]
    ctx.report(
        "MT0501",
        f"the {tool} in the {'right' if reach.goal.effector[0] == 'r' else 'left'} hand cannot "
        f"turn the screw at site `{reach.goal.site}` by {abs(math.degrees(turn)):.0f} deg: "
        f"{abs(math.degrees(turned)):.0f} deg turned in {MAX_GRIPS} grips",
        seg.provenance.origin,
    )


def roll_about(rel: FloatArray, n: FloatArray) -> FloatArray:
    """(K,) signed angle of the rotations ``rel`` (K, 3, 3) about the unit axis ``n``."""
    skew = rel - np.swapaxes(rel, -1, -2)
    vec = 0.5 * np.stack([skew[:, 2, 1], skew[:, 0, 2], skew[:, 1, 0]], axis=-1)
    return np.arctan2(vec @ n, 0.5 * (np.trace(rel, axis1=-2, axis2=-1) - 1.0))


def solve_axial_twists(ir: MotionIR, ctx: PassContext) -> bool:
    """Every screwdriver twist re-solved about its screw's axis, in time order; whether any."""
    from mtlc.passes.state import mark

    twists = sorted((s for s in ir.segments if is_axial_twist(s)), key=lambda s: s.start)
    if not twists:
        return False
    state = PoseState(ir)
    runs: dict[int, TwistRun] = {}
    for seg in twists:
        reach = _reach_before(ir, seg)
        if reach is None:
            continue
        solve_axial_twist(ctx, state, seg, reach, runs)
        mark(ctx.cache, seg)  # from now on: its first keyframe holds the pose before it
    return True


def is_stroke(seg: Segment) -> bool:
    return seg.kind == "TO" and "stroke" in seg.goal.params


def solve(ir: MotionIR, ctx: PassContext) -> MotionIR:
    twisted = solve_axial_twists(ir, ctx)
    strokes = sorted((s for s in ir.segments if is_stroke(s)), key=lambda s: s.start)
    if not strokes:
        if twisted:
            reanchor(ir, ctx.cache, _restaters())
        return ir
    state = PoseState(ir)
    series: dict[Any, Series] = {}
    for seg in strokes:
        solve_stroke(ctx, state, seg, series)
    reanchor(ir, ctx.cache, _restaters())
    return ir
