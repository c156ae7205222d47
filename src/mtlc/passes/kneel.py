"""The stepping kneel: a kneel (and the stand from it) that a person could do, as dense keyframes.

With knee flexion limited to 135° and ankle dorsiflexion to 20°, no path from standing to both
knees on the ground keeps the centre of mass over the feet without a step: a knee lands half a
metre in front of its own toes. People kneel by stepping: the right foot steps back onto its
toes, the body lowers onto the right knee (a half kneel: left foot in front, right knee and toes
down), then the weight goes onto the right leg and the left leg swings back, folded, so that its
knee lands beside the right one. Rising is the same motion in reverse. Each phase (``PHASES``)
keeps the centre of mass over the support of the contacts it has (``mtlc.metrics.support``:
soles, kneeling knees), and a planted foot never slides: it steps (lifts, moves, lands) or
rolls on its balls. A foot with its heel up stands on its balls and toe tip, the toes bent up
at the balls (``TOE_VARS``): on the tip of a rigid foot it was a point, and a knee with its
toe, or two toe tips, a segment with no inside (issue 18).

The motion is solved frame by frame at ``FPS`` by a whole-body inverse kinematics (``track``):
root position, both legs with their toes and the spine (flexion and lateral flexion) by damped Gauss-Newton with
an analytic Jacobian, started from the previous frame moved on by its last change. Planted
contacts weigh most, the centre of mass's target next, and a pull toward the previous frame
keeps the solution smooth; all frames are then polished at once on their planted contacts
(``Body.descend`` solves many frames in one batch). The interpolation grid's frames between
two solved ones are blends polished onto the contacts' straight paths (``KneelPlan.on_grid``).
Everything is computed in the body frame (facing +Z, ground at y = 0) and placed in the world
at the end (``to_world``).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from mtlc.body import (
    center_of_mass,
    forward,
    forward_part,
    site_positions,
)
from mtlc.body.ik.dls import solve_spd
from mtlc.body.kinematics import segment_coms
from mtlc.body.skeleton import Skeleton
from mtlc.ir.model import FloatArray
from mtlc.metrics import CONTACT_TOL

KNEE_HEIGHT = 0.05  # m: knee centre above the ground when kneeling (as the kneel posture)
TUCK_ANKLE = math.radians(15.0)  # kneeling ankles: toes tucked under, the foot near vertical
SPLIT = 0.65  # m: the right toe this far behind the left toe when it lands (a half kneel)
STEP_LIFT = 0.05  # m: a stepping foot's clearance at mid-swing
LAND_PITCH = math.radians(60.0)  # the back foot lands on its balls and toes, heel up this much
KNEEL_COM_BEHIND = 0.12  # m: the kneeling CoM's target behind the knees
SINGLE_KNEE_AT = 0.5  # share of the knee-to-toe distance: the CoM target on one kneeling leg
FPS = 30.0
# rad/s: the fastest a joint turns in the kneel (``track``); issue 19 allows 360°/s (12° a
# 30 fps frame), this leaves room for the balance pass's corrections after it
MAX_JOINT_SPEED = math.radians(300.0)
# rad/s: a blended frame between two solved ones turns its joints no faster than this or than
# the plan does (``pace_bounds``)
GRID_JOINT_SPEED = math.radians(330.0)
ITERATIONS = 8  # Gauss-Newton iterations a frame (it does not converge: see docs/passes.md)
PREDICT = 1.0  # a frame starts from the last one moved on by this share of its last change
STEP_TOL = 1e-5  # rad or m: a frame whose last step was this small has converged
PLANT_W = 1000.0  # residual weights (per metre, per radian)
KNEE_W = 60.0
# the CoM on one kneeling leg (its support is a narrow triangle): strong enough to hold it
# there against the swinging leg (at 60 it sat 17-40 mm off the leg's axis; issue 18)
ONE_KNEE_COM_W = 250.0
# the kneeling leg's planted points during the swing, × PLANT_W: at 1 that CoM pull slid the
# right toe tip 2-3 cm/s for men P90-P99 and women P99
KNEEL_LEG_FIRM = 2.0
HEEL_W = 20.0  # a kneeling heel's guide
LAND_HEEL_W = 20.0  # and a landing one's
SWING_W = 40.0
COM_W = 20.0
SMOOTH_W = 1.0
ROOT_SMOOTH = 10.0  # the root's pull toward its last place, per metre, × a joint's per radian
POLISH_SMOOTH = 0.01
POLISH_ITERATIONS = 8
LEVEL_W = 40.0
NOMINAL_W = 0.1
SPINE_W = 1.0
TOE_NOMINAL_W = 5.0
SWING_TOE_W = 30.0  # the stepping foot's toes led to its heel's pitch (per radian)
GROUND_EPS = 2e-4  # m: the ground's barrier is smooth over this much
# per metre below the ground: at PLANT_W (1000) a swinging toe led by its joint path went
# 1.8 mm into the floor, the path pulling it as hard as the ground pushed (k07, male P95)
GROUND_W = 3000.0

# (name, share of the motion): the phases of kneeling on both knees, in order
# (the shares follow the joint travel each phase asks for at ``MAX_JOINT_SPEED``: with 15 % and
# 26 % the step back's and the second knee's joints ran at that limit for 10-12 of 12 and 16 of
# 20 frames; at 17 % for going down onto the knee both knees ran at it and the pelvis dropped
# 7 cm in a frame, the left forefoot 35 mm into the floor)
PHASES: tuple[tuple[str, float], ...] = (
    ("weight on the left foot", 0.05),
    ("right foot steps back", 0.17),
    ("weight between the feet", 0.05),
    ("down onto the right knee", 0.22),
    ("weight on the right knee", 0.07),
    ("left knee down beside it", 0.34),
    ("settle on both knees", 0.10),
)

LEG_VARS = tuple(
    f"{s}_{d}"
    for s in ("r", "l")
    for d in ("hip_flex", "hip_abd", "hip_rot", "knee_flex", "ankle_dorsi", "ankle_inv")
)
SPINE_VARS = ("lumbar_flex", "lumbar_lat", "thorax_flex", "thorax_lat")
TOE_VARS = ("r_toes_dorsi", "l_toes_dorsi")  # last: the legs' and spine's columns stay put
R_TOES = len(LEG_VARS) + len(SPINE_VARS)  # the right toes' place among a state's joints
SOLE = ("toe", "heel", "ball_med", "ball_lat")
ALL_COLS = np.arange(3 + 12 + 4 + 2)  # every column of a state vector
LEFT_COLS = np.r_[3 + 6 : 3 + 12, 3 + 12 + 4 + 1]  # the left leg's columns in a state vector
# (its six, then its toes': they swing with it from bent on the ground to bent on the ground)
KNEE_COL, HIP_COL, ANKLE_COL = 3, 0, 4  # knee, hip and ankle flexion among a leg's dofs
PELVIS_W = 20.0
# the pose on the right knee alone is solved once with the CoM pulled this hard (at 250 a
# frame's solve left it 4 cm off, the spine at its side-bend limits), and the body is led to
# it at this weight per radian (at 30 the led joints pushed the left forefoot 2 mm into the
# floor)
ONE_POSE_COM_W = 2000.0
ONE_PATH_W = 10.0
# mid-swing of the second knee's leg (hip flex, abd, rot, knee, ankle dorsi, inversion; NaN:
# as the path has it): the knee folded, the thigh turned out and the foot pointed, so the lower
# leg comes round the side; straight back under the hip it would pass 4-7 cm below the ground
# (knee flexion stops at 135°, the kneeling pelvis is 0.48 m up). The thigh is drawn in (20°
# adducted) toward the kneeling one, which keeps the CoM over that leg: abducted 5° and
# turned out 38° it was 4-5 cm off it for the large women, and the old solve got back only by
# flinging the leg across in one frame (issue 19)
SWING_LEG = np.radians([np.nan, -20.0, 25.0, 133.0, -45.0, np.nan, np.nan])
LIFT_END = 0.2  # share of the second knee's phase in which its toe rises straight up
LIFT_HIP = math.radians(15.0)  # and extra hip flexion: the thigh rises first
LIFT_FLEX = math.radians(30.0)  # extra knee flexion at mid-swing: the foot clears the ground
JOINT_W = 30.0
LIFT_W = 150.0
MIN_KNEE = 0.08  # rad: the least knee flexion (the comfortable pose's)
HEEL_DOWN = 0.5  # share of the descent with the front heel down
KNEE_DOWN_BY = 0.8  # share of the descent by which the kneeling knee's path is down
GROUND_SITES = tuple(f"{s}_{n}" for s in ("r", "l") for n in (*SOLE, "foot", "hand", "fingertip"))
SOLE_SITES = {s: tuple(f"{s}_{n}" for n in SOLE) for s in ("r", "l")}
CONTACT_SITES = tuple(f"{s}_{n}" for s in ("r", "l") for n in SOLE)
KNEE_POINTS = ("joint:r_knee", "joint:l_knee")


def smoothstep(s: FloatArray | float) -> FloatArray:
    s = np.clip(np.asarray(s, dtype=float), 0.0, 1.0)
    return s * s * (3.0 - 2.0 * s)


@dataclass
class Targets:
    """What one frame must meet: points (site or ``joint:name``) with weights, a CoM target,
    and relative constraints (a toe-standing foot kept level across and pointing ahead)."""

    points: list[tuple[str, FloatArray, float]] = field(default_factory=list)
    com: FloatArray | None = None
    level: list[str] = field(default_factory=list)  # feet ("r", "l") kept level and ahead
    nominal: FloatArray | None = None  # (V,) joint values weakly pulled toward (NaN: free)
    nominal_w: FloatArray | float = 0.0  # (V,) their weights
    com_w: float = COM_W
    smooth: float = SMOOTH_W
    joints: tuple[FloatArray, FloatArray, float] | None = None  # (columns of x, values, weight)
    root_y: tuple[float, float] | None = None  # a pelvis height and its weight
    # ``Body._linear_rows``'s form, built on first use: a Targets is not changed once solved
    linear: Any = field(default=None, repr=False, compare=False)


LOWER_JOINTS = ("pelvis", "lumbar", "thorax", "r_hip", "r_knee", "r_ankle", "l_hip", "l_knee",
                "l_ankle", "r_toes", "l_toes")  # fmt: skip


def lower_body(skel: Skeleton, q_base: FloatArray) -> Skeleton:
    """The manikin the kneel's solve runs on: the joints it moves (``LOWER_JOINTS``), with the
    head and arms, which keep their ``q_base`` angles, one rigid body with the thorax (their
    mass and centre of mass lumped into its segment, their sites moved onto its frame). The
    same points and centre of mass as ``skel`` for any state; 9 joints 4 deep instead of 19
    joints 7 deep, which is what a frame's forward kinematics costs."""
    pose = forward(skel, np.asarray(q_base, dtype=float)[None])
    th = skel.joint_index("thorax")
    R, p = pose.R[0, th], pose.p[0, th]
    rigid = skel.ancestor[:, th]  # the thorax and every joint below it
    mass = float(skel.masses[rigid].sum())
    com = R.T @ (skel.masses[rigid] @ segment_coms(skel, pose)[0, rigid] / mass - p)
    joints = [
        replace(j, mass=mass, com=tuple(com)) if j.name == "thorax" else j
        for j in skel.joints
        if j.name in LOWER_JOINTS
    ]
    sites = []
    for site in skel.sites:
        if site.joint in LOWER_JOINTS:
            sites.append(site)
            continue
        j = skel.joint_index(site.joint)
        Rj, pj = pose.R[0, j], pose.p[0, j]
        where = R.T @ (pj + Rj @ np.asarray(site.offset) - p)
        direction = None if site.direction is None else tuple(R.T @ Rj @ site.direction)
        sites.append(replace(site, joint="thorax", offset=tuple(where), direction=direction))
    return Skeleton(tuple(joints), tuple(sites), comfort=dict(skel.comfort))


