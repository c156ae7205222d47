"""Head aim: the neck and head dofs that point an aiming site (the gaze) at a point.

The damped least squares solver found a head for each row on its own (60 iterations and
restarts a row, ~0.2 ms an iteration); the head needs far less. Two numbers say where the eyes
look, so the head is given two: a yaw ``ψ`` (the neck's rotation) and a pitch ``θ`` shared
between the neck's and the head's flexion in proportion to their ranges on that side (both reach
their limit together, as the cervical table's 3/4 and 1/4 split intends); the lateral flexions
stay at the comfortable posture (they tilt the view, they do not aim it). From the pitch and yaw
of the line to the target (closed form, the eye's offset from the neck left out), Gauss-Newton
steps on (ψ, θ), vectorised over every row at once, take the eye's own movement into account:
4 to 6 steps reach 1e-10 rad where the target is in range. Steps are projected on the limits (a
coordinate a step takes past its limit is pinned there, the others re-solved), so nothing
leaves its range. A target the yaw and pitch cannot reach is aimed at with every dof free
(projected Gauss-Newton from three starts): turned and tilted, the neck sees lower and further
than flexed alone, and the head rests at its limits, as close to the target as they allow.

A target behind the eyes past the neck's rotation is about as well seen from either rotation
limit; ``aim_head`` solves it from both and keeps the side given by ``side`` (the head's
current rotation) unless the other sees the target better by more than ``near``.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..kinematics import cross, forward_part
from ..skeleton import Skeleton
from .goals import default_dofs

FloatArray = NDArray[np.float64]

MAX_STEPS = 30  # Gauss-Newton steps; in range the aim converges in 4-6
STEP_TOL = 1e-7  # rad: a row whose step is below this has converged (its aim is off by about that)
# regularises the normal equations: yaw and pitch are independent where the target is in view;
# five dofs for a direction overlap (used only past the limits), so their steps are damped more
FREE_DAMPING = 1e-4
COST_TOL = 1e-12  # a row whose |d − w|² fell by less than this in a step has converged
MAX_STEP = 0.3  # rad: the largest change of a coordinate in one step
FREE_FROM = 1e-5  # rad: a row aimed worse than this by yaw and pitch frees every dof


@dataclass(frozen=True)
class _Coordinates:
    """What the Gauss-Newton steps move: the yaw and pitch (``per`` maps them to the dofs)
    or, past their limits, the dofs themselves (``per`` is None)."""

    lower: FloatArray
    upper: FloatArray
    damping: float
    per: tuple[FloatArray, FloatArray] | None = None  # the yaw's and pitch's shares

    def angles(self, x: FloatArray) -> tuple[FloatArray, FloatArray]:
        """The dofs (N, K) of ``x`` and their derivatives (N, m, K) by each coordinate."""
        if self.per is None:
            return x, np.broadcast_to(np.eye(x.shape[1]), (len(x), x.shape[1], x.shape[1]))
        per = np.stack(
            [share[(x[:, i] < 0).astype(np.intp)] for i, share in enumerate(self.per)], axis=1
        )
        return np.einsum("nik,ni->nk", per, x), per


@dataclass(frozen=True)
class HeadChain:
    """The aiming site's neck and head, as the solver needs them (one per skeleton)."""

    dofs: NDArray[np.intp]  # (K,) skeleton dofs, chain order
    base: int  # the joint the first moving joint hangs from (the thorax)
    joints: tuple[int, ...]  # the moving joints, top first
    joint_of_dof: NDArray[np.intp]  # (K,) index into ``joints``
    axes: FloatArray  # (K, 3) each dof's axis in its joint's frame
    offsets: FloatArray  # (len(joints), 3) each joint from its parent
    site_offset: FloatArray  # (3,) the site in the last joint's frame
    site_direction: FloatArray  # (3,) the aim direction in the last joint's frame
    aim: _Coordinates  # yaw and pitch
    free: _Coordinates  # every dof on its own (past the yaw's and the pitch's limits)
    tilts: NDArray[np.intp]  # (T,) the dofs about a forward axis (into ``dofs``)
    axis_of_dof: tuple[int, ...]  # each dof's axis: 0 x (side), 1 y (vertical), 2 z (forward)


