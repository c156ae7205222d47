"""A scalar ``solve_ta`` for one pose and position goals on one serial chain (``passes.tool``).

A wrench stroke's keys are solved one after the other, each from the one before (a
continuation: ``tool._chain``), so they cannot be batched; ``mtlc.body.ik.solve_ta`` with two
position goals (grip and tip) takes its general batched path, where one iteration of one pose
costs ~60 numpy calls. Here the same algorithm runs on Python floats: the chain's frames turn
about the manikin's coordinate axes (two columns a dof), the Jacobian has a column per dof,
and the damped normal equations (6×6 for two goals) go to numpy's LAPACK solve at once. The same error
clamp per goal, null-space pull faded by the error, limit pinning with a re-solve, step cap,
stall bookkeeping and seeded restarts as ``solve_ta``'s general path for one row; the result
equals it to rounding (``tests/passes/test_chain_ik.py``: 1e-12).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence

import numpy as np

from mtlc.body import forward, forward_part
from mtlc.body.ik import ChainModel
from mtlc.body.ik.dls import solve_spd
from mtlc.body.ik.fast import NULL_FADE, chain_plan, walk_chain
from mtlc.body.kinematics import cross
from mtlc.body.skeleton import Skeleton
from mtlc.ir.model import FloatArray

# ``solve_ta``'s defaults, which ``tool._chain`` keeps
MAX_ITER, PATIENCE, DAMPING, MAX_ERROR, MAX_STEP, NULL_GAIN = 60, 8, 0.02, 0.25, 0.5, 0.05


class ScalarChain:
    """The sites' positions and Jacobian on a serial chain of coordinate-axis dofs, for a
    ``ChainModel`` (one base row): the chain's first joint's parent placed once by ``forward``."""

    def __init__(self, skel: Skeleton, model: ChainModel, root: tuple[FloatArray, FloatArray]):
        live = list(model.live)
        if model.B != 1 or any(int(skel.parent[b]) != a for a, b in itertools.pairwise(live)):
            raise ValueError("one base row and a serial chain only")
        site_joints = {skel.joint_index(skel.site(s).joint) for s in model.sites}
        if site_joints != {live[-1]}:
            raise ValueError("every site on the chain's last joint")
        q_base = model.q_base[0]
        pose = forward(skel, q_base[None], root[0][None], root[1][None], with_axes=False)
        top = int(skel.parent[live[0]])
        R0, p0 = pose.R[0, top], pose.p[0, top]
        self.R0 = [[float(R0[i, j]) for i in range(3)] for j in range(3)]  # columns
        self.p0 = [float(v) for v in p0]
        self.plan = chain_plan(model, live, q_base)
        self.site_offsets = [tuple(float(v) for v in skel.site(s).offset) for s in model.sites]
        self.n = model.n
        # the first joint's origin does not move with the chain's angles; no pose puts a site
        # further from it than the chain's links and the site's offset laid end to end
        self.base = p0 + R0 @ skel.offsets[live[0]]
        links = float(sum(np.linalg.norm(skel.offsets[j]) for j in live[1:]))
        self.reach = [links + float(np.linalg.norm(skel.site(s).offset)) for s in model.sites]

    def beyond(self, targets: Sequence[float], slack: float) -> bool:
        """Whether some target is further than ``slack`` past what any pose of the chain can
        reach (``targets``: 3 a site, in the chain's site order)."""
        pts = np.asarray(targets, dtype=float).reshape(-1, 3)
        far = np.linalg.norm(pts - self.base, axis=1) - np.asarray(self.reach)
        return bool(far.max() > slack)

    def eval(self, q: Sequence[float]) -> tuple[list[float], list[list[float]]]:
        """Site positions (3 S,) and the Jacobian as n columns (3 S,) at active angles ``q``."""
        (c0, c1, c2), (px, py, pz), axes, origins = walk_chain(
            self.R0, self.p0, self.plan, q, self.n
        )
        pts: list[float] = []
        for sx, sy, sz in self.site_offsets:
            pts += [
                px + c0[0] * sx + c1[0] * sy + c2[0] * sz,
                py + c0[1] * sx + c1[1] * sy + c2[1] * sz,
                pz + c0[2] * sx + c1[2] * sy + c2[2] * sz,
            ]
        cols = []
        for (ax, ay, az), (qx, qy, qz) in zip(axes, origins, strict=True):
            col = []
            for s in range(0, len(pts), 3):
                dx, dy, dz = pts[s] - qx, pts[s + 1] - qy, pts[s + 2] - qz
                col += [ay * dz - az * dy, az * dx - ax * dz, ax * dy - ay * dx]
            cols.append(col)
        return pts, cols


def _normal_solve(J: FloatArray, damping: FloatArray, rhs: FloatArray) -> FloatArray:
    """y with (J Jᵀ + λ²I) y = rhs, ``J`` given as its (n, m) transpose (numpy's LAPACK solve
    without its wrapper: the matrix is symmetric positive definite, λ² > 0)."""
    return solve_spd((J.T @ J + damping)[None], rhs[None, :, None])[0, :, 0]


class ChainSolve:
    """``solve_ta``'s general path for one row of position goals (``targets``: their points,
    3 a goal, in the chain's site order) from active angles ``q0``, resumable: ``run`` with
    more restarts than the last call goes on from where that one stopped. A fresh solve with
    restarts repeats the warm-started attempt before its first restart (the seeded generator
    is drawn from only at a restart), so ``tool._chain``, which asks for restarts only where
    the warm start stalls short, need not pay for that attempt twice: the same iterates."""

    def __init__(
        self,
        chain: ScalarChain,
        targets: Sequence[float],
        q0: Sequence[float],
        lower: Sequence[float],
        upper: Sequence[float],
        comfort: Sequence[float],
        *,
        tol: float,
        seed: int = 0,
    ) -> None:
        self.chain, self.tol, self.seed = chain, tol, seed
        self.targets = [float(v) for v in targets]
        self.lo, self.hi = [float(v) for v in lower], [float(v) for v in upper]
        self.cf = [float(v) for v in comfort]
        self.q = [min(max(float(v), self.lo[i]), self.hi[i]) for i, v in enumerate(q0)]
        self.best_q, self.best_score = list(self.q), math.inf
        self.best_err = math.inf  # the sites' largest distance to their targets at best_q
        self.n_restart = self.attempt_it = self.since = 0
        self.attempt_best = math.inf
        self.stalled = False  # stopped by the restart limit at a stall (not converged)
        self.converged = False
        self.rng: np.random.Generator | None = None  # made at the first restart

    def run(self, restarts: int) -> list[float]:
        """The best angles found with up to ``restarts`` random restarts in all."""
        if self.converged or (self.stalled and self.n_restart >= restarts):
            return self.best_q
        chain, targets, lo, hi, cf = self.chain, self.targets, self.lo, self.hi, self.cf
        tol, n, m = self.tol, chain.n, len(targets)
        damping = DAMPING * DAMPING * np.eye(m)
        q, best_q, best_score, best_err = self.q, self.best_q, self.best_score, self.best_err
        n_restart, attempt_it, since = self.n_restart, self.attempt_it, self.since
        attempt_best = self.attempt_best
        resume_restart = self.stalled  # the last call stopped here, at a stall: restart
        while True:
            if not resume_restart:
                pts, cols = chain.eval(q)
                e = [targets[i] - pts[i] for i in range(m)]
                nrm = [math.sqrt(e[s] * e[s] + e[s + 1] * e[s + 1] + e[s + 2] * e[s + 2])
                       for s in range(0, m, 3)]  # fmt: skip
                score = max(0.0, *nrm) / tol
                if score < best_score:
                    best_score, best_q, best_err = score, list(q), max(0.0, *nrm)
                done = max(0.0, *nrm) <= tol
                if score < 0.9 * attempt_best:
                    attempt_best, since = score, 0
                else:
                    since += 1
                if done:
                    self.converged = True
                    break
            if resume_restart or since >= PATIENCE or attempt_it >= MAX_ITER:
                resume_restart = False
                if n_restart >= restarts:
                    self.stalled = True
                    break
                if self.rng is None:
                    self.rng = np.random.default_rng(self.seed)
                n_restart += 1
                attempt_it = since = 0
                attempt_best = math.inf
                q = [lo[i] + (hi[i] - lo[i]) * float(u) for i, u in enumerate(self.rng.random(n))]
                continue
            for b, s in enumerate(range(0, m, 3)):  # each goal's error clamped to MAX_ERROR
                sc = min(1.0, MAX_ERROR / max(nrm[b], 1e-300))
                e[s], e[s + 1], e[s + 2] = e[s] * sc, e[s + 1] * sc, e[s + 2] * sc
            fade = min(1.0, math.sqrt(sum(v * v for v in nrm)) / NULL_FADE)
            z = np.array([NULL_GAIN * fade * (cf[i] - q[i]) for i in range(n)])
            J, ev = np.array(cols), np.array(e)  # J: (n, m), the Jacobian's columns as rows
            y = _normal_solve(J, damping, ev - z @ J)
            dq = (J @ y + z).tolist()
            over = [not (lo[i] <= q[i] + dq[i] <= hi[i]) for i in range(n)]
            if any(over):
                pin = np.array([min(max(q[i] + dq[i], lo[i]), hi[i]) - q[i] if over[i] else 0.0
                                for i in range(n)])  # fmt: skip
                free = ~np.array(over)
                Jf = J * free[:, None]
                y2 = _normal_solve(Jf, damping, ev - pin @ J)
                dq = np.where(free, Jf @ y2, pin).tolist()
            big = max(abs(d) for d in dq)
            cap = min(1.0, MAX_STEP / max(big, 1e-300))
            q = [q[i] + (min(max(q[i] + dq[i] * cap, lo[i]), hi[i]) - q[i]) for i in range(n)]
            attempt_it += 1
        self.q, self.best_q, self.best_score, self.best_err = q, best_q, best_score, best_err
        self.n_restart, self.attempt_it, self.since = n_restart, attempt_it, since
        self.attempt_best = attempt_best
        return best_q


def solve_chain(
    chain: ScalarChain,
    targets: Sequence[float],
    q0: Sequence[float],
    lower: Sequence[float],
    upper: Sequence[float],
    comfort: Sequence[float],
    *,
    tol: float,
    restarts: int,
    seed: int = 0,
) -> list[float]:
    """``solve_ta``'s general path for one row of position goals (``targets``: their points,
    3 a goal, in the chain's site order) from active angles ``q0``: the best angles found."""
    return ChainSolve(chain, targets, q0, lower, upper, comfort, tol=tol, seed=seed).run(restarts)


class RowChain:
    """``ScalarChain``'s kinematics over many rows at once (numpy, rows first), each row's
    chain placed on its own base frame: the frame of the chain's first joint's parent and
    the angles of its dofs the solver does not move, from that row's start (``solve_ta``
    rebuilds its model for a start whose trunk differs by a rounding error, so each row's
    own trunk is what it solves with)."""

    def __init__(self, skel: Skeleton, model: ChainModel, root: tuple[FloatArray, FloatArray]):
        live = list(model.live)
        if any(int(skel.parent[b]) != a for a, b in itertools.pairwise(live)):
            raise ValueError("a serial chain only")
        if {skel.joint_index(skel.site(s).joint) for s in model.sites} != {live[-1]}:
            raise ValueError("every site on the chain's last joint")
        self.skel, self.root, self.top = skel, root, int(skel.parent[live[0]])
        self.active, self.n = model.active, model.n
        col = {int(d): i for i, d in enumerate(model.active)}
        self.dofs = np.array(
            [d for j in live for d in range(int(skel.joint_dof_start[j]),
                                            int(skel.joint_dof_start[j] + skel.joint_dof_count[j]))],
            dtype=np.intp,
        )  # fmt: skip
        self.cols = [col.get(int(d), -1) for d in self.dofs]  # each live dof's active column
        self.act_pos = np.array([i for i, c in enumerate(self.cols) if c >= 0], dtype=np.intp)
        self.act_col = np.array([c for c in self.cols if c >= 0], dtype=np.intp)
        axes = skel.dof_axis[self.dofs]
        K = np.zeros((len(axes), 3, 3))
        K[:, 0, 1], K[:, 0, 2], K[:, 1, 2] = -axes[:, 2], axes[:, 1], -axes[:, 0]
        K -= np.swapaxes(K, 1, 2)
        self.A0, self.A1, self.A2 = np.eye(3) + K @ K, K, -(K @ K)
        self.axes = axes
        slot = 0
        self.plan: list[tuple[FloatArray, list[int]]] = []
        for j in live:
            k = int(skel.joint_dof_count[j])
            self.plan.append((skel.offsets[j], list(range(slot, slot + k))))
            slot += k
        self.site_offsets = np.array([skel.site(s).offset for s in model.sites], dtype=float)
        self.sites = tuple(model.sites)

    def base(self, q: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Each row's base frame (b, 3, 3), (b, 3) and live dofs' angles (b, L) at full
        angles ``q`` (b, D)."""
        b = len(q)
        rp, rr = np.tile(self.root[0], (b, 1)), np.tile(self.root[1], (b, 1))
        pose = forward_part(self.skel, q, rp, rr, self.sites)  # the chain's joints alone
        return pose.R[:, self.top], pose.p[:, self.top], q[:, self.dofs]

    def eval(
        self, qa: FloatArray, R0: FloatArray, p0: FloatArray, fixed: FloatArray
    ) -> tuple[FloatArray, FloatArray]:
        """Site positions (b, 3 S) and Jacobians (b, 3 S, n) at active angles ``qa`` (b, n)."""
        b = len(qa)
        th = fixed.copy()
        th[:, self.act_pos] = qa[:, self.act_col]
        s, c = np.sin(th)[..., None, None], np.cos(th)[..., None, None]
        Rd = self.A0 + s * self.A1 + c * self.A2  # (b, L, 3, 3)
        axes, origins = np.empty((b, self.n, 3)), np.empty((b, self.n, 3))
        R, p = R0, p0
        for off, slots in self.plan:
            p = p + R @ off
            for slot in slots:
                ci = self.cols[slot]
                if ci >= 0:
                    axes[:, ci] = R @ self.axes[slot]
                    origins[:, ci] = p
                R = R @ Rd[:, slot]
        pts = p[:, None] + np.einsum("bij,sj->bsi", R, self.site_offsets)  # (b, S, 3)
        d = pts[:, :, None] - origins[:, None]  # (b, S, n, 3)
        J = cross(np.broadcast_to(axes[:, None], d.shape), d)
        return pts.reshape(b, -1), np.swapaxes(J, -1, -2).reshape(b, -1, self.n)


def solve_rows(
    chain: RowChain,
    targets: FloatArray,
    q0: FloatArray,
    lower: FloatArray,
    upper: FloatArray,
    comfort: FloatArray,
    *,
    tol: float,
    null_gain: float = NULL_GAIN,
) -> FloatArray:
    """``solve_ta(..., restarts=0)``'s general path for rows of position goals (``targets``
    (b, 3 S), the sites' points) from full angles ``q0`` (b, D): each row's best full angles
    (b, D). Rows that converge or stall leave the batch, as there."""
    q_out = np.array(q0, dtype=float)
    R0, p0, fixed = chain.base(q_out)
    cur = np.clip(q_out[:, chain.active], lower, upper)
    b, m = cur.shape[0], targets.shape[1]
    best_q, best = cur.copy(), np.full(b, np.inf)
    attempt_it, since = np.zeros(b, dtype=np.intp), np.zeros(b, dtype=np.intp)
    attempt_best = np.full(b, np.inf)
    rows = np.arange(b)
    damping = DAMPING * DAMPING * np.eye(m)
    while rows.size:
        pts, J = chain.eval(cur, R0[rows], p0[rows], fixed[rows])
        e = targets[rows] - pts
        blocks = e.reshape(len(rows), -1, 3)
        nrm = np.sqrt(np.einsum("bki,bki->bk", blocks, blocks))
        score = np.maximum(0.0, nrm.max(axis=1)) / tol
        better = score < best[rows]
        best_q[rows[better]], best[rows[better]] = cur[better], score[better]
        done = nrm.max(axis=1) <= tol
        improved = score < 0.9 * attempt_best[rows]
        attempt_best[rows] = np.where(improved, score, attempt_best[rows])
        since[rows] = np.where(improved, 0, since[rows] + 1)
        stuck = ~done & ((since[rows] >= PATIENCE) | (attempt_it[rows] >= MAX_ITER))
        keep = ~(done | stuck)
        if not keep.all():
            rows, cur, e, J, nrm, blocks = (
                rows[keep],
                cur[keep],
                e[keep],
                J[keep],
                nrm[keep],
                blocks[keep],
            )
            if not rows.size:
                break
        scale = np.minimum(1.0, MAX_ERROR / np.maximum(nrm, 1e-300))
        e = (blocks * scale[..., None]).reshape(len(rows), m)
        Jt = np.swapaxes(J, -1, -2)
        fade = np.minimum(1.0, np.sqrt(np.einsum("bk,bk->b", nrm, nrm)) / NULL_FADE)
        z = (null_gain * fade)[:, None] * (comfort - cur)
        y = solve_spd(J @ Jt + damping, (e - np.einsum("bmn,bn->bm", J, z))[..., None])
        dq = np.einsum("bnm,bm->bn", Jt, y[..., 0]) + z
        qn = cur + dq
        over = (qn > upper) | (qn < lower)
        hit = np.flatnonzero(over.any(axis=-1))
        if hit.size:
            ov, qh, Jh = over[hit], cur[hit], J[hit]
            pin = np.where(ov, np.clip(qn[hit], lower, upper) - qh, 0.0)
            e2 = e[hit] - np.einsum("bmn,bn->bm", Jh, pin)
            Jf = Jh * (~ov)[:, None, :]
            Jft = np.swapaxes(Jf, -1, -2)
            y2 = solve_spd(Jf @ Jft + damping, e2[..., None])[..., 0]
            dq[hit] = np.where(ov, pin, np.einsum("bnm,bm->bn", Jft, y2))
        big = np.max(np.abs(dq), axis=-1)
        dq = dq * np.minimum(1.0, MAX_STEP / np.maximum(big, 1e-300))[:, None]
        cur = cur + (np.clip(cur + dq, lower, upper) - cur)
        attempt_it[rows] += 1
    q_out[:, chain.active] = best_q
    return q_out
