"""Reaches paced like a person's: one bell of hand speed from the start of the approach to contact.

A point-to-point hand movement minimises the integrated squared jerk (Flash & Hogan 1985, "The
coordination of arm movements: an experimentally confirmed mathematical model", J Neurosci
5(7):1688-1703): along its path the hand's progress follows ``s(tau) = 10 tau^3 - 15 tau^4 +
6 tau^5``, one bell of speed that starts and ends at rest. The solving passes key a reach in two
phases (TA: its start pose, the approach pose and maybe a middle key; TO: up to 12 keys at a
steady pace of progress onto the site), and interpolating those keys in time made two
movements: the hand sped up and slowed down to the approach pose, then crept onto the site.

This pass keeps each reach's path (the poses interpolation makes between the keys, so contact,
the floor and the body clearance keep their meaning) and re-times it as one movement: the TA and
the TO that continues it (same goal, adjacent windows), or a TA or TO alone. Progress is the
effector's arc length plus ``JOINT_WEIGHT`` times the joints' own path length (so a turn of the
wrist with the hand in place still takes time); it follows the minimum-jerk profile over the
movement's whole window, and the reach's keys become dense keys on the internal frame grid, so
interpolation cannot put a plateau back. Movements of the two hands in one window share one
timing (their trunk is one). The TO's last stretch is the slow end of the bell.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from mtlc.body import Pose, forward, forward_part, part_site_positions, site_positions
from mtlc.body.capsules import limbs_of_sides, measured_points, self_intersection
from mtlc.body.ik import Goal, solve_ta
from mtlc.body.kinematics import bits_differ, forward_changed
from mtlc.ir.model import FloatArray, Frames, Keyframes, MotionIR, Segment
from mtlc.ir.pchip import pchip
from mtlc.passes import timewarp
from mtlc.passes.approach import FINGERTIPS
from mtlc.passes.carry import (
    FIX_FROM,
    Carry,
    carries,
    hand_pair,
    keep_rigid,
    part_path,
    solve_along,
    solve_arms,
    solve_smoothed,
)
from mtlc.passes.context import INTERNAL_FPS, PassContext
from mtlc.passes.detour import MARGIN, ArmCapsules, Obstacles, obstacles_of
from mtlc.passes.hold import _arm_dofs as arm_dofs
from mtlc.passes.interpolate import correct_base, interpolate_joints, interpolate_root
from mtlc.passes.profile import JOINT_WEIGHT, bell_ldlj
from mtlc.passes.profile import gaussian_rows as gaussian_rows  # re-exported
from mtlc.passes.profile import minimum_jerk as minimum_jerk  # re-exported
from mtlc.passes.profile import smooth_path as smooth_path  # re-exported
from mtlc.passes.state import PoseState
from mtlc.passes.timewarp import Stretch, TimeWarp
from mtlc.passes.tool import is_stroke

PATH_SAMPLES_PER_S = 480.0  # the old motion is measured this densely to find its arc length
MIN_PATH_SAMPLES = 64
# at most this many (8.5 s at 480 a second): a person's reach lasts a second or two, and a
# reach stretched over a minute and a half by a long hold (a fuzzed procedure's) was measured
# at 44,000 samples, 12 keys apart by 3,700, the pass's whole time; 4,096 still put 340
# samples between two keys of its path
MAX_PATH_SAMPLES = 4096
EPS = 1e-6
PATH_POINTS = 241  # the path, resampled at even steps of progress before it is smoothed
SMOOTH_SIGMA = 0.1  # of the path's progress: the Gaussian that smooths it at the least
# ...and wider where the approach allows it, widest first: a corner the path keeps turns the
# hand at speed, and the jerk of that turn, not the timing, is what scored most reaches of
# generated procedures under LDLJ -7 (on a straight line at the same speeds 69 % of them
# passed, as they were 28 %)
SMOOTH_SIGMAS = (0.25, 0.2, 0.15)
APPROACH_SPARE = 1e-3  # m: a wider smoothing may take an effector this much deeper than 10 %
NORMAL_BAND = 0.05  # m: behind a site's surface counts this close to its normal line
# rad/s: the fastest a reach turns a joint at its bell's peak. Output frames at 30 fps may step
# 12 deg (360 deg/s, issue 19); the passes after this one (balance, smoothing, the carry and
# clearance corrections) add a little, so the reach itself keeps a sixth in hand.
PEAK_JOINT_SPEED = float(np.radians(300.0))
MAX_STRETCH = 3.0  # a movement lasts at most this many times the timeline's time for it
# a part carried in both hands (``_carried``): the last share of the path over which the
# correction goes to nothing where its end already holds the part; how close (m) both hands
# must be to their ends of the part for the point to count as reached
END_BLEND = 0.25
CLEAN_SIGMA = 4.0  # points of ``PATH_POINTS``: the carried path's last low-pass (``_cleaned``)
CLEAN_SPARE = 5e-4  # m: how much further from the part's length the low-passed path may go
REACH_TOL = 2e-3
# a reach's path made again on a curve (``_curved``) where it scores under CURVE_FROM
LDLJ_POINTS = 61  # the minimum-jerk clock's samples its LDLJ is measured on (``bell_ldlj``)
CURVE_FROM = -7.0  # LDLJ: a path that scores this well is left as it is
CURVE_MIN_PATH = 0.01  # m: a hand moving less than this is not made again
CURVE_GAIN = 0.3  # LDLJ: the curve must score this much better to replace the path
CURVE_END_SHARE = 0.15  # of the progress: the way the path arrives is measured over its end
CURVE_HANDLES = (0.5, 0.33, 0.2)  # of the chord: the curve's last control point this far out
CURVE_TOL = 1e-3  # m: every point of the curve solved this close
CURVE_STEP = 0.1  # rad a joint may turn between two of the PATH_POINTS points (no branch jump)
NEED_SAMPLES = 512  # the minimum-jerk clock sampled this densely to find the fastest joint


@dataclass
class Movement:
    """The segments one effector's reach is made of, or several reaches in one window."""

    segments: list[Segment]
    start: float
    end: float

    @property
    def effectors(self) -> list[str]:
        return sorted({s.goal.effector for s in self.segments})

    @property
    def dofs(self) -> list[str]:
        names: list[str] = []
        for s in self.segments:
            for n in s.keyframes.dofs if s.keyframes is not None else ():
                if n not in names:
                    names.append(n)
        return names


