"""``forward`` (joints grouped by depth, chunked batches) against the plain per-joint rule of
IR.md, ``W_j = W_parent · T(offset_j) · R(a_1, q_1) · R(a_2, q_2) · …``, written out here."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from mtlc.body import build_manikin
from mtlc.body.kinematics import FK_CHUNK, axis_angle, forward, quat_to_matrix


def reference(skel, q, root_position, root_quat):  # type: ignore[no-untyped-def]
    """One configuration, one joint and one dof at a time."""
    R = np.empty((skel.n_joints, 3, 3))
    p = np.empty((skel.n_joints, 3))
    axes = np.empty((skel.n_dofs, 3))
    for j in range(skel.n_joints):
        parent = int(skel.parent[j])
        if parent < 0:
            Rw = quat_to_matrix(root_quat)
            pw = root_position + Rw @ skel.offsets[j]
        else:
            Rw, pw = R[parent], p[parent] + R[parent] @ skel.offsets[j]
        start = int(skel.joint_dof_start[j])
        for k in range(start, start + int(skel.joint_dof_count[j])):
            axes[k] = Rw @ skel.dof_axis[k]
            Rw = Rw @ axis_angle(skel.dof_axis[k], q[k])
        R[j], p[j] = Rw, pw
    return R, p, axes


@settings(max_examples=25, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    n=st.sampled_from([1, 2, FK_CHUNK - 1, FK_CHUNK, FK_CHUNK + 1, 2 * FK_CHUNK + 5]),
    sex=st.sampled_from(["male", "female"]),
)
def test_forward_matches_the_per_joint_rule(seed: int, n: int, sex: str) -> None:
    skel = build_manikin("gb10000_1988", sex, 50)
    rng = np.random.default_rng(seed)
    q = skel.random_q(rng, n)
    rp = rng.normal(size=(n, 3))
    rq = rng.normal(size=(n, 4))
    pose = forward(skel, q, rp, rq)
    for i in range(n):
        R, p, axes = reference(skel, q[i], rp[i], rq[i])
        np.testing.assert_allclose(pose.R[i], R, atol=1e-12)
        np.testing.assert_allclose(pose.p[i], p, atol=1e-12)
        np.testing.assert_allclose(pose.axes[i], axes, atol=1e-12)


def test_forward_keeps_the_batch_shape() -> None:
    skel = build_manikin("gb10000_1988", "male", 50)
    q = skel.random_q(np.random.default_rng(1), 3 * 70).reshape(3, 70, -1)
    pose = forward(skel, q)
    assert pose.R.shape == (3, 70, skel.n_joints, 3, 3)
    assert pose.axes.shape == (3, 70, skel.n_dofs, 3)
    single = forward(skel, q[2, 69])
    assert single.p.shape == (skel.n_joints, 3)
    np.testing.assert_allclose(single.p, pose.p[2, 69], atol=1e-15)