def head_chain(skel: Skeleton, site: str = "gaze") -> HeadChain:
    """The chain of ``site`` (cached on the skeleton). Dofs about the joint's vertical axis
    turn (yaw), about its side axis pitch, about its forward axis tilt (0 while the yaw and
    pitch can aim)."""
    cache: dict[str, HeadChain] = skel.__dict__.setdefault("_head_chains", {})
    found = cache.get(site)
    if found is None:
        found = cache[site] = _build_chain(skel, site)
    return found


def _build_chain(skel: Skeleton, site: str) -> HeadChain:
    st = skel.site(site)
    if st.direction is None:
        raise ValueError(f"site {site} has no direction to aim with")
    dofs = np.asarray(default_dofs(skel, [site], "arm"), dtype=np.intp)
    joints = tuple(dict.fromkeys(int(skel.dof_joint[d]) for d in dofs))
    if joints[-1] != skel.joint_index(st.joint):
        raise ValueError(f"site {site}: its chain does not end at its joint")
    for upper, lower in itertools.pairwise(joints):
        if int(skel.parent[lower]) != upper:
            raise ValueError(f"site {site}: the moving joints are not one chain")
    axes = skel.dof_axis[dofs]
    kind = np.argmax(np.abs(axes), axis=1)  # 0: side (pitch), 1: vertical (yaw), 2: forward
    if not np.allclose(np.abs(axes).max(axis=1), 1.0) or (axes.max(axis=1) < 0.5).any():
        raise ValueError(f"site {site}: head aim needs +x, +y and +z dof axes")
    lo, hi = skel.lower[dofs], skel.upper[dofs]
    if (lo > 0).any() or (hi < 0).any():
        raise ValueError(f"site {site}: a dof's range excludes 0 (upright, facing ahead)")

    def shares(mask: NDArray[np.bool_]) -> tuple[FloatArray, float, float]:
        """Dofs per unit of the coordinate (>= 0, < 0): the dofs' ranges on that side, shared."""
        up, down = np.where(mask, hi, 0.0), np.where(mask, lo, 0.0)
        top, bottom = float(up.sum()), float(down.sum())
        per = np.stack([up / max(top, 1e-12), down / min(bottom, -1e-12)])
        return per, bottom, top

    yaw, yaw_lo, yaw_hi = shares(kind == 1)
    pitch, pitch_lo, pitch_hi = shares(kind == 0)
    aim = _Coordinates(np.array([yaw_lo, pitch_lo]), np.array([yaw_hi, pitch_hi]), 1e-9,
                       (yaw, pitch))  # fmt: skip
    return HeadChain(
        dofs=dofs,
        base=int(skel.parent[joints[0]]),
        joints=joints,
        joint_of_dof=np.array([joints.index(int(skel.dof_joint[d])) for d in dofs]),
        axes=axes,
        offsets=skel.offsets[list(joints)],
        site_offset=np.asarray(st.offset, dtype=float),
        site_direction=np.asarray(st.direction, dtype=float),
        aim=aim,
        free=_Coordinates(lo, hi, FREE_DAMPING),
        tilts=np.flatnonzero(kind == 2),
        axis_of_dof=tuple(int(a) for a in kind),
    )


@dataclass(frozen=True)
class _Look:
    """Where the eyes are and look for a batch of head angles, and the dofs' world axes."""

    eye: FloatArray  # (N, 3)
    direction: FloatArray  # (N, 3)
    axes: FloatArray  # (N, K, 3) world axis of each dof
    centres: FloatArray  # (N, K, 3) world position of each dof's joint


def _look(chain: HeadChain, base_R: FloatArray, base_p: FloatArray, q: FloatArray) -> _Look:
    """Forward kinematics of the chain from its base frame (the IR's rule: parent · offset ·
    each dof's rotation in turn). The frame is kept as its three columns (N, 3): a turn about
    the frame's own x, y or z axis mixes the other two by the angle's cosine and sine, which
    is all a rotation matrix product would do here, in a few array operations (a solver step's
    cost is numpy's per-call overhead: most parts aim a few rows)."""
    n, k = q.shape
    cos, sin = np.cos(q), np.sin(q)
    cols = [base_R[:, :, 0], base_R[:, :, 1], base_R[:, :, 2]]
    p = base_p
    axes, centres = np.empty((n, k, 3)), np.empty((n, k, 3))
    joint = -1
    for i in range(k):
        while joint < chain.joint_of_dof[i]:
            joint += 1
            p = _moved(p, cols, chain.offsets[joint])
        a = chain.axis_of_dof[i]
        u, v = (a + 1) % 3, (a + 2) % 3
        axes[:, i] = cols[a]
        centres[:, i] = p
        c, s = cos[:, i : i + 1], sin[:, i : i + 1]
        cols[u], cols[v] = c * cols[u] + s * cols[v], c * cols[v] - s * cols[u]
    eye = _moved(p, cols, chain.site_offset)
    direction = _moved(np.zeros_like(p), cols, chain.site_direction)
    return _Look(eye, direction, axes, centres)