def _paced(seg: Segment, sites: set[str]) -> bool:
    kf = seg.keyframes
    return (
        seg.kind in ("TA", "TO")
        and not is_stroke(seg)
        and seg.goal.effector in sites
        and kf is not None
        and len(kf.dofs) > 0
        and len(kf.time) >= 2
        and seg.end - seg.start > EPS
    )


def movements(ir: MotionIR) -> list[Movement]:
    """Each reach (a TA and the TO that continues it, or either alone), reaches of one window
    together."""
    sites = {s.name for s in ir.skeleton.sites}
    segs = sorted((s for s in ir.segments if _paced(s, sites)), key=lambda s: s.start)
    chains: list[list[Segment]] = []
    taken: set[int] = set()
    for seg in segs:
        if id(seg) in taken:
            continue
        chain = [seg]
        taken.add(id(seg))
        if seg.kind == "TA":
            for nxt in segs:
                if (
                    id(nxt) not in taken
                    and nxt.kind == "TO"
                    and nxt.track == seg.track
                    and nxt.goal.effector == seg.goal.effector
                    and nxt.goal.site == seg.goal.site
                    and nxt.provenance.origin == seg.provenance.origin
                    and abs(nxt.start - seg.end) < EPS
                ):
                    chain.append(nxt)
                    taken.add(id(nxt))
                    break
        chains.append(chain)
    windows: dict[tuple[float, float], Movement] = {}
    for chain in chains:
        key = (round(chain[0].start, 6), round(chain[-1].end, 6))
        m = windows.setdefault(key, Movement([], chain[0].start, chain[-1].end))
        m.segments += chain
    keys = dof_keys(ir)
    out = [m for m in windows.values() if not _shares_dofs(ir, m, keys)]
    return sorted(out, key=lambda m: m.start)


# per dof name: every keyframe time that sets it, sorted, and the index of its segment
DofKeys = dict[str, tuple[FloatArray, np.ndarray]]


def dof_keys(ir: MotionIR) -> DofKeys:
    """Every segment's keyframe times by dof, sorted once: which segments key a dof inside a
    window is then two bisections, not a scan of every segment per movement (a procedure of
    200 actions spent a second on that scan)."""
    columns: dict[str, list[tuple[FloatArray, int]]] = {}
    for k, s in enumerate(ir.segments):
        kf = s.keyframes
        if kf is None:
            continue
        t = np.asarray(kf.time, dtype=float)
        for name in dict.fromkeys(kf.dofs):
            columns.setdefault(name, []).append((t, k))
    out: DofKeys = {}
    for name, parts in columns.items():
        t = np.concatenate([p[0] for p in parts])
        owner = np.concatenate([np.full(len(p[0]), p[1], dtype=np.intp) for p in parts])
        order = np.argsort(t, kind="stable")
        out[name] = (t[order], owner[order])
    return out


def _shares_dofs(ir: MotionIR, m: Movement, keys: DofKeys | None = None) -> bool:
    """Another segment keys one of the movement's dofs inside its window: re-timing one of the
    two would tear the curve they make together, so the movement keeps its timing."""
    keys = dof_keys(ir) if keys is None else keys
    own = {id(x) for x in m.segments}
    for name in set(m.dofs):
        t, owner = keys.get(name, (np.zeros(0), np.zeros(0, dtype=np.intp)))
        lo = int(np.searchsorted(t, m.start + EPS, side="right"))  # first key after the start
        hi = int(np.searchsorted(t, m.end - EPS, side="left"))  # first key not before the end
        if any(id(ir.segments[k]) not in own for k in owner[lo:hi].tolist()):
            return True
    return False


def _body(ir: MotionIR, times: FloatArray) -> tuple[FloatArray, Frames]:
    """Joint angles and whole-body frames at ``times`` as interpolation makes them."""
    position, rotation = interpolate_root(ir, times)
    q = interpolate_joints(ir, times)
    frames = Frames(0.0, times, position, rotation, q)
    correct_base(ir, frames)
    return q, frames


def new_times(m: Movement) -> FloatArray:
    """The internal frame grid inside the movement's window, and its segments' ends."""
    k0 = int(np.ceil(m.start * INTERNAL_FPS - 1e-9))
    k1 = int(np.floor(m.end * INTERNAL_FPS + 1e-9))
    ends = [t for s in m.segments for t in (s.start, s.end)]
    return np.unique(np.round(np.r_[ends, np.arange(k0, k1 + 1) / INTERNAL_FPS], 9))


def _frames_at(frames: Frames, times: FloatArray, q: FloatArray | None = None) -> Frames:
    """The body at ``times`` inside ``frames`` (linear between its samples)."""

    def at(v: FloatArray) -> FloatArray:
        return np.stack([np.interp(times, frames.time, v[:, i]) for i in range(v.shape[1])], 1)

    rotation = at(frames.root_rotation)
    rotation /= np.linalg.norm(rotation, axis=1, keepdims=True)
    return Frames(0.0, times, at(frames.root_position), rotation, at(frames.q) if q is None else q)


