"""Batched forward kinematics, Jacobians and centre of mass.

Everything takes joint angles ``q`` of shape ``(..., n_dofs)`` and works on any number of
leading batch dimensions (frames, restarts, manikins of the same topology) at once, because
per-call overhead dominates small numpy work: one call over 1,000 configurations costs about
what ten single calls cost.

The rule is the IR's (``shared/design/IR.md``): ``W_j = W_parent · T(offset_j) · R(a_1, q_1) ·
R(a_2, q_2) · …``; the root starts from the root position and unit quaternion (w, x, y, z).
Jacobian columns for angle ``q_k`` are ``a_k × (p − o_k)`` (position) and ``a_k`` (orientation),
with ``a_k`` the dof's world axis and ``o_k`` its joint's world position. Root columns, when
asked for, are the world translation (x, y, z) then a small world-frame rotation (x, y, z)
about the root position.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .skeleton import Skeleton

FloatArray = NDArray[np.float64]

try:  # ``np.einsum`` without its Python wrapper: with ``optimize=False`` (its default) the
    # wrapper calls this, so the same numbers, 2-3 µs sooner (a solver step calls it 8 times)
    from numpy._core._multiarray_umath import c_einsum as einsum
except ImportError:  # pragma: no cover - another numpy layout
    einsum = np.einsum


@dataclass(frozen=True)
class Pose:
    """World frames of every joint for a batch of configurations.

    ``R`` (..., J, 3, 3) rotations, ``p`` (..., J, 3) positions, ``axes`` (..., D, 3) the world
    axis of each degree of freedom, ``root`` (..., 3) the root position.
    """

    R: FloatArray
    p: FloatArray
    axes: FloatArray
    root: FloatArray

    @property
    def batch_shape(self) -> tuple[int, ...]:
        """Leading batch dimensions."""
        return self.p.shape[:-2]

    def rows(self, rows: ArrayLike) -> Pose:
        """The rows of a batched pose (N, ...)."""
        return Pose(R=self.R[rows], p=self.p[rows], axes=self.axes[rows], root=self.root[rows])

    @staticmethod
    def joined(parts: Sequence[Pose]) -> Pose:
        """Batched poses one after the other."""
        if len(parts) == 1:
            return parts[0]
        return Pose(
            *(np.concatenate([getattr(p, f) for p in parts]) for f in ("R", "p", "axes", "root"))
        )


def quat_to_matrix(quat: ArrayLike) -> FloatArray:
    """Rotation matrices from quaternions (..., 4), w first; normalised on the way."""
    qa = np.asarray(quat, dtype=float)
    qa = qa / np.linalg.norm(qa, axis=-1, keepdims=True)
    w, x, y, z = qa[..., 0], qa[..., 1], qa[..., 2], qa[..., 3]
    out = np.empty((*qa.shape[:-1], 3, 3))
    out[..., 0, 0] = 1 - 2 * (y * y + z * z)
    out[..., 0, 1] = 2 * (x * y - w * z)
    out[..., 0, 2] = 2 * (x * z + w * y)
    out[..., 1, 0] = 2 * (x * y + w * z)
    out[..., 1, 1] = 1 - 2 * (x * x + z * z)
    out[..., 1, 2] = 2 * (y * z - w * x)
    out[..., 2, 0] = 2 * (x * z - w * y)
    out[..., 2, 1] = 2 * (y * z + w * x)
    out[..., 2, 2] = 1 - 2 * (x * x + y * y)
    return out


def matrix_to_quat(R: ArrayLike) -> FloatArray:
    """Unit quaternions (..., 4), w first and w >= 0, from rotation matrices (..., 3, 3)."""
    m = np.asarray(R, dtype=float)
    t = np.trace(m, axis1=-2, axis2=-1)
    cands = np.stack(
        [
            np.stack(
                [
                    1 + t,
                    m[..., 2, 1] - m[..., 1, 2],
                    m[..., 0, 2] - m[..., 2, 0],
                    m[..., 1, 0] - m[..., 0, 1],
                ],
                -1,
            ),
            np.stack(
                [
                    m[..., 2, 1] - m[..., 1, 2],
                    1 + 2 * m[..., 0, 0] - t,
                    m[..., 0, 1] + m[..., 1, 0],
                    m[..., 0, 2] + m[..., 2, 0],
                ],
                -1,
            ),
            np.stack(
                [
                    m[..., 0, 2] - m[..., 2, 0],
                    m[..., 0, 1] + m[..., 1, 0],
                    1 + 2 * m[..., 1, 1] - t,
                    m[..., 1, 2] + m[..., 2, 1],
                ],
                -1,
            ),
            np.stack(
                [
                    m[..., 1, 0] - m[..., 0, 1],
                    m[..., 0, 2] + m[..., 2, 0],
                    m[..., 1, 2] + m[..., 2, 1],
                    1 + 2 * m[..., 2, 2] - t,
                ],
                -1,
            ),
        ],
        -2,
    )
    diag = np.stack([t, m[..., 0, 0], m[..., 1, 1], m[..., 2, 2]], -1)
    k = np.argmax(diag, axis=-1)
    q = np.take_along_axis(cands, k[..., None, None], axis=-2)[..., 0, :]
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    return np.where(q[..., :1] < 0, -q, q)


def axis_angle(axes: ArrayLike, angles: ArrayLike) -> FloatArray:
    """Rotation matrices R(a, θ) (..., 3, 3) by Rodrigues' formula; axes must be unit."""
    a = np.asarray(axes, dtype=float)
    th = np.asarray(angles, dtype=float)
    s, c = np.sin(th)[..., None, None], np.cos(th)[..., None, None]
    K = skew(a)
    return _rodrigues(K, K @ K, s, c)


