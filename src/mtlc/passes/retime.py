"""Pass 11d: a reach the corrections after pace bent is one bell of hand speed again (issue 19).

``pace`` times each reach as one minimum-jerk movement (Flash & Hogan 1985), but the passes after
it correct the arm frame by frame: balance puts a hand back on its site as the pelvis moves,
clearance pushes a forearm out of the trunk or a thigh. Each correction is added on top of the
bell, at its own pace: the aircraft panel's reach to the relay (female P90) went from LDLJ -6.6
after pace to -9.6 after clearance, its hand dipping from 94 to 49 cm/s and back to 73 where the
correction let go; the panel set on the floor while squatting (female P5) -7.1 -> -10.3, with two
speed peaks.

Here, on the dense frames after clearance, each paced reach (``pace.movements``: a TA and the TO
that continues it, or one alone) whose hand scores under ``RETIME_FROM`` (the bench's LDLJ,
``frames_ldlj``) keeps its path, corrections and all, and is run along it again on one
minimum-jerk bell: its arms' joints (``hold._arm_dofs`` of the reaching hands; the trunk and
the legs keep their own clock, what balance made of them) at each frame are those of the point
of the corrected path that the bell's progress has reached (the hands' arc length plus
``JOINT_WEIGHT`` times the arm joints' path, as pace measures progress). The reach's first and
last frames stay as they were, to the bit. Kept where the hand then scores ``RETIME_GAIN``
better, no arm joint turns faster than ``pace.PEAK_JOINT_SPEED`` (or than it did), no hand
arrives faster than ``CONTACT_SPEED`` (or than it did), and neither arm goes deeper into the body than it went anywhere in the reach before
(``DEEPER_INSIDE``; an arm that was clear ``DEEPER`` at most), nor any hand's fingertip lower
than it was or the ground; else the reach stays as it was.

Where the bend is the pelvis's or the trunk's (balance moves the pelvis under a load the hands
carry out, and the hands ride on it), the whole body is run along its own poses on the same
bell (``warped``), if no walk shares the window and no other segment starts or ends inside it
(``_warpable``): also for a part in both hands, whose arms are not re-timed alone. Its soles
may go no further than ``FEET_SLIP`` beyond where they went; of the two ways, the one that
scores better is kept.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from mtlc.body import part_site_positions
from mtlc.body.ik.clearance import penetrations
from mtlc.ir.model import FloatArray, Frames, MotionIR
from mtlc.metrics import FOOT_POINT_NAMES
from mtlc.passes.approach import FINGERTIPS
from mtlc.passes.carry import Carry, carries
from mtlc.passes.context import PassContext
from mtlc.passes.hold import _arm_dofs as arm_dofs
from mtlc.passes.pace import PEAK_JOINT_SPEED, Movement, movements
from mtlc.passes.profile import JOINT_WEIGHT, minimum_jerk, smooth_path

RETIME_FROM = -7.0  # LDLJ: a reach whose hands score this well is left as it is
RETIME_GAIN = 0.3  # LDLJ: the re-timed reach must score this much better
DEEPER = 5e-4  # m: how far into the body an arm that was clear may go (verify reports 1 mm)
DEEPER_INSIDE = 2e-3  # m: how much deeper an arm already inside (a finding) may go
MIN_PATH = 0.01  # m: a hand moving less than this is not judged (the bench's own floor)
MIN_FRAMES = 6
CONTACT_SPEED = 0.05  # m/s: a re-timed hand arrives no faster than this (issue 19's 5 cm/s)
PATH_POINTS = 241  # the corrected path resampled at even progress, as pace samples a reach
SMOOTH_SIGMA = (
    0.05  # of the progress: its low-pass (pace's least is 0.1: this path is bent already)
)
FEET_SLIP = 2e-4  # m: how much further a re-timed body's soles may go than they went
FOOT_SITES = [f"{side}_{point}" for side in "rl" for point in FOOT_POINT_NAMES]
EPS = 1e-9


def frames_ldlj(p: FloatArray, dt: float) -> float:
    """Log dimensionless jerk (Balasubramanian et al. 2012) of a (N, 3) path sampled every
    ``dt`` seconds, at rest before and after it: bench/human.py's reach figure."""
    duration = dt * (len(p) - 1)
    p = np.concatenate([p[:1], p[:1], p, p[-1:], p[-1:]])
    v_peak = float(np.linalg.norm(np.diff(p, axis=0), axis=1).max()) / dt
    jerk = np.diff(p, n=3, axis=0) / dt**3
    integral = float(np.sum(jerk * jerk)) * dt
    if v_peak <= 0.0 or integral <= 0.0:
        return 0.0
    return -math.log(duration**3 / v_peak**2 * integral)