class Body:
    """The whole-body IK's model: which dofs move, limits, and the residual of one frame."""

    def __init__(self, skel: Any, q_base: FloatArray) -> None:
        self.skel = skel
        self.q_base = np.asarray(q_base, dtype=float).copy()
        self.idx = np.array([skel.dof_index(n) for n in (*LEG_VARS, *SPINE_VARS, *TOE_VARS)])
        self.lo, self.hi = skel.lower[self.idx].copy(), skel.upper[self.idx].copy()
        # a straight knee is singular (the hip cannot go down to first order): keep them bent
        for col in (KNEE_COL, 6 + KNEE_COL):
            self.lo[col] = max(self.lo[col], min(MIN_KNEE, float(q_base[self.idx[col]])))
        self.knees = [skel.joint_index("r_knee"), skel.joint_index("l_knee")]
        # the points a target can name: the joint each rides on and its offset there
        names = (*GROUND_SITES, *KNEE_POINTS)
        self.points = {n: i for i, n in enumerate(names)}
        self.n_named = len(names)  # the points a target names; the centre of mass after them
        # what ``kinematics`` runs on: the joints the kneel moves, the rest rigid on the thorax
        small = lower_body(skel, self.q_base)
        self.small = small
        self.small_base = np.array([self.q_base[skel.dof_index(n)] for n in small.dof_names])
        self.small_cols = np.array([small.dof_index(skel.dof_names[i]) for i in self.idx])
        self.point_joint = np.array(
            [small.joint_index(n[6:] if n.startswith("joint:") else small.site(n).joint)
             for n in names]
        )  # fmt: skip
        self.point_offset = np.array(
            [np.zeros(3) if n.startswith("joint:") else small.site(n).offset for n in names],
            dtype=float,
        )
        self.dof_joint = small.dof_joint[self.small_cols]  # (V,) the joint each variable turns
        self.moves = small.ancestor[self.point_joint][:, self.dof_joint]  # (P, V)
        below = small.ancestor[:, self.dof_joint].T  # (V, J): segment j moves with variable v
        self.mass_below = below * small.masses  # (V, J)
        self.carried = (below @ small.masses)[:, None]  # (V, 1): the mass each variable turns
        # the root's Jacobian columns of the points, and of the CoM ([1]) or not ([0])
        self.root_columns = np.zeros((2, len(names) + 1, 3, 3))
        self.root_columns[:, : len(names)] = np.eye(3)
        self.root_columns[1, len(names)] = np.eye(3)
        self.ground_lift = np.zeros(len(names))  # the barrier's height of each named point
        self.ground_lift[len(GROUND_SITES) :] = KNEE_HEIGHT - 0.002  # knees: as kneeling

    def q_of(self, x: FloatArray) -> FloatArray:
        q = np.tile(self.q_base, (len(x), 1))
        q[:, self.idx] = x[:, 3:]
        return q

    def pose(self, x: FloatArray) -> Any:
        return forward(self.skel, self.q_of(x), x[:, :3], with_axes=False)  # the body frame

    def residual(self, x: FloatArray, tg: Targets, prev: FloatArray) -> FloatArray:
        """Residuals (B, R) of a batch of candidate states ``x`` (B, 3 + V): the plain statement
        of what ``_linearise`` computes with its Jacobian for one state (its test's reference)."""
        pose = self.pose(x)
        out = []
        for name, target, w in tg.points:
            if name.startswith("joint:"):
                p = pose.p[:, self.skel.joint_index(name[6:])]
            else:
                p = site_positions(self.skel, pose, name)
            out.append(w * (p - target))
        for side in tg.level:
            pts = site_positions(self.skel, pose, SOLE_SITES[side])
            across = pts[:, 2, 1] - pts[:, 3, 1]  # ball_med vs ball_lat height
            ahead = pts[:, 0, 0] - pts[:, 1, 0]  # toe and heel on one line along +Z
            out.append(np.stack([LEVEL_W * across, PLANT_W * ahead], axis=1))
        if tg.com is not None:
            out.append(tg.com_w * (center_of_mass(self.skel, pose)[:, [0, 2]] - tg.com))
        # nothing below the ground: sole points, ankles, and knees no lower than kneeling
        soles = site_positions(self.skel, pose, GROUND_SITES)[..., 1]
        knees = pose.p[:, self.knees, 1] - (KNEE_HEIGHT - 0.002)
        low = np.concatenate([soles, knees], axis=1)
        out.append(GROUND_W * 0.5 * (low - np.sqrt(low * low + GROUND_EPS**2)))  # smooth min(·, 0)
        out.append(tg.smooth * ROOT_SMOOTH * (x[:, :3] - prev[:3]))
        out.append(tg.smooth * (x[:, 3:] - prev[3:]))
        if tg.root_y is not None:
            out.append(tg.root_y[1] * (x[:, 1:2] - tg.root_y[0]))
        if tg.joints is not None:
            cols, values, w = tg.joints
            out.append(w * (x[:, cols] - values))
        if tg.nominal is not None:
            free = np.isnan(tg.nominal)
            w = np.where(free, 0.0, tg.nominal_w)
            out.append(w * np.where(free, 0.0, x[:, 3:] - np.nan_to_num(tg.nominal)))
        return np.concatenate(out, axis=1)

    def steps(
        self, jac: FloatArray, r0: FloatArray, lam: FloatArray, x: FloatArray,
        lo: FloatArray, hi: FloatArray,
    ) -> FloatArray:  # fmt: skip
        """Damped Gauss-Newton steps (F, n) of F frames at once (``jac`` (F, R, n), ``r0``
        (F, R)); variables at a bound (``lo``, ``hi``: (F, n)) that a step would push past it
        are held (their columns dropped), so the rest of the body still moves."""
        f, n = x.shape
        jtj = np.swapaxes(jac, 1, 2) @ jac
        g0 = np.einsum("frn,fr->fn", jac, r0)
        jtj0, g = jtj.copy(), g0
        low, high = x <= lo + 1e-9, x >= hi - 1e-9
        bound = bool(low.any() or high.any())  # no joint at a limit: nothing to hold
        held = np.zeros((f, n), dtype=bool)
        for _ in range(3):
            diag = jtj.reshape(f, n * n)[:, :: n + 1]  # a view: Marquardt's damping, per variable
            diag += lam[:, None] * (diag + 1e-6)
            step = -solve_spd(jtj, g[..., None])[..., 0]  # np.linalg.solve's LAPACK call
            if not bound:
                break
            step[held] = 0.0
            out = ((low & (step < 0)) | (high & (step > 0))) & ~held
            if not out.any():
                break
            held |= out
            free = ~held  # a held column dropped: its row and column of JᵀJ, its entry of Jᵀr
            jtj = jtj0 * (free[:, :, None] & free[:, None, :])
            g = g0 * free
        return step

    def solve(self, x0: FloatArray, tg: Targets, iterations: int = ITERATIONS) -> FloatArray:
        """Damped Gauss-Newton from ``x0``, joints clipped into their limits at every step, then
        polished (``polish``)."""
        x = self.descend(x0[None], x0[None], [tg], iterations)
        return self.polish(x, [tg])[0]

    def polish(self, x: FloatArray, tgs: list[Targets]) -> FloatArray:
        """A few steps on the planted contacts (weight ``PLANT_W``), levels and CoM alone, for
        states ``x`` (F, n) at once: they put planted points back within microns (a planted
        point that drifts by a fraction of a millimetre a frame skates centimetres a second).
        The CoM is pulled at most at ``COM_W`` here: the polish drops a swinging foot's
        targets, and a frame's stronger pull (``ONE_KNEE_COM_W``) then flung that leg 25 cm
        up in one frame and back, the centre of mass with it (issue 18)."""
        hard = [Targets(points=[p for p in tg.points if p[2] >= PLANT_W], level=tg.level,
                        com=tg.com, com_w=min(tg.com_w, COM_W)) for tg in tgs]  # fmt: skip
        rows = [i for i, tg in enumerate(hard) if tg.points]
        out = x.copy()
        if rows:
            out[rows] = self.descend(x[rows], x[rows], [hard[i] for i in rows], POLISH_ITERATIONS)
        return out

    def descend(
        self, x0: FloatArray, prev: FloatArray, tgs: list[Targets], iterations: int,
        bounds: tuple[FloatArray, FloatArray] | None = None,
    ) -> FloatArray:  # fmt: skip
        """Damped Gauss-Newton of F frames at once (states (F, n), one ``Targets`` each, each
        pulled toward its ``prev``): a frame stops once its step is under ``STEP_TOL``, and
        only the frames still moving are computed. ``bounds`` (each (F, V)) narrow the joint
        limits per frame, and bound the root (``track``'s speed limits)."""
        if bounds is None:
            lo = np.broadcast_to(np.r_[np.full(3, -np.inf), self.lo], x0.shape)
            hi = np.broadcast_to(np.r_[np.full(3, np.inf), self.hi], x0.shape)
        else:
            lo, hi = bounds
        lin = self._stacked_rows(tgs)
        com = any(tg.com is not None for tg in tgs)  # the CoM is computed only if a row uses it
        x, lam = x0.copy(), np.full(len(x0), 1e-2)
        r0, jac = self._linearise_batch(x, lin, prev, com)
        cost = np.einsum("fr,fr->f", r0, r0)
        live = np.arange(len(x0))
        xl = x.copy()
        for _ in range(iterations):
            cand = xl + self.steps(jac, r0, lam, xl, lo, hi)
            cand = np.clip(cand, lo, hi)
            rc, jc = self._linearise_batch(cand, lin, prev, com)
            cost_c = np.einsum("fr,fr->f", rc, rc)
            better = cost_c < cost
            going = ~(better & (np.abs(cand - xl).max(axis=1) < STEP_TOL))
            if better.all():
                xl, r0, jac, cost = cand, rc, jc, cost_c
            else:
                xl[better], r0[better], jac[better] = cand[better], rc[better], jc[better]
                cost = np.where(better, cost_c, cost)
            lam = np.where(better, np.maximum(lam * 0.3, 1e-5), lam * 10.0)
            if not going.all():  # frames that have converged leave the batch
                x[live] = xl
                live, xl, r0, jac, lam, prev, cost, lo, hi = (
                    live[going],
                    xl[going],
                    r0[going],
                    jac[going],
                    lam[going],
                    prev[going],
                    cost[going],
                    lo[going],
                    hi[going],
                )
                lin = tuple(a[going] for a in lin)
                if not live.size:
                    return x
        x[live] = xl
        return x

    def kinematics(self, x: FloatArray, com: bool = True) -> tuple[FloatArray, FloatArray]:
        """Points (F, P + 1, 3) of states ``x`` (F, n): the named points, then the centre of
        mass (zeros unless ``com``); and their Jacobians (F, P + 1, 3, n), from one forward
        kinematics call on ``small``: a point's column for a variable is ``axis × (point −
        joint)``, the CoM's ``axis × (Σ m c − M_v · joint) / M`` over the segments the variable
        turns (M_v their mass), the root's the identity."""
        f, n = x.shape
        small, m = self.small, self.n_named
        q = np.empty((f, len(self.small_base)))
        q[:] = self.small_base
        q[:, self.small_cols] = x[:, 3:]
        pose = forward(small, q, x[:, :3])
        pts = np.zeros((f, m + 1, 3))
        pts[:, :m] = pose.p[:, self.point_joint] + np.einsum(
            "fpab,pb->fpa", pose.R[:, self.point_joint], self.point_offset
        )
        axes, origins = pose.axes[:, self.small_cols], pose.p[:, self.dof_joint]
        # what each axis turns about its joint, and the columns, a coordinate at a time
        # ((3, F, P + 1, V) arrays: long element-wise passes instead of ``cross`` over a last
        # axis of 3; the same products and differences as ``cross``, so the same numbers)
        arms = np.zeros((3, f, m + 1, n - 3))
        for k in range(3):
            arms[k, :, :m] = (pts[:, :m, k, None] - origins[:, None, :, k]) * self.moves
        jac = np.empty((f, m + 1, 3, n))
        jac[..., :3] = self.root_columns[int(com)]
        if com:
            segments = pose.p + np.einsum("fjab,jb->fja", pose.R, small.coms)
            total = small.total_mass
            pts[:, m] = np.einsum("j,fja->fa", small.masses, segments) / total
            com_arms = (self.mass_below @ segments - self.carried * origins) / total
            for k in range(3):
                arms[k, :, m] = com_arms[..., k]
        a0, a1, a2 = (axes[:, None, :, k] for k in range(3))
        b0, b1, b2 = arms
        np.subtract(a1 * b2, a2 * b1, out=jac[:, :, 0, 3:])
        np.subtract(a2 * b0, a0 * b2, out=jac[:, :, 1, 3:])
        np.subtract(a0 * b1, a1 * b0, out=jac[:, :, 2, 3:])
        return pts, jac

    def barrier(self, pts: FloatArray, jac: FloatArray) -> tuple[FloatArray, FloatArray]:
        """The ground's residual (..., P) and Jacobian (..., P, n): a smooth min(height, 0) of
        the named points (knees no lower than kneeling), from ``kinematics``' output."""
        m = self.n_named
        low = pts[..., :m, 1] - self.ground_lift
        root = np.sqrt(low * low + GROUND_EPS**2)
        return GROUND_W * 0.5 * (low - root), (GROUND_W * 0.5 * (1.0 - low / root))[
            ..., None
        ] * jac[..., :m, 1, :]

    def _linear_rows(self, tg: Targets) -> tuple[FloatArray, ...]:
        """``tg``'s residual rows that are linear in the points: A @ points - a (targets,
        levels, the CoM's); and those linear in the state: B @ x - b (smoothness to the
        previous frame, whose part of b is left for the call, then pelvis height, joint
        values, nominal pose). Built once per ``Targets``: a frame's solve reuses them."""
        if tg.linear is not None:
            return tg.linear  # type: ignore[no-any-return]
        n, m = 3 + len(self.idx), self.n_named
        width = 3 * (m + 1)
        # a target point: three rows, w at the point's coordinate
        k = len(tg.points)
        point = np.repeat(np.array([self.points[p[0]] for p in tg.points], dtype=np.intp), 3)
        weight = np.repeat(np.array([p[2] for p in tg.points], dtype=float), 3)
        A = np.zeros((3 * k + 2 * len(tg.level) + 2 * (tg.com is not None), width))
        A[np.arange(3 * k), 3 * point + np.tile(np.arange(3), k)] = weight
        a = [weight * np.array([p[1] for p in tg.points], dtype=float).reshape(3 * k)]
        r = 3 * k
        for side in tg.level:
            toe, heel, med, lat = (self.points[f"{side}_{n}"] for n in SOLE)
            A[r, [3 * med + 1, 3 * lat + 1]] = LEVEL_W, -LEVEL_W  # level across
            A[r + 1, [3 * toe, 3 * heel]] = PLANT_W, -PLANT_W  # toe and heel on one line
            a.append(np.zeros(2))
            r += 2
        if tg.com is not None:
            A[r, 3 * m], A[r + 1, 3 * m + 2] = tg.com_w, tg.com_w
            a.append(tg.com_w * np.asarray(tg.com, dtype=float))
        eye = np.eye(n)
        scale = np.full(n, tg.smooth)
        scale[:3] *= ROOT_SMOOTH
        B, b = [scale[:, None] * eye], [np.zeros(n)]
        if tg.root_y is not None:
            B.append(tg.root_y[1] * eye[1:2])
            b.append(np.array([tg.root_y[1] * tg.root_y[0]]))
        if tg.joints is not None:
            cols, values, w = tg.joints
            B.append(w * eye[cols])
            b.append(w * values)
        if tg.nominal is not None:
            free = np.isnan(tg.nominal)
            w = np.where(free, 0.0, tg.nominal_w)
            B.append(w[:, None] * eye[3:])
            b.append(w * np.where(free, 0.0, np.nan_to_num(tg.nominal)))
        tg.linear = (A, np.concatenate(a), np.concatenate(B), np.concatenate(b), scale)
        return tg.linear  # type: ignore[no-any-return]

    def _stacked_rows(self, tgs: list[Targets]) -> tuple[FloatArray, ...]:
        """``_linear_rows`` of F frames, stacked (frames with fewer rows padded with zeros)."""
        forms = [self._linear_rows(tg) for tg in tgs]
        if len(forms) == 1:
            return tuple(a[None] for a in forms[0])

        def stack(k: int) -> FloatArray:
            parts = [form[k] for form in forms]
            out = np.zeros((len(parts), max(len(p) for p in parts), *parts[0].shape[1:]))
            for f, p in enumerate(parts):
                out[f, : len(p)] = p
            return out

        return tuple(stack(k) for k in range(5))

    def _linearise_batch(
        self, x: FloatArray, lin: tuple[FloatArray, ...], prev: FloatArray, com: bool = True
    ) -> tuple[FloatArray, FloatArray]:
        """Residuals (F, R) and Jacobians (F, R, n) at states ``x`` (F, n), in ``residual``'s
        order (a candidate is evaluated with its Jacobian, which the next step needs if
        accepted)."""
        A, a, B, b, scale = lin
        pts, jac = self.kinematics(x, com)
        f, n = x.shape
        lin_r = np.einsum("frw,fw->fr", A, pts.reshape(f, -1)) - a
        lin_j = A @ jac.reshape(f, -1, n)
        ground_r, ground_j = self.barrier(pts, jac)
        state_r = np.einsum("frn,fn->fr", B, x) - b
        state_r[:, :n] -= scale * prev  # the pull toward the previous frame
        return (np.concatenate([lin_r, ground_r, state_r], axis=1),
                np.concatenate([lin_j, ground_j, B], axis=1))  # fmt: skip

    def _linearise(
        self, x: FloatArray, tg: Targets, prev: FloatArray
    ) -> tuple[FloatArray, FloatArray]:
        """``_linearise_batch`` of one state."""
        r, jac = self._linearise_batch(x[None], self._stacked_rows([tg]), prev[None])
        return r[0], jac[0]


