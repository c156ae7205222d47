"""Kinematics against independent computation: hand-computed poses, finite differences."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mtlc.body import (
    build_manikin,
    center_of_mass,
    com_jacobian,
    forward,
    jacobian,
    matrix_to_quat,
    quat_to_matrix,
    rotation_error,
    site_positions,
    site_rotation,
)
from mtlc.body.capsules import clearance, limbs_of_sides, measured_points, self_intersection
from mtlc.body.kinematics import (
    axis_angle,
    cross,
    forward_below,
    forward_changed,
    forward_part,
    part_site_positions,
    rotate_about,
)

SK = build_manikin("gb10000_1988", "male", 50)


def _q(**angles: float) -> np.ndarray:
    q = np.zeros(SK.n_dofs)
    for k, v in angles.items():
        q[SK.dof_index(k)] = v
    return q


def _p(pose, joint: str) -> np.ndarray:  # type: ignore[no-untyped-def]
    return pose.p[..., SK.joint_index(joint), :]


def test_elbow_flexion_brings_the_wrist_forward() -> None:
    pose = forward(SK, _q(r_elbow_flex=math.pi / 2))
    fore = SK.dims.elbow_height - SK.dims.wrist_height
    np.testing.assert_allclose(_p(pose, "r_wrist") - _p(pose, "r_elbow"), [0, 0, fore], atol=1e-12)
    # The left arm is untouched.
    np.testing.assert_allclose(_p(pose, "l_wrist")[1], SK.dims.wrist_height, atol=1e-12)


def test_shoulder_flexion_and_abduction_raise_the_arm() -> None:
    up = forward(SK, _q(r_shoulder_flex=math.pi))
    d = _p(up, "r_elbow") - _p(up, "r_shoulder")
    np.testing.assert_allclose(d / np.linalg.norm(d), [0, 1, 0], atol=1e-12)
    side = forward(SK, _q(r_shoulder_abd=math.pi / 2, l_shoulder_abd=math.pi / 2))
    dr = _p(side, "r_elbow") - _p(side, "r_shoulder")
    dl = _p(side, "l_elbow") - _p(side, "l_shoulder")
    np.testing.assert_allclose(dr / np.linalg.norm(dr), [-1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(dl / np.linalg.norm(dl), [1, 0, 0], atol=1e-12)


def test_hip_flexion_knee_flexion_and_dorsiflexion_signs() -> None:
    pose = forward(SK, _q(r_hip_flex=math.pi / 2, r_knee_flex=math.pi / 2))
    thigh = SK.dims.hip_height - SK.dims.knee_height
    np.testing.assert_allclose(_p(pose, "r_knee") - _p(pose, "r_hip"), [0, 0, thigh], atol=1e-12)
    shank = _p(pose, "r_ankle") - _p(pose, "r_knee")
    np.testing.assert_allclose(shank / np.linalg.norm(shank), [0, -1, 0], atol=1e-12)
    toe = forward(SK, _q(r_ankle_dorsi=0.3))
    assert site_positions(SK, toe, "r_toe")[1] > 0.05  # toes lift


def test_pronation_turns_the_right_palm_backwards() -> None:
    pose = forward(SK, _q(r_elbow_pro=math.pi / 2))
    palm = site_rotation(SK, pose, "r_hand") @ np.array([1.0, 0, 0])  # palm normal: medial
    np.testing.assert_allclose(palm, [0, 0, -1], atol=1e-12)


def test_spine_signs_and_root_transform() -> None:
    bent = forward(SK, _q(lumbar_flex=0.5))
    assert site_positions(SK, bent, "vertex")[2] > 0.2  # bends forward (+Z)
    turned = forward(SK, _q(neck_rot=math.pi / 2))
    g = site_positions(SK, turned, "gaze") - _p(turned, "head")
    assert g[0] > 0.05  # looks to the left (+X)
    # Root: 90 degrees about Y maps +Z (forward) to +X.
    quat = [math.cos(math.pi / 4), 0, math.sin(math.pi / 4), 0]
    rp = np.array([1.0, 0.9, 2.0])
    a = forward(SK, np.zeros(SK.n_dofs))
    b = forward(SK, np.zeros(SK.n_dofs), rp, quat)
    Ry = quat_to_matrix(quat)
    want = rp + (a.p - a.root) @ Ry.T
    np.testing.assert_allclose(b.p, want, atol=1e-12)


def test_batch_matches_single_calls_in_any_shape() -> None:
    rng = np.random.default_rng(0)
    q = SK.random_q(rng, 6).reshape(2, 3, SK.n_dofs)
    rp = rng.normal(size=(2, 3, 3))
    batched = forward(SK, q, rp)
    for i in range(2):
        for j in range(3):
            one = forward(SK, q[i, j], rp[i, j])
            np.testing.assert_allclose(batched.p[i, j], one.p, atol=1e-13)
            np.testing.assert_allclose(batched.R[i, j], one.R, atol=1e-13)


def _fd_jacobian(
    site: str, q: np.ndarray, rp: np.ndarray, quat: np.ndarray, h: float = 1e-6
) -> np.ndarray:
    """Central differences of position and orientation, incl. root translation/rotation."""
    n = SK.n_dofs
    cols = []
    for k in range(n + 6):
        dq = np.zeros(n)
        dp = np.zeros(3)
        dR = np.eye(3)
        out = []
        for sgn in (1.0, -1.0):
            qq, pp, RR = q.copy(), rp.copy(), quat_to_matrix(quat)
            if k < n:
                qq[k] += sgn * h
            elif k < n + 3:
                pp[k - n] += sgn * h
            else:
                ax = np.eye(3)[k - n - 3]
                RR = axis_angle(ax, sgn * h) @ RR
            pose = forward(SK, qq, pp, RR)
            out.append((site_positions(SK, pose, site), site_rotation(SK, pose, site)))
        del dq, dp, dR
        dpos = (out[0][0] - out[1][0]) / (2 * h)
        drot = rotation_error(out[0][1], out[1][1]) / (2 * h)
        cols.append(np.concatenate([dpos, drot]))
    return np.stack(cols, axis=-1)


@pytest.mark.parametrize("site", ["r_hand", "l_hand", "r_foot", "l_toe", "gaze", "r_ball_lat"])
def test_every_jacobian_column_matches_finite_differences(site: str) -> None:
    rng = np.random.default_rng(11)
    q = SK.random_q(rng, 1)[0]
    rp = np.array([0.1, 0.95, -0.3])
    quat = np.array([0.8, 0.2, 0.4, -0.1])
    quat /= np.linalg.norm(quat)
    pose = forward(SK, q, rp, quat)
    J = jacobian(SK, pose, site, orientation=True, root=True)
    assert J.shape == (6, SK.n_dofs + 6)
    np.testing.assert_allclose(J, _fd_jacobian(site, q, rp, quat), atol=1e-7)
    # Position-only Jacobian is the top block.
    np.testing.assert_allclose(jacobian(SK, pose, site), J[:3, : SK.n_dofs], atol=0)


def test_batched_jacobian_equals_per_item() -> None:
    rng = np.random.default_rng(5)
    q = SK.random_q(rng, 4)
    Jb = jacobian(SK, forward(SK, q), "l_hand", orientation=True)
    for i in range(4):
        np.testing.assert_allclose(
            Jb[i], jacobian(SK, forward(SK, q[i]), "l_hand", orientation=True), atol=1e-14
        )


def test_center_of_mass_is_the_weighted_sum_of_segment_centres() -> None:
    rng = np.random.default_rng(9)
    q = SK.random_q(rng, 3)
    pose = forward(SK, q)
    got = center_of_mass(SK, pose)
    for b in range(3):
        acc = np.zeros(3)
        for j, joint in enumerate(SK.joints):
            acc += joint.mass * (pose.p[b, j] + pose.R[b, j] @ np.array(joint.com))
        np.testing.assert_allclose(got[b], acc / sum(jt.mass for jt in SK.joints), atol=1e-13)


def test_com_jacobian_matches_finite_differences() -> None:
    rng = np.random.default_rng(2)
    q = SK.random_q(rng, 1)[0]
    rp = np.array([0.0, 0.9, 0.1])
    quat = np.array([0.9, -0.1, 0.3, 0.2])
    quat /= np.linalg.norm(quat)
    J = com_jacobian(SK, forward(SK, q, rp, quat), root=True)
    h = 1e-6
    fd = np.zeros_like(J)
    for k in range(SK.n_dofs + 6):
        vals = []
        for sgn in (1.0, -1.0):
            qq, pp, RR = q.copy(), rp.copy(), quat_to_matrix(quat)
            if k < SK.n_dofs:
                qq[k] += sgn * h
            elif k < SK.n_dofs + 3:
                pp[k - SK.n_dofs] += sgn * h
            else:
                RR = axis_angle(np.eye(3)[k - SK.n_dofs - 3], sgn * h) @ RR
            vals.append(center_of_mass(SK, forward(SK, qq, pp, RR)))
        fd[:, k] = (vals[0] - vals[1]) / (2 * h)
    np.testing.assert_allclose(J, fd, atol=1e-8)


def test_quaternion_round_trip_and_rotation_error() -> None:
    rng = np.random.default_rng(4)
    quats = rng.normal(size=(50, 4))
    quats /= np.linalg.norm(quats, axis=1, keepdims=True)
    quats *= np.sign(quats[:, :1])
    np.testing.assert_allclose(matrix_to_quat(quat_to_matrix(quats)), quats, atol=1e-12)
    axes = rng.normal(size=(50, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    ang = rng.uniform(0, math.pi - 1e-3, 50)
    R0 = quat_to_matrix(quats)
    R1 = axis_angle(axes, ang) @ R0
    np.testing.assert_allclose(rotation_error(R1, R0), axes * ang[:, None], atol=1e-9)
    flip = rotation_error(axis_angle(np.array([0, 0, 1.0]), math.pi), np.eye(3))
    np.testing.assert_allclose(np.abs(flip), [0, 0, math.pi], atol=1e-9)


@settings(max_examples=40, deadline=None)
@given(
    lead_a=st.lists(st.integers(1, 4), max_size=3),
    broadcast=st.lists(st.booleans(), min_size=3, max_size=3),
    seed=st.integers(0, 2**31 - 1),
)
def test_cross_is_numpys_cross_to_the_bit(
    lead_a: list[int], broadcast: list[bool], seed: int
) -> None:
    """``cross`` replaces ``np.cross`` in the Jacobians: same values, bit for bit, under
    broadcasting (a dimension of 1 on either side)."""
    rng = np.random.default_rng(seed)
    lead_b = [1 if flat else n for n, flat in zip(lead_a, broadcast, strict=False)]
    a = rng.normal(size=(*lead_a, 3))
    b = rng.normal(size=(*lead_b, 3))
    assert np.array_equal(cross(a, b), np.cross(a, b))
    assert np.array_equal(cross(b, a), np.cross(b, a))


@settings(max_examples=40, deadline=None)
@given(
    rows=st.integers(1, 120),
    joint=st.sampled_from(["r_shoulder", "l_shoulder", "r_elbow", "l_wrist", "r_hip", "neck"]),
    seed=st.integers(0, 2**31 - 1),
)
def test_forward_below_is_whole_body_forward_to_the_bit(rows: int, joint: str, seed: int) -> None:
    """The clearance LM poses only the arm (``forward_below``) from the body's pose at its
    start: every joint, moved or not, equals whole-body forward kinematics of the new angles,
    bit for bit, whatever the batch (the level-by-level and the chain-wise products)."""
    rng = np.random.default_rng(seed)
    top = SK.joint_index(joint)
    moving = np.flatnonzero(SK.ancestor[SK.dof_joint, top])
    q = rng.uniform(SK.lower, SK.upper, size=(rows, SK.n_dofs))
    root = rng.normal(size=(rows, 3)), rng.normal(size=(rows, 4))
    base = forward(SK, q, *root, with_axes=False)
    q[:, moving] = rng.uniform(SK.lower[moving], SK.upper[moving], size=(rows, moving.size))
    whole = forward(SK, q, *root, with_axes=False)
    branch = forward_below(SK, q, base, top)
    assert np.array_equal(branch.p, whole.p)
    assert np.array_equal(branch.R, whole.R)
    assert not np.array_equal(branch.R[:, top], base.R[:, top])  # the branch did move


@settings(max_examples=25, deadline=None)
@given(
    rows=st.integers(1, 300),
    sides=st.sampled_from(["r", "l", "rl"]),
    seed=st.integers(0, 2**31 - 1),
)
def test_clearance_of_the_measured_points_is_the_whole_bodys_to_the_bit(
    rows: int, sides: str, seed: int
) -> None:
    """The pace and clearance passes pose only ``measured_points`` (``forward_part``): the
    depths ``self_intersection`` and ``clearance`` read from that pose are the whole body's."""
    rng = np.random.default_rng(seed)
    q = rng.uniform(SK.lower, SK.upper, size=(rows, SK.n_dofs))
    root = rng.normal(size=(rows, 3)), rng.normal(size=(rows, 4))
    limbs = limbs_of_sides(set(sides))
    whole = forward(SK, q, *root, with_axes=False)
    part = forward_part(SK, q, *root, measured_points(SK, limbs))
    assert np.isnan(part.p).any()  # some joints were left out
    assert np.array_equal(
        self_intersection(SK, part, limbs)[0], self_intersection(SK, whole, limbs)[0]
    )
    assert np.array_equal(clearance(SK, part, limbs), clearance(SK, whole, limbs))


