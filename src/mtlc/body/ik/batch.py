"""Batched TA for the commonest batch: one position goal on one serial chain (e.g. the arm).

The general batch path (:mod:`mtlc.body.ik.dls` over :class:`ChainModel`) stores rotations as
(b, 3, 3) matrices and Jacobians as (b, 3, n); numpy's batched small-matrix kernels (matmul,
``linalg.solve``, ``cross``) then cost 1–3 µs *per row*, so 1,000 targets pay ~2.6 ms per
iteration. Here every quantity is stored component-major with the batch last — frame columns
(3, b), Jacobian (3, n, b), angles (n, b) — so each numpy call is one contiguous elementwise
pass over the batch:

* rotations about the manikin's coordinate axes touch two frame columns (6 vector ops a dof);
* the damped normal equations ``(JJᵀ + λ²I) w = e − Jz`` are 3×3 (position only), solved in
  closed form by the adjugate instead of LAPACK per row; one right-hand side serves both the
  task and the null-space term because ``J⁺(e − Jz) + z`` is the projected step;
* the limit re-solve runs only on the rows (columns) that hit a limit;
* rows that converge or give up leave the working set (every array is compacted), and the
  last few slow rows finish on the scalar path (:func:`mtlc.body.ik.fast.solve_one`).

Same algorithm and iterates as the general path (tested); an iteration on 1,000 rows costs
about 6–8× less.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from .fast import NULL_FADE, SerialChain, solve_one

FloatArray = NDArray[np.float64]

# Below this many working rows one scalar iteration per row (~25 µs) is cheaper than one
# batch iteration (~150 numpy calls, ~200 µs on a few rows); measured best at 8.
TAIL_ROWS = 8


class SerialBatch:
    """Component-major batched kinematics of a :class:`SerialChain`."""

    def __init__(self, chain: SerialChain) -> None:
        self.chain = chain
        n = self.n = chain.n
        self.R0 = [np.asarray(c, dtype=float)[:, None] for c in chain.R0]  # columns (3, 1)
        self.p0 = np.asarray(chain.p0, dtype=float)[:, None]
        sign = np.ones(n)
        # Program: ("off", [(column, value)]), ("rot", k, active col), ("fix", k, cos, sin).
        prog: list[tuple] = []  # type: ignore[type-arg]
        for off, dofs in chain.plan:
            comps = [(i, float(v)) for i, v in enumerate(off) if v != 0.0]
            if comps:
                prog.append(("off", comps))
            for k, sg, ci, fixed in dofs:
                if ci >= 0:
                    sign[ci] = sg
                    prog.append(("rot", k, ci))
                else:
                    prog.append(("fix", k, math.cos(sg * fixed), math.sin(sg * fixed)))
        self.prog = prog
        self.sign = sign[:, None]
        self.sign3 = sign[None, :, None]
        self.site = [(i, float(v)) for i, v in enumerate(chain.site_off) if v != 0.0]

    def eval(self, q: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Site positions (3, b) and position Jacobian (3, n, b) at active angles q (n, b)."""
        b = q.shape[1]
        S = np.sin(q)
        S *= self.sign
        C = np.cos(q)
        c = list(self.R0)
        p = self.p0
        A = np.empty((3, self.n, b))
        org = np.empty((3, self.n, b))
        for step in self.prog:
            kind = step[0]
            if kind == "off":
                for i, v in step[1]:
                    p = p + c[i] * v
            else:
                k = step[1]
                if kind == "rot":
                    ci = step[2]
                    A[:, ci] = c[k]
                    org[:, ci] = p
                    cs, sn = C[ci], S[ci]
                else:
                    cs, sn = step[2], step[3]
                i1, i2 = (k + 1) % 3, (k + 2) % 3
                a, d = c[i1], c[i2]
                c[i1] = a * cs + d * sn
                c[i2] = d * cs - a * sn
        site = p
        for i, v in self.site:
            site = site + c[i] * v
        site = np.broadcast_to(site, (3, b))
        A *= self.sign3
        D = site[:, None, :] - org
        J = np.empty((3, self.n, b))
        np.multiply(A[1], D[2], out=J[0])
        J[0] -= A[2] * D[1]
        np.multiply(A[2], D[0], out=J[1])
        J[1] -= A[0] * D[2]
        np.multiply(A[0], D[1], out=J[2])
        J[2] -= A[1] * D[0]
        return site, J


def _dls_solve(J: FloatArray, lam2: float, r: FloatArray) -> FloatArray:
    """``w = (J Jᵀ + λ²I)⁻¹ r`` for every column: J (3, n, b), r (3, b) -> (3, b).

    The 3×3 matrix is symmetric positive definite (λ > 0), so its adjugate over its
    determinant is the inverse; six cofactors and a few products per row, no LAPACK call.
    """
    A = np.einsum("inb,jnb->ijb", J, J)
    a00, a01, a02 = A[0, 0] + lam2, A[0, 1], A[0, 2]
    a11, a12, a22 = A[1, 1] + lam2, A[1, 2], A[2, 2] + lam2
    i00 = a11 * a22 - a12 * a12
    i01 = a02 * a12 - a01 * a22
    i02 = a01 * a12 - a02 * a11
    i11 = a00 * a22 - a02 * a02
    i12 = a01 * a02 - a00 * a12
    i22 = a00 * a11 - a01 * a01
    inv = 1.0 / (a00 * i00 + a01 * i01 + a02 * i02)
    r0, r1, r2 = r[0] * inv, r[1] * inv, r[2] * inv
    w = np.empty_like(r)
    w[0] = i00 * r0 + i01 * r1 + i02 * r2
    w[1] = i01 * r0 + i11 * r1 + i12 * r2
    w[2] = i02 * r0 + i12 * r1 + i22 * r2
    return w


