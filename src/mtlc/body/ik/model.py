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
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..kinematics import _root_inputs, skew
from ..skeleton import Skeleton

FloatArray = NDArray[np.float64]

# From this many rows the component-major kernel wins (measured on the 36-dof body: equal at
# ~20 rows, 5x faster at 1,000); below it the matrix kernel makes fewer numpy calls.
COLUMNS_MIN_BATCH = 32


@dataclass(frozen=True, eq=False)
class _Structure:
    """What a problem's sites and moving dofs fix of a model, whatever the base angles: built
    once per (skeleton, sites, dofs) and shared (a held arm solved frame after frame rebuilt
    it ~1,800 times per manikin, 1 ms each: most of the model's cost)."""

    active: NDArray[np.intp]
    live: list[int]
    frozen: list[int]
    baked: NDArray[np.intp]
    live_dofs: NDArray[np.intp]
    act_pos: NDArray[np.intp]
    act_col: NDArray[np.intp]
    A0: FloatArray
    A1: FloatArray
    A2: FloatArray
    axis: FloatArray
    plan: list[tuple[int, int, FloatArray, list[tuple[int, int]]]]
    site_joint: list[int]
    site_live: list[int]
    site_off: list[FloatArray]
    site_cols: list[NDArray[np.intp]]
    mask: FloatArray
    lower: FloatArray
    upper: FloatArray
    coordinates: tuple[list[int], FloatArray] | None
    # per frozen joint: joint, parent, its dofs with the axis' K and K @ K (Rodrigues' terms)
    frozen_dofs: list[tuple[int, int, list[tuple[int, FloatArray, FloatArray]]]]
    # ``_StackedPlan`` of the problem, built by the first model that evaluates by matrices
    stacked: list[_StackedPlan] = field(default_factory=list)


def _structure(skel: Skeleton, sites: tuple[str, ...], active: NDArray[np.intp]) -> _Structure:
    """The shared ``_Structure`` of a problem, cached on the skeleton as ``kinematics._part``
    caches its branches (a skeleton's derived arrays never change)."""
    key = (sites, active.tobytes())
    cache: dict[tuple[Any, ...], _Structure] = skel.__dict__.setdefault("_chain_structures", {})
    found = cache.get(key)
    if found is None:
        found = cache[key] = _build_structure(skel, sites, active)
    return found