@settings(max_examples=25, deadline=None)
@given(
    rows=st.integers(1, 300),
    joints=st.sampled_from(
        [[], ["r_elbow"], ["r_shoulder", "r_wrist"], ["l_shoulder", "r_elbow"], ["neck", "r_hip"],
         ["lumbar", "r_wrist"], ["l_knee", "l_ankle"]]
    ),
    seed=st.integers(0, 2**31 - 1),
)  # fmt: skip
def test_forward_changed_is_whole_body_forward_to_the_bit(
    rows: int, joints: list[str], seed: int
) -> None:
    """The pace pass poses a path smoothed again from the pose of the path before
    (``forward_changed``: the branches below the joints whose angles changed): every joint
    equals whole-body forward kinematics of the new angles, bit for bit."""
    rng = np.random.default_rng(seed)
    q = rng.uniform(SK.lower, SK.upper, size=(rows, SK.n_dofs))
    root = rng.normal(size=(rows, 3)), rng.normal(size=(rows, 4))
    base = forward(SK, q, *root, with_axes=False)
    new = q.copy()
    for name in joints:
        dofs = np.flatnonzero(SK.dof_joint == SK.joint_index(name))
        new[:, dofs] = rng.uniform(SK.lower[dofs], SK.upper[dofs], size=(rows, dofs.size))
    whole = forward(SK, new, *root, with_axes=False)
    changed = forward_changed(SK, new, *root, q, base)
    assert np.array_equal(changed.p, whole.p)
    assert np.array_equal(changed.R, whole.R)
    assert np.array_equal(changed.R, base.R) == (not joints)


