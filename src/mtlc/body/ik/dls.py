"""Target approaching (TA): damped least squares with limits, clamping and restarts.

Seed 001 steps the joints by ``Δq = J⁺Δx`` with the Moore-Penrose inverse
``J⁺ = Jᵀ(JJᵀ)⁻¹``. Near singular postures (a straight arm) that step explodes, so this solver
uses the damped form ``Δq = Jᵀ(JJᵀ + λ²I)⁻¹ e`` (Wampler 1986; Buss 2004) and adds what a
manikin needs:

* error clamping: each position error is shortened to ``max_error`` before the step, so far
  targets are approached along a straight line instead of a wild first jump;
* a per-step angle cap ``max_step`` (rad, largest component);
* hard joint limits by clamping: dofs a step would push past a limit are pinned there and the
  remaining error is re-solved with the free dofs only, so nothing ever leaves its range;
* a null-space pull ``(I − J⁺J)·k(q_comfort − q)`` toward a relaxed posture, which settles
  the redundant dofs (7 for a 3-D hand position) without disturbing the task;
* restarts: a row whose error has not improved by 10 % for ``patience`` iterations restarts
  from a random in-limit configuration (seeded), and the best attempt is kept.

Everything is batched over targets: rows that converge leave the working set.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..kinematics import einsum
from ..skeleton import Skeleton
from .batch import SerialBatch, solve_serial_batch
from .fast import NULL_FADE, SerialChain, SerialRows, solve_one
from .goals import Goal, GoalArrays, default_dofs, normalise
from .model import ChainModel
from .result import IKResult, position_targets, residual, returned_errors

FloatArray = NDArray[np.float64]

try:  # numpy's own batched LAPACK solve, without ``np.linalg.solve``'s checks and conversions
    from numpy.linalg import _umath_linalg

    def solve_spd(a: FloatArray, b: FloatArray) -> FloatArray:
        """``np.linalg.solve(a, b)`` for float64 (b, m, m) and (b, m, k): the same LAPACK call
        (the same numbers), without the wrapper that costs more than the 6x6 solve itself (a
        DLS step solves two). Only for matrices that cannot be singular (``JJᵀ + λ²I``)."""
        return _umath_linalg.solve(a, b, signature="dd->d")

except ImportError:  # pragma: no cover - another numpy layout
    solve_spd = np.linalg.solve


def prepare(
    skel: Skeleton,
    goals: Sequence[Goal] | Sequence[str],
    q_base: ArrayLike | None = None,
    *,
    dofs: Sequence[int] | Sequence[str] | None = None,
    reach: str = "arm",
    root_position: ArrayLike | None = None,
    root_rotation: ArrayLike | None = None,
) -> ChainModel:
    """Compile the kinematic problem once for many solves (same sites, dofs and body)."""
    sites = [g if isinstance(g, str) else g.effector for g in goals]
    if dofs is None:
        idx = default_dofs(skel, sites, reach)
    else:
        idx = [d if isinstance(d, int) else skel.dof_index(d) for d in dofs]
    qb = skel.q_comfort if q_base is None else np.asarray(q_base, dtype=float)
    return ChainModel(skel, sites, idx, np.atleast_2d(qb), root_position, root_rotation)


def _initial(
    skel: Skeleton, model: ChainModel, q0: ArrayLike | None, B: int
) -> tuple[FloatArray, FloatArray]:
    """Full (B, D) start configurations and their active part, clipped into the limits."""
    if q0 is None:
        qf = np.broadcast_to(model.q_base if model.B == B else model.q_base[:1], (B, skel.n_dofs))
    else:
        qf = np.broadcast_to(np.atleast_2d(np.asarray(q0, dtype=float)), (B, skel.n_dofs))
    qf = np.array(qf, dtype=float)
    qa = np.clip(qf[:, model.active], model.lower, model.upper)
    return qf, qa


def solve_ta(
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
    max_iter: int = 60,
    restarts: int = 8,
    patience: int = 8,
    damping: float = 0.02,
    max_error: float = 0.25,
    max_step: float = 0.5,
    null_gain: float = 0.05,
    seed: int = 0,
    first_attempt: bool = False,
    measure: bool = True,
) -> IKResult:
    """Solve goals for a batch of targets by damped least squares (TA phase).

    ``q0`` (D,) or (B, D) start (default: the comfortable posture); ``model`` a prepared
    :func:`prepare` problem to skip setup; ``dofs`` the dofs to move (default: each effector's
    chain by ``reach``). Iterations are bounded by ``max_iter · (restarts + 1)`` per row.
    ``first_attempt``: also return (``IKResult.first``) the best of the first attempt, what the
    same call with ``restarts=0`` returns, to the bit: the restarts begin where it stops (the
    gaze asks for both; a second solve repeated the first attempt). One row of goals that are
    not a single position goal only (``_solve_single``). ``measure=False``: one row of one
    position goal on a serial chain reports the solver's own error for the angles it returns
    instead of measuring them afresh by forward kinematics (a fifth of such a call; for callers
    that measure the pose themselves, such as ``carry.solve_along``'s thousands of points).
    """
    ga = normalise(skel, goals)
    B = ga.batch
    if model is None:
        model = prepare(
            skel,
            goals,
            q0 if q0 is not None and np.ndim(q0) == 2 else (skel.q_comfort if q0 is None else q0),
            dofs=dofs,
            reach=reach,
            root_position=root_position,
            root_rotation=root_rotation,
        )
    qf, qa = _initial(skel, model, q0, B)
    model = model.for_start(qf)  # a model prepared for another trunk describes another body
    lo, hi = model.lower, model.upper
    comfort = skel.q_comfort[model.active]
    rng = np.random.default_rng(seed)
    tail_chain = _fast_chain(model) if _position_only(ga) else None
    chain = tail_chain if B == 1 else None
    if chain is not None:
        target = ga.position[0]
        assert target is not None
        qb, _err, it, nr = solve_one(
            chain, target[0], qa[0], lo, hi, comfort, tol=tol, max_iter=max_iter,
            restarts=restarts, patience=patience, damping=damping, max_error=max_error,
            max_step=max_step, null_gain=null_gain, rng=rng,
        )  # fmt: skip
        q_out = qf.copy()
        q_out[0, model.active] = qb
        pos = returned_errors(model, ga, q_out)[0] if measure else np.array([_err])
        return IKResult(
            q=q_out,
            position_error=pos,
            orientation_error=np.zeros(1),
            success=(pos <= tol) & skel.within_limits(q_out),
            iterations=np.array([it]),
            restarts=np.array([nr]),
            method="dls",
        )

    if tail_chain is not None:
        # One position goal on a serial chain: the component-major batch path.
        target = ga.position[0]
        assert target is not None
        qb_all, _err, it_all, nr_all = solve_serial_batch(
            _serial_batch(model, tail_chain), np.broadcast_to(target, (B, 3)), qa, lo, hi,
            comfort, tol=tol, max_iter=max_iter, restarts=restarts, patience=patience,
            damping=damping, max_error=max_error, max_step=max_step, null_gain=null_gain,
            rng=rng,
        )  # fmt: skip
        q_out = qf.copy()
        q_out[:, model.active] = qb_all
        pos, _ = returned_errors(model, ga, q_out)
        return IKResult(
            q=q_out,
            position_error=pos,
            orientation_error=np.zeros(B),
            success=(pos <= tol) & skel.within_limits(q_out),
            iterations=it_all,
            restarts=nr_all,
            method="dls",
        )

    if first_attempt:
        if B != 1 or tail_chain is not None:
            raise ValueError("first_attempt: one row of goals other than a single position")
        return _solve_single(
            skel, ga, model, qf, qa, tol=tol, orientation_tol=orientation_tol,
            max_iter=max_iter, restarts=restarts, patience=patience, damping=damping,
            max_error=max_error, max_step=max_step, null_gain=null_gain, rng=rng,
            first_attempt=True,
        )  # fmt: skip
    solve_rows = _solve_single if B == 1 else _solve_rows
    return solve_rows(
        skel, ga, model, qf, qa, tol=tol, orientation_tol=orientation_tol, max_iter=max_iter,
        restarts=restarts, patience=patience, damping=damping, max_error=max_error,
        max_step=max_step, null_gain=null_gain, rng=rng, tail_chain=tail_chain,
    )  # fmt: skip


def _solve_rows(
    skel: Skeleton,
    ga: GoalArrays,
    model: ChainModel,
    qf: FloatArray,
    qa: FloatArray,
    *,
    tol: float,
    orientation_tol: float,
    max_iter: int,
    restarts: int,
    patience: int,
    damping: float,
    max_error: float,
    max_step: float,
    null_gain: float,
    rng: np.random.Generator,
    tail_chain: SerialChain | None,
) -> IKResult:
    """``solve_ta``'s general loop over a batch of rows: each row steps, restarts or leaves
    the working set on its own."""
    B = ga.batch
    lo, hi = model.lower, model.upper
    comfort = skel.q_comfort[model.active]
    lam2 = damping * damping
    best_q = qa.copy()
    best_score = np.full(B, np.inf)
    best_pos = np.full(B, np.inf)
    best_ori = np.full(B, np.inf)
    iters = np.zeros(B, dtype=np.intp)
    n_restart = np.zeros(B, dtype=np.intp)
    attempt_it = np.zeros(B, dtype=np.intp)
    attempt_best = np.full(B, np.inf)
    since = np.zeros(B, dtype=np.intp)
    rows = np.arange(B)
    full_batch = True  # rows is arange(B): pass None to the model (no fancy indexing)
    cur = qa
    eye_cache: dict[int, FloatArray] = {}

    while rows.size:
        r = residual(model, ga, cur, None if full_batch else rows)
        score = r.pos_err / tol + r.ori_err / orientation_tol
        better = score < best_score[rows]
        if np.any(better):
            br = rows[better]
            best_score[br] = score[better]
            best_q[br] = cur[better]
            best_pos[br] = r.pos_err[better]
            best_ori[br] = r.ori_err[better]
        done = (r.pos_err <= tol) & (r.ori_err <= orientation_tol)
        # Stall bookkeeping per attempt.
        improved = score < 0.9 * attempt_best[rows]
        attempt_best[rows] = np.where(improved, score, attempt_best[rows])
        since[rows] = np.where(improved, 0, since[rows] + 1)
        stuck = ~done & ((since[rows] >= patience) | (attempt_it[rows] >= max_iter))
        can_restart = stuck & (n_restart[rows] < restarts)
        give_up = stuck & ~can_restart
        keep = ~(done | give_up)
        if not np.all(keep):
            rows, cur, r = rows[keep], cur[keep], _sub(r, keep)
            can_restart = can_restart[keep]
            full_batch = False
            if rows.size == 0:
                break
        if rows.size <= 16 and tail_chain is not None:
            # A few slow rows left: finish them on the scalar path, where an iteration
            # costs a few microseconds instead of a hundred of batch overhead.
            target = ga.position[0]
            assert target is not None
            for k, row in enumerate(rows):
                qb, err, it, nr = solve_one(
                    tail_chain, target[row], cur[k], lo, hi, comfort, tol=tol,
                    max_iter=max_iter, restarts=int(restarts - n_restart[row]), patience=patience,
                    damping=damping, max_error=max_error, max_step=max_step,
                    null_gain=null_gain, rng=rng,
                )  # fmt: skip
                iters[row] += it
                n_restart[row] += nr
                if err / tol < best_score[row]:
                    best_score[row], best_pos[row], best_ori[row] = err / tol, err, 0.0
                    best_q[row] = qb
            break
        if np.any(can_restart):
            rr = rows[can_restart]
            n_restart[rr] += 1
            attempt_it[rr] = 0
            attempt_best[rr] = np.inf
            since[rr] = 0
            cur = cur.copy()
            cur[can_restart] = lo + (hi - lo) * rng.random((rr.size, model.n))
            # Re-evaluate the restarted rows next round; step the others now.
            step_rows = ~can_restart
        else:
            step_rows = None
        m = r.e.shape[1]
        eye = eye_cache.get(m)
        if eye is None:
            eye = eye_cache[m] = lam2 * np.eye(m)
        e, J = r.e, r.J
        if step_rows is not None:
            e, J, base = e[step_rows], J[step_rows], cur[step_rows]
        else:
            base = cur
        dq = _dls_step(
            e, J, base, lo, hi, comfort, eye, max_error, max_step, null_gain, len(ga.sites)
        )
        if step_rows is not None:
            cur[step_rows] = base + dq
            iters[rows[step_rows]] += 1
            attempt_it[rows[step_rows]] += 1
        else:
            cur = base + dq
            iters[rows] += 1
            attempt_it[rows] += 1
    q_out = qf.copy()
    q_out[:, model.active] = best_q
    best_pos, best_ori = returned_errors(model, ga, q_out)
    inside = skel.within_limits(q_out)
    success = (best_pos <= tol) & (best_ori <= orientation_tol) & inside
    return IKResult(
        q=q_out,
        position_error=best_pos,
        orientation_error=best_ori,
        success=success,
        iterations=iters,
        restarts=n_restart,
        method="dls",
    )


def _solve_single(
    skel: Skeleton,
    ga: GoalArrays,
    model: ChainModel,
    qf: FloatArray,
    qa: FloatArray,
    *,
    tol: float,
    orientation_tol: float,
    max_iter: int,
    restarts: int,
    patience: int,
    damping: float,
    max_error: float,
    max_step: float,
    null_gain: float,
    rng: np.random.Generator,
    tail_chain: SerialChain | None = None,
    first_attempt: bool = False,
) -> IKResult:
    """``_solve_rows`` for one row, its bookkeeping on Python floats: the same
    steps, restarts and random draws, so the same pose to the bit (tested); the batch's
    per-row arrays cost more than the solve's arithmetic (the passes solve one pose at a
    time, 60 to 540 iterations each). ``first_attempt``: ``IKResult.first`` is the best pose
    when the first restart begins (or at the end without one)."""
    lo, hi = model.lower, model.upper
    comfort = skel.q_comfort[model.active]
    lam2I = damping * damping * np.eye(3 * _blocks(ga))
    targets = position_targets(ga)
    best_q, best_score = qa, math.inf
    iters = n_restart = attempt_it = since = 0
    attempt_best = math.inf
    cur = qa
    first_q = None  # the first attempt's best, once a restart begins
    while True:
        r = residual(model, ga, cur, with_cost=False, targets=targets)
        pos, ori = float(r.pos_err[0]), float(r.ori_err[0])
        score = pos / tol + ori / orientation_tol
        if score < best_score:
            best_score, best_q = score, cur
        done = pos <= tol and ori <= orientation_tol
        if score < 0.9 * attempt_best:
            attempt_best, since = score, 0
        else:
            since += 1
        if done:
            break
        if since >= patience or attempt_it >= max_iter:
            if n_restart >= restarts:
                break
            if n_restart == 0:
                first_q = best_q
            n_restart += 1
            attempt_it, attempt_best, since = 0, math.inf, 0
            cur = lo + (hi - lo) * rng.random((1, model.n))
            continue
        cur = cur + _dls_step_one(
            r.e, r.J, cur, lo, hi, comfort, lam2I, max_error, max_step, null_gain
        )
        iters += 1
        attempt_it += 1
    q_out = qf.copy()
    q_out[:, model.active] = best_q
    best_pos, best_ori = returned_errors(model, ga, q_out)
    success = (best_pos <= tol) & (best_ori <= orientation_tol) & skel.within_limits(q_out)
    first = None
    if first_attempt:
        first = qf.copy()
        first[:, model.active] = best_q if first_q is None else first_q
    return IKResult(
        q=q_out,
        position_error=best_pos,
        orientation_error=best_ori,
        success=success,
        iterations=np.array([iters]),
        restarts=np.array([n_restart]),
        method="dls",
        first=first,
    )


# ``solve_ta_row`` takes no restarts: ``solve_one`` never draws from it
_NO_RESTARTS = np.random.default_rng(0)


def solve_ta_row(
    rows: SerialRows,
    row: int,
    q_full: FloatArray,
    target: FloatArray,
    *,
    tol: float,
    max_iter: int = 60,
    patience: int = 8,
    damping: float = 0.02,
    max_error: float = 0.25,
    max_step: float = 0.5,
    null_gain: float = 0.05,
) -> tuple[FloatArray, float] | None:
    """``solve_ta(skel, [Goal(site, position=target)], q_full, dofs=..., root_position=...,
    root_rotation=..., restarts=0, measure=False)`` on row ``row`` of ``rows``' model (prepared
    once for every row of a path with the same site, dofs and the path's roots and poses), to
    the bit: the full angles (D,) and the solver's own distance of the site from ``target``.
    None when that row's model does not describe ``q_full``'s body (the caller asks
    ``solve_ta``). The keyword defaults are ``solve_ta``'s (``tol`` has none here)."""
    if not rows.describes(row, q_full):
        return None
    model = rows.model
    act, lo, hi = model.active, model.lower, model.upper
    qb, err, _it, _nr = solve_one(
        rows.chain(row, q_full), target, np.clip(q_full[act], lo, hi), lo, hi,
        model.skel.q_comfort[act], tol=tol, max_iter=max_iter, restarts=0, patience=patience,
        damping=damping, max_error=max_error, max_step=max_step, null_gain=null_gain,
        rng=_NO_RESTARTS,
    )  # fmt: skip
    out = q_full.copy()
    out[act] = qb
    return out, err


