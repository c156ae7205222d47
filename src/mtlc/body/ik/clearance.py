"""IK with the body's own volume as a constraint: an arm moved out of the trunk and thighs.

The reach solvers know only where the hand should be. An arm has seven dofs for a hand's six
(position and orientation), so the same hand pose can be held with the elbow swung in, through
the thigh of a squatting body or the side of the trunk, or swung out beside it. ``keep_clear``
solves, per configuration, a small damped (Levenberg-Marquardt) least-squares problem on the
arm's dofs whose residuals are

* the limb's penetration into each capsule with its clearance (``capsules.clearance``: the
  forearm's and hand's surface kept ``CLEARANCE_MARGIN`` outside the trunk and thighs), weight 1;
* the hand's pose (its site, fingertip and wrist frame) where it was, weight ``keep`` per
  configuration: large where the hand is on a site or holds a part (the elbow swings out, the
  goal is kept), small where the hand is free (it may move out too); the site weighs ten times
  its orientation (which yields first when the swivel alone cannot clear), the orientation at
  least ``ORIENT_FLOOR``;
* a small pull toward the start configuration, so nothing moves that need not.

With ``firm``, a configuration of a kept hand the solve leaves inside is solved again with the
clearance and the hand's site weighing ``firm`` times more (its orientation, not: it yields
sooner), and takes that if it is less deep, the hand moved at most ``FIRM_HAND_TOL`` and no
dof more than ``FIRM_TURN``. Configurations already clear are returned unchanged; the dofs stay within
their limits.
Jacobians are analytic (``_jacobian``): every residual is a point of the arm (a limb's sample,
the hand's site and frame points, the elbow) or a dof, and a point's derivative by a dof is the
dof's world axis crossed with the lever arm from its joint; a depth's, that dotted with the
depth's gradient at the sample (``capsules.clearance_gradient``). One arm-only forward
kinematics per iteration (the trial's; the accepted pose is kept), not one per dof.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from ..capsules import (
    COLUMN_SAMPLES,
    body_capsules,
    clearance,
    clearance_directions,
    limb_radius,
    measured_points,
    sample_fractions,
    segment_clearance,
    side_limbs,
)
from ..kinematics import (
    Pose,
    cross,
    dof_world_axes,
    forward,
    forward_below,
    forward_part,
    repeated_rows,
    rotate_about,
    site_positions,
)
from ..skeleton import Skeleton

FloatArray = NDArray[np.float64]

FRAME_ARM = 0.05  # m: the wrist frame's axes are kept as points this far from the wrist
REST_WEIGHT = 0.02  # m per rad toward the start configuration
MAX_ITER = 25
MAX_STEP = 0.15  # rad per dof per iteration
STALL = 1e-12  # a row whose accepted step lowers its cost by less than this share has converged
MAX_DAMPING = 1e8  # ...or whose step fails at this damping (the step is then ~1e-8 of the slope)
# the hand's site weighs fully; its orientation (the other points) yields first: a forearm
# twisted to its limit by a `turn` cannot swing the elbow out with the hand's frame held
POINT_WEIGHT = np.array([1.0, 0.1, 0.1, 0.1, 0.1])
ORIENT_FLOOR = 0.3  # ...but never below this: a free hand moves out, it does not flick
SWIVELS = np.radians([-150.0, -100.0, -50.0, 50.0, 100.0, 150.0])  # elbow turns tried
HAND_TOL = 2e-4  # m: a kept hand (weight ``KEPT`` or more) is restored this close
KEPT = 1.0
MAX_ROWS = 600  # rows solved at most in one call (10 s of 60 fps frames); more: every k-th
SWIVEL_FROM = 1e-3  # m: a pose this far inside after the local solve tries the swivels
FIRM_HAND_TOL = 5e-4  # m: a kept hand the firm solve may move (contact and grip: 1 mm)
FIRM_TURN = 0.35  # rad a dof may turn in the firm solve: more swings between frames
SWIVEL_STAGE = np.radians(15.0)  # rad of an elbow's turn solved at a time (``swiveled``)


def _residuals(
    skel: Skeleton,
    q: FloatArray,
    pose: Pose,
    side: str,
    kept: FloatArray,
    keep: FloatArray,
    q0: FloatArray,
    dofs: Sequence[int],
    clear_weight: float = 1.0,
) -> tuple[FloatArray, FloatArray]:
    """(N, M) residuals of configurations ``q`` (N, D) posed as ``pose`` (see the module
    docstring), and the depth columns' derivatives by their sample points (N, M_pen, 3)."""
    depth, directions = clearance_directions(skel, pose, side_limbs(side))
    pen = clear_weight * np.maximum(depth, 0.0)
    held = _hand_points(skel, pose, side)
    weights = _point_weights(keep)
    weights[:, 0] *= clear_weight  # the site weighs against the clearance as before
    off = (held - kept) * weights[..., None]
    off = off.reshape(len(q), -1)
    rest = REST_WEIGHT * (q[:, dofs] - q0[:, dofs])
    return np.concatenate([pen, off, rest], axis=1), directions