def rotate_about(
    origin: FloatArray, axis: FloatArray, v: FloatArray, cos: ArrayLike, sin: ArrayLike
) -> FloatArray:
    """``origin`` plus the vectors ``v`` (..., 3) turned about unit ``axis`` (..., 3) by the
    angle whose cosine and sine are given (Rodrigues' formula on vectors, broadcast): a
    point turned about a line without a matrix per angle."""
    along = np.einsum("...i,...i->...", axis, v)[..., None]
    return origin + v * cos + cross(axis, v) * sin + axis * along * (1.0 - np.asarray(cos))


def _rodrigues(K: FloatArray, KK: FloatArray, s: FloatArray, c: FloatArray) -> FloatArray:
    return np.eye(3) + s * K + (1 - c) * KK


def cross(a: FloatArray, b: FloatArray) -> FloatArray:
    """``np.cross`` over the last axis (length 3), broadcast: the same products in the same
    order, without its axis bookkeeping (measured: 8 µs against 25 for (16, 3) by (16, 3),
    24 against 36 for the kneel's (1, 37, 16, 3), 0.6 ms against 2.8 for (2000, 30, 3))."""
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    np.subtract(a1 * b2, a2 * b1, out=out[..., 0])
    np.subtract(a2 * b0, a0 * b2, out=out[..., 1])
    np.subtract(a0 * b1, a1 * b0, out=out[..., 2])
    return out


def skew(v: ArrayLike) -> FloatArray:
    """Cross-product matrices [v]× of shape (..., 3, 3)."""
    va = np.asarray(v, dtype=float)
    z = np.zeros(va.shape[:-1])
    x, y, w = va[..., 0], va[..., 1], va[..., 2]
    return np.stack(
        [np.stack([z, -w, y], -1), np.stack([w, z, -x], -1), np.stack([-y, x, z], -1)], -2
    )


def rotation_error(R_target: ArrayLike, R: ArrayLike) -> FloatArray:
    """Axis·angle (..., 3) of the world rotation taking ``R`` to ``R_target``."""
    D = np.asarray(R_target) @ np.swapaxes(np.asarray(R), -1, -2)
    v = 0.5 * np.stack(
        [D[..., 2, 1] - D[..., 1, 2], D[..., 0, 2] - D[..., 2, 0], D[..., 1, 0] - D[..., 0, 1]], -1
    )
    s = np.linalg.norm(v, axis=-1)
    c = 0.5 * (np.trace(D, axis1=-2, axis2=-1) - 1)
    ang = np.arctan2(s, c)
    scale = np.where(s > 1e-12, ang / np.maximum(s, 1e-300), 1.0)
    out = v * scale[..., None]
    # Near pi the antisymmetric part vanishes: take the axis from the symmetric part.
    near_pi = (s < 1e-6) & (c < 0)
    if np.any(near_pi):
        out = np.array(out, copy=True)
        for idx in np.ndindex(near_pi.shape):
            if not near_pi[idx]:
                continue
            Bm = 0.5 * (D[idx] + D[idx].T)  # = -I + 2 a a^T at an angle of pi
            i = int(np.argmax(np.diagonal(Bm)))
            col = Bm[:, i] + np.eye(3)[i]
            out[idx] = np.pi * col / np.linalg.norm(col)
    return out


def _root_inputs(
    skel: Skeleton,
    batch: tuple[int, ...],
    root_position: ArrayLike | None,
    root_rotation: ArrayLike | None,
) -> tuple[FloatArray, FloatArray]:
    rp = skel.root_position if root_position is None else np.asarray(root_position, dtype=float)
    if rp.shape[:-1] != batch:  # (a broadcast costs a solver's small batch more than its FK)
        rp = np.broadcast_to(rp, (*batch, 3))
    if root_rotation is None:
        RR = _identities(batch)
    else:
        rr = np.asarray(root_rotation, dtype=float)
        RR = quat_to_matrix(rr) if rr.shape[-1] == 4 else rr
        if RR.shape[:-2] != batch:
            RR = np.broadcast_to(RR, (*batch, 3, 3))
    return rp, RR


_EYE3, _EYE4 = np.eye(3), np.eye(4)
_ORIGIN = np.zeros(3)
_EYE3.setflags(write=False)
_EYE4.setflags(write=False)


@functools.lru_cache(maxsize=64)
def _identities(batch: tuple[int, ...]) -> FloatArray:
    """A read-only (*batch, 3, 3) view of the identity: no root rotation (a solver's frame-by-
    frame forward kinematics asked ``np.broadcast_to`` for the same view thousands of times)."""
    return np.broadcast_to(_EYE3, (*batch, 3, 3))


