"""IK solvers: reachable targets are solved inside the limits; TO paths are monotone."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mtlc.body import (
    build_manikin,
    forward,
    rotation_error,
    site_direction,
    site_positions,
    site_rotation,
)
from mtlc.body.ik import Goal, default_dofs, prepare, solve, solve_ta, solve_to, solve_transpose

SK = build_manikin("gb10000_1988", "female", 50)
ARM = prepare(SK, ["r_hand"])
SETTINGS = settings(
    max_examples=25, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow]
)


def _random_targets(site: str, dofs: list[int], seed: int, n: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    q = np.tile(SK.q_comfort, (n, 1))
    q[:, dofs] = SK.random_q(rng, n)[:, dofs]
    return q, site_positions(SK, forward(SK, q), site)


@SETTINGS
@given(seed=st.integers(0, 2**31 - 1))
def test_ta_solves_random_reachable_arm_targets_within_limits(seed: int) -> None:
    _q_true, T = _random_targets("r_hand", list(ARM.active), seed, 1)
    res = solve_ta(SK, [Goal("r_hand", position=T[0])], model=ARM, seed=seed)
    assert res.success[0], res
    assert SK.within_limits(res.q)[0]
    got = site_positions(SK, forward(SK, res.q), "r_hand")[0]
    assert np.linalg.norm(got - T[0]) <= 1e-3
    # Dofs outside the chain keep their starting values.
    others = np.setdiff1d(np.arange(SK.n_dofs), ARM.active)
    np.testing.assert_array_equal(res.q[0, others], SK.q_comfort[others])


@SETTINGS
@given(seed=st.integers(0, 2**31 - 1), noise=st.floats(0.0, 0.4))
def test_to_path_is_monotone_continuous_and_in_limits(seed: int, noise: float) -> None:
    q_true, T = _random_targets("r_hand", list(ARM.active), seed, 1)
    rng = np.random.default_rng(seed)
    q0 = q_true[0].copy()
    q0[ARM.active] += rng.normal(0, noise, ARM.n)
    q0 = SK.clip(q0)
    res = solve_to(SK, [Goal("r_hand", position=T[0])], q0, model=ARM, max_iter=400)
    assert res.path is not None
    path = res.path[:, 0]
    d = np.linalg.norm(site_positions(SK, forward(SK, path), "r_hand") - T[0], axis=-1)
    assert np.all(np.diff(d) <= 1e-12)  # monotone non-increasing distance
    if len(path) > 1:  # continuous: every step capped at max_step
        assert np.max(np.abs(np.diff(path, axis=0))) <= 0.05 + 1e-12
    assert np.all(SK.within_limits(path))
    np.testing.assert_allclose(path[-1], res.q[0])
    assert res.iterations[0] <= 400
    assert d[-1] <= d[0]


def test_batched_ta_matches_the_single_solves_and_is_deterministic() -> None:
    _q_true, T = _random_targets("r_hand", list(ARM.active), 123, 40)
    mid = SK.q_comfort.copy()
    mid[ARM.active] = SK.q_middle[ARM.active]
    batch = solve_ta(SK, [Goal("r_hand", position=T)], mid, model=ARM)
    assert batch.success.all()
    again = solve_ta(SK, [Goal("r_hand", position=T)], mid, model=ARM)
    np.testing.assert_array_equal(batch.q, again.q)
    # The scalar single-target fast path and the numpy batch path run the same algorithm.
    slow = prepare(SK, ["r_hand"])
    slow._fast = None  # type: ignore[attr-defined]  # force the numpy path for one row
    for t in T[:10]:
        fast_res = solve_ta(SK, [Goal("r_hand", position=t)], mid, model=ARM)
        slow_res = solve_ta(SK, [Goal("r_hand", position=t)], mid, model=slow)
        assert fast_res.success[0] and slow_res.success[0]
        assert fast_res.iterations[0] == slow_res.iterations[0]
        np.testing.assert_allclose(fast_res.q, slow_res.q, atol=1e-9)


def test_component_major_batch_path_matches_the_general_batch_path() -> None:
    # A position goal on the arm takes the component-major path (ik/batch.py); forcing the
    # general ChainModel path must give the same iterates wherever no restart drew randoms.
    _q_true, T = _random_targets("r_hand", list(ARM.active), 7, 300)
    mid = SK.q_comfort.copy()
    mid[ARM.active] = SK.q_middle[ARM.active]
    general = prepare(SK, ["r_hand"])
    general._fast = None  # type: ignore[attr-defined]
    fast = solve_ta(SK, [Goal("r_hand", position=T)], mid, model=ARM)
    slow = solve_ta(SK, [Goal("r_hand", position=T)], mid, model=general)
    assert fast.success.mean() >= 0.995 and slow.success.mean() >= 0.995
    same = (fast.restarts == 0) & (slow.restarts == 0)
    assert same.mean() >= 0.9
    np.testing.assert_array_equal(fast.iterations[same], slow.iterations[same])
    np.testing.assert_allclose(fast.q[same], slow.q[same], atol=1e-9)
    np.testing.assert_allclose(fast.position_error[same], slow.position_error[same], atol=1e-12)
    assert np.all(SK.within_limits(fast.q))
    got = site_positions(SK, forward(SK, fast.q[fast.success]), "r_hand")
    assert np.max(np.linalg.norm(got - T[fast.success], axis=-1)) <= 1e-3


def test_batch_rows_with_their_own_seeds_match_single_solves() -> None:
    q_true, T = _random_targets("r_hand", list(ARM.active), 11, 24)
    rng = np.random.default_rng(11)
    q0 = SK.clip(q_true + rng.normal(0, 0.25, q_true.shape))
    others = np.setdiff1d(np.arange(SK.n_dofs), ARM.active)
    q0[:, others] = SK.q_comfort[others]
    batch = solve_ta(SK, [Goal("r_hand", position=T)], q0, model=ARM)
    assert batch.success.all()
    for i in range(len(T)):
        one = solve_ta(SK, [Goal("r_hand", position=T[i])], q0[i], model=ARM)
        if batch.restarts[i] == 0 and one.restarts[0] == 0:
            assert one.iterations[0] == batch.iterations[i]
            np.testing.assert_allclose(one.q[0], batch.q[i], atol=1e-9)


@pytest.mark.parametrize("base_rows", [1, 40])
@pytest.mark.parametrize(
    ("sites", "reach"),
    [
        (("r_hand", "l_hand", "r_foot", "l_foot"), "torso"),
        (("r_hand",), "arm"),
        (("l_hand", "r_hand"), "girdle"),
        (("gaze",), "arm"),
    ],
)
def test_component_major_kernel_matches_the_matrix_kernel(
    sites: tuple[str, ...], reach: str, base_rows: int
) -> None:
    rng = np.random.default_rng(base_rows)
    model = prepare(SK, list(sites), SK.random_q(rng, base_rows), reach=reach)
    qa = SK.random_q(rng, 40)[:, model.active]
    for rows in (None if base_rows == 1 else np.arange(40), np.arange(40)[::-1]):
        fast = model.evaluate(qa, rows)  # 40 rows: the component-major kernel
        ref = model.evaluate_matrices(qa, rows)
        for got, want in zip(fast, ref, strict=True):
            assert got.shape == want.shape
            np.testing.assert_allclose(got, want, atol=1e-12)


def test_unreachable_targets_batched_return_best_pose_and_distance() -> None:
    shoulder = forward(SK, SK.q_comfort).p[SK.joint_index("r_shoulder")]
    far = shoulder + np.array([[-2.0, 0.0, 0.0], [0.0, -2.5, 0.0], [0.0, 0.0, 2.2]])
    arm = SK.dims.shoulder_height - SK.dims.wrist_height + 0.4 * SK.dims.hand_length
    for method in ("dls", "gradient", "transpose"):
        res = solve(SK, [Goal("r_hand", position=far)], method=method, model=ARM)
        assert not res.success.any()
        np.testing.assert_allclose(res.position_error, [2.0 - arm, 2.5 - arm, 2.2 - arm], atol=0.02)
        assert np.all(SK.within_limits(res.q))
        assert np.all(res.iterations <= 1000 * 9)


def test_unreachable_target_returns_best_pose_and_remaining_distance() -> None:
    shoulder = forward(SK, SK.q_comfort).p[SK.joint_index("r_shoulder")]
    far = shoulder + np.array([-2.0, 0.0, 0.0])
    for method in ("dls", "gradient", "transpose"):
        res = solve(SK, [Goal("r_hand", position=far)], method=method, model=ARM)
        assert not res.success[0]
        arm = SK.dims.shoulder_height - SK.dims.wrist_height + 0.4 * SK.dims.hand_length
        assert res.position_error[0] == pytest.approx(2.0 - arm, abs=0.02)
        assert SK.within_limits(res.q)[0]
        assert res.iterations[0] <= 1000 * 9  # bounded


def test_position_and_orientation_goal() -> None:
    rng = np.random.default_rng(8)
    q = SK.q_comfort.copy()
    q[ARM.active] = SK.random_q(rng, 1)[0, ARM.active] * 0.6 + 0.4 * SK.q_middle[ARM.active]
    pose = forward(SK, q)
    goal = Goal(
        "r_hand",
        position=site_positions(SK, pose, "r_hand"),
        orientation=site_rotation(SK, pose, "r_hand"),
    )
    res = solve_ta(SK, [goal], model=prepare(SK, [goal]))
    assert res.success[0]
    got = forward(SK, res.q[0])
    want = site_rotation(SK, pose, "r_hand")
    ang = np.linalg.norm(rotation_error(want, site_rotation(SK, got, "r_hand")))
    assert ang <= math.radians(1.0)


def test_gaze_goal_looks_at_the_point() -> None:
    point = np.array([0.4, 1.2, 1.0])
    res = solve_ta(SK, [Goal("gaze", aim=point)])
    assert res.success[0]
    pose = forward(SK, res.q[0])
    d = site_direction(SK, pose, "gaze")
    u = point - site_positions(SK, pose, "gaze")
    assert math.degrees(math.acos(d @ u / np.linalg.norm(u))) <= 1.0
    moved = np.flatnonzero(res.q[0] != SK.q_comfort)
    assert set(moved) <= set(SK.dofs_of_joints(["neck", "head"]))


def test_full_body_two_hands_two_feet_batched() -> None:
    effs = ["r_hand", "l_hand", "r_foot", "l_foot"]
    dofs = default_dofs(SK, effs, reach="torso")
    rng = np.random.default_rng(21)
    q = np.tile(SK.q_comfort, (30, 1))
    q[:, dofs] = SK.random_q(rng, 30)[:, dofs]
    P = site_positions(SK, forward(SK, q), effs)
    goals = [Goal(e, position=P[:, i]) for i, e in enumerate(effs)]
    res = solve_ta(SK, goals, dofs=dofs)
    assert res.success_rate >= 0.95
    ok = res.success
    got = site_positions(SK, forward(SK, res.q[ok]), effs)
    assert np.max(np.linalg.norm(got - P[ok], axis=-1)) <= 1e-3
    assert np.all(SK.within_limits(res.q))


def test_transpose_and_gradient_reach_near_targets() -> None:
    q_true, T = _random_targets("r_foot", SK.chain_dofs("r_foot", "r_hip"), 4, 20)
    q0 = SK.clip(q_true + 0.1)  # a near start, as TO gets after TA
    for fn in (solve_transpose, solve_to):
        res = fn(SK, [Goal("r_foot", position=T)], q0, max_iter=2000)
        assert res.success_rate >= 0.9, fn.__name__
        assert np.all(res.position_error[res.success] <= 1e-3)


def test_unknown_method_and_bad_goals_are_refused() -> None:
    with pytest.raises(ValueError, match="method"):
        solve(SK, [Goal("r_hand", position=[0, 1, 0])], method="ccd")
    with pytest.raises(ValueError, match="nothing"):
        Goal("r_hand")
    with pytest.raises(ValueError, match="direction"):
        solve_ta(SK, [Goal("r_hand", aim=[0, 1, 1])])


def _joint_by_joint(model, qa, rows=None):  # type: ignore[no-untyped-def]
    """The matrix kernel as it was before its products were stacked (the reference): one
    joint, one dof, one numpy call at a time."""
    from mtlc.body.ik.model import _take
    from mtlc.body.kinematics import cross

    b = qa.shape[0]
    ql = _take(model._qlive, rows, b).copy()
    ql[:, model._act_pos] = qa[:, model._act_col]
    Rd = (
        model._A0
        + np.sin(ql)[..., None, None] * model._A1
        + np.cos(ql)[..., None, None] * model._A2
    )
    Rs, ps = [], []
    axes, origins = np.empty((b, model.n, 3)), np.empty((b, model.n, 3))
    for li, pj, off, dofs in model._plan:
        if li >= 0:
            Rp, pp = Rs[li], ps[li]
        else:
            Rp, pp = _take(model._base_R[pj], rows, b), _take(model._base_p[pj], rows, b)
        p = pp + Rp @ off
        R = Rp
        for slot, colk in dofs:
            if colk >= 0:
                axes[:, colk] = R @ model._axis[slot]
                origins[:, colk] = p
            R = R @ Rd[:, slot]
        Rs.append(R)
        ps.append(p)
    site_p = np.empty((b, len(model.sites), 3))
    site_R = np.empty((b, len(model.sites), 3, 3))
    for i, (li, j, off) in enumerate(
        zip(model._site_live, model._site_joint, model._site_off, strict=True)
    ):
        if li >= 0:
            R, p = Rs[li], ps[li]
        else:
            R, p = _take(model._base_R[j], rows, b), _take(model._base_p[j], rows, b)
        site_R[:, i] = R
        site_p[:, i] = p + R @ off
    d = site_p[:, :, None, :] - origins[:, None, :, :]
    ax = np.broadcast_to(axes[:, None], d.shape)
    Jp = cross(ax, d) * model.mask[None, :, :, None]
    Jw = ax * model.mask[None, :, :, None]
    return site_p, site_R, np.swapaxes(Jp, -1, -2), np.swapaxes(Jw, -1, -2)


@pytest.mark.parametrize("base_rows", [1, 5])
@pytest.mark.parametrize(
    ("sites", "reach"),
    [
        (("r_hand", "l_hand", "r_foot", "l_foot"), "torso"),
        (("r_hand", "r_fingertip"), "arm"),
        (("r_hand", "l_hand", "r_fingertip", "l_fingertip"), "torso"),
        (("l_hand", "r_hand"), "girdle"),
        (("gaze",), "arm"),
    ],
)
def test_stacked_matrix_kernel_is_the_joint_by_joint_one_to_the_bit(
    sites: tuple[str, ...], reach: str, base_rows: int
) -> None:
    """``evaluate_matrices`` stacks the products of a depth's joints into one BLAS call: the
    same kernel per 3x3 product, so the same bits (signs of zeros too) as one call each."""
    rng = np.random.default_rng(7 + base_rows)
    model = prepare(SK, list(sites), SK.random_q(rng, base_rows), reach=reach)
    for b in (1, 3, 5):
        if base_rows > 1 and b != base_rows:
            continue
        for rows in (None, np.arange(b)[::-1]) if base_rows > 1 else (None,):
            for _ in range(20):
                qa = SK.random_q(rng, b)[:, model.active]
                qa[:, ::3] = 0.0  # exact zeros in the frames
                got = model.evaluate_matrices(qa, rows)
                want = _joint_by_joint(model, qa, rows)
                for g, w in zip(got, want, strict=True):
                    assert g.shape == w.shape
                    assert np.array_equal(g, w)
                    assert np.array_equal(np.signbit(g), np.signbit(w))


@pytest.mark.parametrize(
    ("sites", "reach"), [(("gaze",), "arm"), (("r_hand", "l_hand", "r_foot", "l_foot"), "torso")]
)
def test_models_of_one_problem_share_the_stacked_plan_and_keep_their_own_angles(
    sites: tuple[str, ...], reach: str
) -> None:
    """The stacked plan is built once per problem (sites and dofs) and shared by every model
    of it; each model still evaluates with its own base angles and frozen frames: the same
    bits as the joint-by-joint reference, for one-row and per-row bases, first built or not."""
    rng = np.random.default_rng(11)
    first = prepare(SK, list(sites), SK.random_q(rng, 1), reach=reach)
    first._structure.stacked.clear()  # this test's first model builds the plan
    models = [first] + [prepare(SK, list(sites), SK.random_q(rng, b), reach=reach) for b in (1, 3)]
    plans = [m._stacked() for m in models]
    assert len(first._structure.stacked) == 1
    assert all(p.steps is plans[0].steps and p.paths is plans[0].paths for p in plans)
    assert not np.array_equal(plans[0].q_steps, plans[1].q_steps)  # each model's own angles
    for model in models:
        b = model.B
        for _ in range(5):
            qa = SK.random_q(rng, b)[:, model.active]
            got = model.evaluate_matrices(qa)
            for g, w in zip(got, _joint_by_joint(model, qa, None), strict=True):
                assert np.array_equal(g, w)


@pytest.mark.parametrize("far", [0.0, 0.6])
@pytest.mark.parametrize("kind", ["two", "orientation", "aim"])
@pytest.mark.parametrize("reach", ["arm", "torso"])
def test_single_row_loop_is_the_batch_loop_to_the_bit(far: float, kind: str, reach: str) -> None:
    """``solve_ta`` of one row runs ``_solve_single`` (Python floats for the bookkeeping);
    the batch loop ``_solve_rows`` on that one row takes the same steps, restarts and draws."""
    from mtlc.body.ik import dls
    from mtlc.body.ik.goals import normalise

    rng = np.random.default_rng(11)
    for _ in range(3):
        q_true = SK.q_comfort.copy()
        q_true[ARM.active] = SK.random_q(rng, 1)[0, ARM.active]
        pts = site_positions(SK, forward(SK, q_true), ["r_hand", "r_fingertip", "gaze"])
        goals = [Goal("r_hand", position=pts[0] + far)]
        if kind == "two":
            goals.append(Goal("r_fingertip", position=pts[1] + far))
        elif kind == "orientation":
            goals = [Goal("r_hand", position=pts[0] + far, orientation=np.array([1.0, 0, 0, 0]))]
        else:
            goals.append(Goal("gaze", aim=pts[0]))
        model = prepare(SK, goals, SK.q_comfort, reach=reach)
        ga = normalise(SK, goals)
        qf, qa = dls._initial(SK, model, SK.q_comfort, 1)
        options = dict(
            tol=1e-3, orientation_tol=math.radians(1.0), max_iter=60, restarts=3, patience=8,
            damping=0.02, max_error=0.25, max_step=0.5, null_gain=0.05,
        )  # fmt: skip
        one = dls._solve_single(SK, ga, model, qf, qa, rng=np.random.default_rng(0), **options)
        rows = dls._solve_rows(
            SK, ga, model, qf, qa, rng=np.random.default_rng(0), tail_chain=None, **options
        )
        for field in ("q", "position_error", "orientation_error", "iterations", "restarts"):
            assert np.array_equal(getattr(one, field), getattr(rows, field)), field


@pytest.mark.parametrize("far", [0.0, 0.4])
@pytest.mark.parametrize("kind", ["one", "two", "orientation"])
def test_single_row_descent_is_the_batch_descent_to_the_bit(far: float, kind: str) -> None:
    """``solve_to`` of one row runs ``_descend_single``; ``_descend_rows`` on that one row
    takes the same path, sample for sample."""
    from mtlc.body.ik import gradient
    from mtlc.body.ik.goals import normalise

    rng = np.random.default_rng(5)
    for _ in range(3):
        q_true = SK.q_comfort.copy()
        q_true[ARM.active] = SK.random_q(rng, 1)[0, ARM.active]
        pts = site_positions(SK, forward(SK, q_true), ["r_hand", "r_fingertip"])
        goals = [Goal("r_hand", position=pts[0] + far)]
        if kind == "two":
            goals.append(Goal("r_fingertip", position=pts[1] + far))
        elif kind == "orientation":
            goals = [Goal("r_hand", position=pts[0] + far, orientation=np.array([1.0, 0, 0, 0]))]
        model = prepare(SK, goals, SK.q_comfort, reach="torso")
        ga = normalise(SK, goals)
        start = SK.q_comfort[model.active][None]
        options = dict(
            tol=1e-3, orientation_tol=math.radians(1.0), max_iter=150, max_step=0.05,
            record_path=True,
        )  # fmt: skip
        one = gradient._descend_single(model, ga, start.copy(), **options)
        rows = gradient._descend_rows(model, ga, start.copy(), **options)
        assert np.array_equal(one[0], rows[0])
        assert np.array_equal(one[3], rows[3])
        assert len(one[4]) == len(rows[4]) > 1
        assert all(np.array_equal(a, b) for a, b in zip(one[4], rows[4], strict=True))


@pytest.mark.parametrize(
    "sites", [("r_hand",), ("r_hand", "r_fingertip"), ("r_hand", "l_hand", "l_fingertip")]
)
def test_position_residual_is_the_general_one_in_numbers_and_layout(sites: tuple[str, ...]) -> None:
    """``residual(..., targets=...)`` (positions alone, side by side) gives the general
    residual's numbers and its Jacobian's memory layout (the solvers' BLAS calls see it)."""
    from mtlc.body.ik.goals import normalise
    from mtlc.body.ik.result import position_targets, residual

    rng = np.random.default_rng(3)
    goals = [Goal(s, position=rng.uniform(-0.5, 1.5, 3)) for s in sites]
    model = prepare(SK, goals, SK.q_comfort, reach="torso")
    ga = normalise(SK, goals)
    targets = position_targets(ga)
    assert targets is not None
    for b in (1, 4):
        qa = SK.random_q(rng, b)[:, model.active]
        want = residual(model, ga, qa)
        got = residual(model, ga, qa, targets=targets)
        for name in ("e", "J", "pos_err", "ori_err", "cost"):
            g, w = getattr(got, name), getattr(want, name)
            assert g.shape == w.shape and g.strides == w.strides, name
            assert np.array_equal(g, w), name
    assert position_targets(normalise(SK, [Goal("gaze", aim=np.zeros(3))])) is None


@SETTINGS
@given(
    seed=st.integers(0, 2**31 - 1),
    aim=st.tuples(*[st.floats(-3.0, 3.0)] * 3),
    restarts=st.integers(1, 3),
)
def test_the_first_attempt_is_what_no_restarts_returns_to_the_bit(
    seed: int, aim: tuple[float, float, float], restarts: int
) -> None:
    """``first_attempt=True`` returns, beside the best of all attempts, the first attempt's
    best: the same pose to the bit as the same solve with ``restarts=0`` (the gaze asks for
    both); targets anywhere, behind the head too, where the first attempt stalls and restarts."""
    rng = np.random.default_rng(seed)
    body = np.clip(SK.q_comfort + rng.normal(0.0, 0.3, SK.n_dofs), SK.lower, SK.upper)
    model = prepare(SK, ["gaze"], body)
    goal = [Goal("gaze", aim=np.asarray(aim))]
    both = solve_ta(SK, goal, body, model=model, restarts=restarts, first_attempt=True)
    alone = solve_ta(SK, goal, body, model=model, restarts=0)
    best = solve_ta(SK, goal, body, model=model, restarts=restarts)
    assert both.first is not None
    assert np.array_equal(both.first, alone.q)
    assert np.array_equal(both.q, best.q)


@SETTINGS
@given(
    seed=st.integers(0, 2**31 - 1),
    rows=st.integers(1, 12),
    far=st.floats(0.0, 0.5),
    twist=st.booleans(),
)
def test_a_row_of_a_prepared_path_is_solve_ta_of_that_row_to_the_bit(
    seed: int, rows: int, far: float, twist: bool
) -> None:
    """``solve_ta_row`` on a model prepared once for a path's rows (bodies, roots) gives what
    ``solve_ta`` gives for each row alone, to the bit: the carry's continuation solves an arm at
    each point of a path this way; targets in and out of reach; a body the row was not
    prepared for (its trunk moved) is refused. ``twist``: the whole arm chain, else the carry's
    (the forearm's twist left out: a fixed angle inside the chain)."""
    from mtlc.body.ik import SerialRows, solve_ta_row

    rng = np.random.default_rng(seed)
    bodies = np.clip(SK.q_comfort + rng.normal(0.0, 0.3, (rows, SK.n_dofs)), SK.lower, SK.upper)
    roots = rng.normal(0.0, 0.5, (rows, 3))
    quats = rng.normal(0.0, 1.0, (rows, 4))  # normalised by the kinematics
    chain = [d for d in default_dofs(SK, ["r_hand"], "arm")
             if twist or "_pro" not in SK.dof_names[d]]  # fmt: skip
    path = SerialRows(
        prepare(SK, ["r_hand"], bodies, dofs=chain, root_position=roots, root_rotation=quats)
    )
    for k in range(rows):
        start = bodies[k].copy()
        start[chain] = np.clip(start[chain] + rng.normal(0.0, 0.2, len(chain)),
                               SK.lower[chain], SK.upper[chain])  # fmt: skip
        hand = site_positions(SK, forward(SK, start[None], roots[k], quats[k]), "r_hand")[0]
        target = hand + rng.normal(0.0, 0.1 + far, 3)
        row = solve_ta_row(path, k, start, target, tol=1e-4, null_gain=0.0)
        alone = solve_ta(
            SK, [Goal("r_hand", position=target)], start, dofs=chain, root_position=roots[k],
            root_rotation=quats[k], restarts=0, null_gain=0.0, tol=1e-4, measure=False,
        )  # fmt: skip
        assert row is not None
        assert np.array_equal(row[0], alone.q[0])
        assert row[1] == alone.position_error[0]
        placed = site_positions(SK, forward(SK, row[0][None], roots[k], quats[k]), "r_hand")[0]
        assert np.abs(np.asarray(path.site(k, row[0])) - placed).max() < 1e-12
    k = int(rng.integers(rows))
    for dof in (
        "lumbar_flex",
        "r_clavicle_elev",
        "thorax_rot",
        *(() if twist else ("r_elbow_pro",)),
    ):
        moved = bodies[k].copy()
        moved[SK.dof_index(dof)] += 0.1
        assert solve_ta_row(path, k, moved, np.zeros(3), tol=1e-4) is None


def test_a_row_solve_takes_solve_ta_s_defaults() -> None:
    """``solve_ta_row`` repeats ``solve_ta``'s keyword defaults: they must not drift apart."""
    import inspect

    from mtlc.body.ik import solve_ta_row

    row = inspect.signature(solve_ta_row).parameters
    full = inspect.signature(solve_ta).parameters
    shared = [n for n, p in row.items() if p.default is not inspect.Parameter.empty]
    assert shared and all(row[n].default == full[n].default for n in shared)
