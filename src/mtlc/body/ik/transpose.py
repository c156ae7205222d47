"""Seed 004's fast variant: Jacobian transpose with an adaptive step.

CN102426709A (claim 5) replaces the inverse by the transpose, ``Δq = α Jᵀe``, and adapts the
step of that gradient descent. The step here is the exact minimiser of the linearised error
along ``Jᵀe`` (Buss 2004): ``α = ⟨e, JJᵀe⟩ / |JJᵀe|²``, capped at ``max_step`` rad per joint,
projected into the joint limits, and halved whenever it would increase the error (so no row
oscillates), with a bounded iteration count. Cheap per iteration (no linear solve) but slow
to converge on ill-conditioned chains; selectable for speed-sensitive, loose-tolerance work.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..skeleton import Skeleton
from .dls import _initial, prepare
from .goals import Goal, normalise
from .model import ChainModel
from .result import IKResult, residual, returned_errors

FloatArray = NDArray[np.float64]


def solve_transpose(
    skel: Skeleton,
    goals: Sequence[Goal],
    q0: ArrayLike | None = None,
    *,
    model: ChainModel | None = None,
    dofs: Sequence[int] | Sequence[str] | None = None,
    reach: str = "arm",
    root_position: ArrayLike | None = None,
    root_rotation: ArrayLike | None = None,
    tol: float = 1e-3,
    orientation_tol: float = math.radians(1.0),
    max_iter: int = 1000,
    max_step: float = 0.3,
) -> IKResult:
    """Jacobian-transpose IK with adaptive step for a batch of targets."""
    ga = normalise(skel, goals)
    B = ga.batch
    if model is None:
        model = prepare(
            skel,
            goals,
            q0 if q0 is not None else skel.q_comfort,
            dofs=dofs,
            reach=reach,
            root_position=root_position,
            root_rotation=root_rotation,
        )
    qf, q_all = _initial(skel, model, q0, B)
    model = model.for_start(qf)  # a model prepared for another trunk describes another body
    lo, hi = model.lower, model.upper
    r = residual(model, ga, q_all)
    pos, ori = r.pos_err.copy(), r.ori_err.copy()
    iters = np.zeros(B, dtype=np.intp)
    # Working set: rows still iterating; finished rows are written back and leave.
    rows = np.flatnonzero(~((pos <= tol) & (ori <= orientation_tol)))
    sel = None if rows.size == B else rows  # None: every row, no fancy indexing
    q = q_all[rows]
    if sel is not None:
        r = _merge(np.zeros(0, dtype=bool), r, r, rows)
    shrink = np.ones(rows.size)
    for _ in range(max_iter):
        if rows.size == 0:
            break
        g = np.einsum("bmn,bm->bn", r.J, r.e)  # J^T e
        Jg = np.einsum("bmn,bn->bm", r.J, g)
        alpha = np.einsum("bm,bm->b", r.e, Jg) / np.maximum(np.einsum("bm,bm->b", Jg, Jg), 1e-300)
        step = (shrink * alpha)[:, None] * g
        big = np.max(np.abs(step), axis=-1)
        step *= np.minimum(1.0, max_step / np.maximum(big, 1e-300))[:, None]
        trial = np.clip(q + step, lo, hi)
        rt = residual(model, ga, trial, sel)
        iters[rows] += 1
        ok = rt.cost < r.cost
        shrink = np.where(ok, np.minimum(1.0, 2.0 * shrink), 0.5 * shrink)
        q = np.where(ok[:, None], trial, q)
        r = _merge(ok, rt, r)
        stalled = ~ok & (shrink < 1e-6)
        converged = (r.pos_err <= tol) & (r.ori_err <= orientation_tol)
        finished = converged | stalled
        if np.any(finished):
            done = rows[finished]
            q_all[done] = q[finished]
            pos[done] = r.pos_err[finished]
            ori[done] = r.ori_err[finished]
            keep = ~finished
            rows, q, shrink = rows[keep], q[keep], shrink[keep]
            r = _merge(np.zeros(0, dtype=bool), r, r, keep)
            sel = rows
    q_all[rows] = q
    pos[rows] = r.pos_err
    ori[rows] = r.ori_err
    q = q_all
    q_out = qf.copy()
    q_out[:, model.active] = q
    pos, ori = returned_errors(model, ga, q_out)
    success = (pos <= tol) & (ori <= orientation_tol) & skel.within_limits(q_out)
    return IKResult(
        q=q_out,
        position_error=pos,
        orientation_error=ori,
        success=success,
        iterations=iters,
        restarts=np.zeros(B, dtype=np.intp),
        method="transpose",
    )


def _merge(ok: NDArray[np.bool_], new, old, take=None):  # type: ignore[no-untyped-def]
    """Row-wise choice between two residuals; with ``take``, only those rows of ``old``."""
    from .result import Residual

    if take is not None:
        return Residual(
            old.e[take], old.J[take], old.pos_err[take], old.ori_err[take], old.cost[take]
        )
    o1, o2, o3 = ok[:, None], ok[:, None, None], ok
    return Residual(
        e=np.where(o1, new.e, old.e),
        J=np.where(o2, new.J, old.J),
        pos_err=np.where(o3, new.pos_err, old.pos_err),
        ori_err=np.where(o3, new.ori_err, old.ori_err),
        cost=np.where(o3, new.cost, old.cost),
    )