@dataclass(frozen=True)
class _Plan:
    """What ``forward`` precomputes once per skeleton (the per-joint Python loop it replaces
    was most of a small batch's cost): each dof's cross-product matrix K and K², where each
    joint's first, second and third dof sit among the dofs (``n_dofs``: no such dof, the
    identity), and the joints grouped by depth in the tree."""

    basis: FloatArray  # (D + 1, 3, 9): I + K², K and K² flattened; last, the identity ("no dof")
    slot_dof: NDArray[np.intp]  # (3, J)
    prefix: NDArray[np.intp]  # (D,) dof k's rotations before it: 0 (none), 1 + J·(slot-1) + joint
    dof_parent: NDArray[np.intp]  # (D,) its joint's parent + 1 (0: the root's base frame)
    levels: tuple[tuple[NDArray[np.intp], NDArray[np.intp]], ...]  # (joints, parents), depth ≥ 1
    chains: NDArray[np.intp]  # (depth + 1, J): each joint's path from the root; J: the identity


def _plan(skel: Skeleton) -> _Plan:
    cached = skel.__dict__.get("_fk_plan")
    if isinstance(cached, _Plan):
        return cached
    nj, nd = skel.n_joints, skel.n_dofs
    if int(skel.joint_dof_count.max(initial=0)) > 3:
        raise ValueError("forward kinematics handles at most 3 dofs a joint")
    slot_dof = np.full((3, nj), nd, dtype=np.intp)
    prefix = np.empty(nd, dtype=np.intp)
    for j in range(nj):
        for k in range(int(skel.joint_dof_count[j])):
            d = int(skel.joint_dof_start[j]) + k
            slot_dof[k, j] = d
            prefix[d] = 0 if k == 0 else 1 + (k - 1) * nj + j
    depth = np.zeros(nj, dtype=np.intp)
    for j in range(1, nj):
        depth[j] = depth[skel.parent[j]] + 1
    levels = tuple(
        (joints, skel.parent[joints])
        for joints in (np.flatnonzero(depth == d) for d in range(1, int(depth.max(initial=0)) + 1))
    )
    chains = np.full((int(depth.max(initial=0)) + 1, nj), nj, dtype=np.intp)
    for j in range(nj):
        k = j
        while k >= 0:
            chains[depth[k], j] = k
            k = int(skel.parent[k])
    K = np.concatenate([skew(skel.dof_axis), np.zeros((1, 3, 3))])
    KK = K @ K
    plan = _Plan(
        np.stack([(np.eye(3) + KK).reshape(-1, 9), K.reshape(-1, 9), KK.reshape(-1, 9)], axis=1),
        slot_dof,
        prefix,
        skel.parent[skel.dof_joint] + 1,
        levels,
        chains,
    )
    skel.__dict__["_fk_plan"] = plan
    return plan


def _homogeneous(R: FloatArray, p: FloatArray) -> FloatArray:
    T = np.zeros((*R.shape[:-2], 4, 4))
    T[..., :3, :3] = R
    T[..., :3, 3] = p
    T[..., 3, 3] = 1.0
    return T


CHAIN_BATCH = 8  # configurations up to which joints are placed by their paths, not by levels
BRANCH_CHUNK = 4096
FK_CHUNK = 48  # configurations a chunk: temporaries stay small (fresh large ones page-fault)


def forward(
    skel: Skeleton,
    q: ArrayLike,
    root_position: ArrayLike | None = None,
    root_rotation: ArrayLike | None = None,
    *,
    with_axes: bool = True,
) -> Pose:
    """Forward kinematics of every joint for a batch of configurations.

    ``q`` is (..., n_dofs); ``root_position`` (..., 3) defaults to standing on the ground;
    ``root_rotation`` is a quaternion (..., 4) w first, or a matrix (..., 3, 3).
    ``with_axes=False`` leaves the dofs' axes out (``axes`` is then (..., 0, 3)): a caller
    that needs no Jacobian saves a quarter of the work.
    """
    qa = np.asarray(q, dtype=float)
    if qa.shape[-1] != skel.n_dofs:
        raise ValueError(f"q has {qa.shape[-1]} angles, the skeleton has {skel.n_dofs}")
    batch = qa.shape[:-1]
    rp, RR = _root_inputs(skel, batch, root_position, root_rotation)
    n, nj = math.prod(batch), skel.n_joints  # (np.prod of a tuple: 3 µs a call)
    qf, rpf, RRf = qa.reshape(n, -1), rp.reshape(n, 3), RR.reshape(n, 3, 3)
    nd = skel.n_dofs if with_axes else 0
    runs = repeated_rows(qf, rpf, RRf)
    if runs is not None:  # each run of identical rows posed once (a hold: one pose a minute)
        heads, at = runs
        one = forward(skel, qf[heads], rpf[heads], RRf[heads], with_axes=with_axes)
        R, p, axes = one.R[at], one.p[at], one.axes[at]
    else:
        R, p, axes = np.empty((n, nj, 3, 3)), np.empty((n, nj, 3)), np.empty((n, nd, 3))
        for a in range(0, n, FK_CHUNK):
            c = slice(a, a + FK_CHUNK)
            R[c], p[c], axes[c] = _forward_flat(skel, qf[c], rpf[c], RRf[c], with_axes)
    return Pose(
        R=R.reshape(*batch, nj, 3, 3), p=p.reshape(*batch, nj, 3),
        axes=axes.reshape(*batch, nd, 3), root=np.array(rp),
    )  # fmt: skip


_OUTPUT_POSE: list[tuple[Skeleton, FloatArray, FloatArray, FloatArray, Pose]] = []