def progress(
    ir: MotionIR, m: Movement, frames: Frames, at: FloatArray | None = None
) -> tuple[FloatArray, float]:
    """Each sample's share of the movement's progress (rising from 0 to 1) and its length: the
    effectors' arc length plus ``JOINT_WEIGHT`` times the movement's joint path. ``at``: the
    effectors' positions (N, E, 3) at the samples, if already known (``approach_depth``)."""
    skel = ir.skeleton
    # the effectors' chains only (7 joints of 21 for a hand): the same numbers as a whole pose
    p = at if at is not None else part_site_positions(
        skel, frames.q, frames.root_position, frames.root_rotation, m.effectors
    )  # fmt: skip
    idx = [skel.dof_index(n) for n in m.dofs]
    step = np.linalg.norm(np.diff(p, axis=0), axis=-1).sum(axis=1)
    step += JOINT_WEIGHT * np.linalg.norm(np.diff(frames.q[:, idx], axis=0), axis=1)
    total = float(np.sum(step))
    u = np.concatenate([[0.0], np.cumsum(step)]) + np.arange(len(step) + 1) * 1e-12 * total
    return u / u[-1] if u[-1] > 0 else u, total


@dataclass
class ReachPath:
    """A movement's smoothed joint path: its dofs' values at rising shares of its progress."""

    progress: FloatArray  # (P,) from 0 to 1
    q: FloatArray  # (P, len(dofs))
    carried: bool = False  # a part in both hands (``_carried``): may end off the solver's pose

    def at(self, s: FloatArray) -> FloatArray:
        return pchip(self.progress, self.q)(s)


def approach_depth(
    ir: MotionIR, m: Movement, body: Frames, like: tuple[Frames, Pose | None] | None = None
) -> tuple[float, FloatArray, Pose | None]:
    """How far (m) the movement's effectors go behind their sites' surfaces (within
    ``NORMAL_BAND`` of the normal line), their hands' fingertips below the ground, or its arms'
    forearms and hands into the trunk or a thigh: what a wider smoothing must not make worse
    (the approach comes in from the site's side; a corner cut short took a forearm 56 mm into
    a thigh on the fuel filter, male P99). And the effectors' positions (N, E, 3), what
    ``progress`` measures, and the body's pose if it was posed (else None). ``like``: another
    path at the same root and its pose from this function: only the joints below the dofs in
    which the two differ are posed again (``forward_changed``: the same numbers)."""
    skel = ir.skeleton
    effectors = m.effectors
    names = effectors + [FINGERTIPS[e] for e in effectors if e in FINGERTIPS]
    # only the moving arms' limbs are measured (and the body posed only if there are any);
    # the sites from that pose are ``part_site_positions``' numbers, bit for bit
    # (tests/body/test_body_kinematics.py): the arms' chains are not posed a second time
    mine = limbs_of_sides({e[0] for e in effectors})
    pose = None
    if mine:
        was, base = like if like is not None else (body, None)
        if base is not None and _same_root(was, body):
            pose = forward_changed(
                skel, body.q, body.root_position, body.root_rotation, was.q, base
            )
        else:  # the joints the sites and the arms' clearance read, not the whole body
            pose = forward_part(
                skel, body.q, body.root_position, body.root_rotation,
                [*names, *measured_points(skel, mine)],
            )  # fmt: skip
        p = site_positions(skel, pose, names)
    else:
        p = part_site_positions(skel, body.q, body.root_position, body.root_rotation, names)
    deepest = max(0.0, ir.ground - float(p[..., 1].min()))
    if pose is not None:
        deepest = max(deepest, float(self_intersection(skel, pose, mine)[0].max()))
    for seg in m.segments:
        normal = seg.goal.params.get("approach_normal") or seg.goal.params.get("normal")
        if normal is None or seg.goal.position is None:
            continue
        n = np.asarray(normal, dtype=float)
        n = n / max(float(np.linalg.norm(n)), EPS)
        rel = p[:, effectors.index(seg.goal.effector)] - np.asarray(seg.goal.position, float)
        d = rel @ n
        near = np.linalg.norm(rel - d[:, None] * n, axis=1) < NORMAL_BAND
        if near.any():
            deepest = max(deepest, -float(d[near].min()))
    return deepest, p[:, : len(effectors)], pose


def _same_root(a: Frames, b: Frames) -> bool:
    """Whether two paths' roots are the same, bit for bit."""
    return all(
        x is y or (np.shape(x) == np.shape(y) and not bits_differ(x, y).any())
        for x, y in ((a.root_position, b.root_position), (a.root_rotation, b.root_rotation))
    )


def _smoothed(
    ir: MotionIR, m: Movement, body: Frames, idx: list[int], held: Sequence[Carry], sigma: float
) -> Frames:
    """The path ``body`` (at even progress) smoothed by a Gaussian of ``sigma`` of its progress,
    the part held in both hands kept rigid."""
    out = Frames(0.0, body.time, body.root_position, body.root_rotation, body.q.copy())
    width = sigma * (PATH_POINTS - 1)
    out.q[:, idx] = smooth_path(body.q[:, idx], width)
    for carry in held:
        keep_rigid(ir.skeleton, out, carry, width, held=None)
    if held:  # the correction has corners of its own (the solver's): smoothed like the path
        out.q[:, idx] = smooth_path(out.q[:, idx], width)
    return out


def grip_length(ir: MotionIR, carry: Carry) -> float:
    """The hands' distance where both closed on the part: the part's length."""
    _, at = _body(ir, np.array([carry.start]))
    hands = hand_pair(ir.skeleton, at, np.array([0]), at.q)[0]
    return float(np.linalg.norm(hands[0] - hands[1]))


