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
"""

from __future__ import annotations

import math

import numpy as np

from mtlc.body import part_site_positions
from mtlc.body.ik.clearance import penetrations
from mtlc.ir.model import FloatArray, Frames, MotionIR
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


def _sites(
    skel: object, frames: Frames, rows: np.ndarray, q: FloatArray, names: list[str]
) -> FloatArray:
    """(len(rows), len(names), 3) the sites ``names`` on the ``rows`` posed ``q``: posed once
    for every measure below."""
    return part_site_positions(
        skel, q, frames.root_position[rows], frames.root_rotation[rows], names
    )


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


def _depths(
    skel: object, frames: Frames, rows: np.ndarray, q: FloatArray, sides: tuple[str, ...]
) -> FloatArray:
    """(len(rows),) the deeper of the ``sides``' arms into the body on each row."""
    got = penetrations(skel, q, (frames.root_position[rows], frames.root_rotation[rows]), sides)
    return np.max(np.stack([got[s] for s in sides]), axis=0)


def reach_again(ir: MotionIR, m: Movement, fps: float, held: list[Carry]) -> bool:
    """Re-time the movement ``m`` on the frames in place where that passes (the module
    docstring); whether it did. ``held``: the spans where both hands hold one part, whose
    reaches are left alone (each arm's joints low-passed on their own would squeeze the part:
    MT0511, three more on the procedures)."""
    skel, frames = ir.skeleton, ir.frames
    assert frames is not None
    hands = [e for e in m.effectors if e in ("r_hand", "l_hand")]
    if not hands or len(hands) != len(m.effectors):
        return False
    if any(c.start < m.end - EPS and c.end > m.start + EPS for c in held):
        return False
    rows = np.flatnonzero((frames.time >= m.start - EPS) & (frames.time <= m.end + EPS))
    if rows.size < MIN_FRAMES:
        return False
    # the hands and their fingertips, posed once for the reach as it is and once re-timed
    names = [*hands, *(FINGERTIPS[h] for h in hands)]
    t, was_q = frames.time[rows], frames.q[rows]
    was_p = _sites(skel, frames, rows, was_q, names)
    n = len(hands)
    before = _worst(t, was_p[:, :n], fps)
    if before >= RETIME_FROM:
        return False
    keyed = set(m.dofs)
    cols = sorted({d for h in hands for d in arm_dofs(skel, h) if skel.dof_names[d] in keyed})
    if not cols:
        return False
    q = retimed(was_q, t, was_p[:, :n], cols)
    p = _sites(skel, frames, rows, q, names)
    if _worst(t, p[:, :n], fps) < before + RETIME_GAIN:
        return False
    # one bell over a path that crept part of the way turns the joints faster at its peak:
    # no faster than pace lets a reach (or than the reach already did), nor arriving faster
    if _fastest(t, q, cols) > max(_fastest(t, was_q, cols), PEAK_JOINT_SPEED):
        return False
    if _arrival(t, p[:, :n], fps) > max(_arrival(t, was_p[:, :n], fps), CONTACT_SPEED):
        return False
    sides = tuple(sorted({h[0] for h in hands}))
    was = float(_depths(skel, frames, rows, was_q, sides).max())
    if float(_depths(skel, frames, rows, q, sides).max()) > (
        was + DEEPER_INSIDE if was > 0.0 else DEEPER
    ):
        return False
    # no fingertip lower than it was, or than the ground
    if float(p[:, n:, 1].min()) < min(float(was_p[:, n:, 1].min()), ir.ground) - EPS:
        return False
    frames.q[rows] = q
    return True


def run(ir: MotionIR, ctx: PassContext) -> MotionIR:
    if ir.frames is None or ir.skeleton is None or not len(ir.frames.time):
        return ir
    held = carries(ir)
    for m in movements(ir):
        reach_again(ir, m, ctx.options.fps, held)
    return ir