def output_pose(
    skel: Skeleton,
    q: FloatArray,
    root_position: FloatArray,
    root_rotation: FloatArray,
    *,
    keep: bool = False,
    posed: Pose | None = None,
) -> Pose:
    """``forward(skel, q, root_position, root_rotation, with_axes=False)`` of a motion's output
    frames, handed on: the verify pass poses them (``keep``: remembered, one batch, its inputs
    copied), then lint's rules or the metrics ask for the same frames and take that pose (a
    long walk's 26,000 frames: a quarter of a second each time). Taking it forgets it, so no
    pose outlives its compile. The pose is shared: read it only. ``posed``: that pose, if the
    caller has it (the verify pass, from the passes before it)."""
    now = [np.ascontiguousarray(x, dtype=float) for x in (q, root_position, root_rotation)]
    kept = _OUTPUT_POSE[:]
    _OUTPUT_POSE.clear()
    same = [k[-1] for k in kept if k[0] is skel and all(map(_same_bits, k[1:4], now))]
    if same:
        pose = same[0]
    elif posed is not None:
        pose = posed
    else:
        pose = forward(skel, q, root_position, root_rotation, with_axes=False)
    if keep:
        _OUTPUT_POSE.append((skel, *(x.copy() for x in now), pose))
    return pose


def forget_output_pose() -> None:
    """Drop a kept ``output_pose`` nobody took (a compile starting: it is not its frames)."""
    _OUTPUT_POSE.clear()


def _same_bits(a: FloatArray, b: FloatArray) -> bool:
    """Whether two float arrays are equal bit for bit (-0.0 is not 0.0; a NaN is itself)."""
    return a.shape == b.shape and bool(np.array_equal(a.view(np.int64), b.view(np.int64)))


REPEAT_MIN_ROWS = 64  # batches from which repeated rows are looked for (a solver's are smaller)


def repeated_rows(*columns: FloatArray) -> tuple[NDArray[np.intp], NDArray[np.intp]] | None:
    """Runs of consecutive rows equal bit for bit in every one of ``columns`` (each (n, ...)):
    the first row of each run and, for each row, its run's number; None for a small batch or
    one with few repeats. The kinematics of a row do not depend on the rows batched with it
    (tests/body/test_body_kinematics.py), so a run's first row gives every row's numbers: a
    held posture is thousands of copies of one frame, posed once."""
    n = len(columns[0])
    if n < REPEAT_MIN_ROWS or any(np.ndim(c) == 0 or len(c) != n for c in columns):
        return None
    same = np.ones(n - 1, dtype=bool)
    for col in columns:
        bits = np.ascontiguousarray(col).reshape(n, -1)
        bits = bits.view(np.int64 if bits.dtype.itemsize == 8 else np.uint8)  # -0.0 is not 0.0
        same &= (bits[1:] == bits[:-1]).all(axis=1)
    if np.count_nonzero(same) < n // 8:
        return None
    head = np.concatenate([[True], ~same])
    return np.flatnonzero(head), np.cumsum(head) - 1