def track(body: Body, x0: FloatArray, targets: Callable[[float, FloatArray], Targets],
          n: int, max_step: float = math.inf) -> FloatArray:  # fmt: skip
    """States (n, 3 + V) for u = 0..1: each frame solved from the previous one, then polished
    on its own targets (pulled toward itself, not the previous frame), which puts planted
    points back within microns. No joint turns more than ``max_step`` (rad) from one frame to
    the next, in the solve and in the polish: where a frame's targets asked for more, a hip
    flipped 50° in one frame and back (issue 19); now the body follows at a person's joint
    speed. (All frames used to be polished at once afterwards on their planted points and CoM
    alone: with the swinging foot's targets dropped, that polish moved joints up to 48°.)"""
    free = np.r_[np.full(3, np.inf), np.full(len(body.lo), max_step)]  # the root is not bound
    low, high = np.r_[np.full(3, -np.inf), body.lo], np.r_[np.full(3, np.inf), body.hi]
    xs = [x0.copy()]
    for k in range(1, n):
        tg = targets(k / (n - 1), xs[-1])
        lo = np.maximum(low, xs[-1] - free)[None]
        hi = np.minimum(high, xs[-1] + free)[None]
        guess = xs[-1] + PREDICT * (xs[-1] - xs[-2]) if k > 1 else xs[-1].copy()
        guess = np.clip(guess, lo[0], hi[0])
        x = body.descend(guess[None], xs[-1][None], [tg], ITERATIONS, (lo, hi))
        xs.append(body.descend(x, x, [tg], POLISH_ITERATIONS, (lo, hi))[0])
    return np.stack(xs)


