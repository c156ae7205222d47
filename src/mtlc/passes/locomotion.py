"""Pass 4: walking. Footsteps along the root plan, legs by IK, step segmentation (seed 004).

Each locomotion segment becomes a footstep plan: feet alternate; a heading change of more than
``TURN_IN_PLACE`` at the start is stepped in place (pivot steps of at most ``MAX_TURN_STEP``);
the walk covers the distance in ``ceil(distance / step length)`` equal steps and a closing step
brings the feet together, already turned (up to ``MAX_TWIST``) toward the work the root plan
arrives facing; a larger turn is finished by pivot steps in place at the goal. The step length comes from stature, the pedometer rule 0.413 × stature
for women and 0.415 × stature for men, inside the 0.41–0.45 H range quoted for normal walking
(see docs/passes.md); a supplied BVH clip replaces it with the clip's adapted gait.

The pelvis passes through the mid-point of the feet at each double support, sways a little
toward the stance foot in single support and bobs down as far as the legs need to reach both
footprints. Leg angles come from an exact analytic leg IK (hip 3 dofs, knee, ankle 2 dofs for
an ankle position and a level foot heading), so the stance foot stays on its footprint at every
keyframe; keyframes are added between them until the interpolated stance foot drifts less
than ``DRIFT_TOL``. Each segment's ``result`` gets the footsteps (which foot, lift-off and
touch-down times, footprint) for the balance pass and the metrics, and the steps that
:func:`segment_steps` recovers from the generated foot heights (seed 004 claim 2).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from numpy.typing import NDArray

from mtlc.body.kinematics import bits_differ
from mtlc.ir.model import Keyframes, MotionIR, Segment, runs_of, yaw_quaternion
from mtlc.ir.pchip import Hermite, hermite, pchip, pchip_slopes
from mtlc.passes.context import INTERNAL_FPS, PassContext
from mtlc.passes.stance import WIDE_RESULT, WIDE_STEP, WIDE_TURN_OUT, needs_wide_squat

# the front end times the turns these thresholds make the gait step (mtlc.semantics.turning)
from mtlc.semantics import gait as steps_time
from mtlc.semantics.gait import CLOSE, PIVOT, START, WALK, pivots
from mtlc.semantics.turning import FINAL_TURN, MAX_TWIST, MIN_DISTANCE, TURN_IN_PLACE, wrap

FloatArray = NDArray[np.float64]

STEP_HEIGHT_RATIO = 0.03  # mid-swing ankle rise / stature: ~7 cm for a 1.6 m manikin
DOUBLE_SUPPORT = 0.2  # share of each step with both feet down (10 % at each end)
# from standing, the first step's heel rises and the weight shifts for this share of the step
# before toe-off (gait initiation's anticipatory phase), and the closing step settles the body
# for this share after its touch-down
START_SHIFT = 0.29
START_ROLL = 0.25  # the first step's toe-off pitch, × TOE_OFF_PITCH
CLOSE_SETTLE = 0.2
SWAY = 0.3  # lateral pelvis shift toward the stance foot in single support, × half stance width
# heel rise at toe-off of a full step (less for shorter ones): the trailing foot's roll lifts
# and brings forward its ankle, so the leg behind needs less hip extension (its limit, -15°,
# set the pelvis's lowest point at 40°, 6.6 cm below standing on the 5th-percentile woman)
TOE_OFF_PITCH = math.radians(60)
HEEL_OFF = 0.6  # the heel rises this many steps before toe-off (in the other foot's swing)
LEAD = 0.25  # at double support the pelvis is ahead of the feet's mid-point by this × the move
LIMIT_MARGIN = math.radians(1.0)  # the pelvis height keeps the legs this far inside the limits
STANCE_REACH = 0.995  # hip–ankle distance while walking, × thigh + shank length
DRIFT_TOL = 3e-4  # m: a planted foot's interpolated drift allowed at the interpolation's frames
SWING_TOL = 5e-3  # m: a swinging foot's
SWING_KEYS = (0.25, 0.5, 0.75, 0.9)  # swing fractions always keyed (0.9: the set-down)
CAP = 0.05  # s after the last keyframe, a copy of it: the legs arrive at rest
ROLL_RATE = 1.2  # rad/s: how fast a planted foot's unscheduled roll may begin or end
ROLL_ROUNDS = 4  # rounds of that roll, each from the last one's
HEIGHT_RATE = 120.0  # Hz: the pelvis height is searched on this grid
REACH_CHUNK = 4096  # grid times whose candidate heights are solved at once (1024: 7 % more time)
REACH_CANDIDATES = 41  # pelvis heights tried, from standing down to 30 % of the leg lower
UNCURED_TOL = 0.02  # rad (or 2 mm of reach): a lower pelvis that helps less does not win
REACH_BLOCKS = (2, 6, 33)  # candidates tried per round, at the times still open: sums to 41
REACH_PIECE = 6  # ...evaluated this many at a time within a round (the same answer, less work)
MIN_DURATION = 1e-6  # s: a walk with less time (a zero-length MTM walk) takes no steps
LEGS = ("r", "l")
LEG_DOFS = ("hip_flex", "hip_abd", "hip_rot", "knee_flex", "ankle_dorsi", "ankle_inv")


# --------------------------------------------------------------------------- leg geometry & IK


@dataclass(frozen=True)
class LegModel:
    """What the analytic leg IK needs from a skeleton (both legs are mirror images)."""

    hip: dict[str, FloatArray]  # hip centre in the pelvis frame
    thigh: float
    shank: float
    ankle_height: float  # ankle centre above the sole plane
    toe: FloatArray  # toe tip in the foot frame (the heel-off pivot)
    heel: FloatArray  # heel point in the foot frame
    dofs: dict[str, list[int]]  # skeleton dof indices, LEG_DOFS order
    sign: dict[str, tuple[float, float, float]]  # (abduction, rotation, inversion) axis signs
    lower: dict[str, FloatArray]
    upper: dict[str, FloatArray]

    @property
    def length(self) -> float:
        return self.thigh + self.shank


def leg_model(skel: Any) -> LegModel:
    hip, dofs, sign, lower, upper = {}, {}, {}, {}, {}
    for s in LEGS:
        hip[s] = np.asarray(skel.joints[skel.joint_index(f"{s}_hip")].offset, dtype=float)
        idx = [skel.dof_index(f"{s}_{d}") for d in LEG_DOFS]
        dofs[s] = idx
        ax = np.asarray(skel.dof_axis)[idx]
        sign[s] = (float(ax[1, 2]), float(ax[2, 1]), float(ax[5, 2]))
        lower[s] = np.asarray(skel.lower)[idx]
        upper[s] = np.asarray(skel.upper)[idx]
    knee = skel.joints[skel.joint_index("r_knee")].offset
    ankle = skel.joints[skel.joint_index("r_ankle")].offset
    heel = np.asarray(skel.site("r_heel").offset, dtype=float)
    # the toe tip rides on the toes' joint; the gait keeps the toes straight (their angle 0)
    toes = skel.joints[skel.joint_index("r_toes")].offset
    toe = np.add(toes, skel.site("r_toe").offset, dtype=float)
    return LegModel(
        hip, -float(knee[1]), -float(ankle[1]), -float(heel[1]), toe, heel, dofs, sign, lower,
        upper,
    )  # fmt: skip


def _axis_matrix(a: Any, i: int, j: int, k: int, sign: float) -> FloatArray:
    """Rotations about coordinate axis ``k`` (the others ``i``, ``j``), filled in place:
    much cheaper than stacking for the many small batches the gait makes."""
    a = np.asarray(a, dtype=float)
    c, s = np.cos(a), np.sin(a)
    out = np.zeros((*a.shape, 3, 3))
    out[..., k, k] = 1.0
    out[..., i, i] = c
    out[..., j, j] = c
    out[..., i, j] = -sign * s
    out[..., j, i] = sign * s
    return out


def _rx(a: Any) -> FloatArray:
    return _axis_matrix(a, 1, 2, 0, 1.0)


def _ry(a: Any) -> FloatArray:
    return _axis_matrix(a, 0, 2, 1, -1.0)


def _rz(a: Any) -> FloatArray:
    return _axis_matrix(a, 0, 1, 2, 1.0)


def leg_ik(
    legs: LegModel,
    side: str,
    root_position: FloatArray,
    root_heading: FloatArray,
    ankle: FloatArray,
    foot_heading: FloatArray,
    foot_pitch: FloatArray | float = 0.0,
    *,
    clip: bool = True,
) -> FloatArray:
    """Exact leg angles (B, 6) putting the ankle centre at ``ankle``, the foot turned to
    ``foot_heading`` and pitched nose down by ``foot_pitch``.

    Closed form: the knee from the hip–ankle distance, the ankle's inversion and dorsiflexion
    from the hip seen in the foot frame, the hip's three angles from the remaining rotation
    (X–Z–Y Euler, the skeleton's dof order). Angles are clipped into the joint limits.
    """
    sa, sr, si = legs.sign[side]
    Rroot = _ry(root_heading)
    pitch = np.broadcast_to(np.asarray(foot_pitch, dtype=float), np.shape(foot_heading))
    F = np.swapaxes(Rroot, -1, -2) @ _ry(foot_heading) @ _rx(pitch)  # foot in the pelvis frame
    T = np.einsum("...ji,...j->...i", Rroot, ankle - root_position) - legs.hip[side]
    L1, L2 = legs.thigh, legs.shank
    dist2 = np.einsum("...i,...i->...", T, T)
    k = np.arccos(np.clip((dist2 - L1 * L1 - L2 * L2) / (2 * L1 * L2), -1.0, 1.0))
    u = np.einsum("...ji,...j->...i", F, T)  # the hip–ankle vector in the foot frame
    eps = np.arctan2(-u[..., 0], -u[..., 1])
    y1 = u[..., 0] * np.sin(eps) + u[..., 1] * np.cos(eps)
    wy, wz = -L1 * np.cos(k) - L2, L1 * np.sin(k)
    delta = np.arctan2(wz, wy) - np.arctan2(u[..., 2], y1)
    delta = (delta + np.pi) % (2 * np.pi) - np.pi
    M = F @ _rz(-eps) @ _rx(-delta - k)  # hip rotation Rx(α) Rz(β) Ry(γ)
    beta = np.arcsin(np.clip(-M[..., 0, 1], -1.0, 1.0))
    gamma = np.arctan2(M[..., 0, 2], M[..., 0, 0])
    alpha = np.arctan2(M[..., 2, 1], M[..., 1, 1])
    q = np.stack([-alpha, sa * beta, sr * gamma, k, -delta, si * eps], axis=-1)
    return np.clip(q, legs.lower[side], legs.upper[side]) if clip else q


def leg_violation(
    legs: LegModel,
    side: str,
    xz: FloatArray,
    heading: FloatArray,
    ankle: FloatArray,
    foot_heading: FloatArray,
    foot_pitch: FloatArray,
    planted: NDArray[np.bool_],
    heights: FloatArray,
) -> FloatArray:
    """How far one leg misses at each of N times (root ``xz`` (N, 2), ``heading``, the foot's
    ``ankle``, heading and pitch) for each of M pelvis ``heights``: (N, M), the sum of its
    angles' excess over the joint limits less ``LIMIT_MARGIN`` (a planted foot's dorsiflexion
    excepted: it rolls instead) plus 10 × the hip–ankle distance's excess over
    ``STANCE_REACH`` × the leg length.

    The angles are :func:`leg_ik`'s, written out for this case: only the pelvis height
    differs between the M candidates, and a height moves the hip–ankle vector along the
    pelvis frame's vertical axis alone, so every rotation is built once a time and the M
    candidates cost a few element-wise operations each (``leg_ik`` on N × M rows built
    N × M rotation matrices: half a long walk's time).
    """
    return leg_violation_at(
        legs, side, leg_frame(legs, side, xz, heading, ankle, foot_heading, foot_pitch),
        planted, heights,
    )  # fmt: skip


@dataclass(frozen=True)
class LegFrame:
    """What :func:`leg_violation` computes once a time, whatever the pelvis height: the
    hip–ankle vector's horizontal part in the pelvis frame, the foot's frame there, the
    ankle's height and the hip's horizontal distance from the ankle (N rows)."""

    tx: FloatArray  # (N, 1)
    tz: FloatArray  # (N, 1)
    dy: FloatArray  # (N,) the ankle's height above the root's ground point
    Fc: tuple[tuple[FloatArray, ...], ...]  # Fc[j][i] = F[:, j, i] as (N, 1)
    flat2: FloatArray  # (N,) the hip's horizontal distance from the ankle, squared
    ankle_y: FloatArray  # (N,)

    def take(self, rows: NDArray[np.intp]) -> LegFrame:
        return LegFrame(
            self.tx[rows], self.tz[rows], self.dy[rows],
            tuple(tuple(x[rows] for x in row) for row in self.Fc), self.flat2[rows],
            self.ankle_y[rows],
        )  # fmt: skip


def leg_frame(
    legs: LegModel,
    side: str,
    xz: FloatArray,
    heading: FloatArray,
    ankle: FloatArray,
    foot_heading: FloatArray,
    foot_pitch: FloatArray,
) -> LegFrame:
    """The per-time part of :func:`leg_violation` (a height search asks it once a time)."""
    Rroot = _ry(heading)  # (N, 3, 3)
    F = np.swapaxes(Rroot, -1, -2) @ _ry(foot_heading) @ _rx(foot_pitch)
    d = ankle - np.stack([xz[:, 0], np.zeros(len(xz)), xz[:, 1]], axis=-1)
    hip = legs.hip[side]
    # the hip–ankle vector in the pelvis frame: the heading turns about the vertical axis
    tx = (Rroot[:, 0, 0] * d[:, 0] + Rroot[:, 2, 0] * d[:, 2] - hip[0])[:, None]
    tz = (Rroot[:, 0, 2] * d[:, 0] + Rroot[:, 2, 2] * d[:, 2] - hip[2])[:, None]
    Fc = tuple(tuple(F[:, j, i, None] for i in range(3)) for j in range(3))
    # the hip's height above the ankle is the only part of their distance a height changes
    hx = Rroot[:, 0, 0] * hip[0] + Rroot[:, 0, 2] * hip[2] + xz[:, 0] - ankle[:, 0]
    hz = Rroot[:, 2, 0] * hip[0] + Rroot[:, 2, 2] * hip[2] + xz[:, 1] - ankle[:, 2]
    return LegFrame(tx, tz, d[:, 1], Fc, hx * hx + hz * hz, ankle[:, 1])


def leg_violation_at(
    legs: LegModel,
    side: str,
    frame: LegFrame,
    planted: NDArray[np.bool_],
    heights: FloatArray,
) -> FloatArray:
    """:func:`leg_violation` from its per-time part ``frame``: (N, M)."""
    sa, sr, si = legs.sign[side]
    hip = legs.hip[side]
    tx, tz, Fc = frame.tx, frame.tz, frame.Fc
    ty = (frame.dy[:, None] - heights[None, :]) - hip[1]  # (N, M)
    L1, L2 = legs.thigh, legs.shank
    dist2 = tx * tx + ty * ty + tz * tz
    k = np.arccos(np.clip((dist2 - L1 * L1 - L2 * L2) / (2 * L1 * L2), -1.0, 1.0))
    u = [Fc[0][i] * tx + Fc[1][i] * ty + Fc[2][i] * tz for i in range(3)]  # Fᵀ t
    eps = np.arctan2(-u[0], -u[1])
    ce, se = np.cos(eps), np.sin(eps)
    y1 = u[0] * se + u[1] * ce
    wy, wz = -L1 * np.cos(k) - L2, L1 * np.sin(k)
    delta = np.arctan2(wz, wy) - np.arctan2(u[2], y1)
    delta = (delta + np.pi) % (2 * np.pi) - np.pi
    b = -delta - k
    cb, sb = np.cos(b), np.sin(b)
    # M = F Rz(-eps) Rx(b): the entries the hip's Euler angles need
    g = [[Fc[r][0] * ce - Fc[r][1] * se, Fc[r][0] * se + Fc[r][1] * ce, Fc[r][2]] for r in range(3)]
    m00 = g[0][0]
    m01 = g[0][1] * cb + g[0][2] * sb
    m02 = g[0][2] * cb - g[0][1] * sb
    m11 = g[1][1] * cb + g[1][2] * sb
    m21 = g[2][1] * cb + g[2][2] * sb
    beta = np.arcsin(np.clip(-m01, -1.0, 1.0))
    q = [
        -np.arctan2(m21, m11), sa * beta, sr * np.arctan2(m02, m00), k, -delta, si * eps,
    ]  # fmt: skip
    lo, hi = legs.lower[side] + LIMIT_MARGIN, legs.upper[side] - LIMIT_MARGIN
    bad = np.zeros(ty.shape)
    for i, qi in enumerate(q):
        bad += np.maximum(lo[i] - qi, 0.0)
        over = np.maximum(qi - hi[i], 0.0)
        if i == 4:
            over = np.where(planted[:, None], 0.0, over)
        bad += over
    hy = heights[None, :] + hip[1] - frame.ankle_y[:, None]
    reach = np.sqrt(frame.flat2[:, None] + hy * hy)
    # a swinging leg does not hold the pelvis down: its ankle rises instead (WalkMotion.pose)
    over = np.where(planted[:, None], np.maximum(reach - STANCE_REACH * legs.length, 0.0), 0.0)
    return bad + 10 * over


# --------------------------------------------------------------------------- gait and footsteps


@dataclass(frozen=True)
class Gait:
    """The walk's parameters: from stature, or adapted from a supplied clip."""

    step_length: float  # m, one foot's touch-down to the other's
    step_height: float  # m, ankle rise at mid-swing
    cadence: float | None = None  # a clip's steps per second; None: from stature (below)
    source: str = "stature"
    stature: float = 1.7  # m: the cadence (semantics.gait) depends on it

    def step_seconds(self, kind: str, length: float) -> float:
        """How long one step takes (``semantics.gait``: the front end times walks alike)."""
        return steps_time.step_seconds(kind, length, self.step_length, self.stature)


def default_gait(skel: Any) -> Gait:
    h = float(skel.dims.stature)
    return Gait(
        steps_time.step_length(h, getattr(skel, "sex", "")), STEP_HEIGHT_RATIO * h, stature=h
    )


@dataclass
class Footprint:
    position: FloatArray  # ankle centre projected on the ground
    heading: float


@dataclass
class Step:
    foot: str
    start: Footprint
    end: Footprint
    pelvis_heading: float  # the pelvis's heading once this step has landed
    t_heel_off: float = 0.0  # the heel rises, the foot rolls about its toe
    t_lift: float = 0.0  # toe-off
    t_land: float = 0.0  # flat on the next footprint
    toe_off_pitch: float = 0.0  # rad, nose down at toe-off
    kind: str = WALK  # semantics.gait's START, WALK, CLOSE or PIVOT: sets its time
    length: float = 0.0  # m, the progression of a walking step
    t_end: float = 0.0  # the step's time ends (the next one's begins)


def _side(heading: float, foot: str, offset: Any) -> FloatArray:
    """A foot's ankle from the stance centre: ``offset`` is (half width, forward) in the body
    frame (the manikin's left is +X at heading 0), or a bare half width."""
    x, z = (float(offset), 0.0) if np.ndim(offset) == 0 else (float(offset[0]), float(offset[1]))
    x = x if foot == "l" else -x
    c, s = math.cos(heading), math.sin(heading)
    return np.array([c * x + s * z, 0.0, -s * x + c * z])


def stance_at(centre: FloatArray, heading: float, half_width: Any) -> dict[str, Footprint]:
    return {f: Footprint(centre + _side(heading, f, half_width), heading) for f in LEGS}


def plan_footsteps(
    stance: dict[str, Footprint],
    goal: FloatArray,
    walk_heading: float,
    final_heading: float,
    gait: Gait,
    half_width: Any,
    first: str = "r",
    min_steps: int = 1,
) -> list[Step]:
    """Pivot steps to the walking heading, equal steps to the goal, a closing step turned
    toward ``final_heading`` (at most ``MAX_TWIST``), pivot steps for the rest of that turn."""
    feet = dict(stance)
    steps: list[Step] = []
    foot = first
    centre = (feet["r"].position + feet["l"].position) / 2
    h0 = math.atan2(
        math.sin(feet["r"].heading) + math.sin(feet["l"].heading),
        math.cos(feet["r"].heading) + math.cos(feet["l"].heading),
    )
    d = goal - centre
    d[1] = 0.0
    distance = float(np.hypot(d[0], d[2]))
    if distance < MIN_DISTANCE:
        walk_heading = h0
    turn = wrap(walk_heading - h0)

    def put(f: str, fp: Footprint, pelvis: float, kind: str = PIVOT, length: float = 0.0) -> None:
        steps.append(Step(f, feet[f], fp, pelvis, kind=kind, length=length))
        feet[f] = fp

    def pivot(at: FloatArray, h_from: float, turn: float, foot: str) -> str:
        """Turn in place about ``at``: steps of at most MAX_TURN_STEP, then a closing step."""
        m = pivots(turn)  # the count semantics.gait timed the walk with
        for j in range(1, m + 1):
            h = h_from + turn * j / m
            put(foot, Footprint(at + _side(h, foot, half_width), h), h_from + turn * (j - 0.5) / m)
            foot = _other(foot)
        h = h_from + turn
        put(foot, Footprint(at + _side(h, foot, half_width), h), h)
        return _other(foot)

    if abs(turn) > TURN_IN_PLACE:
        foot = pivot(centre, h0, turn, "l" if turn > 0 else "r")  # open toward the turn
    twist = float(np.clip(wrap(final_heading - walk_heading), -MAX_TWIST, MAX_TWIST))
    end_heading = walk_heading + twist
    if distance >= MIN_DISTANCE:
        n = max(min_steps, math.ceil(distance / gait.step_length - 1e-9))
        ahead = d / distance
        for k in range(1, n + 1):
            if k == n:
                fp = Footprint(goal + _side(end_heading, foot, half_width), end_heading)
            else:
                fp = Footprint(centre + ahead * distance * k / n
                               + _side(walk_heading, foot, half_width), walk_heading)  # fmt: skip
            # the pelvis turns with the last walking step's foot: turned alone, that foot
            # needed the hip's whole rotation range and the pelvis sank 25 cm
            pelvis = walk_heading + (twist if k == n else 0.0)
            put(foot, fp, pelvis, START if k == 1 else WALK, distance / n)
            foot = _other(foot)
        put(foot, Footprint(goal + _side(end_heading, foot, half_width), end_heading),
            end_heading, CLOSE, distance / n)  # fmt: skip
        foot = _other(foot)
        centre, h0 = goal, end_heading
    # the rest of the turn toward the work, stepped in place (the next foot in turn opens)
    rest = wrap(final_heading - h0)
    if abs(rest) > FINAL_TURN:
        pivot(centre, h0, rest, foot)
    return steps


def widen(steps: list[Step], step: float, turn_out: float) -> list[Step]:
    """The steps with each foot's last landing ``step`` further out to its side and its toes
    turned out by ``turn_out``: the wide stance of a squat in front of the knees
    (``mtlc.passes.stance``). Only the landings move: each foot still steps there."""
    out = list(steps)
    for foot in LEGS:
        last = max((i for i, st in enumerate(out) if st.foot == foot), default=None)
        if last is None:
            continue
        st = out[last]
        h = st.end.heading
        out_h = h + turn_out if foot == "l" else h - turn_out
        end = Footprint(st.end.position + _side(h, foot, step), out_h)
        out[last] = replace(st, end=end)
    return out


def _other(foot: str) -> str:
    return "r" if foot == "l" else "l"


MAX_STRETCH = 1.2  # a walk given more time than its steps need slows them this much at most
# steps/min: the slowest a walk's steps are timed before it takes one step more: the lower end
# of the adult cadence range issue 19 holds the gait to (90-125; normal walking is 100-120)
MIN_CADENCE = 90.0


def time_steps(steps: list[Step], t0: float, t1: float, gait: Gait) -> None:
    """Give each step its time: from stature and step length (``semantics.gait``, the same rule
    the front end gives the walk), or equal shares at a clip's cadence. Steps that do not fit
    the segment (a walk with a stated, shorter time) are shortened alike; a segment longer than
    they need slows them by up to ``MAX_STRETCH`` and the body stands the rest, half before and
    half after. The first step from standing shifts the weight for ``START_SHIFT`` of its time
    before toe-off; the closing step settles for ``CLOSE_SETTLE`` after touch-down."""
    if not steps:
        return
    span = t1 - t0
    if gait.cadence:
        dts = np.full(len(steps), min(span / len(steps), 1.0 / gait.cadence))
    else:
        # the first step starts from standing, whatever it does (as semantics.gait times it)
        kinds = [START] + [st.kind for st in steps[1:]]
        dts = np.array(
            [gait.step_seconds(k, st.length) for k, st in zip(kinds, steps, strict=True)]
        )
        need = float(dts.sum())
        dts *= span / need if need > span else min(span / need, MAX_STRETCH)
    lead = (span - float(dts.sum())) / 2  # stand still before and after if there is time left
    b0 = t0 + lead
    for i, (st, dt) in enumerate(zip(steps, dts, strict=True)):
        before = START_SHIFT if i == 0 else DOUBLE_SUPPORT / 2
        after = CLOSE_SETTLE if st.kind == CLOSE or i == len(steps) - 1 else DOUBLE_SUPPORT / 2
        st.t_heel_off = b0 if i == 0 else max(t0, b0 - HEEL_OFF * dts[i - 1])
        st.t_lift = b0 + before * dt
        st.t_land = b0 + dt - after * dt
        st.t_end = b0 + dt
        travel = float(np.hypot(*(st.end.position - st.start.position)[[0, 2]]))
        # a foot behind the other rolls fully over a step's length of travel; the first step
        # from standing (feet side by side, nothing behind) a quarter as far: rolled 60° in
        # its weight shift it flexed the knee 20-30° in the first frame
        share = START_ROLL if i == 0 else 1.0
        st.toe_off_pitch = share * TOE_OFF_PITCH * min(1.0, travel / gait.step_length)
        b0 += dt


# --------------------------------------------------------------------------- trajectories


@dataclass
class FootTrack:
    """One foot over sampled times."""

    ankle: FloatArray  # (N, 3)
    heading: FloatArray  # (N,)
    pitch: FloatArray  # (N,) nose down
    planted: NDArray[np.bool_]  # (N,): the toe is on its footprint (flat or rolling)
    anchor: FloatArray  # (N, 3): that footprint's toe tip, the roll's pivot


def _moving_copy(ft: FootTrack) -> FootTrack:
    """``ft`` with its own copy of what :meth:`WalkMotion.pose` changes (ankle and pitch)."""
    return FootTrack(ft.ankle.copy(), ft.heading, ft.pitch.copy(), ft.planted, ft.anchor)


_LANDED, _ROLLING, _SWINGING = 1, 2, 3  # what sets a foot at a time (WalkMotion.feet)


@dataclass(frozen=True)
class _StepTable:
    """One foot's steps as arrays (K rows, in the walk's order): ``WalkMotion._geometry``,
    the headings and the turn."""

    row: dict[int, int]  # id(step) -> its row
    a1: FloatArray  # (K, 3) the landing ankle
    R0: FloatArray  # (K, 3, 3) the start's rotation
    toe_w: FloatArray  # (K, 3) the start's toe tip
    toe_end: FloatArray  # (K, 3) the landing toe tip
    h0: FloatArray  # (K,) the start's heading
    h1: FloatArray  # (K,) the landing's heading
    turn: FloatArray  # (K,) wrap(h1 - h0)


def _rolled(R0: FloatArray, toe_w: FloatArray, phi: FloatArray, toe: FloatArray) -> FloatArray:
    """Ankle centres of a foot pitched nose down by ``phi`` about its toe tip ``toe_w``."""
    Rp = np.broadcast_to(R0, (len(phi), 3, 3)) @ _rx(phi)
    return toe_w - Rp @ toe


@dataclass
class WalkMotion:
    """Continuous root and feet over a segment, sampled wherever keyframes are wanted."""

    steps: list[Step]
    stance: dict[str, Footprint]
    t0: float
    t1: float
    root_start: FloatArray
    root_end: FloatArray
    heading_start: float
    heading_end: float
    stand_height: float  # pelvis height above the ground, standing
    ground: float
    gait: Gait
    legs: LegModel
    half_width: Any  # see _side
    cap: bool = False  # a last keyframe repeats the final pose, so the legs come to rest

    def __post_init__(self) -> None:
        self._geo: dict[int, tuple[FloatArray, FloatArray, FloatArray, FloatArray]] = {}
        self._tables: dict[str, _StepTable] = {}
        self._early_roll: dict[str, FloatArray] = {}  # set once the pelvis height is known
        ts, xz, hs = [self.t0], [self.root_start[[0, 2]]], [self.heading_start]
        feet = dict(self.stance)
        last = final_feet(self.stance, self.steps)
        arrive = (last["r"].position + last["l"].position) / 2
        near = 1.5 * float(np.linalg.norm(np.atleast_1d(self.half_width)))
        for st in self.steps:
            stance_foot = "l" if st.foot == "r" else "r"
            mid_t = (st.t_lift + st.t_land) / 2
            b = max(st.t_end, st.t_land + 1e-6)
            centre_before = (feet["r"].position + feet["l"].position) / 2
            feet[st.foot] = st.end
            centre_after = (feet["r"].position + feet["l"].position) / 2
            lateral = feet[stance_foot].position - (centre_before + centre_after) / 2
            heading_dir = np.array([math.sin(st.pelvis_heading), 0.0, math.cos(st.pelvis_heading)])
            lateral = lateral - heading_dir * (lateral @ heading_dir)
            mid = (centre_before + centre_after) / 2 + SWAY * lateral
            move = centre_after - centre_before
            # the first step from standing moves the feet's centre half a step only: the
            # pelvis leads it by a whole step's share, or the leg in front had to reach
            ahead = centre_after + LEAD * move * (2.0 if st.kind == START else 1.0)
            # no overshoot at the goal: the lead stops where it would pass the arrival
            if np.linalg.norm((st.end.position - arrive)[[0, 2]]) <= near and (
                float((arrive - ahead)[[0, 2]] @ move[[0, 2]]) < 0
            ):
                ahead = centre_after
            ts += [mid_t, b]
            xz += [mid[[0, 2]], ahead[[0, 2]]]
            h = hs[-1] + wrap(st.pelvis_heading - hs[-1])
            hs += [(hs[-1] + h) / 2, h]
        ts.append(self.t1)
        xz.append(self.root_end[[0, 2]])
        hs.append(hs[-1] + wrap(self.heading_end - hs[-1]))
        t = np.asarray(ts)
        keep = np.append(np.diff(t) > 1e-6, True)  # at equal times the later knot wins
        self._t = t[keep]
        self._xz = at_rest_ends(self._t, np.asarray(xz)[keep])
        self._h = at_rest_ends(self._t, np.asarray(hs)[keep])
        grid = np.linspace(self.t0, self.t1, max(3, int((self.t1 - self.t0) * HEIGHT_RATE) + 1))
        self._grid = grid
        self._y = self._pelvis_height(grid)
        self._early_roll = self._anticipated_rolls(grid)
        # the swing starts from the foot as it actually leaves: rolled as far as it had to
        lifts = np.array([st.t_lift for st in self.steps])
        for _ in range(2):
            if not len(lifts):
                break
            *_, feet = self.pose(lifts)
            for i, st in enumerate(self.steps):
                st.toe_off_pitch = max(st.toe_off_pitch, float(feet[st.foot].pitch[i]))

    def _anticipated_rolls(self, grid: FloatArray) -> dict[str, FloatArray]:
        """Each planted foot's roll beyond its schedule (what :meth:`pose` adds where the
        ankle would pass its dorsiflexion limit), begun early and let go late at no more than
        ``ROLL_RATE``: the roll a limit needs can jump (a rear foot rolled 4° → 13° in 17 ms
        as the pelvis sank 1.5 mm, its knee 21° → 37°), and a foot that starts rolling
        before it must does not. Kept inside each stance (a lifted or landing foot is not
        rolled by it), on the pelvis grid; :meth:`feet` adds it to the planted feet.

        A round poses only the times whose roll the last round changed (and their neighbours):
        a time's feet and pose are its own (:meth:`feet` reads the roll at that time alone),
        so the others' are the last round's, and a walk's later rounds change a few stances."""
        n = len(grid)
        out = {f: np.zeros(n) for f in LEGS}
        # each foot's scheduled and rolled pitch and whether it is planted, at every time
        planned = {f: np.zeros(n) for f in LEGS}
        pitch = {f: np.zeros(n) for f in LEGS}
        planted = {f: np.zeros(n, dtype=bool) for f in LEGS}
        rows: NDArray[np.intp] | slice = slice(None)
        for _ in range(ROLL_ROUNDS):  # a roll begun early can need more: the limit's other branch
            self._early_roll = out
            before = {f: out[f].copy() for f in LEGS}
            times = grid[rows]
            if len(times):
                # the feet as scheduled, and a copy the pose rolls (``pose`` would make them again)
                sched = self.feet(times)
                *_, rolled = self.pose(times, {f: _moving_copy(ft) for f, ft in sched.items()})
                for f in LEGS:
                    planned[f][rows], pitch[f][rows] = sched[f].pitch, rolled[f].pitch
                    planted[f][rows] = rolled[f].planted
            grown = False
            for f in LEGS:
                on = planted[f]
                extra = np.where(on, np.maximum(pitch[f] - planned[f], 0.0), 0.0)
                if not np.any(extra > 1e-6):
                    continue
                grown = True
                want = out[f] + extra
                env = np.zeros(len(grid))
                for a, b in runs_of(on):
                    t, e = grid[a:b], want[a:b]
                    ahead = np.maximum.accumulate((e - ROLL_RATE * t)[::-1])[::-1] + ROLL_RATE * t
                    after = np.maximum.accumulate(e + ROLL_RATE * t) - ROLL_RATE * t
                    env[a:b] = np.maximum(ahead, after)
                out[f] = env
            if not grown:
                break
            moved = np.zeros(n, dtype=bool)
            for f in LEGS:
                moved |= bits_differ(out[f], before[f])
            moved[1:] |= moved[:-1].copy()  # and each changed time's neighbours
            moved[:-1] |= moved[1:].copy()
            rows = np.flatnonzero(moved)
        return out

    def _geometry(self, st: Step) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """A step's landing ankle, its start's rotation and toe tip, its landing toe tip."""
        key = id(st)
        if key not in self._geo:
            lift = np.array([0.0, self.legs.ankle_height, 0.0])  # footprints are on the ground
            R0 = _ry(st.start.heading)
            a1 = st.end.position + lift
            self._geo[key] = (a1, R0, st.start.position + lift + R0 @ self.legs.toe,
                              a1 + _ry(st.end.heading) @ self.legs.toe)  # fmt: skip
        return self._geo[key]

    def _step_table(self, foot: str) -> _StepTable:
        """The foot's steps' footprints as arrays, made once (their times and toe-off pitch
        are read afresh: they are set while the walk is made)."""
        if foot not in self._tables:
            mine = [st for st in self.steps if st.foot == foot]
            geo = [self._geometry(st) for st in mine]
            self._tables[foot] = _StepTable(
                {id(st): i for i, st in enumerate(mine)},
                *(np.array([g[j] for g in geo]) for j in range(4)),
                np.array([st.start.heading for st in mine]),
                np.array([st.end.heading for st in mine]),
                np.array([wrap(st.end.heading - st.start.heading) for st in mine]),
            )
        return self._tables[foot]

    def feet(self, t: FloatArray) -> dict[str, FootTrack]:
        """Both feet at times ``t``, as scheduled (before :meth:`pose` adds the roll it needs).

        Flat on a footprint in stance; from heel-off to toe-off the foot rolls nose down
        about its toe tip (the toe stays put); in swing the ankle follows a minimum-jerk path
        with a sin² rise of ``step_height`` and lands flat.
        """
        out = {}
        lift = self.legs.ankle_height  # the footprints are on the ground already
        toe = self.legs.toe
        # every step claims index ranges of the sorted times (found by bisection), in order,
        # a later claim winning, and its landing holds only until the foot's next step lands;
        # then each phase is computed once for all the times it won, from the winning step's
        # numbers (the same element-wise arithmetic per time as a step at a time: a long walk
        # spent most of its keyframing in the per-step numpy calls)
        t = np.asarray(t, dtype=float)
        order = np.argsort(t, kind="stable")
        ts = t[order]
        n = len(ts)
        for f in LEGS:
            pos = np.tile(self.stance[f].position, (n, 1))
            head = np.full(n, self.stance[f].heading)
            pitch = np.zeros(n)
            pos[:, 1] += lift
            anchor = pos + _ry(head) @ toe
            planted = np.ones(n, dtype=bool)
            steps = self._steps_touching(f, ts)
            owner = np.full(n, -1)  # the step that set the pose last (-1: the first stance)
            phase = np.zeros(n, dtype=np.int8)  # how: _LANDED, _ROLLING or _SWINGING
            landed_on = np.full(n, -1)  # the step whose landing set the anchor last
            t_land = np.array([st.t_land for st in steps])
            t_lift = np.array([st.t_lift for st in steps])
            lands = np.searchsorted(ts, t_land, side="left").tolist()
            helds = [*lands[1:], n]
            heel_offs = np.searchsorted(
                ts, np.array([st.t_heel_off for st in steps]), side="left"
            ).tolist()
            lifts = np.searchsorted(ts, t_lift, side="right").tolist()
            for k, st in enumerate(steps):
                land, held, lifted = lands[k], helds[k], lifts[k]
                after = slice(land, max(land, held))
                owner[after], phase[after], landed_on[after] = k, _LANDED, k
                ho = slice(heel_offs[k], lifted)
                if ho.stop > ho.start and st.t_lift > st.t_heel_off:
                    owner[ho], phase[ho] = k, _ROLLING
                sw = slice(lifted, land)
                if sw.stop > sw.start:
                    owner[sw], phase[sw] = k, _SWINGING
                    planted[sw] = False
            if steps:
                self._steps_into(steps, ts, owner, phase, landed_on, pos, head, pitch, anchor)
            if self._early_roll:
                extra = np.interp(ts, self._grid, self._early_roll[f])
                rows = planted & (extra > 0.0)
                pitch[rows] += extra[rows]
                pos[rows] = _rolled(_ry(head[rows]), anchor[rows], pitch[rows], toe)
            back = np.empty_like(order)  # the caller's order of ``t``
            back[order] = np.arange(n)
            out[f] = FootTrack(pos[back], head[back], pitch[back], planted[back], anchor[back])
        return out

    def _steps_into(
        self,
        steps: list[Step],
        ts: FloatArray,
        owner: NDArray[np.intp],
        phase: NDArray[np.int8],
        landed_on: NDArray[np.intp],
        pos: FloatArray,
        head: FloatArray,
        pitch: FloatArray,
        anchor: FloatArray,
    ) -> None:
        """Write each time's foot as the step ``owner`` sets it in ``phase`` (see :meth:`feet`)."""
        toe = self.legs.toe
        index = self._step_table(steps[0].foot)
        at = np.array([index.row[id(st)] for st in steps])
        a1, R0, toe_w, toe_end = index.a1[at], index.R0[at], index.toe_w[at], index.toe_end[at]
        h0, h1, turn = index.h0[at], index.h1[at], index.turn[at]
        top = np.array([st.toe_off_pitch for st in steps])  # these change as the walk is made
        t_ho = np.array([st.t_heel_off for st in steps])
        t_lift = np.array([st.t_lift for st in steps])
        t_land = np.array([st.t_land for st in steps])
        rows = np.flatnonzero(landed_on >= 0)
        anchor[rows] = toe_end[landed_on[rows]]
        rows = np.flatnonzero(phase == _LANDED)
        k = owner[rows]
        pos[rows], head[rows], pitch[rows] = a1[k], h1[k], 0.0
        rows = np.flatnonzero(phase == _ROLLING)
        if rows.size:
            k = owner[rows]
            tau = (ts[rows] - t_ho[k]) / (t_lift[k] - t_ho[k])
            phi = top[k] * tau * tau * (3 - 2 * tau)
            pos[rows], head[rows], pitch[rows] = _rolled(R0[k], toe_w[k], phi, toe), h0[k], phi
        rows = np.flatnonzero(phase == _SWINGING)
        if rows.size:
            k = owner[rows]
            start = _rolled(R0, toe_w, top, toe)[k]  # the foot as it leaves its toe
            tau = (ts[rows] - t_lift[k]) / (t_land[k] - t_lift[k])
            # the foot travels over the whole swing (a smoothstep: at rest at both ends, its
            # peak speed 1.5 × the mean), lifts briskly off its toe (sin) and sets down softly
            # (sin²). The minimum-jerk move over the middle 75 % of the swing reached over the
            # landing point while the pelvis was still half a step behind (the pelvis sank up
            # to 25 cm) at up to 8.7 m/s.
            s = tau * tau * (3 - 2 * tau)
            pos[rows] = start + s[:, None] * (a1[k] - start)
            head[rows] = h0[k] + s * turn[k]
            # level from 60 % of the swing on (levelled as it travelled, the toe hung low and
            # touched down a fifth of the swing early), smoothly from the roll (a kink here is
            # a "jump" the smooth pass blends for 50 frames)
            u = np.clip(tau / 0.6, 0.0, 1.0)
            pitch[rows] = top[k] * (1 - u * u * (3 - 2 * u))
            pos[rows, 1] = self._swing_height(tau, pitch[rows], toe_w[k, 1], toe_end[k, 1])

    def _swing_height(
        self, tau: FloatArray, pitch: FloatArray, toe_from: FloatArray, toe_to: FloatArray
    ) -> FloatArray:
        """The swinging ankle's height: as high as the foot's pitch needs for its toe to be
        ``clearance`` above the floor (the toe-off roll unwinds as the foot levels), no more.
        ``toe_from``, ``toe_to``: the toe tip's height at toe-off and at the landing."""
        floor = toe_from + tau * tau * (3 - 2 * tau) * (toe_to - toe_from)
        # lifts briskly off its toe (sin) and sets down late and softly (sin^1.5: at rest on
        # touch-down, over 5 mm until 95 % of the swing; sin² was under it from 91 %)
        bump = np.sin(np.pi * np.clip(tau, 0.0, 1.0))
        clearance = self.gait.step_height * np.where(tau < 0.5, bump, bump**1.5)
        toe = self.legs.toe
        # the toe tip's height from the ankle for a foot pitched nose down (Rx(pitch) @ toe)
        toe_y = np.cos(pitch) * toe[1] - np.sin(pitch) * toe[2]
        return floor + clearance - toe_y

    def _steps_touching(self, foot: str, t: FloatArray) -> list[Step]:
        """The foot's steps that set any of ``t`` in :meth:`feet`, in order. A step wholly
        before every time (landed, lifted) sets them all to its landing and nothing else, so
        such steps before the last such one are overwritten; a step wholly after every time
        sets none. Keeps a long walk's chunks linear in time, not each chunk visiting every step.
        """
        mine = [st for st in self.steps if st.foot == foot]
        if not len(t):
            return mine
        t_min, t_max = float(np.min(t)), float(np.max(t))
        before = [t_min >= st.t_land and t_min > st.t_lift for st in mine]
        last = max((i for i, b in enumerate(before) if b), default=-1)
        return [
            st
            for i, st in enumerate(mine)
            if not (before[i] and i < last)
            and not (t_max < st.t_heel_off and t_max < st.t_land and t_max <= st.t_lift)
        ]

    def _reach_height(self, t: FloatArray, xz: FloatArray, heading: FloatArray) -> FloatArray:
        """The highest pelvis from which both legs reach their ankles within their limits.

        Candidate heights from standing down to 30 % of the leg length lower are tried with
        the exact leg IK; the highest one where both legs reach (``STANCE_REACH``) and stay
        ``LIMIT_MARGIN`` inside every joint limit wins (else the least violating one).

        The candidates are tried from the top in growing blocks (``REACH_BLOCKS``), each only
        at the times no higher candidate settled: most times take one of the first few, so a
        walk solves a few heights a time instead of all 41. The answer is the same as trying
        all at once (the first that fits; where none does, the first of the least violating).
        What every height shares (the legs' frames at a time, ``leg_frame``) is computed once
        a time, and a block is tried ``REACH_PIECE`` heights at a time (``_block``): on a long
        walk 40 % of the times reach the last block, and those that fit there fit within its
        first six heights.
        """
        if len(t) > REACH_CHUNK:  # a long walk's grid a chunk at a time: bounded memory
            return np.concatenate([
                self._reach_height(t[a : a + REACH_CHUNK], xz[a : a + REACH_CHUNK],
                                   heading[a : a + REACH_CHUNK])
                for a in range(0, len(t), REACH_CHUNK)
            ])  # fmt: skip
        top = self.ground + self.stand_height
        cand = top - np.linspace(0.0, 0.3 * self.legs.length, REACH_CANDIDATES)
        n = len(t)
        feet = self.feet(t)
        legs = {  # what every candidate shares, once a time
            f: (leg_frame(self.legs, f, xz, heading, ft.ankle, ft.heading, ft.pitch), ft.planted)
            for f, ft in feet.items()
        }
        choice = np.full(n, -1)  # the candidate settled for each time, -1 while open
        best = np.full(n, np.inf)  # the least violation so far, where none fits
        best_j = np.zeros(n, dtype=int)
        rows = np.arange(n)
        j0 = 0
        for width in REACH_BLOCKS:
            j1 = min(j0 + width, len(cand))
            if not len(rows) or j0 >= j1:
                break
            fits, first, least, low = self._block(rows, cand, j0, j1, legs)
            choice[rows[fits]] = first[fits]
            # by more than a tolerance: near-ties keep the higher candidate (a limit no height
            # cures, such as a hip's rotation, sank the pelvis to the lowest candidate)
            better = least < best[rows] - UNCURED_TOL
            best[rows[better]] = least[better]
            best_j[rows[better]] = low[better]
            rows = rows[~fits]
            j0 = j1
        choice[rows] = best_j[rows]
        return cand[choice]

    def _block(
        self,
        rows: NDArray[np.intp],
        cand: FloatArray,
        j0: int,
        j1: int,
        legs: dict[str, tuple[LegFrame, NDArray[np.bool_]]],
    ) -> tuple[NDArray[np.bool_], NDArray[np.intp], FloatArray, NDArray[np.intp]]:
        """Candidates ``j0:j1`` at the times ``rows``: whether one fits, the first that does,
        the least violation and the first candidate with it (valid where none fits).

        Tried ``REACH_PIECE`` candidates at a time, each only at the times none fitted yet: a
        time that fits stops there (a long walk's times mostly fit within a few candidates of
        the last block or within none). The first that fits, the least violation and its
        first candidate are those of the whole block at once: each violation is one time's
        and one height's, and a later piece's least replaces an earlier one only if smaller."""
        n = len(rows)
        fits = np.zeros(n, dtype=bool)
        first = np.zeros(n, dtype=np.intp)
        least = np.full(n, np.inf)
        low = np.full(n, j0, dtype=np.intp)
        open_ = np.arange(n)
        for a in range(j0, j1, REACH_PIECE):
            b = min(a + REACH_PIECE, j1)
            bad = self._violation(rows[open_], cand[a:b], legs)
            ok = bad <= 1e-12
            hit = ok.any(axis=1)
            fits[open_[hit]] = True
            first[open_[hit]] = a + ok[hit].argmax(axis=1)
            at = bad.argmin(axis=1)
            small = bad[np.arange(len(open_)), at]
            smaller = small < least[open_]
            least[open_[smaller]] = small[smaller]
            low[open_[smaller]] = a + at[smaller]
            open_ = open_[~hit]
            if not open_.size:
                break
        return fits, first, least, low

    def _violation(
        self,
        rows: NDArray[np.intp],
        cand: FloatArray,
        legs: dict[str, tuple[LegFrame, NDArray[np.bool_]]],
    ) -> FloatArray:
        """How far each candidate pelvis height misses at each time (``rows`` of the times):
        joint-limit excess of both legs plus 10 × the reach excess, (len(rows), len(cand)).
        ``legs``: each leg's :func:`leg_frame` at every time and whether its foot is planted."""
        bad = np.zeros((len(rows), len(cand)))
        for f, (frame, planted) in legs.items():
            bad += leg_violation_at(self.legs, f, frame.take(rows), planted[rows], cand)
        return bad

    def _pelvis_height(self, grid: FloatArray) -> FloatArray:
        y = self._reach_height(grid, self._xz(grid), self._h(grid))
        stand = self.ground + self.stand_height
        y = np.minimum(y + self._end_allowance(grid, stand - y[0], stand - y[-1]), stand)
        y[0] = y[-1] = stand  # meet the standing root at the ends
        # erosion then a box average of the same width (narrowing at the ends, which must
        # stay at the standing height): smooth, and below the reach bound
        eroded = _window(y, int(0.1 * HEIGHT_RATE), np.min)
        return np.minimum(_window(eroded, int(0.1 * HEIGHT_RATE), np.mean), y)

    def _end_allowance(self, grid: FloatArray, first: float, last: float) -> FloatArray:
        """How far above the reach bound the pelvis may be near the walk's ends. The rest pose
        stands with its legs straighter than ``STANCE_REACH`` allows (the bound is ~5 mm
        lower): the pelvis sank those millimetres in the first frame (the knees 4.6° → 15° in
        17 ms). The allowance fades out smoothly from the start to the first toe-off, and in
        from the last touch-down to the end, while both feet are down."""
        out = np.zeros(len(grid))
        if not self.steps:
            return out
        for t_a, t_b, amount, rising in (
            (self.t0, min(st.t_lift for st in self.steps), first, False),
            (max(st.t_land for st in self.steps), self.t1, last, True),
        ):
            if amount <= 0 or t_b <= t_a:
                continue
            u = np.clip((grid - t_a) / (t_b - t_a), 0.0, 1.0)
            w = u * u * (3 - 2 * u)
            inside = (grid >= t_a) & (grid <= t_b)
            out[inside] = np.maximum(out[inside], amount * (w if rising else 1 - w)[inside])
        return out

    def root(self, t: FloatArray) -> tuple[FloatArray, FloatArray]:
        tt = np.clip(t, self.t0, self.t1)
        xz = self._xz(tt)
        y = np.interp(tt, self._grid, self._y)
        return np.stack([xz[:, 0], y, xz[:, 1]], axis=-1), self._h(tt)

    def _within_reach(self, foot: str, ft: FootTrack, pos: FloatArray, head: FloatArray) -> None:
        """Lift a swinging ankle that the leg would reach only straighter than
        ``STANCE_REACH``: late in the swing the foot is over its landing point before the
        pelvis is; it waits above it (the leg near straight, as in terminal swing) while the
        pelvis comes forward and down, instead of the pelvis sinking early to reach it."""
        rows = np.flatnonzero(~ft.planted)
        if not rows.size:
            return
        hip = pos[rows] + _ry(head[rows]) @ self.legs.hip[foot]
        d = ft.ankle[rows] - hip
        flat2 = d[:, 0] ** 2 + d[:, 2] ** 2
        reach = STANCE_REACH * self.legs.length
        low = hip[:, 1] - np.sqrt(np.maximum(reach * reach - flat2, 0.0))
        lift = (flat2 < reach * reach) & (ft.ankle[rows, 1] < low)
        ft.ankle[rows[lift], 1] = low[lift]

    def pose(
        self, t: FloatArray, feet: dict[str, FootTrack] | None = None
    ) -> tuple[FloatArray, FloatArray, dict[str, FloatArray], dict[str, FootTrack]]:
        """Root position, heading, each leg's six angles and the feet at times ``t``.

        A planted foot whose ankle would pass its dorsiflexion limit rolls about its toe
        just enough (the heel rises when the ankle can bend no further, as in real gait).
        ``feet``: :meth:`feet` at ``t``, if the caller has them (their ankles and pitches are
        changed in place).
        """
        pos, head = self.root(t)
        legs, feet = {}, self.feet(t) if feet is None else feet
        for f, ft in feet.items():
            self._within_reach(f, ft, pos, head)
            hi = self.legs.upper[f][4] - LIMIT_MARGIN
            q = leg_ik(self.legs, f, pos, head, ft.ankle, ft.heading, ft.pitch, clip=False)
            sub = np.flatnonzero(q[:, 4] > hi + 1e-7)  # only these rows roll (the root is set)
            prev_p = prev_e = None
            for _ in range(12):
                if not sub.size:
                    break
                e = q[sub, 4] - hi
                need = e > 1e-7
                if not need.any():
                    break
                step = e.copy()  # first a plain step, then secant steps (the ankle rises too)
                if prev_p is not None and prev_e is not None:
                    de, dp = prev_e - e, ft.pitch[sub] - prev_p
                    ok = (de > 1e-9) & (dp > 1e-9)
                    step[ok] = np.minimum(e[ok] * dp[ok] / de[ok], 4 * e[ok])
                prev_p, prev_e = ft.pitch[sub].copy(), e
                rows = sub[need]
                ft.pitch[rows] += np.maximum(step[need], 0.0)  # in swing: just point the toes
                roll = rows[ft.planted[rows]]
                ft.ankle[roll] = _rolled(_ry(ft.heading[roll]), ft.anchor[roll], ft.pitch[roll],
                                         self.legs.toe)  # fmt: skip
                q[sub] = leg_ik(self.legs, f, pos[sub], head[sub], ft.ankle[sub], ft.heading[sub],
                                ft.pitch[sub], clip=False)  # fmt: skip
            legs[f] = np.clip(q, self.legs.lower[f], self.legs.upper[f])
        return pos, head, legs, feet


def at_rest_ends(t: FloatArray, y: FloatArray) -> Hermite:
    """PCHIP through the knots, but at rest at the first and the last: PCHIP's end slopes are
    extrapolated, and the pelvis set off at 13 cm/s in the first frame of a walk (a hand that
    had just put the avionics unit on its site was 1.5 mm off it 13 ms later). A smaller end
    slope keeps the curve monotone where PCHIP's was (Fritsch & Carlson 1980)."""
    slopes = pchip_slopes(t, y)
    slopes[0] = 0.0
    slopes[-1] = 0.0
    return hermite(t, y, slopes)


def _window(x: FloatArray, half: int, op: Any) -> FloatArray:
    """``op`` over the window of ``half`` samples either side of each sample, narrowed at the
    ends to what fits on both sides. The interior in one sliding-window call (a call per sample
    was a tenth of a long walk's time); each window is the same slice, so the same numbers."""
    n = len(x)
    out = np.empty(n)
    if n > 2 * half:
        out[half : n - half] = op(sliding_window_view(x, 2 * half + 1), axis=1)
    for i in [*range(min(half, n)), *range(max(half, n - half), n)]:
        w = min(half, i, n - 1 - i)
        out[i] = op(x[i - w : i + w + 1])
    return out


def leg_fk(
    legs: LegModel, side: str, root_position: FloatArray, heading: FloatArray, q: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Ankle centre and toe tip of one leg (N, 3 each): the drift measure of the keyframes."""
    sa, sr, si = legs.sign[side]
    R = _ry(heading) @ _rx(-q[:, 0]) @ _rz(sa * q[:, 1]) @ _ry(sr * q[:, 2])
    hip = root_position + np.einsum("...ij,j->...i", _ry(heading), legs.hip[side])
    knee = hip + R @ np.array([0.0, -legs.thigh, 0.0])
    Rs = R @ _rx(q[:, 3])
    ankle = knee + Rs @ np.array([0.0, -legs.shank, 0.0])
    Rf = Rs @ _rx(-q[:, 4]) @ _rz(si * q[:, 5])
    return ankle, ankle + Rf @ legs.toe


def _heading_of(quat: FloatArray) -> FloatArray:
    return 2 * np.arctan2(quat[:, 2], quat[:, 0])


Pose = tuple[FloatArray, FloatArray, dict[str, FloatArray], dict[str, FootTrack]]


def _rows(pose: Pose, idx: Any) -> Pose:
    """Some rows (times) of a :meth:`WalkMotion.pose`."""
    pos, head, legq, feet = pose
    return (
        pos[idx], head[idx], {f: q[idx] for f, q in legq.items()},
        {f: FootTrack(ft.ankle[idx], ft.heading[idx], ft.pitch[idx], ft.planted[idx],
                      ft.anchor[idx]) for f, ft in feet.items()},
    )  # fmt: skip


def _key_times(motion: WalkMotion) -> tuple[FloatArray, Pose]:
    """A few keyframes per step, refined until the interpolated feet stay on their paths;
    and the pose at them.

    The check interpolates the keyframes as the interpolate pass will (PCHIP of the angles
    and of the root, the root's quaternion normalised) and keys every interpolation frame
    where a foot's ankle or toe strays by more than ``DRIFT_TOL`` from where it should be.
    The keys are the first few and interpolation frames, so the pose is solved once at all
    of them and each round picks its rows (a pose is solved time by time: a time's row is
    the same whatever else is solved with it); a round solved every key again, most of a
    walk's keyframing time.
    """
    t_end = motion.t1
    ts = [motion.t0, motion.t1]
    for st in motion.steps:
        sw = st.t_land - st.t_lift
        ts += [st.t_lift, st.t_land] + [st.t_lift + sw * f for f in SWING_KEYS]
    keys = np.unique(np.round(np.asarray(ts), 9))
    # the interpolate pass's frames inside the window
    k0, k1 = math.ceil(motion.t0 * INTERNAL_FPS - 1e-9), math.floor(t_end * INTERNAL_FPS + 1e-9)
    dense = np.unique(np.r_[motion.t0, np.arange(k0, k1 + 1) / INTERNAL_FPS, t_end])
    every = np.unique(np.r_[keys, dense])
    solved = motion.pose(every)
    _, _, _, want = _rows(solved, np.searchsorted(every, dense))
    want_toe = {}
    for f in LEGS:
        w = want[f]
        want_toe[f] = w.ankle + (_ry(w.heading) @ _rx(w.pitch)) @ motion.legs.toe
    for _ in range(8):
        at_keys = _rows(solved, np.searchsorted(every, keys))
        pos, head, legq, _ = at_keys
        if motion.cap:
            keys_c = np.append(keys, t_end + CAP)
            pos = np.vstack([pos, pos[-1]])
            head = np.append(head, head[-1])
            legq = {f: np.vstack([v, v[-1]]) for f, v in legq.items()}
        else:
            keys_c = keys
        rp = pchip(keys_c, pos)(dense)
        quat = pchip(keys_c, yaw_quaternion(head))(dense)
        rh = _heading_of(quat / np.linalg.norm(quat, axis=1, keepdims=True))
        bad = np.zeros(len(dense), dtype=bool)
        for f in LEGS:
            q = pchip(keys_c, legq[f])(dense)
            ankle, toe = leg_fk(motion.legs, f, rp, rh, q)
            da, dt = ankle - want[f].ankle, toe - want_toe[f]
            err = np.maximum(np.linalg.norm(da, axis=1), np.linalg.norm(dt, axis=1))
            # a swinging foot near the ground is held as tight as a planted one: 5 mm let
            # the interpolated toe through the floor just before it set down
            near = want_toe[f][:, 1] - motion.ground < 2 * SWING_TOL
            bad |= err > np.where(want[f].planted | near, DRIFT_TOL, SWING_TOL)
        if not bad.any():
            break
        # key the frames that stray: interpolation is then exact there, and PCHIP is local
        keys = np.unique(np.concatenate([keys, dense[bad]]))
        at_keys = _rows(solved, np.searchsorted(every, keys))
    return keys, at_keys


# --------------------------------------------------------------------------- step segmentation


@dataclass(frozen=True)
class DetectedStep:
    foot: str
    t_lift: float
    t_land: float
    position: tuple[float, float, float]  # where the foot came down
    height: float  # highest rise above its stance height during the swing


def segment_steps(
    time: FloatArray,
    heights: dict[str, FloatArray],
    positions: dict[str, FloatArray] | None = None,
    *,
    threshold: float | None = None,
    speed_threshold: float | None = None,
    min_swing: float = 0.08,
) -> list[DetectedStep]:
    """Steps from foot heights over frames (seed 004 claim 2).

    (1.1) the heights are filtered (a 3-frame median against spikes); (1.2)–(1.3) a foot is
    in the air where its height is above its stance level (the 5th percentile of its height)
    by more than ``threshold`` (default: 1 cm, or 15 % of its range if that is smaller) and,
    when positions are given and ``speed_threshold`` set, where it moves faster than that;
    (1.4) each flight longer than ``min_swing`` is one step: lift-off and touch-down at the
    threshold crossings (linearly interpolated between frames), the touch-down point and the
    swing's peak height.
    """
    t = np.asarray(time, dtype=float)
    out: list[DetectedStep] = []
    for foot, h in heights.items():
        h = np.asarray(h, dtype=float)
        if len(h) >= 3:
            hf = np.median(np.stack([np.r_[h[:1], h[:-1]], h, np.r_[h[1:], h[-1:]]]), axis=0)
        else:
            hf = h
        base = float(np.percentile(hf, 5))
        span = float(hf.max() - base)
        thr = threshold if threshold is not None else min(0.01, 0.15 * span) if span > 0 else 0.01
        air = hf > base + thr
        if positions is not None and speed_threshold is not None and len(t) > 1:
            p = np.asarray(positions[foot], dtype=float)
            v = np.gradient(p[:, [0, 2]], t, axis=0)
            air |= (np.hypot(v[:, 0], v[:, 1]) > speed_threshold) & (hf > base + thr / 4)
        edges = np.diff(air.astype(int))
        lifts = list(np.flatnonzero(edges == 1) + 1)
        lands = list(np.flatnonzero(edges == -1) + 1)
        if air[0]:
            lifts.insert(0, 0)
        if air[-1]:
            lands.append(len(t) - 1)
        level = base + thr
        for i0, i1 in zip(lifts, lands, strict=False):

            def cross(i: int, hf: FloatArray = hf, level: float = level) -> float:
                if i == 0 or i >= len(t):
                    return float(t[min(i, len(t) - 1)])
                a, b = hf[i - 1], hf[i]
                f = 0.0 if b == a else (level - a) / (b - a)
                return float(t[i - 1] + np.clip(f, 0.0, 1.0) * (t[i] - t[i - 1]))

            t_lift, t_land = cross(i0), cross(i1)
            if t_land - t_lift < min_swing:
                continue
            where: tuple[float, ...] = (math.nan, math.nan, math.nan)
            if positions is not None:  # the footprint: the median of the first half of stance
                nxt = [i for i in lifts if i > i1]
                stop = nxt[0] if nxt else len(t)
                stance = np.asarray(positions[foot])[i1 : max(i1 + 1, (i1 + stop) // 2)]
                where = tuple(float(x) for x in np.median(stance, axis=0))
            peak = float(hf[i0:i1].max() - base)
            out.append(DetectedStep(foot, t_lift, t_land, where, peak))  # type: ignore[arg-type]
    out.sort(key=lambda s: s.t_lift)
    return out


def gait_of(steps: Sequence[DetectedStep]) -> dict[str, float]:
    """Step length, height and cadence of detected steps (seed 004 claim 2, step 1.4)."""
    if len(steps) < 2:
        return {"steps": float(len(steps))}
    lands = np.array([s.position for s in steps])[:, [0, 2]]
    # step length is measured along the walk (one foot to its next footprint), not across it
    way = np.zeros(2)
    for f in {st.foot for st in steps}:
        own = lands[[i for i, st in enumerate(steps) if st.foot == f]]
        if len(own) > 1:
            way += own[-1] - own[0]
    if not way.any():
        way = lands[-1] - lands[0]
    way = way / np.linalg.norm(way) if np.linalg.norm(way) > 1e-9 else np.zeros(2)
    lengths = [
        abs(float((lands[i] - lands[i - 1]) @ way))
        for i in range(1, len(steps))
        if steps[i].foot != steps[i - 1].foot
    ]
    t = [s.t_land for s in steps]
    return {
        "steps": float(len(steps)),
        "step_length": float(np.median(lengths)) if lengths else math.nan,
        "step_height": float(np.median([s.height for s in steps])),
        "cadence": (len(steps) - 1) / (t[-1] - t[0]) if t[-1] > t[0] else math.nan,
    }


# --------------------------------------------------------------------------- the pass


def _postures_between(ir: MotionIR, t0: float, t1: float) -> bool:
    return any(
        s.track == "root" and s.kind == "posture" and s.end > t0 and s.start < t1
        for s in ir.segments
    )


def _step_dicts(steps: list[Step]) -> list[dict[str, Any]]:
    return [
        {
            "foot": s.foot,
            "t_heel_off": round(s.t_heel_off, 6),
            "t_lift": round(s.t_lift, 6),
            "t_land": round(s.t_land, 6),
            "from": [round(float(x), 6) for x in s.start.position],
            "position": [round(float(x), 6) for x in s.end.position],
            "heading": round(s.end.heading, 6),
        }
        for s in steps
    ]


def walk_gait(ir: MotionIR, ctx: PassContext, seg: Segment) -> Gait:
    """The stature gait, or the supplied clip's gait adapted to this walk (claims 3–4)."""
    base = default_gait(ir.skeleton)
    if ctx.options.walk_clip is None:
        return base
    from mtlc.passes import bvh_clip  # the clip machinery is only loaded when asked for

    return bvh_clip.gait_for_walk(ir, ctx, seg, base)


def rest_stance(
    legs: LegModel, rest: FloatArray, root: FloatArray, heading: float
) -> dict[str, Footprint]:
    """Footprints of level feet whose toes are where the rest pose's toes are, under a root on
    the ground at ``root``. The rest pose's soles are pitched 1.7° nose down (hip 0.05, knee
    0.08 rad), its toes on the ground: levelling a foot about its toe moves no sole point more
    than 0.1 mm sideways, about its ankle it slid the toe ~2 mm (5.5 cm/s in one frame)."""
    out = {}
    h = np.array([heading])
    level_toe = (_ry(h) @ legs.toe)[0]
    for f in LEGS:
        _, toe = leg_fk(legs, f, np.zeros((1, 3)), h, rest[None, legs.dofs[f]])
        at = root + toe[0] - level_toe
        at[1] = root[1]
        out[f] = Footprint(at, heading)
    return out


@dataclass
class Arrival:
    """Where a walk left the body: the next walk steps off from these footprints and this root."""

    feet: dict[str, Footprint]
    root: FloatArray  # (3,) the root at the gait's last keyframe
    time: float  # when the walk ended


def final_feet(stance: dict[str, Footprint], steps: list[Step]) -> dict[str, Footprint]:
    feet = dict(stance)
    for st in steps:
        feet[st.foot] = st.end
    return feet


def settle_plan(ir: MotionIR, legs: LegModel, kf: Keyframes, t_from: float, t_to: float) -> None:
    """Shift the root plan's knots in ``[t_from, t_to]`` so that the standing body, anchored by
    ``interpolate.anchored_root`` under the plan, is exactly where the gait's last keyframe left
    it: no settle from the gait's level-footed stance to the rest pose's feet (whose centre lies
    ~2 mm elsewhere from the root), hence no skating at the walk's end."""
    from mtlc.passes.interpolate import anchored_root  # interpolate imports nothing of ours

    plan, skel = ir.root_plan, ir.skeleton
    assert plan is not None and kf.root_position is not None and kf.root_rotation is not None
    q = np.asarray(skel.q_comfort, dtype=float).copy()
    q[legs.dofs["r"] + legs.dofs["l"]] = kf.q[-1]
    planned = plan.at(float(kf.time[-1]))[0]
    anchored = anchored_root(skel, q[None], planned[None], kf.root_rotation[-1:], ir.ground)[0]
    delta = kf.root_position[-1] - anchored
    delta[1] = 0.0
    inside = (plan.time >= t_from - 1e-9) & (plan.time <= t_to + 1e-9)
    plan.position[inside] += delta
    # a walk that only turned its pelvis under the feet ends facing the feet's way (see generate)
    turn = wrap(float(_heading_of(kf.root_rotation[-1:])[0]) - float(plan.at(t_from)[1]))
    if abs(turn) > 1e-7:
        plan.heading[inside] += turn


def generate(ir: MotionIR, ctx: PassContext) -> MotionIR:
    skel, plan = ir.skeleton, ir.root_plan
    if skel is None or plan is None:
        return ir
    legs = ctx.cache.get("legs")
    if legs is None:
        legs = ctx.cache["legs"] = leg_model(skel)
    # stand the feet where the comfortable pose puts them, as interpolation anchors them
    rest = np.asarray(skel.q_comfort, dtype=float)
    ankle_rest, _ = leg_fk(legs, "l", np.zeros((1, 3)), np.zeros(1), rest[None, legs.dofs["l"]])
    half_width = np.array([ankle_rest[0, 0], ankle_rest[0, 2]])
    stand = legs.ankle_height - float(ankle_rest[0, 1])
    walks = sorted((s for s in ir.segments if s.kind == "locomotion"), key=lambda s: s.start)
    instant = [s for s in walks if s.end - s.start < MIN_DURATION]
    walks = [s for s in walks if s.end - s.start >= MIN_DURATION]
    next_foot = "r"
    arrival: Arrival | None = None
    for i, seg in enumerate(walks):
        t0, t1 = seg.start, seg.end
        p0, h0 = plan.at(t0)
        p1, h1 = plan.at(t1)
        h0, h1 = float(h0), float(h1)
        if arrival is not None and _plan_moved(plan, arrival.time, t0):
            arrival = None  # the plan moved the standing body since: start from where it is
        if arrival is None:  # from the rest pose, which interpolation anchors under the plan
            stance = rest_stance(legs, rest, np.array([p0[0], ir.ground, p0[2]]), h0)
            root_start = np.array([p0[0], 0.0, p0[2]])
        else:  # from where the last walk left the feet and the root
            stance, root_start = arrival.feet, np.array([arrival.root[0], 0.0, arrival.root[2]])
        next_start = walks[i + 1].start if i + 1 < len(walks) else math.inf
        gait = walk_gait(ir, ctx, seg)
        goal = np.array([p1[0], ir.ground, p1[2]])
        # the plan arrives facing the work (h1); the feet walk facing the way they go
        way = goal - (stance["r"].position + stance["l"].position) / 2
        walk_heading = math.atan2(way[0], way[2]) if math.hypot(way[0], way[2]) > 1e-9 else h0
        steps = plan_footsteps(stance, goal, walk_heading, h1, gait, half_width, next_foot)
        walking = sum(st.kind in (START, WALK) for st in steps)
        if (
            walking
            and _steps_need(steps, gait) * _slowest(steps, gait) < t1 - t0
            and (gait.cadence is None)
        ):
            # the front end counted one step more (its distance is the root's, ours the feet's
            # centre's, which can straddle a multiple of the step length): take it, rather than
            # stand a third of the walk (62 steps/min on the 1st-percentile woman's 0.6 m)
            more = plan_footsteps(stance, goal, walk_heading, h1, gait, half_width, next_foot,
                                  walking + 1)  # fmt: skip
            if _steps_need(more, gait) <= (t1 - t0) * (1 + 1e-9):
                steps = more
        wide = bool(steps) and needs_wide_squat(ir, t1, next_start, goal, h1)
        if wide:
            steps = widen(steps, WIDE_STEP * legs.length, WIDE_TURN_OUT)
        time_steps(steps, t0, t1, gait)
        root_end, h_end = np.array([p1[0], 0.0, p1[2]]), h1
        if not _travels(stance, goal):  # the root moves and turns only as the feet in place do
            last = final_feet(stance, steps)
            root_end = root_start + _root_over(last, half_width) - _root_over(stance, half_width)
            h_end = _unstepped_heading(last, h1)
        motion = WalkMotion(
            steps, stance, t0, t1, root_start, root_end,
            h0, h_end, stand, ir.ground, gait, legs, half_width,
        )  # fmt: skip
        motion.cap = not _postures_between(ir, t1, t1 + CAP + 1e-9) and t1 + CAP < next_start
        keys, (pos, head, legq, kfeet) = _key_times(motion)
        clipped = 0
        for f in LEGS:
            ft = kfeet[f]
            raw = leg_ik(legs, f, pos, head, ft.ankle, ft.heading, ft.pitch, clip=False)
            clipped += int(np.any(np.abs(raw - legq[f]) > 1e-6, axis=1).sum())
        times = keys
        if motion.cap:
            times = np.append(keys, t1 + CAP)
            pos = np.vstack([pos, pos[-1]])
            head = np.append(head, head[-1])
            legq = {f: np.vstack([v, v[-1]]) for f, v in legq.items()}
        dof_names = tuple(f"{f}_{d}" for f in LEGS for d in LEG_DOFS)
        seg.keyframes = Keyframes(
            time=times,
            dofs=dof_names,
            q=np.hstack([legq[f] for f in LEGS]),
            root_position=pos,
            root_rotation=yaw_quaternion(head),
        )
        detected = _segment_generated(motion)
        seg.result.update(
            {
                "steps": _step_dicts(steps),
                "stance": {f: [round(float(x), 6) for x in stance[f].position] for f in LEGS},
                "gait": {
                    "step_length": round(gait.step_length, 6),
                    "step_height": round(gait.step_height, 6),
                    "cadence": None if gait.cadence is None else round(gait.cadence, 6),
                    "source": gait.source,
                },
                "feet_held_until": round(float(times[-1]), 6),
                "keyframes_at_limits": clipped,
                "segmentation": [
                    {"foot": d.foot, "t_lift": round(d.t_lift, 6), "t_land": round(d.t_land, 6)}
                    for d in detected
                ],
            }
        )
        if wide:
            seg.result[WIDE_RESULT] = {"step": round(WIDE_STEP * legs.length, 6),
                                       "turn_out": round(WIDE_TURN_OUT, 6)}  # fmt: skip
        if steps:
            next_foot = "l" if steps[-1].foot == "r" else "r"
        # the standing body after the walk stays where the gait left it, until the next walk
        settle_plan(ir, legs, seg.keyframes, t1, next_start)
        arrival = Arrival(final_feet(stance, steps), seg.keyframes.root_position[-1].copy(), t1)
    for seg in instant:
        _record_instant_walk(seg)
    return ir


def _slowest(steps: list[Step], gait: Gait) -> float:
    """How much :func:`time_steps` may slow these steps before a step more is taken: by
    ``MAX_STRETCH``, and no slower than ``MIN_CADENCE`` (a walk the footing pass shortened
    by 12 cm kept 7 steps in the 8's time: 81.6 steps/min)."""
    need = _steps_need(steps, gait)
    if need <= 0.0:
        return MAX_STRETCH
    return max(1.0, min(MAX_STRETCH, 60.0 * len(steps) / need / MIN_CADENCE))


def _steps_need(steps: list[Step], gait: Gait) -> float:
    """Seconds the steps take at the stature's cadence (as :func:`time_steps` times them)."""
    kinds = [START] + [st.kind for st in steps[1:]]
    return sum(gait.step_seconds(k, st.length) for k, st in zip(kinds, steps, strict=True))


def _travels(stance: dict[str, Footprint], goal: FloatArray) -> bool:
    """Whether :func:`plan_footsteps` walks to ``goal`` (shorter walks only turn in place)."""
    d = goal - (stance["r"].position + stance["l"].position) / 2
    return float(np.hypot(d[0], d[2])) >= MIN_DISTANCE


def _root_over(feet: dict[str, Footprint], half_width: Any) -> FloatArray:
    """The ground root that stands over ``feet`` as :func:`stance_at` puts feet under a root.
    A walk too short to step moves the root only by as much as this moves, not to its goal, or
    the feet would slide under the standing body after it (1 cm walks skated 2.2 cm/s)."""
    heading = _feet_heading(feet)
    centre = (feet["r"].position + feet["l"].position) / 2
    forward = _side(heading, "l", half_width) + _side(heading, "r", half_width)
    root = centre - forward / 2
    return np.array([root[0], 0.0, root[2]])


def _feet_heading(feet: dict[str, Footprint]) -> float:
    return math.atan2(
        math.sin(feet["r"].heading) + math.sin(feet["l"].heading),
        math.cos(feet["r"].heading) + math.cos(feet["l"].heading),
    )


def _unstepped_heading(feet: dict[str, Footprint], planned: float) -> float:
    """The heading a walk that does not travel ends in: the feet's, when the plan's turn was too
    small to step (under ``FINAL_TURN``); the pelvis turned alone and the standing body after it
    turned its feet on the spot (1 cm walks skated 1.7 cm/s)."""
    feet_heading = _feet_heading(feet)
    off = wrap(planned - feet_heading)
    return planned if abs(off) < 1e-9 else planned - off


def _plan_moved(plan: Any, t_from: float, t_to: float) -> bool:
    """Whether the root plan moves or turns the standing body between two walks (it does when
    a walk without time, absorbed by the plan, falls between them)."""
    (a, ha), (b, hb) = plan.at(t_from), plan.at(t_to)
    return bool(np.hypot(*(b - a)[[0, 2]]) > 1e-6 or abs(wrap(float(hb) - float(ha))) > 1e-6)


def _record_instant_walk(seg: Segment) -> None:
    """A walk without time (zero length, so zero MTM paces) takes no steps and has no gait: the
    body stands, and the root plan holds wherever the walk put it."""
    seg.keyframes = None
    seg.result.update(
        {"steps": [], "feet_held_until": round(seg.end, 6), "keyframes_at_limits": 0,
         "segmentation": []}
    )  # fmt: skip


def sole_points(legs: LegModel, feet: dict[str, FootTrack]) -> dict[str, FloatArray]:
    """The lowest of heel and toe tip of each foot (N, 3): what touches the ground."""
    out = {}
    for f, ft in feet.items():
        R = _ry(ft.heading) @ _rx(ft.pitch)
        pts = np.stack([ft.ankle + R @ legs.heel, ft.ankle + R @ legs.toe], axis=1)
        out[f] = np.take_along_axis(pts, pts[:, :, 1].argmin(axis=1)[:, None, None], 1)[:, 0]
    return out


def _segment_generated(motion: WalkMotion) -> list[DetectedStep]:
    """Claim 2 on our own gait: the plan's steps must come back from the foot heights.

    Also sets each step's ``t_heel_off`` to when its foot actually stopped being flat (the
    roll that the ankle's dorsiflexion limit asks for may start before the scheduled one).
    """
    t = np.arange(motion.t0, motion.t1 + 1e-9, 1 / 120)
    *_, feet = motion.pose(t)
    for st in motion.steps:
        flat = (t <= st.t_lift) & (feet[st.foot].pitch <= 1e-6)
        if flat.any():
            st.t_heel_off = min(st.t_heel_off, float(t[np.flatnonzero(flat)[-1]]))
    low = sole_points(motion.legs, feet)
    return segment_steps(t, {f: low[f][:, 1] for f in LEGS}, low, threshold=0.005, min_swing=0.02)