def solve_serial_batch(
    sb: SerialBatch,
    targets: FloatArray,
    q0: FloatArray,
    lower: FloatArray,
    upper: FloatArray,
    comfort: FloatArray,
    *,
    tol: float,
    max_iter: int,
    restarts: int,
    patience: int,
    damping: float,
    max_error: float,
    max_step: float,
    null_gain: float,
    rng: np.random.Generator,
    tail_rows: int = TAIL_ROWS,
) -> tuple[FloatArray, FloatArray, NDArray[np.intp], NDArray[np.intp]]:
    """DLS for B position targets (B, 3) from q0 (B, n) (already inside the limits).

    Returns best q (B, n), best error (B,), iterations (B,) and restarts (B,).
    """
    B, n = q0.shape
    lo, hi = lower[:, None], upper[:, None]
    cf = comfort[:, None]
    span = upper - lower
    lam2 = damping * damping
    out_q = np.array(q0, dtype=float)
    out_err = np.full(B, np.inf)
    out_it = np.zeros(B, dtype=np.intp)
    out_rs = np.zeros(B, dtype=np.intp)
    # Working set, one column per unfinished row.
    rows = np.arange(B)
    q = np.ascontiguousarray(q0.T, dtype=float)
    T = np.ascontiguousarray(targets.T, dtype=float)
    best = np.full(B, np.inf)
    best_q = q.copy()
    att_best = np.full(B, np.inf)
    since = np.zeros(B, dtype=np.intp)
    att_it = np.zeros(B, dtype=np.intp)
    n_rs = np.zeros(B, dtype=np.intp)
    its = np.zeros(B, dtype=np.intp)
    while rows.size:
        site, J = sb.eval(q)
        e = T - site
        err = np.sqrt(np.einsum("ib,ib->b", e, e))
        better = err < best
        if np.count_nonzero(better):
            best = np.where(better, err, best)
            best_q[:, better] = q[:, better]
        done = err <= tol
        improved = err < 0.9 * att_best
        att_best = np.where(improved, err, att_best)
        since = np.where(improved, 0, since + 1)
        stuck = ~done & ((since >= patience) | (att_it >= max_iter))
        can_restart = stuck & (n_rs < restarts)
        leave = done | (stuck & ~can_restart)
        if np.count_nonzero(leave):
            gone = rows[leave]
            out_q[gone] = best_q[:, leave].T
            out_err[gone] = best[leave]
            out_it[gone] = its[leave]
            out_rs[gone] = n_rs[leave]
            keep = ~leave
            rows, q, T, e, J = rows[keep], q[:, keep], T[:, keep], e[:, keep], J[..., keep]
            err = err[keep]
            best, best_q, att_best, since = best[keep], best_q[:, keep], att_best[keep], since[keep]
            att_it, n_rs, its, can_restart = att_it[keep], n_rs[keep], its[keep], can_restart[keep]
            if rows.size == 0:
                break
        if rows.size <= tail_rows:
            for k, row in enumerate(rows):
                qb, eb, it, nr = solve_one(
                    sb.chain, targets[row], q[:, k], lower, upper, comfort, tol=tol,
                    max_iter=max_iter, restarts=int(restarts - n_rs[k]), patience=patience,
                    damping=damping, max_error=max_error, max_step=max_step,
                    null_gain=null_gain, rng=rng,
                )  # fmt: skip
                out_it[row] = its[k] + it
                out_rs[row] = n_rs[k] + nr
                if eb < best[k]:
                    out_q[row], out_err[row] = qb, eb
                else:
                    out_q[row], out_err[row] = best_q[:, k], best[k]
            break
        # One damped least-squares step for every working row (error clamp, null-space pull).
        z = (null_gain * np.minimum(1.0, err / NULL_FADE)) * (cf - q)
        e = e * np.minimum(1.0, max_error / np.maximum(err, 1e-300))
        w = _dls_solve(J, lam2, e - np.einsum("inb,nb->ib", J, z))
        dq = np.einsum("inb,ib->nb", J, w)
        dq += z
        qn = q + dq
        over = (qn > hi) | (qn < lo)
        hit = over.any(axis=0)
        if np.count_nonzero(hit):
            # Pin the offending dofs at their limits and re-solve the rest of the error with
            # the free dofs, on the rows that hit a limit only.
            cols = np.flatnonzero(hit)
            ov = over[:, cols]
            qc = q[:, cols]
            pin = np.where(ov, np.minimum(np.maximum(qn[:, cols], lo), hi) - qc, 0.0)
            Jc = J[..., cols]
            e2 = e[:, cols] - np.einsum("inb,nb->ib", Jc, pin)
            Jf = Jc * ~ov
            w2 = _dls_solve(Jf, lam2, e2)
            dq[:, cols] = np.where(ov, pin, np.einsum("inb,ib->nb", Jf, w2))
        big = np.abs(dq).max(axis=0)
        dq *= np.minimum(1.0, max_step / np.maximum(big, 1e-300))
        dq += q
        q = np.minimum(np.maximum(dq, lo, out=dq), hi, out=dq)
        stepped = ~can_restart
        its += stepped
        att_it += stepped
        if np.count_nonzero(can_restart):
            # Restarted rows take a random in-limit start instead of the step (drawn in row
            # order, as the general path does) and are evaluated next round.
            idx = np.flatnonzero(can_restart)
            n_rs[idx] += 1
            att_it[idx] = 0
            att_best[idx] = np.inf
            since[idx] = 0
            q[:, idx] = (lower + span * rng.random((idx.size, n))).T
    return out_q, out_err, out_it, out_rs