def _bisect(f: Callable[[float], float], lo: float, hi: float, n: int = 40) -> float:
    flo = f(lo)
    for _ in range(n):
        mid = 0.5 * (lo + hi)
        if (f(mid) > 0) == (flo > 0):
            lo, flo = mid, f(mid)
        else:
            hi = mid
    return 0.5 * (lo + hi)


def kneeling_reach(skel: Any, side: str = "r") -> float:
    return tucked_foot(skel, side)[0]


def rigid_kneeling_reach(skel: Any, side: str = "r") -> float:
    """The knee-to-toe distance of the kneel before the toes bent (a rigid foot on its toe tip,
    ankle 10° dorsiflexed): the kneel keeps its knees where that one put them (the place the
    tasks were written for), so its toes land this less ``kneeling_reach`` further forward."""
    q = np.asarray(skel.q_comfort, dtype=float).copy()
    q[skel.dof_index(f"{side}_hip_flex")] = 0.0
    q[skel.dof_index(f"{side}_ankle_dorsi")] = math.radians(10.0)
    names = [f"{side}_{n}" for n in SOLE]
    k_dof, knee = skel.dof_index(f"{side}_knee_flex"), skel.joint_index(f"{side}_knee")

    def shape(k: float) -> tuple[float, float]:
        qq = q.copy()
        qq[k_dof] = k
        pose = forward(skel, qq[None])
        pts = site_positions(skel, pose, names)[0]
        return float(pose.p[0, knee, 1] - pts[:, 1].min() - KNEE_HEIGHT), float(
            pose.p[0, knee, 2] - pts[0, 2]
        )

    return shape(_bisect(lambda k: shape(k)[0], math.radians(45), float(skel.upper[k_dof])))[1]