def _carried(
    ir: MotionIR, m: Movement, body: Frames, idx: list[int], carry: Carry, bend: bool = False
) -> Frames:
    """A path on which the part in both hands is rigid by construction: each arm's own path
    (at even progress, smoothed by ``SMOOTH_SIGMA``) says where the part goes, the part's
    path (``carry.part_path``: its centre, its axis turning on one plane, its length the
    grip's) says where each hand goes, and both arms follow it, each point solved on from the
    one before (``carry.solve_along``). Interpolating the two arms' keys each on its own and
    correcting the part frame by frame afterwards squeezed a hood edge lifted overhead by 14 to
    27 cm and flipped a shoulder between IK branches (issue 19).

    Where the path's end already holds the part (both hands on their goals, the grip's length
    apart) the end pose is the solver's: the correction goes to nothing over the last
    ``END_BLEND`` of the path and those points are solved again from there. Where the goal is
    out of reach for the part held rigid, the part stops at the last point both hands reach
    (``REACH_TOL``) and the path is that far (the goal's shortfall is the hands' distance to
    their goals there; verify reports it, MT0501). ``bend``: the part's centre on a curve
    (``_curved_part``)."""
    skel = ir.skeleton
    smooth = _smoothed(ir, m, body, idx, (), SMOOTH_SIGMA)
    rows = np.arange(len(smooth.time))
    hands = hand_pair(skel, smooth, rows, smooth.q)
    goal = part_path(hands, grip_length(ir, carry))
    if bend:
        goal = _curved_part(goal)
    # the arm chains the later arm segments key (shoulder, elbow, wrist): a clavicle moved here
    # kept its new angle until something keyed it again, and the next two-handed reach, solved
    # from the old one, closed on its part 6 cm wide (vehicle_battery male P5)
    sides = {hand: arm_dofs(skel, hand) for hand in ("r_hand", "l_hand")}
    q, _, _ = solve_along(skel, smooth, goal, sides)
    end = hand_pair(skel, smooth, rows[-1:], smooth.q[-1:])[0]
    if float(np.linalg.norm(end - goal[-1], axis=-1).max()) <= REACH_TOL:
        # the end holds the part: the path ends on the solver's pose. Two ways there, the one
        # that holds the part better (then turns the arms less from point to point): the
        # continuation with its correction faded out over the last ``END_BLEND`` and solved
        # again from there, or each point solved from the path's own pose and its correction
        # smoothed (carry.solve_smoothed; the continuation can stall at a joint's limit); or,
        # where neither holds the part (both re-solve each point on its own, and the blend can
        # leave the arms' reach: a box put on a bench 68 mm squeezed, female P5), the
        # continuation to its own end pose (the hands on their goals, the arms turned another
        # way: the arm segments after it start from the solver's pose)
        fade = 1.0 - minimum_jerk((np.linspace(0.0, 1.0, len(q)) - (1.0 - END_BLEND)) / END_BLEND)
        candidates = [
            _onto(skel, smooth, smooth.q + fade[:, None] * (q - smooth.q), goal, sides),
            _onto(skel, smooth, smooth.q, goal, sides, SMOOTH_SIGMA * (PATH_POINTS - 1)),
            q,  # the continuation to its own end, where neither of those holds the part
        ]
        best = min(candidates, key=lambda c: _holding(skel, smooth, c, goal))
        best = _cleaned(skel, smooth, best, goal, idx)
        return Frames(0.0, smooth.time, smooth.root_position, smooth.root_rotation, best)
    # out of reach: the arms take the part as far along its path as they can, held (the
    # continuation stops it there, ``carry.solve_along``)
    q = _cleaned(skel, smooth, q, goal, idx)
    out = Frames(0.0, smooth.time, smooth.root_position, smooth.root_rotation, q)
    _record_shortfall(ir, m, out)
    return out


def _curved_part(goal: FloatArray) -> FloatArray:
    """The part's path ``goal`` (P, 2, 3: its two ends) with its centre moved onto the best
    of ``_curved``'s six Bezier curves (``bezier``) by the centre's own score on the
    minimum-jerk clock, each point shifted as a whole (the part stays rigid); as it was where
    none scores ``CURVE_GAIN`` better."""
    centre = goal.mean(axis=1)

    def share(path: FloatArray) -> FloatArray:
        step = np.linalg.norm(np.diff(path, axis=0), axis=1)
        u = np.concatenate([[0.0], np.cumsum(step)])
        return u / max(float(u[-1]), EPS) + np.arange(len(u)) * 1e-12

    u = share(centre)
    before = bell_ldlj([centre], u, LDLJ_POINTS)
    best: tuple[float, FloatArray] | None = None
    for handle, leaving in itertools.product(CURVE_HANDLES, (True, False)):
        curve = bezier(centre, u, handle, leaving)
        if curve is None:
            continue
        score = bell_ldlj([curve], share(curve), LDLJ_POINTS)
        if score >= before + CURVE_GAIN and (best is None or score > best[0]):
            best = (score, goal + (curve - centre)[:, None, :])
    return goal if best is None else best[1]