def _point_weights(keep: FloatArray) -> FloatArray:
    """(N, 5) the weights of the hand's site and its four orientation points: the site
    ``keep``, its orientation a tenth of that, but never less than ``ORIENT_FLOOR`` (a free
    hand may move out of the way; flipping the wrist to its limits frame by frame is no way)."""
    w = keep[:, None] * POINT_WEIGHT
    w[:, 1:] = np.maximum(w[:, 1:], ORIENT_FLOOR)
    return w


def _hand_points(skel: Skeleton, pose: object, side: str) -> FloatArray:
    """(N, 5, 3) the hand's site, fingertip and three points of the wrist's frame: the hand's
    whole pose, and with it any tool it holds."""
    sites = site_positions(skel, pose, [f"{side}_hand", f"{side}_fingertip"])  # type: ignore[arg-type]
    w = skel.joint_index(f"{side}_wrist")
    p, r = pose.p[:, w], pose.R[:, w]  # type: ignore[attr-defined]
    frame = p[:, None, :] + FRAME_ARM * np.swapaxes(r, -1, -2)
    return np.concatenate([sites, frame], axis=1)


def arm_dofs(skel: Skeleton, side: str) -> list[int]:
    """The arm's own dofs (shoulder, elbow, forearm twist, wrist) of one side."""
    return [d for d, n in enumerate(skel.dof_names) if n.startswith(f"{side}_") and
            n.split("_")[1] in ("shoulder", "elbow", "wrist")]  # fmt: skip


def penetration(
    skel: Skeleton, q: FloatArray, root: tuple[FloatArray, FloatArray], side: str
) -> FloatArray:
    """(N,) the deepest point of the side's forearm or hand inside a capsule with clearance."""
    return penetrations(skel, q, root, (side,))[side]


def penetrations(
    skel: Skeleton,
    q: FloatArray,
    root: tuple[FloatArray, FloatArray],
    sides: tuple[str, ...],
    pose: Pose | None = None,
) -> dict[str, FloatArray]:
    """``penetration`` of each of ``sides`` (N,), from one forward kinematics of ``q`` (or
    ``pose``, ``q``'s if the caller has it: the same numbers); a run of identical frames (a
    hold) is measured once (``repeated_rows``)."""
    runs = repeated_rows(q, root[0], root[1])
    if runs is not None:
        heads, at = runs
        one = None if pose is None else pose.rows(heads)
        once = penetrations(skel, q[heads], (root[0][heads], root[1][heads]), sides, one)
        return {side: depth[at] for side, depth in once.items()}
    limbs = tuple(limb for side in sides for limb in side_limbs(side))
    if pose is None:
        pose = forward_part(skel, q, root[0], root[1], measured_points(skel, limbs))
    return {side: clearance(skel, pose, side_limbs(side)).max(axis=1) for side in sides}