def _forward_flat(
    skel: Skeleton, q: FloatArray, rp: FloatArray, RR: FloatArray, with_axes: bool
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """``forward`` of (n, D) angles, joint-major inside (a joint's or dof's frames are one
    contiguous block, so gathering them is a copy, not a strided walk): each joint's local
    transform for all joints at once, then the joints of one depth placed together (19 joints
    are 7 levels deep)."""
    plan = _plan(skel)
    n = len(q)
    qt = np.concatenate([q.T, np.zeros((1, n))])  # (D + 1, n): a 0 for "no dof"
    coef = _rodrigues_coefficients(qt)
    Rd = (coef @ plan.basis).reshape(-1, n, 3, 3)  # Rodrigues: I + K² + sin·K − cos·K²
    G = Rd[plan.slot_dof]  # (3, J, n, 3, 3): each joint's first, second and third dof
    P2 = G[0] @ G[1]
    W = np.empty((skel.n_joints, n, 4, 4))  # each joint in its parent's frame, then the world
    W[..., :3, :3] = P2 @ G[2]
    W[..., :3, 3] = skel.offsets[:, None]
    W[..., 3, :] = (0.0, 0.0, 0.0, 1.0)
    W[0] = _homogeneous(RR, rp) @ W[0]
    if n <= CHAIN_BATCH:  # a few numpy calls over every joint's path at once
        L = np.concatenate([W, np.broadcast_to(_EYE4, (1, n, 4, 4))])[plan.chains]
        W = L[0]
        for link in L[1:]:
            W = W @ link  # the same products, in the same order, as level by level
    else:  # a large batch: each product once (a path's padding would multiply it)
        for joints, parents in plan.levels:
            W[joints] = W[parents] @ W[joints]
    if not with_axes:
        none = np.empty((n, 0, 3))
        return W[..., :3, :3].transpose(1, 0, 2, 3), W[..., :3, 3].transpose(1, 0, 2), none
    # a dof's axis turns with its parent's frame and the joint's dofs before it
    before = np.concatenate([Rd[-1:], G[0], P2])[plan.prefix]  # (D, n, 3, 3); Rd[-1]: I
    frames = np.concatenate([RR[None], W[..., :3, :3]])[plan.dof_parent] @ before
    axes = np.einsum("dnab,db->dna", frames, skel.dof_axis)
    return (
        W[..., :3, :3].transpose(1, 0, 2, 3), W[..., :3, 3].transpose(1, 0, 2),
        axes.transpose(1, 0, 2),
    )  # fmt: skip


PART_CHUNK = 256  # configurations a chunk of ``forward_part``


def forward_part(
    skel: Skeleton,
    q: ArrayLike,
    root_position: ArrayLike | None,
    root_rotation: ArrayLike | None,
    sites: Sequence[str],
) -> Pose:
    """``forward(skel, q, ...)`` (``with_axes=False``) of only the joints that carry ``sites``
    (site or joint names) and their ancestors; every other joint's frame is NaN. The same
    products in the same order as ``forward``, so the same numbers: a pass that needs a hand's
    or the feet's positions on thousands of frames places 7 or 9 joints, not 21."""
    qa = np.asarray(q, dtype=float)
    if qa.shape[-1] != skel.n_dofs:
        raise ValueError(f"q has {qa.shape[-1]} angles, the skeleton has {skel.n_dofs}")
    batch = qa.shape[:-1]
    rp, RR = _root_inputs(skel, batch, root_position, root_rotation)
    n, nj = math.prod(batch), skel.n_joints
    qf, rpf, RRf = qa.reshape(n, -1), rp.reshape(n, 3), RR.reshape(n, 3, 3)
    runs = repeated_rows(qf, rpf, RRf)
    if runs is not None:  # each run of identical rows posed once (``repeated_rows``)
        heads, at = runs
        one = forward_part(skel, qf[heads], rpf[heads], RRf[heads], sites)
        return Pose(
            R=one.R[at].reshape(*batch, nj, 3, 3), p=one.p[at].reshape(*batch, nj, 3),
            axes=np.empty((*batch, 0, 3)), root=np.array(rp),
        )  # fmt: skip
    part = _part(skel, tuple(sites))
    R, p = np.full((n, nj, 3, 3), np.nan), np.full((n, nj, 3), np.nan)
    for a in range(0, n, PART_CHUNK):
        c = slice(a, a + PART_CHUNK)
        start = _homogeneous(RRf[c], rpf[c])
        R[c, part.joints], p[c, part.joints] = _forward_branch(skel, part, qf[c], start)
    return Pose(
        R=R.reshape(*batch, nj, 3, 3), p=p.reshape(*batch, nj, 3),
        axes=np.empty((*batch, 0, 3)), root=np.array(rp),
    )  # fmt: skip


def part_site_positions(
    skel: Skeleton,
    q: ArrayLike,
    root_position: ArrayLike | None,
    root_rotation: ArrayLike | None,
    sites: Sequence[str],
) -> FloatArray:
    """``site_positions(skel, forward(skel, q, ...), sites)`` (N, S, 3) for (N, D) angles, by
    ``forward_part``'s joints only, chunk by chunk: the same numbers without the whole body's
    frames (what the pace and interpolation passes ask of thousands of frames)."""
    qa = np.asarray(q, dtype=float)
    n = len(qa)
    rp, RR = _root_inputs(skel, (n,), root_position, root_rotation)
    runs = repeated_rows(qa, rp, RR)
    if runs is not None:  # each run of identical rows posed once (``repeated_rows``)
        heads, at = runs
        return part_site_positions(skel, qa[heads], rp[heads], RR[heads], sites)[at]
    part = _part(skel, tuple(sites))
    where = {int(j): k for k, j in enumerate(part.joints)}
    js, offs = _site_lookup(skel, tuple(sites))
    local = [where[j] for j in js]
    out = np.empty((n, len(js), 3))
    for a in range(0, n, PART_CHUNK):
        c = slice(a, a + PART_CHUNK)
        R, p = _forward_branch(skel, part, qa[c], _homogeneous(RR[c], rp[c]))
        out[c] = p[:, local] + np.einsum("...sij,sj->...si", R[:, local], offs)
    return out


def _part(skel: Skeleton, sites: tuple[str, ...]) -> _Branch:
    """The root-down branch of the joints that carry ``sites`` (or are named: a joint's own
    name carries its origin; cached per skeleton)."""
    cache: dict[tuple[str, ...], _Branch] = skel.__dict__.setdefault("_fk_parts", {})
    found = cache.get(sites)
    if found is None:
        carriers = {
            skel.joint_index(name if name in skel.joint_names else skel.site(name).joint)
            for name in sites
        }
        keep = skel.ancestor[list(carriers)].any(axis=0)  # (ancestor[j, k]: k is j or above it)
        found = cache[sites] = _subtree(skel, np.flatnonzero(keep))
    return found


def forward_below(skel: Skeleton, q: ArrayLike, base: Pose, top: int) -> Pose:
    """``forward(skel, q, ...)`` (``with_axes=False``) of configurations ``q`` (n, D) that
    differ from ``base``'s (n rows, the same root) only in the dofs of joint ``top`` and the
    joints below it: those joints placed from their parent's frame in ``base``, every other
    joint copied. The same products in the same order as ``forward``, so the same numbers; an
    arm's solver that moves only the arm pays for three joints, not nineteen."""
    if skel.parent[top] < 0:
        raise ValueError("forward_below needs a joint below the root (the root: forward)")
    qa = np.asarray(q, dtype=float)
    branch = _branch(skel, top)
    n = len(qa)
    R, p = base.R.reshape(n, skel.n_joints, 3, 3).copy(), base.p.reshape(n, -1, 3).copy()
    above = int(skel.parent[top])
    for a in range(0, n, BRANCH_CHUNK):
        c = slice(a, a + BRANCH_CHUNK)
        start = _homogeneous(R[c, above], p[c, above])
        R[c, branch.joints], p[c, branch.joints] = _forward_branch(skel, branch, qa[c], start)
    return Pose(R=R, p=p, axes=np.empty((n, 0, 3)), root=np.array(base.root))


def bits_differ(a: ArrayLike, b: ArrayLike) -> NDArray[np.bool_]:
    """Elementwise whether two float arrays of one shape differ bit for bit (-0.0 is not 0.0):
    which angles a pass changed, where equal-within-rounding would hide a changed last bit."""
    x = np.ascontiguousarray(a, dtype=float).view(np.int64)
    return x != np.ascontiguousarray(b, dtype=float).view(np.int64)


def forward_changed(
    skel: Skeleton,
    q: ArrayLike,
    root_position: ArrayLike | None,
    root_rotation: ArrayLike | None,
    base_q: FloatArray,
    base: Pose,
) -> Pose:
    """``forward(skel, q, root_position, root_rotation, with_axes=False)`` of configurations
    ``q`` (n, D) given ``base``, that call's pose of ``base_q`` (n, D) with the same root: only
    the branches below the topmost joints whose dofs differ (bit for bit) are placed again
    (``forward_below``), so the same numbers. A path smoothed again moves one arm: its trunk
    and legs are not posed a second time."""
    qa = np.asarray(q, dtype=float)
    if len(qa) == 0 or qa.shape != np.shape(base_q):
        return forward(skel, qa, root_position, root_rotation, with_axes=False)
    bits = bits_differ(qa, base_q)
    joints = np.unique(skel.dof_joint[np.flatnonzero(bits.any(axis=0))])
    # a changed joint with no changed joint above it (ancestor[j, k]: k is j or above it)
    tops = joints[skel.ancestor[np.ix_(joints, joints)].sum(axis=1) == 1].tolist()
    if any(skel.parent[top] < 0 for top in tops):  # the root's own dofs: every joint moves
        return forward(skel, qa, root_position, root_rotation, with_axes=False)
    pose = base
    for top in tops:
        pose = forward_below(skel, qa, pose, top)
    return pose


def forward_rows_changed(
    skel: Skeleton,
    before: Pose,
    q0: FloatArray,
    root0: FloatArray,
    q: FloatArray,
    root: FloatArray,
    rot: FloatArray,
    rot0: FloatArray | None = None,
) -> Pose:
    """``forward(skel, q, root, rot, with_axes=False)`` given ``before``, that call's pose of
    ``q0`` and ``root0`` (and ``rot0``, if not ``rot``), row by row: a row that did not change
    is ``before``'s; a row whose root stayed has only the branches below its topmost changed
    joints placed again (``forward_below``: the same numbers), rows grouped by those joints;
    the others are posed whole. ``forward_changed`` is the same for rows that all keep their
    root and change the same joints. A long walk's blend changes one swinging leg of most
    frames (4 joints of 21) and nothing of a fifth of them, and a pass after it changes few."""
    n = len(q)
    R, p = before.R.copy(), before.p.copy()
    moved = bits_differ(root, root0).any(axis=1)
    if rot0 is not None:
        moved |= bits_differ(rot, rot0).reshape(n, -1).any(axis=1)
    changed = np.zeros((n, skel.n_joints), dtype=bool)  # (row, joint) a dof of it changed
    for d in np.flatnonzero(bits_differ(q, q0).any(axis=0)):
        changed[:, skel.dof_joint[d]] |= bits_differ(q[:, d], q0[:, d])
    # a changed joint with no changed joint above it (ancestor[j, k]: k is j or above it)
    tops = changed & (changed.astype(np.int64) @ skel.ancestor.T.astype(np.int64) == 1)
    whole = moved | tops[:, skel.parent < 0].any(axis=1)
    tops[whole] = False
    code = tops @ (1 << np.arange(skel.n_joints, dtype=np.int64))  # the set of tops, a number
    order = np.argsort(code, kind="stable")
    edges = np.flatnonzero(np.diff(code[order])) + 1
    for rows in np.split(order, edges):
        if rows.size == 0 or code[rows[0]] == 0:  # nothing changed, or posed whole below
            continue
        part = Pose(R=R[rows], p=p[rows], axes=before.axes[rows], root=before.root[rows])
        for top in np.flatnonzero(tops[rows[0]]):
            part = forward_below(skel, q[rows], part, int(top))
        R[rows], p[rows] = part.R, part.p
    rows = np.flatnonzero(whole)
    if rows.size:
        part = forward(skel, q[rows], root[rows], rot[rows], with_axes=False)
        R[rows], p[rows] = part.R, part.p
    return Pose(R=R, p=p, axes=before.axes, root=np.array(root, dtype=float))


def dof_world_axes(skel: Skeleton, pose: Pose, q: ArrayLike, dofs: Sequence[int]) -> FloatArray:
    """World axes (n, len(dofs), 3) of ``dofs`` at configurations ``q`` (n, D) posed as
    ``pose`` (which may lack ``axes``: ``forward_below``'s): a dof's axis turned by its joint's
    dofs before it (the nearest first), then by the parent joint's frame, as ``forward`` turns
    it. What an analytic Jacobian of a few dofs needs without a whole-body
    ``forward(with_axes=True)``."""
    qa = np.asarray(q, dtype=float)
    local, parents, turns = _axes_plan(skel, tuple(int(k) for k in dofs))
    v = np.array(np.broadcast_to(local, (len(qa), len(local), 3)))
    for sel, prev, axis in turns:
        angle = qa[:, prev, None]
        v[:, sel] = rotate_about(_ORIGIN, axis, v[:, sel], np.cos(angle), np.sin(angle))
    return np.einsum("nkab,nkb->nka", pose.R[:, parents], v)


def _axes_plan(
    skel: Skeleton, dofs: tuple[int, ...]
) -> tuple[
    FloatArray, NDArray[np.intp], list[tuple[NDArray[np.intp], NDArray[np.intp], FloatArray]]
]:
    """``dof_world_axes``' look-ups, once per skeleton and dofs: the dofs' own axes, their
    joints' parents, and per turn back (1, 2) the dofs turned, by which dof, about which axis."""
    cache: dict[tuple[int, ...], tuple] = skel.__dict__.setdefault("_axes_plans", {})
    found = cache.get(dofs)
    if found is None:
        ks = np.asarray(dofs, dtype=np.intp)
        joints = skel.dof_joint[ks]
        if np.any(skel.parent[joints] < 0):
            raise ValueError(
                "dof_world_axes: the root joint's dofs turn with the root, not a parent"
            )
        slot = ks - skel.joint_dof_start[joints]
        turns = []
        for back in range(1, int(slot.max(initial=0)) + 1):
            sel = np.flatnonzero(slot >= back)
            turns.append((sel, ks[sel] - back, skel.dof_axis[ks[sel] - back]))
        found = cache[dofs] = (skel.dof_axis[ks], skel.parent[joints], turns)
    return found


@dataclass(frozen=True)
class _Branch:
    """A joint and the joints below it, in depth order: their dofs, each joint's first,
    second and third dof among them (``len(dofs)``: none) and its parent among them (-1: the
    branch's fixed parent)."""

    joints: NDArray[np.intp]
    dofs: NDArray[np.intp]
    slot: NDArray[np.intp]  # (3, B)
    parent: NDArray[np.intp]  # (B,)


def _branch(skel: Skeleton, top: int) -> _Branch:
    cache: dict[int, _Branch] = skel.__dict__.setdefault("_fk_branches", {})
    found = cache.get(top)
    if found is None:
        found = cache[top] = _subtree(skel, np.flatnonzero(skel.ancestor[:, top]))
    return found


def _subtree(skel: Skeleton, joints: NDArray[np.intp]) -> _Branch:
    """The ``_Branch`` of a set of joints closed downward from one joint (a branch) or upward
    to the root (``_part``): a joint's parent is among them or is the branch's fixed start."""
    plan = _plan(skel)
    depth = [int(skel.ancestor[j].sum()) for j in joints]
    joints = joints[np.argsort(depth, kind="stable")]
    dofs = np.concatenate([np.flatnonzero(skel.dof_joint == j) for j in joints]).astype(np.intp)
    local = {int(d): k for k, d in enumerate(dofs)}
    slot = np.array(
        [[local.get(int(plan.slot_dof[s, j]), len(dofs)) for j in joints] for s in range(3)],
        dtype=np.intp,
    )
    where = {int(j): k for k, j in enumerate(joints)}
    parent = np.array([where.get(int(skel.parent[j]), -1) for j in joints], dtype=np.intp)
    return _Branch(joints, dofs, slot, parent)


def _forward_branch(
    skel: Skeleton, branch: _Branch, q: FloatArray, start: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """World rotations (n, B, 3, 3) and positions (n, B, 3) of a branch's joints from the
    world frame ``start`` (n, 4, 4) of its parent: ``_forward_flat``'s arithmetic on the
    branch's joints alone."""
    plan = _plan(skel)
    n = len(q)
    qt = np.concatenate([q[:, branch.dofs].T, np.zeros((1, n))])
    coef = _rodrigues_coefficients(qt)
    basis = plan.basis[np.append(branch.dofs, skel.n_dofs)]
    Rd = (coef @ basis).reshape(-1, n, 3, 3)
    G = Rd[branch.slot]
    W = np.empty((len(branch.joints), n, 4, 4))
    W[..., :3, :3] = (G[0] @ G[1]) @ G[2]
    W[..., :3, 3] = skel.offsets[branch.joints][:, None]
    W[..., 3, :] = (0.0, 0.0, 0.0, 1.0)
    for k, up in enumerate(branch.parent):
        W[k] = (W[up] if up >= 0 else start) @ W[k]
    return W[..., :3, :3].transpose(1, 0, 2, 3), W[..., :3, 3].transpose(1, 0, 2)


def _rodrigues_coefficients(angles: FloatArray) -> FloatArray:
    """(..., 3): 1, sin and −cos of each angle, the weights of a dof's I + K², K and K² (filled
    in place: ``np.stack`` of the three was a sixth of a one-frame forward kinematics)."""
    out = np.empty((*angles.shape, 3))
    out[..., 0] = 1.0
    out[..., 1] = np.sin(angles)
    out[..., 2] = -np.cos(angles)
    return out


def site_positions(skel: Skeleton, pose: Pose, names: Sequence[str] | str) -> FloatArray:
    """World positions (..., S, 3) of named sites (or (..., 3) for one name)."""
    single = isinstance(names, str)
    js, offs = _site_lookup(skel, (names,) if isinstance(names, str) else tuple(names))
    out = pose.p[..., js, :] + np.einsum("...sij,sj->...si", pose.R[..., js, :, :], offs)
    return out[..., 0, :] if single else out


def _site_lookup(skel: Skeleton, names: tuple[str, ...]) -> tuple[list[int], FloatArray]:
    """The sites' joints and offsets, looked up once per skeleton (solvers ask for the same
    sites thousands of times; the look-up was a fifth of a small batch's cost)."""
    cache: dict[tuple[str, ...], tuple[list[int], FloatArray]]
    cache = skel.__dict__.setdefault("_site_lookup", {})
    found = cache.get(names)
    if found is None:
        js = [skel.joint_index(skel.site(n).joint) for n in names]
        found = cache[names] = (js, np.array([skel.site(n).offset for n in names], dtype=float))
    return found


def site_rotation(skel: Skeleton, pose: Pose, name: str) -> FloatArray:
    """World orientation (..., 3, 3) of the frame a site is fixed in."""
    return pose.R[..., skel.joint_index(skel.site(name).joint), :, :]


def site_direction(skel: Skeleton, pose: Pose, name: str) -> FloatArray:
    """World direction (..., 3) of an aiming site (e.g. the gaze)."""
    st = skel.site(name)
    if st.direction is None:
        raise ValueError(f"site {name} has no direction")
    return site_rotation(skel, pose, name) @ np.asarray(st.direction, dtype=float)


def point_jacobian(
    skel: Skeleton,
    pose: Pose,
    joint: int,
    point: FloatArray,
    *,
    orientation: bool = False,
    root: bool = False,
) -> FloatArray:
    """Jacobian (..., 3|6, D[+6]) of a world point rigidly attached to ``joint``.

    Columns of dofs that do not move the joint are zero.
    """
    mask = skel.ancestor[joint][skel.dof_joint]  # (D,)
    origins = pose.p[..., skel.dof_joint, :]
    Jp = cross(pose.axes, point[..., None, :] - origins) * mask[:, None]
    Jp = np.swapaxes(Jp, -1, -2)
    blocks = [Jp]
    if orientation:
        blocks = [np.concatenate([Jp, np.swapaxes(pose.axes * mask[:, None], -1, -2)], axis=-2)]
    J = blocks[0]
    if root:
        batch = pose.batch_shape
        rows = J.shape[-2]
        Jr = np.zeros((*batch, rows, 6))
        Jr[..., :3, :3] = np.eye(3)
        Jr[..., :3, 3:] = -_skew_batch(point - pose.root)
        if orientation:
            Jr[..., 3:, 3:] = np.eye(3)
        J = np.concatenate([J, Jr], axis=-1)
    return J


def _skew_batch(v: FloatArray) -> FloatArray:
    return skew(v)


def jacobian(
    skel: Skeleton,
    pose: Pose,
    site: str,
    *,
    orientation: bool = False,
    root: bool = False,
) -> FloatArray:
    """Jacobian (..., 3 or 6, n_dofs [+6]) of a site: position rows, then orientation rows."""
    j = skel.joint_index(skel.site(site).joint)
    pt = site_positions(skel, pose, site)
    return point_jacobian(skel, pose, j, pt, orientation=orientation, root=root)


def segment_coms(skel: Skeleton, pose: Pose) -> FloatArray:
    """World centre of mass (..., J, 3) of every segment."""
    return pose.p + np.einsum("...jab,jb->...ja", pose.R, skel.coms)


def center_of_mass(skel: Skeleton, pose: Pose) -> FloatArray:
    """Whole-body centre of mass (..., 3): the mass-weighted mean of the segment centres."""
    c = segment_coms(skel, pose)
    return np.einsum("j,...ja->...a", skel.masses, c) / skel.total_mass


def com_jacobian(
    skel: Skeleton, pose: Pose, *, root: bool = False, dofs: NDArray[np.intp] | None = None
) -> FloatArray:
    """Jacobian (..., 3, n_dofs [+6]) of the whole-body centre of mass.

    Column k is ``a_k × (Σ_{j below k} m_j c_j − M_k o_k) / M``, with M_k the mass carried by
    the dof's joint and everything below it. ``dofs``: only those columns (..., 3, len(dofs)),
    the same numbers as theirs in the whole Jacobian (the balance pass's trunk lean reads 4 of
    37 columns on thousands of frames); not with ``root``.
    """
    c = segment_coms(skel, pose)
    M = skel.total_mass
    # below[k, j]: segment j moves with dof k (the dof's joint is j or an ancestor of j).
    below = skel.ancestor[:, skel.dof_joint].T  # (D, J)
    mk = below.astype(float) @ skel.masses  # (D,)
    axes, joints = pose.axes, skel.dof_joint
    if dofs is not None:
        if root:
            raise ValueError("com_jacobian: dofs or root, not both")
        below, mk, axes, joints = below[dofs], mk[dofs], axes[..., dofs, :], joints[dofs]
    mc = np.einsum("kj,j,...ja->...ka", below, skel.masses, c)
    origins = pose.p[..., joints, :]
    cols = cross(axes, mc - mk[:, None] * origins) / M
    J = np.swapaxes(cols, -1, -2)
    if root:
        com = center_of_mass(skel, pose)
        batch = pose.batch_shape
        Jr = np.zeros((*batch, 3, 6))
        Jr[..., :3, :3] = np.eye(3)
        Jr[..., :3, 3:] = -skew(com - pose.root)
        J = np.concatenate([J, Jr], axis=-1)
    return J