def _moved(p: FloatArray, cols: list[FloatArray], offset: FloatArray) -> FloatArray:
    """``p`` plus ``offset`` given in the frame whose columns are ``cols``."""
    for j in range(3):
        if offset[j] != 0.0:
            p = p + cols[j] * offset[j]
    return p


def _first_guess(
    chain: HeadChain, base_R: FloatArray, base_p: FloatArray, targets: FloatArray
) -> FloatArray:
    """Yaw and pitch of the line from the eye (head at rest) to the target, in the base's frame:
    the aim itself but for the neck's flexion before its rotation and the eye's offset."""
    rest = _look(chain, base_R, base_p, np.zeros((len(targets), len(chain.dofs))))
    u = np.einsum("nji,nj->ni", base_R, targets - rest.eye)  # into the base's frame
    yaw = np.arctan2(u[:, 0], u[:, 2])
    pitch = np.arctan2(-u[:, 1], np.hypot(u[:, 0], u[:, 2]))
    return np.clip(np.stack([yaw, pitch], axis=1), chain.aim.lower, chain.aim.upper)


def _refine(
    chain: HeadChain,
    base_R: FloatArray,
    base_p: FloatArray,
    targets: FloatArray,
    x: FloatArray,
    coords: _Coordinates,
) -> tuple[FloatArray, FloatArray]:
    """Projected Gauss-Newton on ``d − w`` (the eye's direction less the unit line to the
    target), all rows at once until every step is below ``STEP_TOL``. Past the limits the
    residual stays large and a full step can overshoot: a row whose step made it worse goes
    back to its best and steps again at a quarter of the length (never worse than its start).
    Returns the best coordinates and their aim errors (rad)."""
    best = x.copy()
    best_cost = np.full(len(x), np.inf)
    radius = np.full(len(x), MAX_STEP)
    x = x.copy()
    rows = np.arange(len(x))
    whole = True  # every row works: no indexing by rows (most parts aim a few rows)
    for _ in range(MAX_STEPS):
        if not rows.size:
            break
        if whole:
            xr, R, p, t = x, base_R, base_p, targets
        else:
            xr, R, p, t = x[rows], base_R[rows], base_p[rows], targets[rows]
        q, per = coords.angles(xr)
        look = _look(chain, R, p, q)
        line = t - look.eye
        dist = np.maximum(np.sqrt(np.einsum("nj,nj->n", line, line))[:, None], 1e-9)
        w = line / dist
        r = look.direction - w
        cost = np.einsum("nj,nj->n", r, r)
        worse = cost > best_cost[rows]
        back = rows[worse]
        if back.size:
            x[back], radius[back] = best[back], radius[back] * 0.25
            keep = ~worse
            rows, xr, per, r, dist, w, cost = (a[keep] for a in (rows, xr, per, r, dist, w, cost))
            look = _Look(*(a[keep] for a in (look.eye, look.direction, look.axes, look.centres)))
        settled = best_cost[rows] - cost < COST_TOL  # past the limits: on the limits' floor
        best[rows], best_cost[rows] = xr, cost
        # per dof: how the direction turns, less how the line to the target turns as the eye moves
        turn = cross(look.axes, look.direction[:, None, :])
        moved = cross(look.axes, look.eye[:, None, :] - look.centres)
        along = np.einsum("nkj,nj->nk", moved, w)[..., None]
        per_dof = turn + (moved - w[:, None, :] * along) / dist[:, :, None]
        J = np.einsum("nkj,nik->nji", per_dof, per)  # (N, 3, m)
        solve = _aim_step if J.shape[2] == 2 else _projected_step
        step = solve(J, r, xr, coords.lower, coords.upper, coords.damping)
        big = np.abs(step).max(axis=1)
        step *= np.minimum(1.0, radius[rows] / np.maximum(big, 1e-300))[:, None]
        big = np.minimum(big, radius[rows])
        moved_x = np.minimum(np.maximum(xr + step, coords.lower), coords.upper)
        if whole and not back.size:
            x = moved_x
        else:
            x[rows] = moved_x
        going = (big > STEP_TOL) & ~settled
        whole = whole and not back.size and bool(going.all())
        if not whole:
            mask = np.zeros(len(x), dtype=bool)
            mask[rows[going]] = True
            mask[back[radius[back] > STEP_TOL]] = True
            rows = np.flatnonzero(mask)
    return best, _angle(best_cost)