def penetration_dofs(skel: Skeleton, side: str) -> NDArray[np.bool_]:
    """(D,) the dofs ``penetration`` of ``side`` can depend on: those of the joints that place
    a capsule's ends or the side's limbs, and of their ancestors (a frame whose other dofs
    changed is as deep as it was)."""
    names = [n for cap in body_capsules(skel) for end in cap.ends for n in end]
    for limb in side_limbs(side):
        names += [
            n if n in skel.joint_names else skel.site(n).joint for n in (limb.start, limb.end)
        ]
    used = skel.ancestor[[skel.joint_index(n) for n in names]].any(axis=0)  # (J,)
    return used[skel.dof_joint]


@dataclass(frozen=True)
class _Problem:
    """One row per configuration: what its residuals compare against."""

    root: tuple[FloatArray, FloatArray]  # (N, 3), (N, 4)
    kept: FloatArray  # (N, 5, 3) the hand's points to keep
    keep: FloatArray  # (N,) their weight
    rest: FloatArray  # (N, D) the start configurations
    elbow: FloatArray | None = None  # (N, 3) a swivel seed's elbow target
    clear_weight: float = 1.0  # the clearance residuals' weight
    # (N rows) the whole body at the LM's start: the arm's dofs are all the LM moves, so the
    # trunk, thighs and the arm's parent frame stay these and only the arm is posed again
    base: Pose | None = None

    def take(self, idx: np.ndarray) -> _Problem:
        return _Problem(
            (self.root[0][idx], self.root[1][idx]), self.kept[idx], self.keep[idx],
            self.rest[idx], None if self.elbow is None else self.elbow[idx], self.clear_weight,
            None if self.base is None else self.base.rows(idx),
        )  # fmt: skip


def _pose(skel: Skeleton, q: FloatArray, side: str, pb: _Problem) -> Pose:
    """The whole body's pose at ``q``: only the arm placed again from ``pb.base`` (the same
    numbers as whole-body forward kinematics, a fraction of the work), else all of it."""
    if pb.base is None:
        return forward(skel, q, pb.root[0], pb.root[1], with_axes=False)
    return forward_below(skel, q, pb.base, skel.joint_index(f"{side}_shoulder"))


def _res(
    skel: Skeleton,
    q: FloatArray,
    side: str,
    pb: _Problem,
    dofs: list[int],
    pose: Pose | None = None,
) -> FloatArray:
    """The residuals, or a swivel seed's (the elbow's target and the hand's pose); ``pose``:
    ``q``'s, if already known."""
    return _res_directions(skel, q, side, pb, dofs, pose)[0]


def _res_directions(
    skel: Skeleton,
    q: FloatArray,
    side: str,
    pb: _Problem,
    dofs: list[int],
    pose: Pose | None = None,
) -> tuple[FloatArray, FloatArray | None]:
    """``_res``, and the depth columns' derivatives by their samples (none for a seed)."""
    pose = _pose(skel, q, side, pb) if pose is None else pose
    if pb.elbow is None:
        return _residuals(skel, q, pose, side, pb.kept, pb.keep, pb.rest, dofs, pb.clear_weight)
    off = (_hand_points(skel, pose, side) - pb.kept) * _point_weights(pb.keep)[..., None]
    elbow = pose.p[:, skel.joint_index(f"{side}_elbow")] - pb.elbow
    return np.concatenate([elbow, off.reshape(len(q), -1)], axis=1), None


def _carrier(skel: Skeleton, name: str) -> int:
    """The joint whose frame a joint's or site's point is fixed in."""
    return skel.joint_index(name if name in skel.joint_names else skel.site(name).joint)