@settings(max_examples=60)
@given(
    rows=st.integers(1, 600),
    sites=st.sampled_from(
        [["r_hand"], ["l_fingertip", "r_hand"], ["r_heel", "l_toe", "r_ball_lat"], ["gaze"]]
    ),
    seed=st.integers(0, 2**31 - 1),
)
def test_forward_part_is_whole_body_forward_to_the_bit(
    rows: int, sites: list[str], seed: int
) -> None:
    """The pace, interpolation and balance passes pose only the chains that carry the sites
    they measure (``forward_part``, ``part_site_positions``): the same numbers, bit for bit, as
    the whole body's pose, whatever the batch; the joints not on those chains are NaN."""
    rng = np.random.default_rng(seed)
    q = rng.uniform(SK.lower, SK.upper, size=(rows, SK.n_dofs))
    root = rng.normal(size=(rows, 3)), rng.normal(size=(rows, 4))
    whole = forward(SK, q, *root, with_axes=False)
    part = forward_part(SK, q, *root, sites)
    assert np.array_equal(site_positions(SK, part, sites), site_positions(SK, whole, sites))
    assert np.array_equal(
        part_site_positions(SK, q, *root, sites), site_positions(SK, whole, sites)
    )
    carried = SK.ancestor[[SK.joint_index(SK.site(n).joint) for n in sites]].any(axis=0)
    assert np.array_equal(part.R[:, carried], whole.R[:, carried])
    assert np.isnan(part.p[:, ~carried]).all()


