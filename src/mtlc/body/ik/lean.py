"""The least lean that meets every goal: a whole-body solve for a hand held while the other reaches.

``solve_ta``'s null-space pull toward the comfortable pose fades as the task error goes to 0
(``NULL_FADE``): it settles the redundant dofs only while the hand is far. With two goals (a
hand reaching low while the other holds its site) the descent could then end anywhere on the
set of poses that meet both, or short of it at a deep lean: a PSU latch 72 cm in front of a
standing male P50, the left hand on a handle, was reported 1.1 mm short (MT0501) at 90 deg of
trunk flexion, though poses that meet both goals exist.

``solve_held`` keeps the goals as the task and descends a secondary objective, the trunk near
upright and the other joints near comfortable, in the goals' null space until it converges,
not only while the error is large. It starts from several seeds at once (the given start, that
start with the trunk upright, the caller's seeds and seeded random poses), one batch, and
keeps the pose of least objective among those that meet every goal (else the nearest).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..kinematics import einsum
from ..skeleton import Skeleton
from .dls import prepare, solve_spd, solve_ta
from .goals import Goal, normalise
from .result import IKResult, residual, returned_errors

FloatArray = NDArray[np.float64]

TRUNK = ("lumbar_flex", "lumbar_lat", "lumbar_rot", "thorax_flex", "thorax_lat", "thorax_rot")
TRUNK_WEIGHT = 10.0  # the trunk's departure from upright against any other joint's
RANDOM_SEEDS = 12  # random in-limit starts besides the given ones
REFINE_ITER = 80  # null-space descent steps after the first solve
NULL_GAIN = 0.2  # share of the (weighted) way to comfort a step asks of the null space
DAMPING = 0.005  # small: the goals are met to tol, not traded against the objective
MAX_STEP = 0.2  # rad, the largest component of a refinement step


def objective(skel: Skeleton, q: FloatArray) -> FloatArray:
    """The secondary cost of poses ``q`` (..., D): the trunk's squared departure from its rest
    pose, ``TRUNK_WEIGHT`` times any other joint's from comfortable."""
    w = _weights(skel)
    d = q - skel.q_comfort
    return einsum("...d,d->...", d * d, w)


def _weights(skel: Skeleton) -> FloatArray:
    w = np.ones(skel.n_dofs)
    for name in TRUNK:
        w[skel.dof_index(name)] = TRUNK_WEIGHT
    return w


def solve_held(
    skel: Skeleton,
    goals: Sequence[Goal],
    q0: ArrayLike,
    *,
    reach: str = "torso",
    root_position: ArrayLike | None = None,
    root_rotation: ArrayLike | None = None,
    seeds: Sequence[ArrayLike] = (),
    tol: float = 2e-4,
    random_seeds: int = RANDOM_SEEDS,
    refine_iter: int = REFINE_ITER,
    seed: int = 0,
) -> IKResult:
    """One pose (a row of ``IKResult``) meeting every position goal with the least
    ``objective``, or the nearest to meeting them when no start gets there. ``q0`` (D,) the
    body as it is (dofs outside the chain keep their values); ``seeds`` more starts."""
    q0 = np.asarray(q0, dtype=float)
    idx = prepare(skel, goals, q0, reach=reach).active
    trunk = [skel.dof_index(n) for n in TRUNK]
    upright = q0.copy()
    upright[trunk] = skel.q_comfort[trunk]
    starts = [q0, upright, *(np.asarray(s, dtype=float) for s in seeds)]
    rng = np.random.default_rng(seed)
    lo, hi = skel.lower[idx], skel.upper[idx]
    rand = np.tile(q0, (random_seeds, 1))
    rand[:, idx] = lo + (hi - lo) * rng.random((random_seeds, len(idx)))
    qs = np.vstack([np.stack(starts), rand])
    B = len(qs)
    root_p = None if root_position is None else np.tile(np.asarray(root_position), (B, 1))
    root_r = None if root_rotation is None else np.tile(np.asarray(root_rotation), (B, 1))
    batch = [Goal(g.effector, position=np.tile(np.asarray(g.position), (B, 1))) for g in goals]
    model = prepare(
        skel, batch, qs, reach=reach, root_position=root_p, root_rotation=root_r
    )  # fmt: skip
    first = solve_ta(skel, batch, qs, model=model, restarts=0, max_iter=120, tol=tol)
    ga = normalise(skel, batch)
    model = model.for_start(first.q)
    qa = first.q[:, model.active]
    lo, hi = model.lower, model.upper
    w = _weights(skel)[model.active]
    comfort = skel.q_comfort[model.active]
    eye = DAMPING * DAMPING * np.eye(3 * len(goals))
    best_q = first.q.copy()
    best_obj = np.where(first.position_error <= tol, objective(skel, first.q), np.inf)
    near_q, near_err = first.q.copy(), first.position_error.copy()
    for _ in range(refine_iter):
        r = residual(model, ga, qa, with_cost=False)
        q_full = model.full(qa)
        met = r.pos_err <= tol
        obj = objective(skel, q_full)
        take = met & (obj < best_obj)
        best_q[take], best_obj[take] = q_full[take], obj[take]
        closer = r.pos_err < near_err
        near_q[closer], near_err[closer] = q_full[closer], r.pos_err[closer]
        # the task's correction plus the weighted pull to comfort in the goals' null space:
        # dq = J⁺e + (I − J⁺J)z = J⁺(e − Jz) + z, the pull never fading
        z = NULL_GAIN * (comfort - qa) * (w / w.max())
        J = r.J
        Jt = J.swapaxes(-1, -2)
        y = solve_spd(J @ Jt + eye, (r.e - einsum("bmn,bn->bm", J, z))[..., None])[..., 0]
        dq = einsum("bnm,bm->bn", Jt, y) + z
        big = np.abs(dq).max(axis=1)
        dq *= np.minimum(1.0, MAX_STEP / np.maximum(big, 1e-300))[:, None]
        qa = np.clip(qa + dq, lo, hi)
    r = residual(model, ga, qa, with_cost=False)
    q_full = model.full(qa)
    obj = objective(skel, q_full)
    take = (r.pos_err <= tol) & (obj < best_obj)
    best_q[take], best_obj[take] = q_full[take], obj[take]
    if np.isfinite(best_obj).any():
        q = best_q[int(np.argmin(best_obj))]
    else:
        closer = r.pos_err < near_err
        near_q[closer], near_err[closer] = q_full[closer], r.pos_err[closer]
        q = near_q[int(np.argmin(near_err))]
    one = prepare(skel, goals, q, reach=reach, root_position=root_position,
                  root_rotation=root_rotation)  # fmt: skip
    pos, ori = returned_errors(one, normalise(skel, goals), q[None])
    return IKResult(
        q=q[None],
        position_error=pos,
        orientation_error=ori,
        success=(pos <= tol) & skel.within_limits(q[None]),
        iterations=np.array([120 + refine_iter]),
        restarts=np.array([B - 1]),
        method="held",
    )