def tucked_foot(skel: Any, side: str = "r") -> tuple[float, FloatArray]:
    """Horizontal distance (m) from a kneeling knee to its toe tip, toes tucked: the thigh
    vertical, the ankle at ``TUCK_ANKLE``, the foot near vertical on its balls
    ``KNEE_HEIGHT`` below the knee and the toes bent up at the balls to lie flat, pointing
    toward the knee (a rigid foot stood on its toe tip, balls 7 cm up: issue 18). Also where
    the heel is then, from the toe tip (y, z): the knee, toe and balls alone leave the ankle
    free to swing up the shank's circle, the foot past vertical and the toes past their
    90°.

    A property of the manikin, found once per skeleton and side (two nested bisections, ~4,000
    poses of the leg: every kneel of a task asked it again)."""
    cache: dict[str, tuple[float, FloatArray]] = skel.__dict__.setdefault("_tucked_foot", {})
    if side not in cache:
        cache[side] = _tucked_foot(skel, side)
    reach, heel = cache[side]
    return reach, heel.copy()


def _tucked_foot(skel: Any, side: str) -> tuple[float, FloatArray]:
    q = np.asarray(skel.q_comfort, dtype=float).copy()
    q[skel.dof_index(f"{side}_hip_flex")] = 0.0
    q[skel.dof_index(f"{side}_ankle_dorsi")] = TUCK_ANKLE
    names = [f"{side}_{n}" for n in ("ball_med", "ball_lat", "toe")]
    k_dof, knee = skel.dof_index(f"{side}_knee_flex"), skel.joint_index(f"{side}_knee")
    t_dof = skel.dof_index(f"{side}_toes_dorsi")

    def pose_at(k: float) -> tuple[Any, FloatArray]:
        qq = q.copy()
        qq[k_dof] = k
        qq[t_dof] = _bisect(toe_above_balls(skel, qq, side), 0.0, float(skel.upper[t_dof]))
        pose = forward_part(skel, qq[None], None, None, [*names, f"{side}_heel"])
        return pose, site_positions(skel, pose, names)[0]

    def height(k: float) -> float:
        pose, pts = pose_at(k)
        return float(pose.p[0, knee, 1] - pts[:2, 1].min() - KNEE_HEIGHT)

    pose, pts = pose_at(_bisect(height, math.radians(45), float(skel.upper[k_dof])))
    heel = site_positions(skel, pose, f"{side}_heel")[0]
    return float(pose.p[0, knee, 2] - pts[2, 2]), np.array(
        [0.0, heel[1] - pts[2, 1], heel[2] - pts[2, 2]]
    )


def toe_above_balls(skel: Any, q: FloatArray, side: str) -> Callable[[float], float]:
    """The height of the toe tip above the middle of the balls as a function of the toes'
    angle, the rest of the leg at ``q``: the ankle's frame is placed once and the toe tip
    turned about the toes' joint by Rodrigues' formula (``_tucked_foot``'s inner bisection
    asked ``part_site_positions`` for the whole leg 40 times a knee angle; equal to it to
    1e-15 m, ``tests/passes/test_rekneel.py``)."""
    names = [f"{side}_{n}" for n in ("ball_med", "ball_lat")]
    pose = forward_part(skel, np.asarray(q, dtype=float)[None], None, None, names)
    ankle = skel.joint_index(skel.site(names[0]).joint)
    toes = skel.joint_index(f"{side}_toes")
    (dof,) = np.flatnonzero(skel.dof_joint == toes)
    R, p = pose.R[0, ankle], pose.p[0, ankle]
    balls = float(site_positions(skel, pose, names)[0, :, 1].mean())
    base = float(p[1] + R[1] @ skel.offsets[toes]) - balls  # the toes' joint above the balls
    a = skel.dof_axis[dof]
    o = np.asarray(skel.site(f"{side}_toe").offset, dtype=float)
    # the tip's offset turned by t: o cos t + (a × o) sin t + a (a · o)(1 − cos t), seen in
    # the world's y through the ankle's frame
    ry = R[1]
    c_o, c_ao, c_a = float(ry @ o), float(ry @ np.cross(a, o)), float(ry @ a) * float(a @ o)

    def height(t: float) -> float:
        c, s = math.cos(t), math.sin(t)
        return base + (c_o * c + c_ao * s + c_a * (1.0 - c))

    return height


def _rx(a: float) -> FloatArray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


@dataclass
class Geometry:
    """The kneel's footholds in the body frame (x left, y up from the ground, z ahead)."""

    rel: dict[str, FloatArray]  # sole points (toe, heel, balls) from the toe of a flat foot
    toe0: dict[str, FloatArray]  # standing toes
    left0: FloatArray  # the left toe, where it stands until its knee goes down
    toe: dict[str, FloatArray]  # kneeling toes (the right one lands there from its step)
    knees: dict[str, FloatArray]  # kneeling knee centres
    heels: dict[str, FloatArray]  # kneeling heels (toes tucked), a weak guide
    com_right: FloatArray  # (2,) CoM targets: over the right foot...
    com_left: FloatArray  # ...over the left foot stepped forward...
    com_split: FloatArray  # ...between the left foot and the right forefoot...
    com_half: FloatArray  # ...between both forefeet as the right knee goes down...
    com_one: FloatArray  # ...over the right kneeling leg...
    com_kneel: FloatArray  # ...and kneeling on both knees

    def foot(self, side: str, toe: FloatArray, pitch: float) -> list[FloatArray]:
        """Sole points of a foot with its toe at ``toe`` and its heel raised by ``pitch`` about
        the balls, the toes flat (they bend at the balls)."""
        pts = [toe + r for r in self.rel[side]]
        balls = 0.5 * (pts[2] + pts[3])
        pts[1] = balls + _rx(pitch) @ (pts[1] - balls)
        return pts


def geometry(body: Body, x0: FloatArray) -> Geometry:
    skel = body.skel
    pose = body.pose(x0[None])
    rel, toe0, centre = {}, {}, {}
    for side in ("r", "l"):
        pts = site_positions(skel, pose, [f"{side}_{n}" for n in SOLE])[0]
        toe0[side] = pts[0].copy()
        rel[side] = pts - pts[0]
        rel[side][:, 1] = pts[:, 1] - pts[:, 1].min()  # soles level, on the ground
        centre[side] = pts[:, [0, 2]].mean(axis=0)
    reach, heel = tucked_foot(skel)
    left0 = toe0["l"]
    right = np.array([toe0["r"][0], 0.0, left0[2] - SPLIT + rigid_kneeling_reach(skel) - reach])
    toe = {"r": right, "l": np.array([toe0["l"][0], 0.0, right[2]])}
    knees = {s: toe[s] + np.array([0.0, KNEE_HEIGHT, reach]) for s in ("r", "l")}
    heels = {s: toe[s] + heel for s in ("r", "l")}
    # the middle of the forefoot a heel-up foot stands on: toe tip and both balls
    fore_r, fore_l = (p[[0, 2]] + rel[s][[0, 2, 3]][:, [0, 2]].mean(axis=0)
                      for s, p in (("r", toe["r"]), ("l", left0)))  # fmt: skip
    kr = knees["r"][[0, 2]]
    left_c = centre["l"]
    return Geometry(
        rel, toe0, left0, toe, knees, heels, centre["r"], left_c, 0.5 * (left_c + fore_r),
        0.5 * (fore_r + fore_l), kr + SINGLE_KNEE_AT * (fore_r - kr),
        0.5 * (knees["r"] + knees["l"])[[0, 2]] - np.array([0.0, KNEEL_COM_BEHIND]),
    )  # fmt: skip