def test_forward_below_refuses_the_root() -> None:
    base = forward(SK, np.zeros(SK.n_dofs), with_axes=False)
    with pytest.raises(ValueError, match="below the root"):
        forward_below(SK, np.zeros((1, SK.n_dofs)), base, 0)


def test_rotate_about_is_the_axis_angle_matrix_on_a_point() -> None:
    """The vector Rodrigues (balance's fingertip heights, the clearance swivel's elbow) turns a
    point as ``axis_angle``'s matrix does, angles broadcast against points."""
    rng = np.random.default_rng(3)
    axis = rng.normal(size=(20, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    origin, v = rng.normal(size=(20, 3)), rng.normal(size=(20, 3))
    angles = np.array([-2.5, -0.3, 0.0, 1.0, math.pi])
    turned = rotate_about(
        origin[:, None], axis[:, None], v[:, None], np.cos(angles)[:, None], np.sin(angles)[:, None]
    )
    R = axis_angle(axis[:, None], angles[None, :])  # (20, 5, 3, 3)
    expected = origin[:, None] + np.einsum("rnab,rb->rna", R, v)
    np.testing.assert_allclose(turned, expected, atol=1e-12)
    np.testing.assert_array_equal(turned[:, 2], origin + v)  # no turn: the point itself


def test_com_jacobian_of_some_dofs_is_their_columns_of_the_whole_to_the_bit() -> None:
    """``com_jacobian(..., dofs=...)`` (the balance pass's trunk lean asks for 4 columns):
    the same numbers as those columns of the whole Jacobian, for one pose and for batches."""
    rng = np.random.default_rng(3)
    for sk in (SK, build_manikin("gb10000_1988", "male", 95)):
        dofs = np.asarray([sk.dof_index(n) for n in ("lumbar_flex", "lumbar_lat", "thorax_flex",
                                                       "thorax_lat", "r_knee_flex")])  # fmt: skip
        for n in (1, 9, 400):
            pose = forward(sk, sk.random_q(rng, n), rng.normal(0.0, 1.0, (n, 3)))
            assert np.array_equal(
                com_jacobian(sk, pose, dofs=dofs), com_jacobian(sk, pose)[..., dofs]
            )
    with pytest.raises(ValueError):
        com_jacobian(SK, forward(SK, SK.q_comfort), root=True, dofs=dofs)


@settings(max_examples=40)
@given(
    runs=st.lists(st.integers(1, 40), min_size=1, max_size=30),
    with_axes=st.booleans(),
    seed=st.integers(0, 2**31 - 1),
)
def test_repeated_rows_are_posed_once_to_the_bit(
    runs: list[int], with_axes: bool, seed: int
) -> None:
    """A batch with runs of identical rows (a hold) is posed once per run (``repeated_rows``):
    every output, whole body, part and sites, is bit for bit what posing every row gives, a
    -0.0 angle kept apart from a 0.0."""
    import mtlc.body.kinematics as kin

    rng = np.random.default_rng(seed)
    q = rng.uniform(SK.lower, SK.upper, size=(len(runs), SK.n_dofs))
    q[rng.random(len(runs)) < 0.3, 0] = 0.0
    q[rng.random(len(runs)) < 0.3, 0] = -0.0
    root = rng.normal(size=(len(runs), 3)), rng.normal(size=(len(runs), 4))
    at = np.repeat(np.arange(len(runs)), runs)
    q, root = q[at], (root[0][at], root[1][at])
    sites = ["r_hand", "l_toe"]

    def every(q: np.ndarray, root: tuple[np.ndarray, np.ndarray]) -> list[np.ndarray]:
        pose = forward(SK, q, *root, with_axes=with_axes)
        part = forward_part(SK, q, *root, sites)
        return [pose.R, pose.p, pose.axes, part.R, part.p,
                part_site_positions(SK, q, *root, sites)]  # fmt: skip

    got = every(q, root)
    saved = kin.REPEAT_MIN_ROWS
    kin.REPEAT_MIN_ROWS = 10**9  # every row posed
    try:
        want = every(q, root)
    finally:
        kin.REPEAT_MIN_ROWS = saved
    for a, b in zip(got, want, strict=True):
        assert a.shape == b.shape and a.tobytes() == b.tobytes()
    found = kin.repeated_rows(q, *root)
    if len(q) >= kin.REPEAT_MIN_ROWS and found is not None:
        heads, which = found
        assert np.array_equal(q[heads][which], q) and len(heads) < len(q)


def test_repeated_rows_tells_minus_zero_and_nan_apart() -> None:
    from mtlc.body.kinematics import repeated_rows

    a = np.zeros((200, 2))
    a[100:, 1] = -0.0
    a[150:, 0] = np.nan
    heads, at = repeated_rows(a)  # type: ignore[misc]
    assert heads.tolist() == [0, 100, 150] and at[99] == 0 and at[100] == 1 and at[-1] == 2
    assert repeated_rows(np.arange(200.0)) is None  # no repeats: nothing to gain
    assert repeated_rows(a[:10]) is None  # a solver's small batch: not looked at