def _point_motion(
    skel: Skeleton,
    axes: FloatArray,
    origins: FloatArray,
    dofs: list[int],
    carriers: list[int],
    points: FloatArray,
) -> FloatArray:
    """(n, P, n_d, 3) how points (n, P, 3), each fixed in its ``carriers`` joint's frame, move
    per radian of each of ``dofs``: the dof's world axis (n, n_d, 3) crossed with the lever
    arm from its joint (``origins``), where the dof turns that joint or one above it, else
    nothing (a joint's own dofs do not move its centre: the lever is zero)."""
    moves = skel.ancestor[carriers][:, skel.dof_joint[dofs]]  # (P, n_d)
    lever = points[:, :, None, :] - origins[:, None, :, :]
    return cross(axes[:, None, :, :], lever) * moves[None, :, :, None]


def _limb_ends(skel: Skeleton, pose: Pose, side: str) -> tuple[FloatArray, list[int]]:
    """(n, 2L, 3) the side's limbs' start and end points before ``limb_axis`` shortens a
    hand's end (limb by limb), and the joints they are fixed in."""
    names = [name for limb in side_limbs(side) for name in (limb.start, limb.end)]
    points = [
        pose.p[:, skel.joint_index(n)] if n in skel.joint_names else site_positions(skel, pose, n)
        for n in names
    ]
    return np.stack(points, axis=1), [_carrier(skel, n) for n in names]


def _jacobian(
    skel: Skeleton,
    q: FloatArray,
    pose: Pose,
    side: str,
    pb: _Problem,
    dofs: list[int],
    r: FloatArray,
    directions: FloatArray | None = None,
) -> FloatArray:
    """(n, M, n_d) the derivative of the residuals ``r`` (``_res`` at ``q`` posed as
    ``pose``) by the arm's dofs, analytic. The hand's points and the elbow are points of the
    wrist's and the shoulder's frames; the rest pull is the identity; a depth column is zero
    where the residual is (clipped at 0: outside), else its derivative by its sample
    (``directions``, from ``_res_directions``; computed here if not given) dotted with the
    sample's motion: (1 - f) of its limb's start's plus f of its end's, a hand's end
    (``limb_axis``: a fixed length short of the fingertip on the rigid hand) that share of the
    fingertip's and the wrist's. Only the columns inside are computed: a few of the 42."""
    n, n_d = len(q), len(dofs)
    axes = dof_world_axes(skel, pose, q, dofs)
    origins = pose.p[:, skel.dof_joint[dofs]]
    wrist = skel.joint_index(f"{side}_wrist")
    held = _hand_points(skel, pose, side)
    weights = _point_weights(pb.keep)
    if pb.elbow is not None:
        elbow = skel.joint_index(f"{side}_elbow")
        points = np.concatenate([pose.p[:, elbow][:, None], held], axis=1)
        moves = _point_motion(skel, axes, origins, dofs, [elbow] + [wrist] * 5, points)
        moves[:, 1:] *= weights[:, :, None, None]
        return np.swapaxes(moves, 2, 3).reshape(n, -1, n_d)
    weights[:, 0] *= pb.clear_weight
    held_moves = _point_motion(skel, axes, origins, dofs, [wrist] * 5, held)
    off = np.swapaxes(held_moves * weights[:, :, None, None], 2, 3).reshape(n, -1, n_d)
    n_pen = r.shape[1] - off.shape[1] - n_d
    pen = np.zeros((n, n_pen, n_d))
    row, col = np.nonzero(r[:, :n_pen] > 0.0)
    if row.size:
        if directions is None:
            directions = clearance_directions(skel, pose, side_limbs(side))[1]
        limbs = side_limbs(side)
        n_caps = n_pen // (len(limbs) * COLUMN_SAMPLES)
        limb, cap, sample = np.unravel_index(col, (len(limbs), n_caps, COLUMN_SAMPLES))
        # the limbs' ends' motion, on the rows with a column inside only
        rows, at = np.unique(row, return_inverse=True)
        sub = Pose(pose.R[rows], pose.p[rows], pose.axes, pose.root)
        ends, carriers = _limb_ends(skel, sub, side)
        moves = _point_motion(skel, axes[rows], origins[rows], dofs, carriers, ends)
        for i, lb in enumerate(limbs):
            if lb.end.endswith("fingertip"):  # as ``limb_axis`` shortens it
                length = np.linalg.norm(ends[:, 2 * i + 1] - ends[:, 2 * i], axis=-1)
                length = np.maximum(length, 1e-9)[:, None, None]
                share = np.minimum(limb_radius(skel, lb), 0.5 * length) / length
                moves[:, 2 * i + 1] = (1.0 - share) * moves[:, 2 * i + 1] + share * moves[:, 2 * i]
        # a sample's motion at its place (the closest point's slides along the limb, but the
        # distance is least there: sliding changes it by nothing to first order)
        frac = sample_fractions(skel, sub, limbs)[at, limb, cap, sample][:, None, None]
        motion = (1.0 - frac) * moves[at, 2 * limb] + frac * moves[at, 2 * limb + 1]
        pen[row, col] = pb.clear_weight * np.einsum("kx,kdx->kd", directions[row, col], motion)
    rest = np.broadcast_to(REST_WEIGHT * np.eye(n_d), (n, n_d, n_d))
    return np.concatenate([pen, off, rest], axis=1)