def _carried_curve(
    ir: MotionIR, m: Movement, body: Frames, idx: list[int], carry: Carry, chosen: Frames,
    at: FloatArray, u: FloatArray, models: ModelCheck | None,
) -> tuple[Frames, FloatArray] | None:  # fmt: skip
    """A part moved in both hands whose path turns a corner at speed (``corner_score``, on
    the hands ``at`` of the carried path ``chosen`` at progress ``u``), carried again with its
    centre on a curve (``_carried`` with ``bend``): kept, with its progress, where the hands
    then score ``CURVE_GAIN`` better and it goes no deeper behind a site, under the ground,
    into the body or the scene's models; else None. The carried path doubles back where the
    TO's line in along the site's normal starts in the part's own plane (a module pushed into
    its rack slot, LDLJ -8.0 with a perfect bell of speed)."""
    before = corner_score(at, u)
    if before is None:
        return None
    skel = ir.skeleton
    bent = _carried(ir, m, body, idx, carry, bend=True)
    at_bent = part_site_positions(skel, bent.q, bent.root_position, bent.root_rotation,
                                  m.effectors)  # fmt: skip
    u_bent, _ = progress(ir, m, bent, at_bent)
    if bell_ldlj(list(at_bent.transpose(1, 0, 2)), u_bent, LDLJ_POINTS) < before + CURVE_GAIN:
        return None
    if approach_depth(ir, m, bent)[0] > approach_depth(ir, m, chosen)[0] + APPROACH_SPARE:
        return None
    if models is not None and models.depth(m, bent) > (
        max(models.depth(m, chosen), -MARGIN) + APPROACH_SPARE
    ):
        return None
    return bent, u_bent


def _cleaned(
    skel: object, path: Frames, q: FloatArray, goal: FloatArray, idx: list[int]
) -> FloatArray:
    """``q`` low-passed over ``CLEAN_SIGMA`` points (its ends kept) where that holds the part
    as well, within ``CLEAN_SPARE``: the solver's point-by-point answers zig-zag by a few
    tenths of a mm and stall at a joint's limit then catch up 7 mm in one point, and at speed
    that was a second bell and LDLJ -13 for a hood lifted in both hands (vehicle_battery
    female P50)."""
    out = q.copy()
    out[:, idx] = smooth_path(q[:, idx], CLEAN_SIGMA)
    was, now = _holding(skel, path, q, goal), _holding(skel, path, out, goal)
    if now[0] > was[0] or now[1] > was[1] + CLEAN_SPARE * 1000.0:
        return q
    return out


def _onto(
    skel: object,
    path: Frames,
    seed: FloatArray,
    goal: FloatArray,
    dofs: dict[str, list[int]],
    sigma: float = 0.0,
) -> FloatArray:
    """``seed`` with both arms (``dofs``) solved onto ``goal`` where they are off it (from
    ``seed``; with a smoothed correction solved again when ``sigma`` > 0)."""
    rows = np.arange(len(seed))
    now = hand_pair(skel, path, rows, seed)
    fix = np.flatnonzero(np.linalg.norm(now - goal, axis=-1).max(axis=1) > FIX_FROM)
    if not fix.size:
        return seed
    if sigma > 0.0:
        return solve_smoothed(skel, path, rows, fix, seed, now, goal, sigma, dofs)
    return solve_arms(skel, path, rows, fix, seed, now, goal, dofs)


def _holding(
    skel: object, path: Frames, q: FloatArray, goal: FloatArray
) -> tuple[bool, float, float]:
    """How well poses ``q`` hold the part: whether they miss its goal at the end (by more than
    ``REACH_TOL``: contact not made), how far they squeeze or stretch it from its length (whole
    mm, the worst point; a hand that lags with the other holding the part's other end where it
    is still holds it), then the largest turn of a joint between two points."""
    hands = hand_pair(skel, path, np.arange(len(q)), q)
    apart = np.linalg.norm(hands[:, 0] - hands[:, 1], axis=1)
    length = np.linalg.norm(goal[:, 0] - goal[:, 1], axis=1)
    off = float(np.abs(apart - length).max())
    misses = float(np.linalg.norm(hands[-1] - goal[-1], axis=-1).max()) > REACH_TOL
    return (misses, round(off * 1000.0), float(np.abs(np.diff(q, axis=0)).max(initial=0.0)))


def _record_shortfall(ir: MotionIR, m: Movement, path: Frames) -> None:
    """Each goal of the movement that its hand no longer reaches at the path's end: its
    distance there, what verify reads (a part stopped short of a goal out of reach)."""
    ends = hand_pair(ir.skeleton, path, np.array([len(path.time) - 1]), path.q[-1:])[0]
    for seg in m.segments:
        if seg.goal.position is None or seg.goal.effector not in ("r_hand", "l_hand"):
            continue
        if abs(seg.end - m.end) > EPS:
            continue
        at = ends[0 if seg.goal.effector == "r_hand" else 1]
        off = float(np.linalg.norm(at - np.asarray(seg.goal.position, dtype=float)))
        if off > max(float(seg.result.get("distance", 0.0)), REACH_TOL):
            seg.result = {**seg.result, "distance": off, "reached": False}