def phase_edges(count: int = len(PHASES)) -> FloatArray:
    """Where the first ``count`` phases start and end, as shares (0..1) of the motion."""
    edges = np.cumsum([0.0, *(share for _, share in PHASES[:count])])
    return edges / edges[-1]


def _phase(u: float, count: int = len(PHASES)) -> tuple[int, float]:
    """Which phase ``u`` (0..1 of the motion) falls in, and the progress through it."""
    edges = phase_edges(count)
    k = int(min(np.searchsorted(edges, u, side="right") - 1, count - 1))
    return k, float((u - edges[k]) / (edges[k + 1] - edges[k]))


def kneel_targets(
    body: Body, geo: Geometry, x0: FloatArray, count: int = len(PHASES)
) -> Callable[[float, FloatArray], Targets]:
    """The targets of each frame of kneeling (the first ``count`` ``PHASES``), by u (0..1)."""
    skel = body.skel
    com0 = center_of_mass(skel, body.pose(x0[None]))[0, [0, 2]]
    # joints pulled weakly toward where they started: the spine most (a person shifts the
    # pelvis over the feet rather than folding the trunk), the hips' and ankles' side turns less
    weights = np.zeros(len(body.idx))
    for i, n in enumerate((*LEG_VARS, *SPINE_VARS, *TOE_VARS)):
        if n in SPINE_VARS:
            weights[i] = SPINE_W
        elif n in TOE_VARS:  # straight unless the balls and toe tip are held on the ground:
            weights[i] = TOE_NOMINAL_W  # a free toe would reach a stepping foot's target itself
        elif n.endswith(("hip_rot", "ankle_inv", "hip_abd")):
            weights[i] = NOMINAL_W
    nominal = np.where(weights > 0, x0[3:], np.nan)
    start: dict[int, FloatArray] = {}  # the state each phase started from

    def flat(side: str, toe: FloatArray) -> list[tuple[str, FloatArray, float]]:
        pts = geo.foot(side, toe, 0.0)
        return [(f"{side}_{n}", p, PLANT_W) for n, p in zip(SOLE, pts, strict=True)]

    def swing(side: str, a: FloatArray, b: FloatArray, pa: float, pb: float, s: float) -> list:
        """A stepping foot: up, across (done by 80 % of the swing), straight down; held as
        firmly as a planted foot as it leaves the ground, so it does not slip first."""
        e = float(smoothstep(s / 0.8))
        toe = a + e * (b - a)
        toe[1] += STEP_LIFT * math.sin(math.pi * s)
        pts = geo.foot(side, toe, pa + e * (pb - pa))
        firm = 1.0 - float(smoothstep(s / 0.25)) + float(smoothstep((s - 0.75) / 0.25))
        w = SWING_W + (PLANT_W - SWING_W) * firm  # firm as it leaves and as it lands
        return [(f"{side}_{n}", p, w) for n, p in zip(SOLE, pts, strict=True)]

    def knee_at(side: str, x: FloatArray) -> FloatArray:
        return body.pose(x[None]).p[0, skel.joint_index(f"{side}_knee")].copy()

    def com_path(a: FloatArray, b: FloatArray, s: float) -> FloatArray:
        return a + float(smoothstep(s)) * (b - a)

    toe = geo.toe

    def planted(*names: str) -> list[tuple[str, FloatArray, float]]:
        out = []
        for n in names:
            side, what = n.split("_", 1)
            if what in ("toe0", "toe"):  # a foot on its toes: toe tip and balls, toes flat
                at = geo.left0 if what == "toe0" else toe[side]
                out += [(f"{side}_{p}", at + r, PLANT_W)
                        for p, r in zip(SOLE, geo.rel[side], strict=True) if p != "heel"]  # fmt: skip
            else:  # a kneeling knee, and its heel guided to where the toes stay flat
                out.append((f"joint:{n}", geo.knees[side], PLANT_W))
                out.append((f"{side}_heel", geo.heels[side], HEEL_W))
        return out

    def targets(u: float, x: FloatArray) -> Targets:
        k, s = _phase(u, count)
        start.setdefault(k, x.copy())
        tg = Targets(nominal=nominal, nominal_w=weights)
        if k == 0:
            tg.points = flat("r", geo.toe0["r"]) + flat("l", geo.left0)
            tg.com = com_path(com0, geo.com_left, s)
        elif k == 1:
            # the right foot steps back, every sole point led: it lifts level and lands on its
            # balls and toes, the heel up by ``LAND_PITCH`` (the toes bent)
            tg.points = flat("l", geo.left0) + swing(
                "r", geo.toe0["r"], toe["r"], 0.0, LAND_PITCH, s
            )
            tg.level = ["r"]
            tg.com = geo.com_left
            # its toes bend up as its heel rises, so it lands shaped for its forefoot: pulled
            # straight, they bent at touchdown and the toe tip went 6-9 mm into the floor
            tg.nominal, tg.nominal_w = nominal.copy(), weights.copy()
            tg.nominal[R_TOES] = float(smoothstep(s / 0.8)) * LAND_PITCH
            tg.nominal_w[R_TOES] = SWING_TOE_W
        elif k == 2:
            heel = geo.foot("r", toe["r"], LAND_PITCH)[1]  # the heel stays up
            tg.points = flat("l", geo.left0) + planted("r_toe") + [("r_heel", heel, LAND_HEEL_W)]
            tg.level = ["r"]
            tg.com = com_path(geo.com_left, geo.com_split, s)
        elif k == 3:
            # the left heel stays down for the first half, then the foot may roll on its toe
            k0 = knee_at("r", start[k])
            # the knee's path ends before the phase does: the knees bend at most at the joint
            # speed limit and lag it, and kneel(1) ends with this phase (7 cm up, not 5)
            knee = k0 + float(smoothstep(s / KNEE_DOWN_BY)) * (geo.knees["r"] - k0)
            give = 1.0 - float(smoothstep((s - HEEL_DOWN + 0.15) / 0.3))  # the heel may rise
            left = [
                (n, p, w * give + 1e-3 if n == "l_heel" else w) for n, p, w in flat("l", geo.left0)
            ]
            # ...and lands: held as a contact from then on (led at ``KNEE_W`` alone it stayed
            # 2 cm up, between the CoM's pull and the left forefoot, for kneel(1) to keep)
            land = float(smoothstep((s - KNEE_DOWN_BY) / (1.0 - KNEE_DOWN_BY)))
            w = KNEE_W + (PLANT_W - KNEE_W) * land
            tg.points = left + planted("r_toe") + [("joint:r_knee", knee, w)]
            tg.level = ["r", "l"]
            tg.com = com_path(geo.com_split, geo.com_half, s)
        elif k == 4:
            # the kneeling leg held as firmly as in the swing: led onto it, the CoM's growing
            # pull slid the right toe tip 2-3.5 cm/s
            tg.points = planted("l_toe0") + [(n, p, w * KNEEL_LEG_FIRM if w >= PLANT_W else w)
                                             for n, p, w in planted("r_toe", "r_knee")]  # fmt: skip
            tg.level = ["r", "l"]
            tg.com = com_path(geo.com_half, geo.com_one, s)
            # the weight goes onto the kneeling leg before the other lifts: the CoM's pull
            # grows to the swing's, so the swing starts from the CoM over its support
            tg.com_w = COM_W + (ONE_KNEE_COM_W - COM_W) * float(smoothstep(s))
            tg.root_y = (start[k][1], PELVIS_W * float(smoothstep(s)))
            # ...along a planned path: the pose with the CoM over the kneeling leg is solved
            # once, and the body is led to it (followed frame by frame, the CoM's pull left the
            # spine at its side-bend limits, the CoM 4 cm off and the pelvis where it was)
            if "one" not in start:
                start["one"] = body.solve(start[k], one_knee_targets(), iterations=80)
            path = start[k] + float(smoothstep(s)) * (start["one"] - start[k])
            tg.joints = (ALL_COLS, path, ONE_PATH_W)
        elif k == 5:
            # the left leg swings in joint space from where it was to its kneeling angles: the
            # thigh lifts, the knee folds fully and the foot points back (the toes clear the
            # ground), then knee and toe are guided onto their places
            if "final" not in start:
                start["final"] = body.solve(x, final_targets(x), iterations=80)
            x_final = start["final"]
            # the kneeling leg held firmer than elsewhere: the CoM's pull on it is stronger
            tg.points = [(n, p, w * KNEEL_LEG_FIRM if w >= PLANT_W else w)
                         for n, p, w in planted("r_toe", "r_knee")]  # fmt: skip
            if "foot" not in start:
                pose = body.pose(start[k][None])
                start["foot"] = site_positions(skel, pose, [f"l_{n}" for n in SOLE])[0]
            rise = float(smoothstep(s / LIFT_END))
            held = 1.0 - float(smoothstep((s - LIFT_END) / 0.1))  # the foot is held as it was
            if held > 0.0:  # ...while it rises straight up
                up = np.array([0.0, 2 * STEP_LIFT * rise, 0.0])
                w = LIFT_W + (PLANT_W - LIFT_W) * (1.0 - rise)
                tg.points += [
                    (f"l_{n}", p + up, w * held) for n, p in zip(SOLE, start["foot"], strict=True)
                ]
            if s >= LIFT_END:
                x_lift = start.setdefault("lifted", x.copy())
                v = (s - LIFT_END) / (1.0 - LIFT_END)
                e = float(smoothstep(v / 0.8))
                legs = x_lift[LEFT_COLS] + e * (x_final[LEFT_COLS] - x_lift[LEFT_COLS])
                fold = float(smoothstep(v / 0.25) - smoothstep((v - 0.55) / 0.3))
                legs = np.where(np.isnan(SWING_LEG), legs, legs + fold * (SWING_LEG - legs))
                land = float(smoothstep((v - 0.45) / 0.35))
                ramp = float(smoothstep(v / 0.15))
                tg.joints = (LEFT_COLS, legs, JOINT_W * ramp * (1.0 - land) + 1e-3)
                if land > 0.0:  # above its place first, then straight down
                    hover = np.array(
                        [0.0, 0.04 * (1.0 - float(smoothstep((v - 0.75) / 0.25))), 0.0]
                    )
                    tg.points += [
                        (f"l_{p}", toe["l"] + r + hover, PLANT_W * land)
                        for p, r in zip(SOLE, geo.rel["l"], strict=True)
                        if p != "heel"
                    ]
                    tg.points += [("joint:l_knee", geo.knees["l"] + hover, SWING_W * land)]  # fmt: skip
            tg.level = ["r"]
            tg.com = geo.com_one
            tg.com_w = ONE_KNEE_COM_W
            tg.root_y = (start[4][1], PELVIS_W)
        else:
            tg.points = planted("r_toe", "l_toe", "r_knee", "l_knee")
            tg.level = ["r", "l"]
            tg.com = com_path(geo.com_one, geo.com_kneel, s)
        return tg

    def one_knee_targets() -> Targets:
        tg = Targets(nominal=nominal, nominal_w=weights, level=["r", "l"], com=geo.com_one)
        tg.points = planted("l_toe0", "r_toe", "r_knee")
        tg.com_w = ONE_POSE_COM_W
        tg.root_y = (start[4][1], PELVIS_W)
        return tg

    def final_targets(x: FloatArray) -> Targets:
        tg = Targets(nominal=nominal, nominal_w=weights, level=["r", "l"], com=geo.com_kneel)
        tg.points = planted("r_toe", "l_toe", "r_knee", "l_knee")
        return tg

    return targets