def _lm(
    skel: Skeleton,
    start: FloatArray,
    side: str,
    pb: _Problem,
    dofs: list[int],
    max_iter: int,
    base: Pose | None = None,
) -> tuple[FloatArray, FloatArray]:
    """Levenberg-Marquardt on the arm's dofs from ``start``: (configurations, final cost). A
    row stops once it is clear (a swivel seed: once its elbow is there) or has converged
    (``STALL``, ``MAX_DAMPING``: most rows left inside, a third of the work); the Jacobian of every
    working row is ``_jacobian``'s at its current pose (kept from the trial that won), so an
    iteration poses only its trial, the arm alone (the body's other dofs stay ``start``'s:
    ``forward_below``); ``base``: ``start``'s pose, if known."""
    lo, hi = skel.lower[dofs], skel.upper[dofs]
    n_d = len(dofs)
    cur = np.array(start, dtype=float)
    if base is None:
        base = forward(skel, cur, pb.root[0], pb.root[1], with_axes=False)
    pb = replace(pb, base=base)
    R, p = base.R.copy(), base.p.copy()  # the current configurations' pose
    r, directions = _res_directions(skel, cur, side, pb, dofs, base)
    cost = np.einsum("nm,nm->n", r, r)
    mu = np.full(len(cur), 1e-3)
    eye = np.eye(n_d)
    n_pen = r.shape[1] - 15 - n_d  # the clearance columns come first
    settled = np.zeros(len(cur), dtype=bool)
    for _ in range(max_iter):
        if pb.elbow is None:
            # at work while inside, or (``HAND_TOL``) while a kept hand is off its pose
            off = np.abs(r[:, n_pen : n_pen + 3]).max(axis=1) / np.maximum(pb.keep, 1e-12)
            inside = r[:, :n_pen].max(axis=1, initial=0.0) > 0.0
            work = np.flatnonzero((inside | ((off > HAND_TOL) & (pb.keep >= KEPT))) & ~settled)
        else:
            work = np.flatnonzero((np.abs(r[:, :3]).max(axis=1) > 1e-3) & ~settled)
        if work.size == 0:
            break
        sub = pb.take(work)
        qw = cur[work]
        now = Pose(R=R[work], p=p[work], axes=base.axes[work], root=base.root[work])
        at = None if directions is None else directions[work]
        J = _jacobian(skel, qw, now, side, sub, dofs, r[work], at)  # (m, M, n_d)
        Jt = np.swapaxes(J, 1, 2)
        A = Jt @ J + mu[work, None, None] * eye
        g = np.einsum("nkm,nm->nk", Jt, r[work])
        dq = -np.linalg.solve(A, g[..., None])[..., 0]
        dq *= np.minimum(1.0, MAX_STEP / np.maximum(np.abs(dq).max(axis=1), 1e-12))[:, None]
        trial = qw.copy()
        trial[:, dofs] = np.clip(qw[:, dofs] + dq, lo, hi)
        posed = _pose(skel, trial, side, sub)
        rt, dt = _res_directions(skel, trial, side, sub, dofs, posed)
        ct = np.einsum("nm,nm->n", rt, rt)
        better = ct < cost[work]
        gain = cost[work] - ct
        won = work[better]
        cur[won], r[won], cost[won] = trial[better], rt[better], ct[better]
        R[won], p[won] = posed.R[better], posed.p[better]
        if directions is not None and dt is not None:
            directions[won] = dt[better]
        mu[work] = np.where(better, mu[work] * 0.3, mu[work] * 10.0)
        # converged: a step that gains nothing measurable, or damping so large that a step
        # is no step (measured on fuzz seed 23 #1726: the final costs 2e-11 apart at most)
        settled[work] = np.where(better, gain <= STALL * ct, mu[work] > MAX_DAMPING)
    return cur, cost