def _sites(skel: object, body: Body, names: list[str]) -> FloatArray:
    """(N, len(names), 3) the sites ``names`` of the poses ``body``: posed once for every
    measure below."""
    return part_site_positions(skel, body.q, body.root_position, body.root_rotation, names)


def _worst(t: FloatArray, p: FloatArray, fps: float) -> float:
    """The worst ``frames_ldlj`` of the hands' positions ``p`` (N, H, 3) at times ``t``, on the
    output frames' grid (``fps``: at the dense 60 a second the corrections' zig-zag of a tenth
    of a millimetre outweighs every bell); 0.0 for a hand that moves less than ``MIN_PATH``."""
    grid = np.arange(np.ceil(t[0] * fps - 1e-6), np.floor(t[-1] * fps + 1e-6) + 1) / fps
    if len(grid) < 4:
        return 0.0
    worst = 0.0
    for k in range(p.shape[1]):
        at = np.stack([np.interp(grid, t, p[:, k, c]) for c in range(3)], axis=1)
        if float(np.linalg.norm(np.diff(at, axis=0), axis=1).sum()) >= MIN_PATH:
            worst = min(worst, frames_ldlj(at, 1.0 / fps))
    return worst


def retimed(q: FloatArray, t: FloatArray, p: FloatArray, cols: list[int]) -> FloatArray:
    """The poses ``q`` (at times ``t``, the hands at ``p`` (N, H, 3)) with the ``cols`` run
    along their own path on one minimum-jerk bell over the times: the path at ``PATH_POINTS``
    even steps of progress (the hands' arc length plus ``JOINT_WEIGHT`` times the ``cols``'
    path), low-passed by ``SMOOTH_SIGMA`` of it as pace does (both ends kept); the first and
    last rows as they were."""
    step = np.linalg.norm(np.diff(p, axis=0), axis=-1).sum(axis=1)
    step += JOINT_WEIGHT * np.linalg.norm(np.diff(q[:, cols], axis=0), axis=1)
    u = np.concatenate([[0.0], np.cumsum(step)])
    u = u / u[-1] + np.arange(len(u)) * 1e-12  # strictly rising where nothing moved
    even = np.linspace(0.0, 1.0, PATH_POINTS)
    path = np.stack([np.interp(even, u, q[:, d]) for d in cols], axis=1)
    path = smooth_path(path, SMOOTH_SIGMA * (PATH_POINTS - 1))
    s = minimum_jerk((t - t[0]) / (t[-1] - t[0]))
    out = q.copy()
    for k, d in enumerate(cols):
        out[:, d] = np.interp(s, even, path[:, k])
    out[0], out[-1] = q[0], q[-1]
    return out


def _fastest(t: FloatArray, q: FloatArray, cols: list[int]) -> float:
    """rad/s: the fastest of the ``cols`` of poses ``q`` (at times ``t``) between two rows."""
    dt = np.maximum(np.diff(t), EPS)
    return float((np.abs(np.diff(q[:, cols], axis=0)) / dt[:, None]).max(initial=0.0))


def _arrival(t: FloatArray, p: FloatArray, fps: float) -> float:
    """m/s: the fastest of the hands at ``p`` (N, H, 3) over the last output frame before
    the reach's end."""
    last = np.array([t[-1] - 1.0 / fps, t[-1]])
    ends = np.stack([[np.interp(last, t, p[:, k, c]) for c in range(3)] for k in range(p.shape[1])])
    return float(np.linalg.norm(ends[:, :, 1] - ends[:, :, 0], axis=1).max()) * fps