def _blocks(ga: GoalArrays) -> int:
    """The 3-vectors of the stacked error: one per position, orientation and aim goal."""
    return sum(
        (p is not None) + (o is not None) + (a is not None)
        for p, o, a in zip(ga.position, ga.orientation, ga.aim, strict=True)
    )


def _position_only(ga: GoalArrays) -> bool:
    return len(ga.sites) == 1 and ga.position[0] is not None and ga.orientation[0] is None


def _fast_chain(model: ChainModel) -> SerialChain | None:
    """The model's scalar serial chain, built once; None when the model is not one."""
    cached = getattr(model, "_fast", False)
    if cached is False:
        try:
            cached = SerialChain(model) if model.B == 1 else None
        except ValueError:
            cached = None
        model._fast = cached  # type: ignore[attr-defined]
    return cached  # type: ignore[return-value]


def _serial_batch(model: ChainModel, chain: SerialChain) -> SerialBatch:
    """The model's component-major batch kinematics, built once."""
    cached = getattr(model, "_batch", None)
    if cached is None or cached.chain is not chain:
        cached = SerialBatch(chain)
        model._batch = cached  # type: ignore[attr-defined]
    return cached


def _sub(r, keep):  # type: ignore[no-untyped-def]
    from .result import Residual

    return Residual(r.e[keep], r.J[keep], r.pos_err[keep], r.ori_err[keep], r.cost[keep])