def _build_structure(
    skel: Skeleton, sites: tuple[str, ...], active: NDArray[np.intp]
) -> _Structure:
    site_j = [skel.joint_index(skel.site(s).joint) for s in sites]
    nj = skel.n_joints
    relevant = sorted({k for j in site_j for k in range(nj) if skel.ancestor[j, k]})
    act = set(active.tolist())
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
    moved = [int(d) for d in active if int(skel.dof_joint[d]) not in live]
    if moved:
        names = ", ".join(skel.dof_names[d] for d in moved)
        raise ValueError(f"dofs {names} do not move any goal site")
    # the dofs whose angles the model bakes in from ``q_base``: every dof on a path from the
    # root to a site that the solver does not move (``for_start`` checks a start against them)
    baked = np.asarray(
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
    # Live dofs, in order; which of them are active and at which active column.
    live_dofs = [
        d
        for j in live
        for d in range(
            int(skel.joint_dof_start[j]), int(skel.joint_dof_start[j] + skel.joint_dof_count[j])
        )
    ]
    live_idx = np.asarray(live_dofs, dtype=np.intp)
    col = {int(d): i for i, d in enumerate(active)}
    K = skew(skel.dof_axis[live_idx])
    # Per live joint: parent (live index or frozen id), offset, its live-dof slots.
    pos_in_live = {j: i for i, j in enumerate(live)}
    plan: list[tuple[int, int, FloatArray, list[tuple[int, int]]]] = []
    slot = 0
    for j in live:
        pj = int(skel.parent[j])
        n = int(skel.joint_dof_count[j])
        dofs = []
        for k in range(n):
            d = live_dofs[slot + k]
            dofs.append((slot + k, col.get(d, -1)))
        slot += n
        plan.append((pos_in_live.get(pj, -1), pj, skel.offsets[j], dofs))
    dj = skel.dof_joint[active]
    axis = skel.dof_axis[live_idx]
    return _Structure(
        active=active,
        live=live,
        frozen=frozen,
        baked=baked,
        live_dofs=live_idx,
        act_pos=np.array([i for i, d in enumerate(live_dofs) if d in col], dtype=np.intp),
        act_col=np.array([col[d] for d in live_dofs if d in col], dtype=np.intp),
        A0=np.eye(3) + K @ K,
        A1=K,
        A2=-(K @ K),
        axis=axis,
        plan=plan,
        # Sites: joint (live index or frozen), offset; Jacobian mask (S, nA).
        site_joint=site_j,
        site_live=[pos_in_live.get(j, -1) for j in site_j],
        site_off=[np.asarray(skel.site(s).offset, dtype=float) for s in sites],
        site_cols=[
            np.array(
                [i for i, d in enumerate(active) if skel.ancestor[j, skel.dof_joint[d]]]
            ).astype(np.intp)
            for j in site_j
        ],
        mask=np.array([[skel.ancestor[j, k] for k in dj] for j in site_j], dtype=float),
        lower=skel.lower[active],
        upper=skel.upper[active],
        coordinates=_coordinate_plan(axis),
        frozen_dofs=[(j, int(skel.parent[j]), _axis_terms(skel, j)) for j in frozen],
    )


def _axis_terms(skel: Skeleton, j: int) -> list[tuple[int, FloatArray, FloatArray]]:
    """Joint ``j``'s dofs with their axes' K and K @ K."""
    s = int(skel.joint_dof_start[j])
    out = []
    for k in range(s, s + int(skel.joint_dof_count[j])):
        K = skew(skel.dof_axis[k])
        out.append((k, K, K @ K))
    return out


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
        act = np.asarray(sorted(set(active)), dtype=np.intp)
        if act.size == 0:
            raise ValueError("no dofs to move")
        st = _structure(skel, self.sites, act)
        self._structure = st
        self.active = st.active
        qb = np.atleast_2d(np.asarray(q_base, dtype=float))
        self.B = qb.shape[0]
        self.q_base = qb
        self._root_args = (root_position, root_rotation)
        self.live = st.live
        self.baked = st.baked
        # Frozen frames: FK over frozen joints only (their ancestors are frozen too).
        rp, RR = _root_inputs(skel, (self.B,), root_position, root_rotation)
        self.root = rp
        base_R: dict[int, FloatArray] = {}
        base_p: dict[int, FloatArray] = {}
        eye = np.eye(3)
        for j, pj, dofs in st.frozen_dofs:
            if pj < 0:
                Rw, pw = RR, rp + RR @ skel.offsets[j]
            else:
                Rw, pw = base_R[pj], base_p[pj] + base_R[pj] @ skel.offsets[j]
            for k, K, KK in dofs:
                angles = qb[:, k]
                s = np.sin(angles)[:, None, None]
                c = np.cos(angles)[:, None, None]
                Rw = Rw @ (eye + s * K + (1 - c) * KK)
            base_R[j], base_p[j] = Rw, pw
        self._base_R, self._base_p = base_R, base_p
        self._live_dofs = st.live_dofs
        self._act_pos, self._act_col = st.act_pos, st.act_col
        self._qlive = qb[:, self._live_dofs].copy()
        self._A0, self._A1, self._A2 = st.A0, st.A1, st.A2
        self._axis = st.axis
        self._plan = st.plan
        self._site_joint = st.site_joint
        self._site_live = st.site_live
        self._site_off = st.site_off
        self._site_cols = st.site_cols
        self.mask = st.mask
        self.lower = st.lower
        self.upper = st.upper
        self.n = self.active.size
        self._cm = st.coordinates

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
        """:meth:`evaluate` with (b, 3, 3) Rodrigues matrices: any axis, the reference.

        The same arithmetic as a joint-by-joint loop (``R = R_parent @ R(a, q)`` per dof,
        ``p = p_parent + R_parent @ offset``, tested to the bit) in a third of its numpy calls
        (``_Stacked``): the products are BLAS's 3x3 ``matmul`` (fused multiply-adds), one
        stacked call for the joints of a depth at each dof step (a stacked call computes each
        product with the kernel a call of its own uses); every offset and dof axis is turned
        by its frame in one stacked call; the positions are running sums down each site's
        chain (``cumsum``: the same additions, in the same order)."""
        st = self._stacked()
        b = qa.shape[0]
        if b == 1 and st.one is not None:
            return st.one.evaluate(qa, st)
        ql = _take(st.q_steps, rows, b).copy()  # the live angles in the order of the steps
        ql[:, st.act_steps] = qa[:, st.act_cols]
        s = np.sin(ql)[..., None, None]
        c = np.cos(ql)[..., None, None]
        Rd = st.A0 + s * st.A1 + c * st.A2  # (b, steps, 3, 3)
        Z = np.empty((b, st.n_frames, 3, 3))  # frozen frames, then each dof step's products
        X = np.empty((b, st.n_terms, 3))  # frozen positions, turned vectors, a zero (padding)
        if self.B == 1:
            Z[:, : st.n_frozen] = st.frozen_R
            X[:, : st.n_frozen] = st.frozen_p
        else:
            for f, j in enumerate(st.frozen):
                Z[:, f] = _take(self._base_R[j], rows, b)
                X[:, f] = _take(self._base_p[j], rows, b)
        for src, rot, dst in st.steps:
            np.matmul(Z[:, src], Rd[:, rot], out=Z[:, dst])
        X[:, st.n_frozen : -1] = (Z[:, st.turn_frames] @ st.turn_vectors)[..., 0]
        X[:, -1] = 0.0
        axes = X[:, st.axis_terms]  # (b, nA, 3)
        X2 = np.concatenate((X, X), axis=-1)  # each vector written twice over: [x y z x y z]
        sums = X2[:, st.paths].cumsum(axis=2).reshape(b, -1, 6)  # (b, S * L, 6)
        site_p2, o2 = sums[:, st.site_sums], sums[:, st.axis_sums]
        site_p = site_p2[..., :3]
        site_R = Z[:, st.site_frames]
        # Jacobians: columns a_k x (p_s - o_k), masked to the dofs that move each site; the
        # cross product on vectors written twice over (its turned components are slices),
        # the same products and differences as ``cross``.
        # Jp is computed dof-major, (b, nA, S, 3), so that a site's rows side by side (the
        # stacked error's Jacobian) are a view in the layout ``np.concatenate`` gives them.
        a2 = np.concatenate((axes, axes), axis=-1)[:, :, None]
        d2 = site_p2[:, None] - o2[:, :, None]
        Jp = (a2[..., 1:4] * d2[..., 2:5] - a2[..., 2:5] * d2[..., 1:4]) * st.mask_dof_major
        Jw = axes[:, None] * st.mask
        return site_p, site_R, Jp.transpose(0, 2, 3, 1), Jw.swapaxes(-1, -2)

    def _stacked(self) -> _Stacked:
        """The stacked evaluation's plan (built on first use)."""
        st = self.__dict__.get("_stacked_plan")
        if st is None:
            st = self.__dict__["_stacked_plan"] = _Stacked(self)
        return st


Selector = slice | NDArray[np.intp]


def _selector(indices: list[int], broadcast: bool = False) -> Selector:
    """Indices as a slice where they are a run (or, ``broadcast``, one index repeated: a slice
    of one that broadcasts), so numpy takes a view instead of a copy."""
    if broadcast and all(i == indices[0] for i in indices):
        return slice(indices[0], indices[0] + 1)
    if indices == list(range(indices[0], indices[0] + len(indices))):
        return slice(indices[0], indices[0] + len(indices))
    return np.array(indices, dtype=np.intp)


class _Stacked:
    """``evaluate_matrices``' plan for one model: the problem's ``_StackedPlan`` (its
    attributes, the same objects) and the model's own numbers: the fixed angles in the order
    of the steps (``q_steps``), the frozen frames and positions of a one-row base, the one-row
    evaluation's buffers (``one``)."""

    def __init__(self, model: ChainModel) -> None:
        st = model._structure
        if not st.stacked:
            st.stacked.append(_StackedPlan(model))
        plan = st.stacked[0]
        self.__dict__.update(plan.__dict__)
        self.q_steps = model._qlive[:, plan.perm]
        if model.B == 1:
            self.frozen_R = np.array([model._base_R[j][0] for j in plan.frozen]).reshape(-1, 3, 3)
            self.frozen_p = np.array([model._base_p[j][0] for j in plan.frozen]).reshape(-1, 3)
        self.one = _OneRow(self) if model.B == 1 and plan.steps_are_views else None


class _StackedPlan:
    """Where ``evaluate_matrices`` keeps each number: what the problem's structure fixes of
    it (the sites, dofs and joints; not the base angles), built once per ``_Structure`` (a
    pass that solves one pose at a time builds a model a solve: this was half its cost).

    ``Z`` (b, n_frames, 3, 3): the frozen joints' frames, then one block per depth of live
    joints and dof step (the step's joints' running products, the joints with more dofs
    first); ``steps``: ``Z[dst] = Z[src] @ Rd[rot]`` in order. ``X`` (b, n_terms, 3): the
    frozen joints' positions, then the vectors ``Z[turn_frames] @ turn_vectors`` (each live
    joint's offset by its parent's frame, each site's offset by its frame, each active dof's
    axis by the frame before it), then a zero; ``paths`` (S, L): per site, the terms whose
    running sum is its chain's positions (a frozen position, the joints' offsets, the site's
    offset; the zero after the end); ``site_sums`` and ``axis_sums`` pick the site's and each
    dof's joint's position from the flattened sums."""

    def __init__(self, model: ChainModel) -> None:
        plan = model._plan
        n_live = len(plan)
        level = [0] * n_live
        for i, (li, _pj, _off, _dofs) in enumerate(plan):
            level[i] = 0 if li < 0 else level[li] + 1
        site_live = list(zip(model._site_live, model._site_joint, strict=True))
        frozen = sorted(
            {pj for li, pj, _o, _d in plan if li < 0} | {j for li, j in site_live if li < 0}
        )
        self.frozen, self.n_frozen = frozen, len(frozen)
        frozen_at = {j: f for f, j in enumerate(frozen)}
        final: dict[int, int] = {}  # live index -> Z index of its world frame
        parent_frame: dict[int, int] = {}  # live index -> Z index of its parent's frame
        z = len(frozen)
        perm: list[int] = []
        axis_frame: dict[int, int] = {}  # active column -> Z index of the frame before its dof
        axis_joint: dict[int, int] = {}  # active column -> its joint's live index
        order: list[int] = []  # live indices in the order of their offsets' terms
        steps = []
        for depth in range(max(level, default=-1) + 1):
            members = sorted(
                (i for i in range(n_live) if level[i] == depth), key=lambda i: -len(plan[i][3])
            )
            order += members
            src = [final[plan[i][0]] if plan[i][0] >= 0 else frozen_at[plan[i][1]] for i in members]
            for r, i in enumerate(members):
                parent_frame[i] = final[i] = src[r]  # a joint without dofs: its parent's frame
            for k in range(max((len(plan[i][3]) for i in members), default=0)):
                m = sum(1 for i in members if len(plan[i][3]) > k)
                for r, i in enumerate(members[:m]):
                    slot, colk = plan[i][3][k]
                    if colk >= 0:
                        axis_frame[colk], axis_joint[colk] = src[r], i
                    perm.append(slot)
                    final[i] = z + r
                steps.append(
                    (_selector(src[:m], True), slice(len(perm) - m, len(perm)), slice(z, z + m))
                )
                src, z = list(range(z, z + m)), z + m
        self.steps = tuple(steps)
        self.n_frames = z
        self.perm = perm
        act = dict(zip(model._act_pos.tolist(), model._act_col.tolist(), strict=True))
        self.act_steps = np.array([t for t, slot in enumerate(perm) if slot in act], dtype=np.intp)
        self.act_cols = np.array([act[slot] for slot in perm if slot in act], dtype=np.intp)
        self.A0, self.A1, self.A2 = model._A0[perm], model._A1[perm], model._A2[perm]
        cols = range(model.n)
        n_sites = len(site_live)
        axis_slot = {colk: slot for _li, _pj, _o, dofs in plan for slot, colk in dofs}
        self.turn_frames = np.array(
            [parent_frame[i] for i in order]
            + [final[li] if li >= 0 else frozen_at[j] for li, j in site_live]
            + [axis_frame[c] for c in cols],
            dtype=np.intp,
        )
        self.turn_vectors = np.concatenate(
            [
                np.array([plan[i][2] for i in order], dtype=float).reshape(-1, 3),
                np.array(model._site_off, dtype=float).reshape(-1, 3),
                model._axis[[axis_slot[c] for c in cols]].reshape(-1, 3),
            ]
        )[..., None]
        term = {i: len(frozen) + r for r, i in enumerate(order)}  # a live joint's offset term
        first_site = len(frozen) + n_live
        self.axis_terms = _selector([first_site + n_sites + c for c in cols])
        self.n_terms = first_site + n_sites + model.n + 1
        # per site its chain: the frozen joint it hangs from, the live joints down to it
        chains = []
        for li, j in site_live:
            chain = []
            while li >= 0:
                chain.append(li)
                li, top = plan[li][0], plan[li][1]
            chains.append((frozen_at[top] if chain else frozen_at[j], chain[::-1]))
        length = max(len(chain) for _f, chain in chains) + 2
        paths = np.full((n_sites, length), self.n_terms - 1, dtype=np.intp)
        where: dict[int, int] = {}  # live index -> its position among the flattened sums
        site_sums = []
        for s, (f, chain) in enumerate(chains):
            paths[s, 0] = f
            for d, i in enumerate(chain, start=1):
                paths[s, d] = term[i]
                where.setdefault(i, s * length + d)
            paths[s, len(chain) + 1] = first_site + s
            site_sums.append(s * length + len(chain) + 1)
        self.paths = paths
        self.site_sums = np.array(site_sums, dtype=np.intp)
        self.axis_sums = np.array([where[axis_joint[c]] for c in cols], dtype=np.intp)
        # (an index, not a slice: each site's frame a copy of its own, contiguous, as before)
        self.site_frames = np.array(
            [final[li] if li >= 0 else frozen_at[j] for li, j in site_live], dtype=np.intp
        )
        self.mask = model.mask[None, :, :, None]
        self.mask_dof_major = model.mask.T[None, :, :, None]
        self.steps_are_views = all(isinstance(src, slice) for src, _rot, _dst in self.steps)


class _OneRow:
    """``evaluate_matrices`` of one row (what every pass's solve asks, thousands of times)
    in arrays kept from call to call: the frozen frames and positions written once, every
    step's operands views made once, the products written in place (``out=``). The same
    operations on the same numbers as the general evaluation, so the same results."""

    def __init__(self, st: _Stacked) -> None:
        n_steps = len(st.q_steps[0])
        self.ql = st.q_steps.copy()  # the fixed angles stay; the active ones are written
        self.sin, self.cos = np.empty((1, n_steps)), np.empty((1, n_steps))
        self.tmp, self.Rd = np.empty((1, n_steps, 3, 3)), np.empty((1, n_steps, 3, 3))
        self.Z = np.empty((1, st.n_frames, 3, 3))
        self.Z[:, : st.n_frozen] = st.frozen_R
        self.steps = [
            (self.Z[:, src], self.Rd[:, rot], self.Z[:, dst]) for src, rot, dst in st.steps
        ]
        n_turns = len(st.turn_frames)
        self.turned_frames = np.empty((1, n_turns, 3, 3))
        self.turned = np.empty((1, n_turns, 3, 1))
        self.X2 = np.empty((1, st.n_terms, 6))  # each term written twice over: [x y z x y z]
        self.X2[:, : st.n_frozen, :3] = st.frozen_p
        self.X2[:, : st.n_frozen, 3:] = st.frozen_p
        self.X2[:, -1] = 0.0
        self.terms = (self.X2[:, st.n_frozen : -1, :3], self.X2[:, st.n_frozen : -1, 3:])
        self.along = np.empty((1, *st.paths.shape, 6))
        self.sums = np.empty((1, *st.paths.shape, 6))
        self.flat_sums = self.sums.reshape(1, -1, 6)

    def evaluate(
        self, qa: FloatArray, st: _Stacked
    ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        self.ql[:, st.act_steps] = qa[:, st.act_cols]
        np.sin(self.ql, out=self.sin)
        np.cos(self.ql, out=self.cos)
        # A0 + s * A1 + c * A2, in that order
        np.multiply(self.sin[..., None, None], st.A1, out=self.tmp)
        np.add(st.A0, self.tmp, out=self.Rd)
        np.multiply(self.cos[..., None, None], st.A2, out=self.tmp)
        np.add(self.Rd, self.tmp, out=self.Rd)
        for src, rot, dst in self.steps:
            np.matmul(src, rot, out=dst)
        np.take(self.Z, st.turn_frames, axis=1, out=self.turned_frames, mode="clip")
        np.matmul(self.turned_frames, st.turn_vectors, out=self.turned)
        self.terms[0][...] = self.turned[..., 0]
        self.terms[1][...] = self.turned[..., 0]
        np.take(self.X2, st.paths, axis=1, out=self.along, mode="clip")
        np.cumsum(self.along, axis=2, out=self.sums)
        site_p2 = self.flat_sums[:, st.site_sums]
        o2 = self.flat_sums[:, st.axis_sums]
        a2 = self.X2[:, st.axis_terms][:, :, None]
        d2 = site_p2[:, None] - o2[:, :, None]
        Jp = (a2[..., 1:4] * d2[..., 2:5] - a2[..., 2:5] * d2[..., 1:4]) * st.mask_dof_major
        Jw = a2[:, :, 0, :3][:, None] * st.mask
        site_R = self.Z[:, st.site_frames]
        return site_p2[..., :3], site_R, Jp.transpose(0, 2, 3, 1), Jw.swapaxes(-1, -2)


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