def _depths(skel: object, body: Body, sides: tuple[str, ...]) -> FloatArray:
    """(N,) the deeper of the ``sides``' arms into the body on each pose of ``body``."""
    got = penetrations(skel, body.q, (body.root_position, body.root_rotation), sides)
    return np.max(np.stack([got[s] for s in sides]), axis=0)


@dataclass(frozen=True)
class Body:
    """The poses of a reach's rows: joints and root."""

    q: FloatArray
    root_position: FloatArray
    root_rotation: FloatArray

    @classmethod
    def of(cls, frames: Frames, rows: np.ndarray) -> Body:
        return cls(frames.q[rows], frames.root_position[rows], frames.root_rotation[rows])

    def with_q(self, q: FloatArray) -> Body:
        return Body(q, self.root_position, self.root_rotation)


def warped(body: Body, t: FloatArray, p: FloatArray, cols: list[int]) -> Body:
    """The whole body (every joint and the root) run along its own poses on one minimum-jerk
    bell of the hands' progress (their arc length plus ``JOINT_WEIGHT`` times the ``cols``'
    path, as ``retimed`` measures it): a monotone warp of the window's clock, each new pose
    between two neighbouring ones, nothing low-passed. The feet stay where they stand and a
    part in both hands keeps its length (every pose is one the corrections made); the first
    and last rows as they were."""
    step = np.linalg.norm(np.diff(p, axis=0), axis=-1).sum(axis=1)
    step += JOINT_WEIGHT * np.linalg.norm(np.diff(body.q[:, cols], axis=0), axis=1)
    u = np.concatenate([[0.0], np.cumsum(step)])
    u = u / u[-1] + np.arange(len(u)) * 1e-12
    at = np.interp(minimum_jerk((t - t[0]) / (t[-1] - t[0])), u, np.arange(len(u), dtype=float))
    i = np.clip(np.floor(at).astype(np.intp), 0, len(u) - 2)
    f = (at - i)[:, None]

    def between(v: FloatArray) -> FloatArray:
        return v[i] * (1.0 - f) + v[i + 1] * f

    rot0, rot1 = body.root_rotation[i], body.root_rotation[i + 1]
    rot1 = np.where(np.sum(rot0 * rot1, axis=1, keepdims=True) < 0.0, -rot1, rot1)
    rotation = rot0 * (1.0 - f) + rot1 * f
    rotation /= np.linalg.norm(rotation, axis=1, keepdims=True)
    out = Body(between(body.q), between(body.root_position), rotation)
    for v, was in zip(
        (out.q, out.root_position, out.root_rotation),
        (body.q, body.root_position, body.root_rotation),
        strict=True,
    ):
        v[0], v[-1] = was[0], was[-1]
    return out


# segments whose start or end inside a window is a claim at that time: a warp of the window's
# clock would move it (the reach's own TA → TO boundary is its own)
TIMED_KINDS = frozenset({"TA", "TO", "grip", "posture", "hold", "rest"})


def _warpable(ir: MotionIR, m: Movement) -> bool:
    """Whether the whole body may be re-timed over ``m``'s window: no walk in it, and no other
    segment starts or ends inside it."""
    own = {id(s) for s in m.segments}
    for s in ir.segments:
        if id(s) in own or s.end <= m.start + EPS or s.start >= m.end - EPS:
            continue
        if s.kind == "locomotion":
            return False
        if s.kind in TIMED_KINDS and any(m.start + EPS < x < m.end - EPS for x in (s.start, s.end)):
            return False
    return True


def _feet_moved(skel: object, body: Body) -> float:
    """m: how far the soles' points go from where they are on the first pose."""
    p = _sites(skel, body, FOOT_SITES)
    return float(np.linalg.norm(p - p[:1], axis=-1).max())