def _swivel_targets(
    skel: Skeleton, q: FloatArray, root: tuple[FloatArray, FloatArray], side: str, angle: float
) -> FloatArray:
    """(N, 3) the elbow turned by ``angle`` about the line from the shoulder to the wrist: the
    arm's one free motion when the hand stays where it is."""
    pose = forward(skel, q, root[0], root[1], with_axes=False)
    s, e, _, k = _swivel_line(skel, pose, side)
    return rotate_about(s, k, e - s, np.cos(angle), np.sin(angle))


def _swivel_line(
    skel: Skeleton, pose: Pose, side: str
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """(N, 3) each: the shoulder, elbow and wrist of the ``side`` arm, and the unit vector from
    the shoulder to the wrist (the line the elbow turns about when the hand stays put)."""
    s, e, w = (pose.p[:, skel.joint_index(f"{side}_{j}")] for j in ("shoulder", "elbow", "wrist"))
    k = w - s
    k /= np.maximum(np.linalg.norm(k, axis=1, keepdims=True), 1e-12)
    return s, e, w, k


def swivel_clearance(
    skel: Skeleton,
    q: FloatArray,
    root: tuple[FloatArray, FloatArray],
    side: str,
    turns: FloatArray,
) -> tuple[FloatArray, FloatArray]:
    """(N, G) how far the ``side`` forearm goes into the trunk or a thigh (``clearance``'s
    measure, deepest sample) with its elbow turned by each of ``turns`` (G,) about the line
    from the shoulder to the wrist and the hand where it is: the one motion of an arm whose
    hand holds its pose, measured on the turned elbow without solving the arm for it; and (N,)
    how far the elbow is from that line (m: near a straight arm, a turn is a twist of the
    whole arm that moves nothing)."""
    pose = forward(skel, q, *root, with_axes=False)
    s, e, w, k = _swivel_line(skel, pose, side)
    cos, sin = np.cos(turns)[None, :, None], np.sin(turns)[None, :, None]
    elbows = rotate_about(s[:, None], k[:, None], (e - s)[:, None], cos, sin)  # (N, G, 3)
    forearm = next(limb for limb in side_limbs(side) if limb.start == f"{side}_elbow")
    wrists = np.broadcast_to(w[:, None], elbows.shape)
    offset = np.linalg.norm(np.cross(e - s, k), axis=1)
    return segment_clearance(skel, pose, elbows, wrists, limb_radius(skel, forearm)), offset


def swiveled(
    skel: Skeleton,
    q: FloatArray,
    root: tuple[FloatArray, FloatArray],
    side: str,
    turns: FloatArray,
    keep: float,
    max_iter: int = MAX_ITER,
) -> FloatArray:
    """``q`` (N, D) with the ``side`` elbow turned by ``turns`` (N,) about the line from the
    shoulder to the wrist, the hand's pose held with weight ``keep`` (``_lm`` toward the turned
    elbow, as ``keep_clear``'s swivel seeds); a row turned by 0 comes back as it is."""
    out = np.array(q, dtype=float)
    rows = np.flatnonzero(turns != 0.0)
    if rows.size == 0:
        return out
    root_n = (root[0][rows], root[1][rows])
    q0 = out[rows]
    pose = forward(skel, q0, *root_n, with_axes=False)
    s, e, _, k = _swivel_line(skel, pose, side)
    pb = _Problem(root_n, _hand_points(skel, pose, side), np.full(len(rows), keep), q0)
    dofs = arm_dofs(skel, side)
    # the turn taken in stages of at most ``SWIVEL_STAGE``, each solved from the last: the
    # solution follows the turn from the frame's own pose, so two neighbouring frames turned
    # alike end alike (one solve of a large turn fell into either of two wrist twists)
    stages = max(1, int(np.ceil(np.abs(turns[rows]).max() / SWIVEL_STAGE)))
    cur = q0
    for k_stage in range(1, stages + 1):
        a = (turns[rows] * k_stage / stages)[:, None]
        target = rotate_about(s, k, e - s, np.cos(a), np.sin(a))
        cur, _ = _lm(skel, cur, side, replace(pb, elbow=target), dofs, max_iter,
                     pose if k_stage == 1 else None)  # fmt: skip
    out[rows] = cur
    return out


def keep_clear(
    skel: Skeleton,
    q: FloatArray,
    root: tuple[FloatArray, FloatArray],
    side: str,
    keep: FloatArray,
    max_iter: int = MAX_ITER,
    swivel: bool = False,
    start: FloatArray | None = None,
    firm: float = 0.0,
    inside: FloatArray | None = None,
) -> FloatArray:
    """Configurations ``q`` (N, D) with the ``side`` arm moved clear of the trunk and thighs.

    ``root``: (N, 3) positions and (N, 4) rotations; ``keep`` (N,) the weight of the hand's
    pose against the clearance (see the module docstring). Rows already clear come back as
    they were; a row that cannot be cleared keeps its best configuration. ``swivel``: a row
    the local solve leaves inside also tries the elbow turned about the shoulder-wrist line by
    each of ``SWIVELS`` (a pose through the trunk is often a local minimum: the way out is
    round, not straight), keeping the best; for single poses (keyframes), where no
    neighbouring frame has to agree. ``start``: where to start from instead of ``q`` (the
    hand's pose and the rest pull stay ``q``'s); a row clear there is returned as it is.
    ``firm``: a row the solve leaves inside the clearance is solved again with the clearance
    weighing ``firm`` (its orientation then yields ``firm`` times sooner), and takes that if it
    is less deep and a kept hand stays within ``FIRM_HAND_TOL`` of its pose. ``inside``: (N,)
    ``penetration`` of the rows where they start, if the caller has it (the clearance pass
    poses every frame once for both arms)."""
    q = np.array(q, dtype=float)
    begin = q if start is None else np.asarray(start, dtype=float)
    if inside is None:
        inside = penetration(skel, begin, root, side)
    need = np.flatnonzero(inside > 0.0)
    if need.size == 0:
        return np.array(begin, dtype=float)
    if need.size > MAX_ROWS:
        return _keep_clear_sparse(
            skel, q, root, side, keep, need, begin, max_iter, swivel, inside, firm
        )
    dofs = arm_dofs(skel, side)
    root_n = (root[0][need], root[1][need])
    q0 = q[need].copy()
    posed = forward(skel, q0, *root_n, with_axes=False)
    kept = _hand_points(skel, posed, side)
    pb = _Problem(root_n, kept, np.asarray(keep, dtype=float)[need], q0)
    # started from ``q`` itself (or the same numbers), its pose is the LM's start: posed once
    same = start is None or np.array_equal(begin[need], q0)
    best, cost = _lm(skel, begin[need], side, pb, dofs, max_iter, posed if same else None)
    if swivel:
        left = np.flatnonzero(penetration(skel, best, root_n, side) > SWIVEL_FROM)
        if left.size:
            # every turn of every row in one batch: rows (turn, row)
            turns = len(SWIVELS)
            rows = np.tile(left, turns)
            root_n_left = (root_n[0][left], root_n[1][left])
            sub = pb.take(rows)
            target = np.concatenate(
                [_swivel_targets(skel, q0[left], root_n_left, side, a)
                 for a in SWIVELS]
            )  # fmt: skip
            seed, _ = _lm(skel, q0[rows], side, replace(sub, elbow=target), dofs, max_iter)
            cand, c = _lm(skel, seed, side, sub, dofs, max_iter)
            c = c.reshape(turns, len(left))
            pick = np.argmin(c, axis=0)
            c_best = c[pick, np.arange(len(left))]
            won = c_best < cost[left]
            chosen = cand.reshape(turns, len(left), -1)[pick, np.arange(len(left))]
            best[left[won]], cost[left[won]] = chosen[won], c_best[won]
    if firm > 0.0:
        best = _firm(skel, best, side, pb, dofs, max_iter, firm)
    out = np.array(begin, dtype=float)
    out[need] = best
    return out


def _firm(
    skel: Skeleton,
    best: FloatArray,
    side: str,
    pb: _Problem,
    dofs: list[int],
    max_iter: int,
    weight: float,
) -> FloatArray:
    """``best`` with the rows of a kept hand (weight ``KEPT`` or more) still inside the
    clearance solved again from there with the clearance and the hand's site weighing
    ``weight`` times more, its orientation not (a grip on a valve can turn a few degrees; a
    forearm cannot be in a thigh): taken where less deep, the site within ``FIRM_HAND_TOL``
    and no dof turned more than ``FIRM_TURN``. A free hand is not: it may move out already."""
    root = pb.root
    depth = penetration(skel, best, root, side)
    left = np.flatnonzero((depth > 0.0) & (pb.keep >= KEPT))
    if left.size == 0:
        return best
    sub = pb.take(left)
    cand, _ = _lm(skel, best[left], side, replace(sub, clear_weight=weight), dofs, max_iter)
    root_left = (root[0][left], root[1][left])
    pose = forward(skel, cand, *root_left, with_axes=False)
    moved = np.linalg.norm(_hand_points(skel, pose, side)[:, 0] - sub.kept[:, 0], axis=1)
    ok = penetration(skel, cand, root_left, side) < depth[left]
    ok &= moved <= FIRM_HAND_TOL
    ok &= np.abs(cand - best[left]).max(axis=1) <= FIRM_TURN
    out = best.copy()
    out[left[ok]] = cand[ok]
    return out


def _keep_clear_sparse(
    skel: Skeleton,
    q: FloatArray,
    root: tuple[FloatArray, FloatArray],
    side: str,
    keep: FloatArray,
    need: np.ndarray,
    begin: FloatArray,
    max_iter: int,
    swivel: bool,
    inside: FloatArray,
    firm: float = 0.0,
) -> FloatArray:
    """``keep_clear`` of more than ``MAX_ROWS`` rows: every k-th of them solved, the others'
    corrections interpolated between their solved neighbours (dof by dof). Every row solved
    was 25 iterations of 8 whole-body poses each: a 10-minute inspect with the arm in the
    thigh linted for 213 s in 1.6 GB. What the interpolated rows leave inside, verify reports
    (MT0514)."""
    step = -(-need.size // MAX_ROWS)
    picked = np.unique(np.concatenate([need[::step], need[-1:]]))
    solved = keep_clear(
        skel, q[picked], (root[0][picked], root[1][picked]), side,
        np.asarray(keep, dtype=float)[picked], max_iter, swivel, begin[picked], firm,
        inside[picked],
    )  # fmt: skip
    correction = solved - begin[picked]
    out = np.array(begin, dtype=float)
    for d in np.flatnonzero(np.abs(correction).max(axis=0) > 0.0):
        out[need, d] = begin[need, d] + np.interp(need, picked, correction[:, d])
    return skel.clip(out)