HALF_KNEEL_PHASES = 4  # kneel(1) stops after "down onto the right knee"


@dataclass
class KneelPlan:
    """A kneel solved frame by frame, in the body frame (facing +Z, ground at y = 0), and what
    the metrics need to know (times in s from the motion's start)."""

    body: Body
    time: FloatArray  # (N,)
    x: FloatArray  # (N, 3 + V) body-frame states: root position, then ``dofs``
    phases: list[dict[str, Any]]  # name, start, end
    steps: list[dict[str, Any]]  # foot, t_lift, t_land: a foot in the air
    rolls: list[dict[str, Any]]  # foot, from, to: a foot on its toe only

    @property
    def dofs(self) -> tuple[str, ...]:
        return (*LEG_VARS, *SPINE_VARS, *TOE_VARS)

    def reversed(self, duration: float) -> KneelPlan:
        """The same motion backwards (standing up from the kneel), lasting ``duration``."""
        d, k = float(self.time[-1]), duration / float(self.time[-1])
        return KneelPlan(
            self.body, (d - self.time[::-1]) * k, self.x[::-1].copy(),
            [{"name": f"{p['name']} (reversed)", "start": (d - p["end"]) * k,
              "end": (d - p["start"]) * k} for p in reversed(self.phases)],
            [{"foot": x["foot"], "t_lift": (d - x["t_land"]) * k, "t_land": (d - x["t_lift"]) * k}
             for x in self.steps],
            [{"foot": x["foot"], "from": (d - x["to"]) * k, "to": (d - x["from"]) * k}
             for x in self.rolls],
        )  # fmt: skip

    def window(self, start: float, end: float, duration: float | None = None) -> KneelPlan:
        """The part of the motion from ``start`` to ``end`` (s; cut at the solved frames there),
        its times from 0 and stretched to last ``duration`` (default: as long as it was), with
        the phases, steps and rolls that overlap it, clipped to it: a kneel taken up or undone
        part of the way (kneel(2) from kneeling on one knee and back, ``passes.posture``)."""
        a = int(np.searchsorted(self.time, start - 1e-9))
        b = int(np.searchsorted(self.time, end + 1e-9))
        time = self.time[a:b]
        t0, t1 = float(time[0]), float(time[-1])
        k = (t1 - t0 if duration is None else duration) / (t1 - t0)

        def clipped(items: list[dict[str, Any]], lo: str, hi: str) -> list[dict[str, Any]]:
            return [{**x, lo: (max(x[lo], t0) - t0) * k, hi: (min(x[hi], t1) - t0) * k}
                    for x in items if x[hi] > t0 + 1e-9 and x[lo] < t1 - 1e-9]  # fmt: skip

        return KneelPlan(
            self.body, (time - t0) * k, self.x[a:b].copy(), clipped(self.phases, "start", "end"),
            clipped(self.steps, "t_lift", "t_land"), clipped(self.rolls, "from", "to"),
        )  # fmt: skip

    def on_grid(self, t0: float, fps: float) -> tuple[FloatArray, FloatArray]:
        """(times, states) at ``t0`` and then at the interpolation grid's instants (multiples of
        1/fps): the frames the motion is made of are then solved poses, not blends of two.

        Between two solved frames a state is blended, then its sole points and knees are put
        where a straight line between the two frames has them (``polish_frames``): blending the
        angles of two poses moves a foot off its place (millimetres sideways as a heel starts
        to rise and hip and ankle trade turns; centimetres as a foot leaves the ground).
        """
        end = t0 + float(self.time[-1])
        grid = np.arange(np.floor(t0 * fps) + 1, np.floor(end * fps + 1e-6) + 1) / fps
        times = np.unique(np.concatenate([[t0], grid[grid < end - 1e-6], [end]]))
        rel = times - t0
        k = np.clip(np.searchsorted(self.time, rel, side="right") - 1, 0, len(self.time) - 2)
        f = (rel - self.time[k]) / (self.time[k + 1] - self.time[k])
        x = self.x[k] + f[:, None] * (self.x[k + 1] - self.x[k])
        out = x.copy()
        exact = (f < 1e-9) | (f > 1 - 1e-9)
        out[exact] = np.where((f[exact] < 0.5)[:, None], self.x[k[exact]], self.x[k[exact] + 1])
        blended = np.flatnonzero(~exact)
        if blended.size:
            a, b = (contact_points(self.body, self.x[k[blended] + i]) for i in (0, 1))
            low = np.full(a.shape[1], CONTACT_TOL)
            low[len(CONTACT_SITES) :] += KNEE_HEIGHT
            down = (a[..., 1] < low) & (b[..., 1] < low)  # on the ground in both: firm
            target = a + f[blended, None, None] * (b - a)
            weight = np.where(down, PLANT_W, SWING_W)
            bounds = pace_bounds(self.body, self.x[k[blended]], self.x[k[blended] + 1],
                                 f[blended], (self.time[k + 1] - self.time[k])[blended])  # fmt: skip
            out[blended] = polish_frames(self.body, x[blended], target, weight, bounds)
        return times, out


