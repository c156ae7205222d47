"""Target overlapping (TO): a continuous, monotone gradient path to the target.

Seed 000 (Wang et al. 2014, §4.2) moves the joint angles down the gradient of the end-effector
distance, so the motion is continuous and never moves away from the target; its loop uses a
central-difference gradient of ±1 degree, a fixed unit step and ``while dist > 0.1`` with no
bound. This version keeps the idea and fixes the loop:

* the gradient of ``f(q) = ½|e(q)|²`` is analytic, ``∇f = −Jᵀe`` (one Jacobian, no 2n FK calls);
* the step is adaptive (seed 004, claim 5): a Barzilai-Borwein step ``α = sᵀs / sᵀy`` from the
  last two iterates (first step: the exact line minimiser of the linearised cost,
  ``|g|² / |Jg|²``), halved until the cost decreases (backtracking), so the distance is
  monotonically non-increasing along the path by construction;
* each accepted step is capped at ``max_step`` rad per joint, so consecutive path samples are
  close (a smooth path to animate, not just an end pose);
* angles are projected into the joint limits, and the iteration count is bounded;
* every iterate is rounded to a 1e-9 rad grid (``PATH_GRID``) and a step that rounds to nothing
  ends the row: the BB iteration is chaotic, and without the grid the last-bit differences of
  another BLAS kernel grew into paths (and keyframes) degrees apart (issue 17, docs/passes.md).

It returns the path (every accepted configuration), not only the end pose.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..kinematics import einsum
from ..skeleton import Skeleton
from .dls import _clip, _initial, prepare
from .goals import Goal, GoalArrays, normalise
from .model import ChainModel
from .result import IKResult, position_targets, residual, returned_errors

FloatArray = NDArray[np.float64]

# Joint angles of the path live on this grid (radians). The Barzilai-Borwein iteration is
# chaotic: a 1e-16 difference in one Jacobian (another BLAS kernel) grows to 1e-4 rad within a
# hundred steps. On the grid two machines follow the same lattice path: a rounding differs only
# when a value falls within the noise of a half-grid point.
PATH_GRID = 1e-9


def on_grid(q: FloatArray, grid: float = PATH_GRID) -> FloatArray:
    """``q`` rounded to the path grid (see PATH_GRID)."""
    return np.round(q / grid) * grid


def solve_to(
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
    max_iter: int = 500,
    max_step: float = 0.05,
    record_path: bool = True,
) -> IKResult:
    """Gradient-path IK for a batch of targets (TO phase); ``result.path`` is (T, B, n_dofs).

    Each row stops when within tolerance, when the step can no longer reduce the cost, or
    after ``max_iter`` iterations (cost evaluations), whichever comes first.
    """
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
    descend = _descend_single if B == 1 else _descend_rows
    q, pos, ori, iters, path = descend(
        model, ga, q_all, tol=tol, orientation_tol=orientation_tol, max_iter=max_iter,
        max_step=max_step, record_path=record_path,
    )  # fmt: skip
    q_out = qf.copy()
    q_out[:, model.active] = q
    pos, ori = returned_errors(model, ga, q_out)
    success = (pos <= tol) & (ori <= orientation_tol) & skel.within_limits(q_out)
    full_path = None
    if record_path:
        pa = np.stack(path)  # (T, B, nA)
        full_path = np.broadcast_to(qf, (pa.shape[0], B, skel.n_dofs)).copy()
        full_path[:, :, model.active] = pa
    return IKResult(
        q=q_out,
        position_error=pos,
        orientation_error=ori,
        success=success,
        iterations=iters,
        restarts=np.zeros(B, dtype=np.intp),
        method="gradient",
        path=full_path,
    )


def _descend_rows(
    model: ChainModel,
    ga: GoalArrays,
    q_all: FloatArray,
    *,
    tol: float,
    orientation_tol: float,
    max_iter: int,
    max_step: float,
    record_path: bool,
) -> tuple[FloatArray, FloatArray, FloatArray, NDArray[np.intp], list[FloatArray]]:
    """``solve_to``'s descent of a batch of rows from ``q_all`` (B, nA): the end angles, their
    errors, iterations and the accepted configurations (B, nA) one after the other."""
    B = q_all.shape[0]
    lo, hi = model.lower, model.upper
    r = residual(model, ga, q_all)
    pos, ori = r.pos_err.copy(), r.ori_err.copy()
    iters = np.zeros(B, dtype=np.intp)
    path = [q_all.copy()] if record_path else []
    # Working set: rows still iterating; finished rows are written back to q_all and leave.
    rows = np.flatnonzero(~((pos <= tol) & (ori <= orientation_tol)))
    sel = None if rows.size == B else rows  # None: every row, no fancy indexing
    q = q_all[rows]
    f = r.cost[rows]
    J, e = r.J[rows], r.e[rows]
    g = -einsum("bmn,bm->bn", J, e)
    Jg = einsum("bmn,bn->bm", J, g)
    alpha = einsum("bn,bn->b", g, g) / np.maximum(einsum("bm,bm->b", Jg, Jg), 1e-300)
    for _ in range(max_iter):
        if rows.size == 0:
            break
        step = -alpha[:, None] * g
        big = np.max(np.abs(step), axis=-1)
        # the cap leaves room for the rounding to the grid, so a step stays within max_step
        step *= np.minimum(1.0, (max_step - PATH_GRID) / np.maximum(big, 1e-300))[:, None]
        trial = np.clip(on_grid(q + step), lo, hi)
        rt = residual(model, ga, trial, sel)
        iters[rows] += 1
        # a step that rounds to nothing is a rejected one (its cost differs from f by noise)
        ok = (rt.cost < f) & np.any(trial != q, axis=-1)
        # Rejected rows: halve the step; rows whose step vanished have converged as far as
        # the limits allow and stop.
        alpha = np.where(ok, alpha, 0.5 * alpha)
        moved = trial - q
        any_ok = bool(np.any(ok))
        if any_ok:
            gn = -einsum("bmn,bm->bn", rt.J, rt.e)
            s, y = moved, gn - g
            sy = einsum("bn,bn->b", s, y)
            bb = einsum("bn,bn->b", s, s) / np.where(sy > 1e-300, sy, np.inf)
            bb = np.where(bb > 0, bb, 2.0 * alpha)
            okc = ok[:, None]
            q = np.where(okc, trial, q)
            g = np.where(okc, gn, g)
            f = np.where(ok, rt.cost, f)
            moved_rows = rows[ok]
            pos[moved_rows] = rt.pos_err[ok]
            ori[moved_rows] = rt.ori_err[ok]
            alpha = np.where(ok, bb, alpha)
            if record_path:
                q_all[moved_rows] = q[ok]
                path.append(q_all.copy())
        stalled = ~ok & (np.max(np.abs(moved), axis=-1) < 1e-12)
        finished = ((pos[rows] <= tol) & (ori[rows] <= orientation_tol)) | stalled
        if np.any(finished):
            q_all[rows[finished]] = q[finished]
            keep = ~finished
            rows, q, g, f, alpha = rows[keep], q[keep], g[keep], f[keep], alpha[keep]
            sel = rows
    q_all[rows] = q
    return q_all, pos, ori, iters, path


_ROW = np.zeros(1, dtype=np.intp)  # the one row, as an index (``rows`` of one row)


def _descend_single(
    model: ChainModel,
    ga: GoalArrays,
    q_all: FloatArray,
    *,
    tol: float,
    orientation_tol: float,
    max_iter: int,
    max_step: float,
    record_path: bool,
) -> tuple[FloatArray, FloatArray, FloatArray, NDArray[np.intp], list[FloatArray]]:
    """``_descend_rows`` of one row, its step sizes and tests on Python floats: the same
    einsums on the same arrays, so the same path to the bit (tested)."""
    lo, hi = model.lower, model.upper
    targets = position_targets(ga)
    r = residual(model, ga, q_all, targets=targets)
    pos, ori = r.pos_err.copy(), r.ori_err.copy()
    path = [q_all.copy()] if record_path else []
    if pos[0] <= tol and ori[0] <= orientation_tol:
        return q_all, pos, ori, np.zeros(1, dtype=np.intp), path
    q = q_all[_ROW]
    f = float(r.cost[0])
    J, e = r.J[_ROW], r.e[_ROW]  # (indexed as the batch's rows are: the einsums sum alike)
    g = -einsum("bmn,bm->bn", J, e)
    Jg = einsum("bmn,bn->bm", J, g)
    alpha = float(einsum("bn,bn->b", g, g)[0]) / max(float(einsum("bm,bm->b", Jg, Jg)[0]), 1e-300)
    iters = 0
    for _ in range(max_iter):
        step = -alpha * g
        big = float(np.abs(step).max())
        # the cap leaves room for the rounding to the grid, so a step stays within max_step
        if big > max_step - PATH_GRID:  # (else the factor is 1.0: the step as it is)
            step *= (max_step - PATH_GRID) / big
        # on_grid: np.round with no decimals is rint
        trial = _clip(np.rint((q + step) / PATH_GRID) * PATH_GRID, lo, hi)
        rt = residual(model, ga, trial, targets=targets)
        iters += 1
        moved = trial - q
        # a step that rounds to nothing is a rejected one (its cost differs from f by noise)
        if float(rt.cost[0]) < f and (trial != q).any():
            gn = -einsum("bmn,bm->bn", rt.J, rt.e)
            y = gn - g
            sy = float(einsum("bn,bn->b", moved, y)[0])
            bb = float(einsum("bn,bn->b", moved, moved)[0]) / (sy if sy > 1e-300 else math.inf)
            alpha = bb if bb > 0 else 2.0 * alpha
            q, g, f = trial, gn, float(rt.cost[0])
            pos, ori = rt.pos_err, rt.ori_err
            if record_path:
                q_all[0] = q
                path.append(q_all.copy())
            if pos[0] <= tol and ori[0] <= orientation_tol:
                break
        else:
            # rejected: halve the step; a step that vanished has converged as far as the
            # limits allow
            alpha = 0.5 * alpha
            if float(np.abs(moved).max()) < 1e-12:
                break
    q_all[0] = q
    return q_all, pos, ori, np.array([iters]), path