def _dls_step(
    e: FloatArray,
    J: FloatArray,
    q: FloatArray,
    lo: FloatArray,
    hi: FloatArray,
    comfort: FloatArray,
    lam2I: FloatArray,
    max_error: float,
    max_step: float,
    null_gain: float,
    n_goals: int,
) -> FloatArray:
    """One damped least-squares step with error clamping, limit clamping and a step cap."""
    # Error clamping (per 3-vector block).
    b, m = e.shape
    blocks = e.reshape(b, m // 3, 3)
    nrm = np.sqrt(einsum("bki,bki->bk", blocks, blocks))
    scale = np.minimum(1.0, max_error / np.maximum(nrm, 1e-300))
    e = (blocks * scale[..., None]).reshape(b, m)
    Jt = J.swapaxes(-1, -2)
    A = J @ Jt + lam2I
    fade = np.minimum(1.0, np.sqrt(einsum("bk,bk->b", nrm, nrm)) / NULL_FADE)
    z = (null_gain * fade)[:, None] * (comfort - q)
    # J⁺e + (I − J⁺J)z = J⁺(e − Jz) + z: one right-hand side for task and null space.
    rhs = e - einsum("bmn,bn->bm", J, z)
    y = solve_spd(A, rhs[..., None])[..., 0]
    dq = einsum("bnm,bm->bn", Jt, y) + z
    qn = q + dq
    over = (qn > hi) | (qn < lo)
    hit = np.flatnonzero(over.any(axis=-1))
    if hit.size:
        # Pin the offending dofs at their limits; re-solve the rest of the error with the
        # free dofs only, on the rows that hit a limit.
        ov, qh, Jh = over[hit], q[hit], J[hit]
        dq_pin = np.where(ov, np.clip(qn[hit], lo, hi) - qh, 0.0)
        e2 = e[hit] - einsum("bmn,bn->bm", Jh, dq_pin)
        Jf = Jh * (~ov)[:, None, :]
        Jft = Jf.swapaxes(-1, -2)
        y2 = solve_spd(Jf @ Jft + lam2I, e2[..., None])[..., 0]
        dq[hit] = np.where(ov, dq_pin, einsum("bnm,bm->bn", Jft, y2))
    big = np.max(np.abs(dq), axis=-1)
    dq = dq * np.minimum(1.0, max_step / np.maximum(big, 1e-300))[:, None]
    return np.clip(q + dq, lo, hi) - q


_clip = getattr(getattr(np, "_core", None), "umath", np).clip  # np.clip's ufunc, unwrapped
_ROW = np.zeros(1, dtype=np.intp)  # the one row, as an index (``hit`` of one row)


def _dls_step_one(
    e: FloatArray,
    J: FloatArray,
    q: FloatArray,
    lo: FloatArray,
    hi: FloatArray,
    comfort: FloatArray,
    lam2I: FloatArray,
    max_error: float,
    max_step: float,
    null_gain: float,
) -> FloatArray:
    """``_dls_step`` of one row (b = 1): the same numpy operations on the same arrays where
    they sum (einsum, BLAS, LAPACK), Python floats where a batch needed an array of one (the
    fade, the step cap), and no multiplication by a scale of exactly 1 (x * 1.0 is x), so
    the same step to the bit."""
    m = e.shape[1]
    blocks = e.reshape(1, m // 3, 3)
    nrm = np.sqrt(einsum("bki,bki->bk", blocks, blocks))
    if (nrm > max_error).any():
        scale = np.minimum(1.0, max_error / np.maximum(nrm, 1e-300))
        e = (blocks * scale[..., None]).reshape(1, m)
    Jt = J.swapaxes(-1, -2)
    A = J @ Jt + lam2I
    fade = min(1.0, math.sqrt(float(einsum("bk,bk->b", nrm, nrm)[0])) / NULL_FADE)
    z = (null_gain * fade) * (comfort - q)
    rhs = e - einsum("bmn,bn->bm", J, z)
    y = solve_spd(A, rhs[..., None])[..., 0]
    dq = einsum("bnm,bm->bn", Jt, y) + z
    qn = q + dq
    over = (qn > hi) | (qn < lo)
    hit = over.any()
    if hit:
        # as _dls_step's rows that hit a limit, taken the same way (``J[hit]`` is a copy in
        # the layout numpy's indexing picks, and the einsum below sums in that layout's order)
        Jh = J[_ROW]
        dq_pin = np.where(over, _clip(qn[_ROW], lo, hi) - q[_ROW], 0.0)
        e2 = e[_ROW] - einsum("bmn,bn->bm", Jh, dq_pin)
        Jf = Jh * (~over)[:, None, :]
        Jft = Jf.swapaxes(-1, -2)
        y2 = solve_spd(Jf @ Jft + lam2I, e2[..., None])[..., 0]
        dq = np.where(over, dq_pin, einsum("bnm,bm->bn", Jft, y2))
    big = float(np.abs(dq).max())
    if big > max_step:  # (else the cap is 1.0: the step as it is)
        dq = dq * (max_step / big)
    elif not hit:
        return _clip(qn, lo, hi) - q  # q + dq is qn
    return _clip(q + dq, lo, hi) - q