def reach_path(
    ir: MotionIR, m: Movement, frames: Frames, rigid: Sequence[Carry] = (),
    models: ModelCheck | None = None,
) -> ReachPath | None:  # fmt: skip
    """The movement's path as interpolation makes it, resampled at even progress and smoothed
    (None when nothing moves): by the widest of ``SMOOTH_SIGMAS`` that takes nothing deeper
    behind its site, below the ground or into the body than ``SMOOTH_SIGMA`` does (by
    ``APPROACH_SPARE``; ``approach_depth``), else by ``SMOOTH_SIGMA``. Where both hands move holding one part
    (``rigid``: the carries), the path keeps the part rigid (``carry.keep_rigid``): the two
    arms' keys are interpolated each on its own and squeezed the avionics unit by 16 cm
    between them, and the carry pass's correction, made after the timing, turned an elbow
    18 deg in one output frame; made here on the path, it is timed with the rest (and counts
    in ``needed_time``)."""
    idx = [ir.skeleton.dof_index(n) for n in m.dofs]
    u, total = progress(ir, m, frames)
    if total <= 1e-6:
        return None
    even = np.linspace(0.0, 1.0, PATH_POINTS)
    body = _frames_at(frames, np.interp(even, u, frames.time))
    both = {"r_hand", "l_hand"} <= set(m.effectors)  # one hand's reach keeps its own path
    held = [c for c in rigid if both and c.start < m.end - EPS and c.end > m.start + EPS]
    if len(held) == 1 and held[0].start <= m.start + EPS:  # the part moved from where it is
        chosen = _carried(ir, m, body, idx, held[0])
        at = part_site_positions(ir.skeleton, chosen.q, chosen.root_position,
                                 chosen.root_rotation, m.effectors)  # fmt: skip
        u2, _ = progress(ir, m, chosen, at)
        bent = _carried_curve(ir, m, body, idx, held[0], chosen, at, u2, models)
        if bent is not None:
            chosen, u2 = bent
        return ReachPath(u2, chosen.q[:, idx], carried=True)
    chosen = _smoothed(ir, m, body, idx, held, SMOOTH_SIGMA)
    allowed, at, pose = approach_depth(ir, m, chosen)
    allowed += APPROACH_SPARE
    # a part in both hands keeps 10 %: smoothed wider after it is made rigid, the correction
    # is undone (tests/data/arms a02's box squeezed by 83 mm, male P99)
    for sigma in () if held else SMOOTH_SIGMAS:
        wider = _smoothed(ir, m, body, idx, held, sigma)
        depth, at_wider, pose_wider = approach_depth(ir, m, wider, like=(chosen, pose))
        if depth <= allowed:
            chosen, at, pose = wider, at_wider, pose_wider
            break
    u2, _ = progress(ir, m, chosen, at)
    curved = None if held else _curved(ir, m, chosen, at, u2, idx, allowed, models, pose)
    if curved is not None:
        return curved
    return ReachPath(u2, chosen.q[:, idx])


class ModelCheck:
    """The scene's models as ``detour`` measures a reach against them (``detour.Obstacles``),
    made when a curve first asks: a curve must not cut through what the path was bent round."""

    def __init__(self, ir: MotionIR) -> None:
        self.ir = ir

    @cached_property
    def obstacles(self) -> Obstacles | None:
        return obstacles_of(self.ir, PoseState(self.ir))

    def depth(self, m: Movement, path: Frames) -> float:
        """How deep (m, positive inside) the movement's hands, forearms and held tools go into
        the models along ``path``; -inf without models."""
        if self.obstacles is None:
            return -np.inf
        sides = sorted({e[0] for e in m.effectors})
        arms = ArmCapsules(self.ir, sides, m.start, m.end)
        pose = forward(self.ir.skeleton, path.q, path.root_position, path.root_rotation,
                       with_axes=False)  # fmt: skip
        return float(arms.depth(self.obstacles, pose, path.time).max(initial=-np.inf))


def corner_score(at: FloatArray, u: FloatArray) -> float | None:
    """The hands' worst score (``bell_ldlj``) of a path whose hands are ``at`` (N, H, 3) at
    progress ``u``, where it is worth making again on a curve: under ``CURVE_FROM`` and at
    least ``CURVE_MIN_PATH`` long (a press in place: its jerk is the solver's noise, not a
    corner); else None."""
    if float(np.linalg.norm(np.diff(at, axis=0), axis=-1).sum(axis=0).max()) < CURVE_MIN_PATH:
        return None
    before = bell_ldlj(list(at.transpose(1, 0, 2)), u, LDLJ_POINTS)
    return before if before < CURVE_FROM else None


def _curved(
    ir: MotionIR, m: Movement, chosen: Frames, at: FloatArray, u: FloatArray, idx: list[int],
    allowed: float, models: ModelCheck | None, pose: Pose | None = None,
) -> ReachPath | None:  # fmt: skip
    """A reach whose smoothed path still turns a corner at speed (its LDLJ on the minimum-jerk
    clock under ``CURVE_FROM``), made again on a curve: each hand on a cubic Bezier from where
    it starts to its site, arriving along the way the path arrives (the TO's line in along the
    site's normal), the arm solved onto it point by point from the path's own pose. The
    approach point's corner, smoothed no wider for the site's surface, turned the drain valve's
    reach 70 deg in three frames at 40 cm/s (LDLJ -8.0 where its speed profile alone scores
    -5.3). Six curves are tried (``CURVE_HANDLES``, each leaving the way the path leaves or
    straight at its last control point); the best is kept that is solved within ``CURVE_TOL``
    on every point, turns no joint more than ``CURVE_STEP`` between two, goes no deeper behind
    a site, under the ground or into the body (``approach_depth``) nor into the scene's models
    (``models``), and scores ``CURVE_GAIN`` better; else None (the path stays as it was).
    ``pose``: ``chosen``'s from ``approach_depth``, if it posed one (a curve moves the arms
    alone: only the joints below them are posed again)."""
    if not set(m.effectors) <= {"r_hand", "l_hand"}:
        return None
    before = corner_score(at, u)
    if before is None:
        return None
    # the moving hands' arms alone: the trunk as the path has it (solved with the trunk, the
    # curve bobbed the thorax 17 deg out and back, and the joints' share of the progress then
    # slowed the hand where they turned: LDLJ -11 for a curve that scores -6 by its length)
    arms = {d for e in m.effectors for d in arm_dofs(ir.skeleton, e)}
    moving = [d for d in idx if d in arms]
    if not moving:
        return None
    best: tuple[float, ReachPath] | None = None
    was: float | None = None  # the path's own depth into the models, once asked
    for tried in _on_curves(ir, m, chosen, at, u, idx, moving):
        if tried is None:
            continue
        curve, at_curve, u_curve = tried
        score = bell_ldlj(list(at_curve.transpose(1, 0, 2)), u_curve, LDLJ_POINTS)
        if score < before + CURVE_GAIN or (best is not None and score <= best[0]):
            continue
        if approach_depth(ir, m, curve, like=(chosen, pose))[0] > allowed:
            continue
        # with scene models the path may have been bent round them (``detour``): the curve
        # keeps ``detour.MARGIN`` where the path did, and goes no deeper where it did not
        if models is not None:
            if was is None:
                was = max(models.depth(m, chosen), -MARGIN)
            if models.depth(m, curve) > was + APPROACH_SPARE:
                continue
        best = (score, ReachPath(u_curve, curve.q[:, idx]))
    return None if best is None else best[1]