def _angle(cost: FloatArray) -> FloatArray:
    """The angle (rad) between two unit vectors whose difference has squared length ``cost``."""
    return 2.0 * np.arcsin(np.minimum(np.sqrt(cost) / 2.0, 1.0))


def _aim_step(
    J: FloatArray,
    r: FloatArray,
    x: FloatArray,
    lower: FloatArray,
    upper: FloatArray,
    damping: float,
) -> FloatArray:
    """``_projected_step`` for two coordinates, its 2x2 systems solved in closed form (the
    batched LAPACK call and its pinning loop cost more than the arithmetic of a few rows)."""
    j0, j1 = J[:, :, 0], J[:, :, 1]
    a00 = np.einsum("nk,nk->n", j0, j0) + damping
    a11 = np.einsum("nk,nk->n", j1, j1) + damping
    a01 = np.einsum("nk,nk->n", j0, j1)
    b0, b1 = -np.einsum("nk,nk->n", j0, r), -np.einsum("nk,nk->n", j1, r)
    det = a00 * a11 - a01 * a01
    s0, s1 = (a11 * b0 - a01 * b1) / det, (a00 * b1 - a01 * b0) / det
    x0, x1 = x[:, 0], x[:, 1]
    out0 = (x0 + s0 > upper[0]) | (x0 + s0 < lower[0])
    out1 = (x1 + s1 > upper[1]) | (x1 + s1 < lower[1])
    if out0.any() or out1.any():
        f0 = np.minimum(np.maximum(x0 + s0, lower[0]), upper[0]) - x0
        f1 = np.minimum(np.maximum(x1 + s1, lower[1]), upper[1]) - x1
        s0, s1 = (
            np.where(out0, f0, np.where(out1, (b0 - a01 * f1) / a00, s0)),
            np.where(out1, f1, np.where(out0, (b1 - a01 * f0) / a11, s1)),
        )
        # the coordinate solved alone may leave in turn: pinned too
        s0 = np.minimum(np.maximum(x0 + s0, lower[0]), upper[0]) - x0
        s1 = np.minimum(np.maximum(x1 + s1, lower[1]), upper[1]) - x1
    return np.stack([s0, s1], axis=1)


def _projected_step(
    J: FloatArray,
    r: FloatArray,
    x: FloatArray,
    lower: FloatArray,
    upper: FloatArray,
    damping: float,
) -> FloatArray:
    """The Gauss-Newton step (N, m); a coordinate it would take past a limit goes to the limit
    and the others are solved again with it fixed (until none leaves)."""
    m = J.shape[2]
    a = np.einsum("nki,nkj->nij", J, J) + damping * np.eye(m)
    b = -np.einsum("nki,nk->ni", J, r)
    pinned = np.zeros(x.shape, dtype=bool)
    step = np.linalg.solve(a, b[..., None])[..., 0]
    for _ in range(m):
        out = ~pinned & ((x + step > upper) | (x + step < lower))
        if not out.any():
            break
        pinned |= out
        fixed = np.where(pinned, np.clip(x + step, lower, upper) - x, 0.0)
        both = ~pinned[:, :, None] & ~pinned[:, None, :]
        a_free = np.where(both, a, 0.0) + np.where(pinned[:, :, None], np.eye(m), 0.0)
        b_free = np.where(pinned, fixed, b - np.einsum("nij,nj->ni", a, fixed))
        step = np.linalg.solve(a_free, b_free[..., None])[..., 0]
    return step