def reach_again(ir: MotionIR, m: Movement, fps: float, held: list[Carry]) -> bool:
    """Re-time the movement ``m`` on the frames in place where that passes (the module
    docstring); whether it did. ``held``: the spans where both hands hold one part, whose arms
    are not re-timed alone (each arm's joints low-passed on their own would squeeze the part:
    MT0511, three more on the procedures); the whole body may be."""
    skel, frames = ir.skeleton, ir.frames
    assert frames is not None
    hands = [e for e in m.effectors if e in ("r_hand", "l_hand")]
    if not hands or len(hands) != len(m.effectors):
        return False
    rows = np.flatnonzero((frames.time >= m.start - EPS) & (frames.time <= m.end + EPS))
    if rows.size < MIN_FRAMES:
        return False
    # the hands and their fingertips, posed once for the reach as it is and once re-timed
    names = [*hands, *(FINGERTIPS[h] for h in hands)]
    t, was = frames.time[rows], Body.of(frames, rows)
    was_p = _sites(skel, was, names)
    n = len(hands)
    before = _worst(t, was_p[:, :n], fps)
    if before >= RETIME_FROM:
        return False
    keyed = set(m.dofs)
    cols = sorted({d for h in hands for d in arm_dofs(skel, h) if skel.dof_names[d] in keyed})
    if not cols:
        return False
    sides = tuple(sorted({h[0] for h in hands}))
    check = Check(skel, ir.ground, fps, t, was, names, was_p, n, sides, before)
    together = any(c.start < m.end - EPS and c.end > m.start + EPS for c in held)
    tries: list[tuple[Body, list[int], bool]] = []  # the poses, the joints judged, whole body
    if not together:
        tries.append((was.with_q(retimed(was.q, t, was_p[:, :n], cols)), cols, False))
    # where the trunk, the pelvis or the other arm made the bend, the whole body runs again
    if _warpable(ir, m):
        moving = np.flatnonzero(np.ptp(was.q, axis=0) > 0.0).tolist()
        tries.append((warped(was, t, was_p[:, :n], cols), moving, True))
    best: tuple[float, Body] | None = None
    for body, checked, whole in tries:
        score = check.passes(body, checked)
        if score is None or (best is not None and score <= best[0]):
            continue
        if whole and _feet_moved(skel, body) > _feet_moved(skel, was) + FEET_SLIP:
            continue
        best = (score, body)
    if best is None:
        return False
    body = best[1]
    frames.q[rows], frames.root_position[rows] = body.q, body.root_position
    frames.root_rotation[rows] = body.root_rotation
    return True


@dataclass(frozen=True)
class Check:
    """What a re-timed reach must keep (the module docstring), against the reach as it was."""

    skel: object
    ground: float
    fps: float
    t: FloatArray
    was: Body
    names: list[str]  # the hands, then their fingertips
    was_p: FloatArray  # (N, len(names), 3)
    n: int  # hands
    sides: tuple[str, ...]
    before: float  # the hands' worst LDLJ as they were

    @cached_property
    def was_arrival(self) -> float:
        return _arrival(self.t, self.was_p[:, : self.n], self.fps)

    @cached_property
    def was_depth(self) -> float:
        return float(_depths(self.skel, self.was, self.sides).max())

    def passes(self, body: Body, cols: list[int]) -> float | None:
        """The re-timed hands' worst LDLJ where ``body`` keeps all of it (``cols``: the
        joints whose speed is judged), else None."""
        t, n, fps = self.t, self.n, self.fps
        p = _sites(self.skel, body, self.names)
        score = _worst(t, p[:, :n], fps)
        if score < self.before + RETIME_GAIN:
            return None
        # one bell over a path that crept part of the way turns the joints faster at its
        # peak: no faster than pace lets a reach (or than the reach already did), nor arriving
        # faster
        if _fastest(t, body.q, cols) > max(_fastest(t, self.was.q, cols), PEAK_JOINT_SPEED):
            return None
        if _arrival(t, p[:, :n], fps) > max(self.was_arrival, CONTACT_SPEED):
            return None
        was = self.was_depth
        if float(_depths(self.skel, body, self.sides).max()) > (
            was + DEEPER_INSIDE if was > 0.0 else DEEPER
        ):
            return None
        # no fingertip lower than it was, or than the ground
        if float(p[:, n:, 1].min()) < min(float(self.was_p[:, n:, 1].min()), self.ground) - EPS:
            return None
        return score


def run(ir: MotionIR, ctx: PassContext) -> MotionIR:
    if ir.frames is None or ir.skeleton is None or not len(ir.frames.time):
        return ir
    held = carries(ir)
    for m in movements(ir):
        reach_again(ir, m, ctx.options.fps, held)
    return ir