def bezier(at: FloatArray, u: FloatArray, handle: float, leaving: bool) -> FloatArray | None:
    """A path's points ``at`` (N, 3) at progress ``u`` remade as a cubic Bezier from its start
    to its end at N even steps of its parameter: the last control point ``handle`` x the chord
    out on the line the path arrives along, the first as far along the way it leaves where
    ``leaving``, else a third of the way to the last. None where it does not move or has no
    way in or out."""
    start, end = at[0], at[-1]
    chord = float(np.linalg.norm(end - start))
    # the ways the path leaves and arrives, each over ``CURVE_END_SHARE`` of it: a hand by the
    # knee, sent straight at the curve's far end, took its forearm 83 mm into the thigh where
    # the path's own first stretch leaves it
    leave = at[int(np.searchsorted(u, CURVE_END_SHARE))] - start
    arrive = end - at[int(np.searchsorted(u, 1.0 - CURVE_END_SHARE))]
    if chord <= EPS or min(float(np.linalg.norm(leave)), float(np.linalg.norm(arrive))) <= EPS:
        return None
    c2 = end - handle * chord * arrive / float(np.linalg.norm(arrive))
    c1 = start + (handle * chord * leave / float(np.linalg.norm(leave)) if leaving
                  else (c2 - start) / 3.0)  # fmt: skip
    w = np.linspace(0.0, 1.0, len(at))[:, None]
    return (1 - w) ** 3 * start + 3 * (1 - w) ** 2 * w * c1 + 3 * (1 - w) * w**2 * c2 + w**3 * end


def _on_curves(
    ir: MotionIR, m: Movement, chosen: Frames, at: FloatArray, u: FloatArray, idx: list[int],
    moving: list[int],
) -> list[tuple[Frames, FloatArray, FloatArray] | None]:  # fmt: skip
    """For each curve shape (``CURVE_HANDLES`` x leaving or not, in that order): the path
    with each hand on its cubic Bezier (the last control point ``handle`` x the chord out on
    the line it arrives along; the first as far along the way the path leaves where
    ``leaving``, else a third of the way to the last), the ``moving`` dofs solved onto it from
    the path's pose at the same share of the way; its hands' positions and progress. None
    where a point is off by more than ``CURVE_TOL`` or a joint turns more than ``CURVE_STEP``
    between two. The shapes' points are solved in one batch, a third of a solve per shape's
    time: the same numbers to rounding (rows leave the batch as they converge, and the batch's
    kernel then sums in another order: 1e-15 to 1e-11 rad), the outputs of 100 compiles and the
    200-action procedure byte-identical to a solve per shape."""
    n = len(chosen.time)
    shapes = list(itertools.product(CURVE_HANDLES, (True, False)))
    targets: list[FloatArray] = []
    for handle, leaving in shapes:
        points = [bezier(at[:, e], u, handle, leaving) for e in range(at.shape[1])]
        if any(c is None for c in points):  # no way in or out: no shape has one
            return [None] * len(shapes)
        targets.append(np.stack(points, axis=1))  # type: ignore[arg-type]
    k = len(shapes)
    stacked = np.concatenate(targets)  # (k n, H, 3)
    seed = chosen.q[np.clip(np.searchsorted(u, np.linspace(0.0, 1.0, n)), 0, n - 1)]
    goals = [Goal(e, position=stacked[:, j]) for j, e in enumerate(m.effectors)]
    res = solve_ta(ir.skeleton, goals, np.tile(seed, (k, 1)), dofs=moving,
                   root_position=np.tile(chosen.root_position, (k, 1)),
                   root_rotation=np.tile(chosen.root_rotation, (k, 1)), restarts=0,
                   tol=1e-6)  # fmt: skip
    out: list[tuple[Frames, FloatArray, FloatArray] | None] = []
    for c in range(k):
        rows = slice(c * n, (c + 1) * n)
        if not float(np.max(res.position_error[rows])) <= CURVE_TOL:
            out.append(None)
            continue
        q = ir.skeleton.clip(np.asarray(res.q[rows]))
        q[0], q[-1] = chosen.q[0], chosen.q[-1]
        if float(np.abs(np.diff(q[:, idx], axis=0)).max(initial=0.0)) > CURVE_STEP:
            out.append(None)
            continue
        curve = Frames(0.0, chosen.time, chosen.root_position, chosen.root_rotation, q)
        at_curve = part_site_positions(ir.skeleton, q, curve.root_position,
                                       curve.root_rotation, m.effectors)  # fmt: skip
        u_curve, _ = progress(ir, m, curve, at_curve)
        out.append((curve, at_curve, u_curve))
    return out


