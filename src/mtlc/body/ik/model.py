"""A kinematic problem compiled for fast repeated evaluation.

Solvers evaluate the same few sites many times while only some dofs move. ``ChainModel``
computes once the world frames of every joint that no moving dof affects (the *frozen* base,
e.g. pelvis → thorax → clavicle for an arm chain), precomputes Rodrigues terms
``R(a, θ) = A0 + sin θ·A1 + cos θ·A2`` for the moving joints, and then evaluates site
frames and the Jacobian of the active dofs with a short fixed sequence of small batched numpy
operations. Per-call overhead, not arithmetic, is what a single solve pays for.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..kinematics import _root_inputs, cross, skew
from ..skeleton import Skeleton

FloatArray = NDArray[np.float64]

# From this many rows the component-major kernel wins (measured on the 36-dof body: equal at
# ~20 rows, 5x faster at 1,000); below it the matrix kernel makes fewer numpy calls.
COLUMNS_MIN_BATCH = 32


class ChainModel:
    """Site positions, rotations and Jacobians of ``active`` dofs for a batch (B rows)."""

    def __init__(
        self,
        skel: Skeleton,
        sites: Sequence[str],
        active: Sequence[int],
        q_base: ArrayLike,
        root_position: ArrayLike | None = None,
        root_rotation: ArrayLike | None = None,
    ) -> None:
        self.skel = skel
        self.sites = tuple(sites)
        self.active = np.asarray(sorted(set(active)), dtype=np.intp)
        if self.active.size == 0:
            raise ValueError("no dofs to move")
        qb = np.atleast_2d(np.asarray(q_base, dtype=float))
        self.B = qb.shape[0]
        self.q_base = qb
        self._root_args = (root_position, root_rotation)
        site_j = [skel.joint_index(skel.site(s).joint) for s in self.sites]
        nj = skel.n_joints
        relevant = sorted({k for j in site_j for k in range(nj) if skel.ancestor[j, k]})
        act = set(self.active.tolist())
        has_act = [
            any(
                d in act
                for d in range(
                    int(skel.joint_dof_start[k]),
                    int(skel.joint_dof_start[k] + skel.joint_dof_count[k]),
                )
            )
            for k in range(nj)
        ]
        live = [j for j in relevant if any(has_act[k] for k in range(nj) if skel.ancestor[j, k])]
        frozen = [j for j in relevant if j not in live]
        moved = [int(d) for d in self.active if int(skel.dof_joint[d]) not in live]
        if moved:
            names = ", ".join(skel.dof_names[d] for d in moved)
            raise ValueError(f"dofs {names} do not move any goal site")
        self.live = live
        # the dofs whose angles the model bakes in from ``q_base``: every dof on a path from the
        # root to a site that the solver does not move (``for_start`` checks a start against them)
        self.baked = np.asarray(
            [
                d
                for j in relevant
                for d in range(
                    int(skel.joint_dof_start[j]),
                    int(skel.joint_dof_start[j] + skel.joint_dof_count[j]),
                )
                if d not in act
            ],
            dtype=np.intp,
        )
        # Frozen frames: FK over frozen joints only (their ancestors are frozen too).
        rp, RR = _root_inputs(skel, (self.B,), root_position, root_rotation)
        self.root = rp
        base_R: dict[int, FloatArray] = {}
        base_p: dict[int, FloatArray] = {}
        for j in frozen:
            pj = int(skel.parent[j])
            if pj < 0:
                Rw, pw = RR, rp + RR @ skel.offsets[j]
            else:
                Rw, pw = base_R[pj], base_p[pj] + base_R[pj] @ skel.offsets[j]
            s = int(skel.joint_dof_start[j])
            for k in range(s, s + int(skel.joint_dof_count[j])):
                Rw = Rw @ _rot(skel.dof_axis[k], qb[:, k])
            base_R[j], base_p[j] = Rw, pw
        self._base_R, self._base_p = base_R, base_p
        # Live dofs, in order; which of them are active and at which active column.
        live_dofs = [
            d
            for j in live
            for d in range(
                int(skel.joint_dof_start[j]), int(skel.joint_dof_start[j] + skel.joint_dof_count[j])
            )
        ]
        self._live_dofs = np.asarray(live_dofs, dtype=np.intp)
        col = {int(d): i for i, d in enumerate(self.active)}
        self._act_pos = np.array([i for i, d in enumerate(live_dofs) if d in col], dtype=np.intp)
        self._act_col = np.array([col[d] for d in live_dofs if d in col], dtype=np.intp)
        self._qlive = qb[:, self._live_dofs].copy()
        K = skew(skel.dof_axis[self._live_dofs])
        self._A0 = np.eye(3) + K @ K
        self._A1 = K
        self._A2 = -(K @ K)
        self._axis = skel.dof_axis[self._live_dofs]
        # Per live joint: parent (live index or frozen id), offset, its live-dof slots.
        pos_in_live = {j: i for i, j in enumerate(live)}
        self._plan: list[tuple[int, int, FloatArray, list[tuple[int, int]]]] = []
        slot = 0
        for j in live:
            pj = int(skel.parent[j])
            n = int(skel.joint_dof_count[j])
            dofs = []
            for k in range(n):
                d = live_dofs[slot + k]
                dofs.append((slot + k, col.get(d, -1)))
            slot += n
            self._plan.append((pos_in_live.get(pj, -1), pj, skel.offsets[j], dofs))
        # Sites: joint (live index or frozen), offset; Jacobian mask (S, nA).
        self._site_joint = site_j
        self._site_live = [pos_in_live.get(j, -1) for j in site_j]
        self._site_off = [np.asarray(skel.site(s).offset, dtype=float) for s in self.sites]
        self._site_cols = [
            np.array(
                [i for i, d in enumerate(self.active) if skel.ancestor[j, skel.dof_joint[d]]]
            ).astype(np.intp)
            for j in site_j
        ]
        dj = skel.dof_joint[self.active]
        self.mask = np.array([[skel.ancestor[j, k] for k in dj] for j in site_j], dtype=float)
        self.lower = skel.lower[self.active]
        self.upper = skel.upper[self.active]
        self.n = self.active.size
        self._cm = _coordinate_plan(self._axis)

    def for_start(self, q_full: FloatArray) -> ChainModel:
        """This model if it was built for the start ``q_full`` (B, D) (the same angles of every
        baked dof), else one built for it. A model evaluates its sites with the angles it was
        prepared with: reused for a start with another trunk, it would place the hand where
        that trunk is not, and call a miss of 20 cm a success."""
        qf = np.atleast_2d(np.asarray(q_full, dtype=float))
        if self.baked.size == 0:
            return self
        base = self.q_base[:, self.baked]
        if (self.B == 1 or qf.shape[0] == self.B) and np.array_equal(
            qf[:, self.baked], np.broadcast_to(base, (qf.shape[0], base.shape[1]))
        ):
            return self
        root_position, root_rotation = self._root_args
        return ChainModel(self.skel, self.sites, self.active, qf, root_position, root_rotation)

    def evaluate(
        self, qa: FloatArray, rows: NDArray[np.intp] | None = None
    ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """Site positions (b,S,3), rotations (b,S,3,3), position and angular Jacobians (b,S,3,nA).

        ``rows`` selects which batch rows of the base ``qa`` belongs to (default: all).
        Batches of coordinate-axis dofs (every manikin dof) take the component-major kernel;
        small batches and other axes the matrix one. Both give the same numbers (tested).
        """
        if self._cm is not None and qa.shape[0] >= COLUMNS_MIN_BATCH:
            return self._evaluate_columns(qa, rows)
        return self.evaluate_matrices(qa, rows)

    def _evaluate_columns(
        self, qa: FloatArray, rows: NDArray[np.intp] | None
    ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """Frames as three (3, b) columns, batch last: each numpy call is one elementwise pass
        over the batch, where batched (b, 3, 3) matmul and ``cross`` pay per row."""
        assert self._cm is not None
        k_of, sign = self._cm
        b = qa.shape[0]
        ql = _take(self._qlive, rows, b).copy()
        ql[:, self._act_pos] = qa[:, self._act_col]
        qt = np.ascontiguousarray(ql.T)
        S = np.sin(qt)
        S *= sign[:, None]
        C = np.cos(qt)
        A = np.empty((3, self.n, b))
        org = np.empty((3, self.n, b))
        frames: list[tuple[list[FloatArray], FloatArray]] = []
        for li, pj, off, dofs in self._plan:
            if li >= 0:
                cols, p = list(frames[li][0]), frames[li][1]
            else:
                cols, p = self._base_columns(pj, rows, b)
            for i in range(3):
                if off[i] != 0.0:
                    p = p + cols[i] * off[i]
            for slot, colk in dofs:
                k = k_of[slot]
                if colk >= 0:
                    A[:, colk] = cols[k] if sign[slot] > 0 else -cols[k]
                    org[:, colk] = p
                i1, i2 = (k + 1) % 3, (k + 2) % 3
                a, d = cols[i1], cols[i2]
                cs, sn = C[slot], S[slot]
                cols[i1] = a * cs + d * sn
                cols[i2] = d * cs - a * sn
            frames.append((cols, p))
        nS = len(self.sites)
        # Component-major outputs, returned as batch-first views (no transposing copies here;
        # consumers slice per site and concatenate, which copies once anyway).
        site_p = np.empty((nS, 3, b))
        site_R = np.empty((nS, 3, 3, b))
        Jp = np.zeros((nS, 3, self.n, b))
        Jw = np.zeros((nS, 3, self.n, b))
        for s, (li, j, off) in enumerate(
            zip(self._site_live, self._site_joint, self._site_off, strict=True)
        ):
            cols, p = frames[li] if li >= 0 else self._base_columns(j, rows, b)
            for i in range(3):
                if off[i] != 0.0:
                    p = p + cols[i] * off[i]
            site_p[s] = p
            for i in range(3):
                site_R[s, :, i] = cols[i]
            idx = self._site_cols[s]
            if idx.size == 0:
                continue
            a = A[:, idx]
            d = p[:, None, :] - org[:, idx]
            J = np.empty_like(a)
            np.multiply(a[1], d[2], out=J[0])
            J[0] -= a[2] * d[1]
            np.multiply(a[2], d[0], out=J[1])
            J[1] -= a[0] * d[2]
            np.multiply(a[0], d[1], out=J[2])
            J[2] -= a[1] * d[0]
            Jp[s][:, idx] = J
            Jw[s][:, idx] = a
        return (
            np.moveaxis(site_p, -1, 0),
            np.moveaxis(site_R, -1, 0),
            np.moveaxis(Jp, -1, 0),
            np.moveaxis(Jw, -1, 0),
        )

    def _base_columns(
        self, j: int, rows: NDArray[np.intp] | None, b: int
    ) -> tuple[list[FloatArray], FloatArray]:
        """A frozen joint's frame as columns (3, 1) (one base row) or (3, b) (per-row base)."""
        R, p = self._base_R[j], self._base_p[j]
        if R.shape[0] == 1:
            return [R[0][:, i, None] for i in range(3)], p[0][:, None]
        R, p = _take(R, rows, b), _take(p, rows, b)
        return [np.ascontiguousarray(R[:, :, i].T) for i in range(3)], np.ascontiguousarray(p.T)

    def q_active(self, q: ArrayLike) -> FloatArray:
        """The active columns of full configurations (B, n_dofs) -> (B, nA)."""
        return np.asarray(q, dtype=float)[..., self.active]

    def full(self, qa: FloatArray, rows: NDArray[np.intp] | None = None) -> FloatArray:
        """Full configurations from active values (fixed dofs from ``q_base``)."""
        out = _take(self.q_base, rows, qa.shape[0]).copy()
        out[:, self.active] = qa
        return out

    def evaluate_matrices(
        self, qa: FloatArray, rows: NDArray[np.intp] | None = None
    ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """:meth:`evaluate` with (b, 3, 3) Rodrigues matrices: any axis, the reference."""
        b = qa.shape[0]
        ql = _take(self._qlive, rows, b).copy()
        ql[:, self._act_pos] = qa[:, self._act_col]
        s = np.sin(ql)[..., None, None]
        c = np.cos(ql)[..., None, None]
        Rd = self._A0 + s * self._A1 + c * self._A2  # (b, nL, 3, 3)
        Rs: list[FloatArray] = []
        ps: list[FloatArray] = []
        axes = np.empty((b, self.n, 3))
        origins = np.empty((b, self.n, 3))
        for li, pj, off, dofs in self._plan:
            if li >= 0:
                Rp, pp = Rs[li], ps[li]
            else:
                Rp, pp = _take(self._base_R[pj], rows, b), _take(self._base_p[pj], rows, b)
            p = pp + Rp @ off
            R = Rp
            for slot, colk in dofs:
                if colk >= 0:
                    axes[:, colk] = R @ self._axis[slot]
                    origins[:, colk] = p
                R = R @ Rd[:, slot]
            Rs.append(R)
            ps.append(p)
        site_p = np.empty((b, len(self.sites), 3))
        site_R = np.empty((b, len(self.sites), 3, 3))
        for i, (li, j, off) in enumerate(
            zip(self._site_live, self._site_joint, self._site_off, strict=True)
        ):
            if li >= 0:
                R, p = Rs[li], ps[li]
            else:
                R, p = _take(self._base_R[j], rows, b), _take(self._base_p[j], rows, b)
            site_R[:, i] = R
            site_p[:, i] = p + R @ off
        # Jacobians: columns a_k x (p_s - o_k), masked to the dofs that move each site.
        d = site_p[:, :, None, :] - origins[:, None, :, :]  # (b, S, nA, 3)
        ax = np.broadcast_to(axes[:, None], d.shape)
        Jp = cross(ax, d) * self.mask[None, :, :, None]
        Jw = ax * self.mask[None, :, :, None]
        return site_p, site_R, np.swapaxes(Jp, -1, -2), np.swapaxes(Jw, -1, -2)


def _coordinate_plan(axes: FloatArray) -> tuple[list[int], FloatArray] | None:
    """Per live dof, which coordinate axis it turns about and the sign; None if any does not."""
    k_of: list[int] = []
    sign = np.empty(len(axes))
    for i, ax in enumerate(axes):
        k = int(np.argmax(np.abs(ax)))
        if abs(abs(ax[k]) - 1.0) > 1e-12:
            return None
        k_of.append(k)
        sign[i] = np.sign(ax[k])
    return k_of, sign


def _take(arr: FloatArray, rows: NDArray[np.intp] | None, b: int) -> FloatArray:
    """Rows of a per-batch base array: all, a broadcast single row, or an index."""
    if arr.shape[0] == b and rows is None:
        return arr
    if arr.shape[0] == 1:
        return np.broadcast_to(arr, (b, *arr.shape[1:]))
    if rows is None:
        raise ValueError(f"batch of {b} does not match the model's {arr.shape[0]} base rows")
    return arr[rows]


def _rot(axis: FloatArray, angles: FloatArray) -> FloatArray:
    K = skew(axis)
    s = np.sin(angles)[:, None, None]
    c = np.cos(angles)[:, None, None]
    return np.eye(3) + s * K + (1 - c) * (K @ K)