def pace_bounds(
    body: Body, a: FloatArray, b: FloatArray, f: FloatArray, dt: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Per-frame bounds (each (F, 3 + V)) of blended states at share ``f`` of the way from
    solved state ``a`` to ``b``, ``dt`` apart: each joint turns no faster from ``a`` to the
    blend and from it to ``b`` than the plan does between them or than ``GRID_JOINT_SPEED``
    (the root is free). Polished without them, an ankle went 1.4 deg off its blend to put
    the soles on their straight paths, and the 30 fps output frames around it stepped 12.1 deg
    where the plan's frames step 10 deg (a stand, women P90 and P95)."""
    room = np.maximum(np.abs(b - a), GRID_JOINT_SPEED * dt[:, None])
    fa, fb = f[:, None] * room, (1.0 - f[:, None]) * room
    lo = np.maximum(np.maximum(a - fa, b - fb), np.r_[np.full(3, -np.inf), body.lo])
    hi = np.minimum(np.minimum(a + fa, b + fb), np.r_[np.full(3, np.inf), body.hi])
    lo[:, :3], hi[:, :3] = -np.inf, np.inf
    return lo, hi


def contact_points(body: Body, x: FloatArray) -> FloatArray:
    """Sole sites and knee centres (F, P, 3) of states ``x`` (F, 3 + V)."""
    pose = body.pose(x)
    sites = site_positions(body.skel, pose, CONTACT_SITES)
    return np.concatenate([sites, pose.p[:, body.knees]], axis=1)


def polish_frames(
    body: Body, x0: FloatArray, target: FloatArray, weight: FloatArray,
    bounds: tuple[FloatArray, FloatArray] | None = None,
) -> FloatArray:  # fmt: skip
    """``Body.descend`` of F frames on their contact points alone (``CONTACT_SITES`` and the
    knees, at ``target`` (F, 10, 3) with ``weight`` (F, 10)), with ``POLISH_SMOOTH`` and
    ``POLISH_ITERATIONS``, within ``bounds`` if given (``pace_bounds``)."""
    names = (*CONTACT_SITES, *KNEE_POINTS)
    tgs = [Targets(points=list(zip(names, t, w, strict=True)), smooth=POLISH_SMOOTH)
           for t, w in zip(target, weight.tolist(), strict=True)]  # fmt: skip
    if bounds is not None:
        x0 = np.clip(x0, *bounds)
    return body.descend(x0, x0, tgs, POLISH_ITERATIONS, bounds)


def to_world(x: FloatArray, root_start: FloatArray, heading: float, ground: float) -> FloatArray:
    """World root positions (N, 3) of body-frame states (the body frame's origin is under the
    starting root, its +Z the heading)."""
    c, s = math.cos(heading), math.sin(heading)
    return np.stack([root_start[0] + c * x[:, 0] + s * x[:, 2], ground + x[:, 1],
                     root_start[2] - s * x[:, 0] + c * x[:, 2]], axis=1)  # fmt: skip


_PLANS: dict[bytes, tuple[Any, KneelPlan]] = {}


def clear_plans() -> None:
    """Forget the memoised kneels (``bench/compile.py`` times each compile's own solve)."""
    _PLANS.clear()


def plan_kneel(
    skel: Any, q_start: FloatArray, root_start: FloatArray, ground: float, knees: int,
    duration: float,
) -> KneelPlan:  # fmt: skip
    """Kneel on ``knees`` (1: the right, 2: both) from standing pose ``q_start`` (its root
    ``root_start`` high) in ``duration`` seconds, solved at ``FPS``, in the body frame.

    Memoised per skeleton and inputs (a compile solves each kneel once, but tests and tools
    compile the same task many times; the entry keeps the skeleton alive so its id is not
    reused). The result is the same either way: the solve is deterministic.
    """
    key = np.concatenate([q_start, [root_start[1] - ground, knees, duration]]).tobytes()
    key += id(skel).to_bytes(8, "little")
    hit = _PLANS.get(key)
    if hit is not None and hit[0] is skel:
        return hit[1]
    if len(_PLANS) > 32:
        _PLANS.clear()
    plan = _solve_kneel(skel, q_start, root_start, ground, knees, duration)
    _PLANS[key] = (skel, plan)
    return plan


def _solve_kneel(
    skel: Any, q_start: FloatArray, root_start: FloatArray, ground: float, knees: int,
    duration: float,
) -> KneelPlan:  # fmt: skip
    count = len(PHASES) if knees == 2 else HALF_KNEEL_PHASES
    body = Body(skel, q_start)
    x0 = np.concatenate([[0.0, float(root_start[1]) - ground, 0.0], q_start[body.idx]])
    geo = geometry(body, x0)
    n = max(round(duration * FPS) + 1, 2)
    step = MAX_JOINT_SPEED * duration / (n - 1)
    xs = track(body, x0, kneel_targets(body, geo, x0, count), n, step)
    edges = phase_edges(count) * duration
    phases = [{"name": PHASES[k][0], "start": float(edges[k]), "end": float(edges[k + 1])}
              for k in range(count)]  # fmt: skip
    steps = [{"foot": "r", "t_lift": float(edges[1]), "t_land": float(edges[2])}]
    rolls = [{"foot": "r", "from": float(edges[2]), "to": duration}]
    left_roll = float(edges[3] + HEEL_DOWN * (edges[4] - edges[3]))
    if knees == 2:
        steps.append({"foot": "l", "t_lift": float(edges[5]), "t_land": float(edges[6])})
        rolls += [{"foot": "l", "from": left_roll, "to": float(edges[5])},
                  {"foot": "l", "from": float(edges[6]), "to": duration}]  # fmt: skip
    else:
        rolls.append({"foot": "l", "from": left_roll, "to": duration})
    times = np.linspace(0.0, duration, n)
    for step in steps:
        step["t_lift"], step["t_land"] = _airborne(body, xs, times, step)
    return KneelPlan(body, times, xs, phases, steps, rolls)


STILL = 0.5 * 0.02 / FPS  # m a frame: a foot slower than half the skating limit (2 cm/s) stands


def _airborne(
    body: Body, xs: FloatArray, times: FloatArray, step: dict[str, Any]
) -> tuple[float, float]:
    """When a stepping foot really leaves and reaches the ground: around the step's phase, the
    first and last frames in which a sole point near the ground (within ``CONTACT_TOL``) still
    moves; a touchdown ends when the foot has stopped, not when its phase does."""
    pts = site_positions(body.skel, body.pose(xs), [f"{step['foot']}_{n}" for n in SOLE])
    near = pts[..., 1] <= CONTACT_TOL
    slide = np.where(near[1:] | near[:-1], np.linalg.norm(np.diff(pts, axis=0), axis=-1), 0.0)
    moving = slide.max(axis=1) > STILL  # (n-1,): a point on the ground slides (rolling is not)
    a = int(np.searchsorted(times, step["t_lift"]))
    b = int(np.searchsorted(times, step["t_land"]))
    window = np.flatnonzero(moving[max(a - 2, 0) : min(b + 6, len(moving))]) + max(a - 2, 0)
    if window.size == 0:
        return float(step["t_lift"]), float(step["t_land"])
    return float(times[window[0]]), float(times[window[-1] + 1])