def _from_carried_end(
    m: Movement, t_new: FloatArray, tau: FloatArray, values: FloatArray,
    ends: dict[str, tuple[float, float]], keys: DofKeys,
) -> None:  # fmt: skip
    """Start the movement's ``values`` (in place) where a carried path before it left its dofs
    (``ends``; no key of the dof in between), the difference let go of on the movement's own
    minimum-jerk bell. A part in both hands can end on the arms' own end pose, turned another
    way than the solver's, and the next reach, solved from the solver's, began with a jump that
    joint_speed gave a second of its own: two bells (vehicle_battery female P1, the wrench's
    reach after the hood is lifted)."""
    fade = 1.0 - minimum_jerk(tau)
    for k, name in enumerate(m.dofs):
        if name not in ends:
            continue
        at, value = ends[name]
        t, _ = keys.get(name, (np.zeros(0), None))
        between = t[(t > at + EPS) & (t < m.start - EPS)]
        delta = value - float(values[0, k])
        if between.size == 0 and abs(delta) > EPS:
            values[:, k] += fade * delta


def paced(ir: MotionIR, m: Movement, frames: Frames, t_new: FloatArray) -> FloatArray | None:
    """The movement's dofs at ``t_new``: its path, smoothed, with minimum-jerk progress (None
    when nothing moves)."""
    path = reach_path(ir, m, frames)
    if path is None:
        return None
    return path.at(minimum_jerk((t_new - m.start) / (m.end - m.start)))


def needed_time(path: ReachPath) -> float:
    """The shortest time (s) in which the path, on the minimum-jerk clock, turns no joint
    faster than ``PEAK_JOINT_SPEED``: its fastest dof's largest rate per unit of normalised
    time over that speed (on a straight joint path the bell's peak is 1.875 times the mean
    rate, Flash & Hogan 1985, so this is 1.875 x the largest excursion / the speed)."""
    tau = np.linspace(0.0, 1.0, NEED_SAMPLES + 1)
    q = path.at(minimum_jerk(tau))
    rate = float(np.abs(np.diff(q, axis=0)).max(initial=0.0)) * NEED_SAMPLES
    return rate / PEAK_JOINT_SPEED


def stretchable(ir: MotionIR, m: Movement) -> bool:
    """Nothing that keeps its own clock runs inside the movement's window: a walk (its
    cadence), a kneel or a stand that keys the root, a wrench's strokes."""
    own = {id(s) for s in m.segments}
    for s in ir.segments:
        if id(s) in own or s.end <= m.start + EPS or s.start >= m.end - EPS:
            continue
        if (
            s.kind == "locomotion"
            or (s.kind == "posture" and s.result.get("root") == "keyed")
            or is_stroke(s)
        ):
            return False
    return True


def stretch_for(ir: MotionIR, m: Movement, path: ReachPath | None, fps: float) -> Stretch | None:
    """How much longer the movement must last for its joints (None: its time will do): whole
    output frames (``fps``), so everything after it falls on the output grid as it did (a goal
    ending 29 ms before the frame that checks it, with a walk starting at its end, was found
    1.5 mm off its site), decided on a rounded value (docs/passes.md, determinism)."""
    if path is None:
        return None
    duration = m.end - m.start
    need = min(needed_time(path), MAX_STRETCH * duration)
    extra = np.ceil(round((need - duration) * fps, 6)) / fps
    if extra <= 0.0 or not stretchable(ir, m):
        return None
    return Stretch(m.start, m.end, float(extra))


def path_grid(m: Movement) -> FloatArray:
    """The times at which the old motion of a movement is measured: 480 a second, at least
    ``MIN_PATH_SAMPLES`` and at most ``MAX_PATH_SAMPLES`` intervals."""
    n = max(MIN_PATH_SAMPLES, int(np.ceil((m.end - m.start) * PATH_SAMPLES_PER_S)))
    return np.linspace(m.start, m.end, min(n, MAX_PATH_SAMPLES) + 1)


def run(ir: MotionIR, ctx: PassContext) -> MotionIR:
    if ir.skeleton is None:
        return ir
    moves = movements(ir)
    if not moves:
        return ir
    # the old motion first, for every movement at once (the keys are replaced afterwards)
    grids = [path_grid(m) for m in moves]
    _, frames_all = _body(ir, np.concatenate(grids))
    paths: list[ReachPath | None] = []
    rigid = carries(ir)
    models = ModelCheck(ir) if ir.geometry else None
    a = 0
    for m, grid in zip(moves, grids, strict=True):
        b = a + len(grid)
        part = Frames(0.0, grid, frames_all.root_position[a:b], frames_all.root_rotation[a:b],
                      frames_all.q[a:b])  # fmt: skip
        a = b
        paths.append(reach_path(ir, m, part, rigid, models))
    # movements too short for their joints last longer, and everything after them waits
    fps = ctx.options.fps
    stretches = [
        st for m, p in zip(moves, paths, strict=True) if (st := stretch_for(ir, m, p, fps))
    ]
    warp = TimeWarp.of(stretches)
    timewarp.apply(ir, warp)
    keys = dof_keys(ir)
    ends: dict[str, tuple[float, float]] = {}  # dof -> (time, value) a carried path ended on
    for m, path in zip(moves, paths, strict=True):
        m.start, m.end = warp(m.start), warp(m.end)
        if path is None:
            continue
        t_new = new_times(m)
        tau = (t_new - m.start) / (m.end - m.start)
        values = path.at(minimum_jerk(tau))
        _from_carried_end(m, t_new, tau, values, ends, keys)
        if path.carried:
            ends.update({n: (m.end, float(values[-1, k])) for k, n in enumerate(m.dofs)})
        for seg in m.segments:
            inside = (t_new >= seg.start - EPS) & (t_new <= seg.end + EPS)
            seg.keyframes = Keyframes(time=t_new[inside], dofs=tuple(m.dofs), q=values[inside])
            seg.result = {**seg.result, "paced": "minimum_jerk"}
    return ir