def aim_head(
    skel: Skeleton,
    q: FloatArray,
    root_position: FloatArray,
    root_rotation: FloatArray,
    targets: FloatArray,
    *,
    site: str = "gaze",
    side: FloatArray | None = None,
    near: float = 0.0,
) -> FloatArray:
    """``q`` (N, D) with the neck and head of every row aimed at its target (N, 3).

    The body below the neck is each row's own. ``side`` (N,): the neck's rotation each row
    would keep (the head's before the aim): a row whose target is past the rotation limit is
    solved at both limits and keeps that side unless the other sees the target better by more
    than ``near`` (rad); without ``side``, the side that sees it best."""
    chain = head_chain(skel, site)
    q = np.array(q, dtype=float, copy=True)
    targets = np.asarray(targets, dtype=float)
    pose = forward_part(skel, q, root_position, root_rotation, [site])
    base_R, base_p = pose.R[:, chain.base], pose.p[:, chain.base]
    x, errors = _refine(chain, base_R, base_p, targets,
                        _first_guess(chain, base_R, base_p, targets), chain.aim)  # fmt: skip
    yaw_lo, yaw_hi = chain.aim.lower[0], chain.aim.upper[0]
    at_limit = np.flatnonzero((x[:, 0] <= yaw_lo + 1e-9) | (x[:, 0] >= yaw_hi - 1e-9))
    if at_limit.size:
        x[at_limit], errors[at_limit] = _other_side(
            chain, base_R, base_p, targets, x, errors, at_limit, side, near
        )
    head = chain.aim.angles(x)[0]
    missed = np.flatnonzero(errors > FREE_FROM)
    if missed.size:
        head[missed] = _past_the_limits(
            chain, base_R[missed], base_p[missed], targets[missed], head[missed]
        )
    q[:, chain.dofs] = head
    return q


def head_yaw(skel: Skeleton, q: FloatArray, site: str = "gaze") -> FloatArray:
    """The neck's rotation (N,) of poses ``q`` (N, D): the sum of the turning dofs, the side
    ``aim_head`` keeps a head on."""
    chain = head_chain(skel, site)
    turning = chain.aim.per[0][0] > 0  # type: ignore[index]
    return np.asarray(q, dtype=float)[:, chain.dofs[turning]].sum(axis=1)


def _past_the_limits(
    chain: HeadChain, base_R: FloatArray, base_p: FloatArray, targets: FloatArray, q: FloatArray
) -> FloatArray:
    """The best aim with every dof free, from the yaw and pitch found, upright and tilted to
    either side (looking down and to the side, the neck's lateral flexion brings the eyes
    lower than its flexion alone; from a yaw at its limit the first step may tilt the wrong
    way). Where starts tie, the first: the one from upright."""
    starts = np.stack([q, q.copy(), q.copy()])
    starts[1][:, chain.tilts] = chain.free.upper[chain.tilts]
    starts[2][:, chain.tilts] = chain.free.lower[chain.tilts]
    n = len(q)
    many = (np.tile(base_R, (3, 1, 1)), np.tile(base_p, (3, 1)), np.tile(targets, (3, 1)))
    found, errors = _refine(chain, *many, starts.reshape(3 * n, -1), chain.free)
    errors = errors.reshape(3, n)
    best = np.argmin(errors, axis=0)
    return found.reshape(3, n, -1)[best, np.arange(n)]


def _other_side(
    chain: HeadChain,
    base_R: FloatArray,
    base_p: FloatArray,
    targets: FloatArray,
    x: FloatArray,
    errors: FloatArray,
    rows: NDArray[np.intp],
    side: FloatArray | None,
    near: float,
) -> tuple[FloatArray, FloatArray]:
    """For rows at a rotation limit: the aim from the opposite limit, kept where it is on the
    preferred side (and not worse by more than ``near``) or, without a preference, better."""
    found = x[rows]
    start = found.copy()
    start[:, 0] = np.where(found[:, 0] > 0, chain.aim.lower[0], chain.aim.upper[0])
    R, p, t = base_R[rows], base_p[rows], targets[rows]
    other, e_other = _refine(chain, R, p, t, start, chain.aim)
    e_found = errors[rows]
    if side is None:
        take = e_other < e_found
    else:
        want = np.sign(np.asarray(side, dtype=float)[rows])
        on_side_other = np.sign(other[:, 0]) == want
        on_side_found = np.sign(found[:, 0]) == want
        take = np.where(
            on_side_other & ~on_side_found,
            e_other <= e_found + near,
            np.where(on_side_found & ~on_side_other, e_other + near < e_found, e_other < e_found),
        )
    return np.where(take[:, None], other, found), np.where(take, e_other, e_found)
