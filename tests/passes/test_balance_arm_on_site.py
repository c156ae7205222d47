"""``balance.arm_on_site`` (the pinned arm's single-frame solve of ``pinned_arms_on_branch``)
returns what the ``solve_ta`` call it replaced returns, to the bit, and the same verdict on
the hand's distance: on seeds around a hand's site, within reach, at its edge and beyond."""

from __future__ import annotations

import numpy as np
import pytest

from mtlc.body import build_manikin, forward, site_positions
from mtlc.body.ik import Goal, prepare, solve_ta
from mtlc.body.kinematics import quat_to_matrix
from mtlc.passes.balance import POSITION_TOL, arm_dofs, arm_on_site, root_matrices

SKELS = [build_manikin("gb10000_1988", "female", 5), build_manikin("gb10000_1988", "male", 95)]


def reference(skel, hand, seed, target, root, rot):  # type: ignore[no-untyped-def]
    """The call ``pinned_arms_on_branch`` made before."""
    goal = [Goal(hand, position=target[None])]
    model = prepare(skel, goal, seed[None], root_position=root, root_rotation=rot)
    res = solve_ta(
        skel, goal, seed[None], model=model, restarts=0, null_gain=0.0, tol=2e-4, max_iter=40
    )
    return res.q[0], bool(res.position_error[0] <= POSITION_TOL)


@pytest.mark.parametrize("skel", SKELS, ids=["female-p5", "male-p95"])
@pytest.mark.parametrize("hand", ["r_hand", "l_hand"])
def test_arm_on_site_equals_solve_ta(skel, hand) -> None:  # type: ignore[no-untyped-def]
    rng = np.random.default_rng(17)
    cols = np.asarray(arm_dofs(skel, hand))
    held = moved = 0
    for n in range(120):
        seed = np.clip(skel.q_comfort + rng.normal(0.0, 0.3, skel.n_dofs), skel.lower, skel.upper)
        root = np.array([[rng.normal(0, 0.5), 0.9 + rng.normal(0, 0.05), rng.normal(0, 0.5)]])
        yaw = rng.uniform(-np.pi, np.pi)
        rot = np.array([[np.cos(yaw / 2), 0.0, np.sin(yaw / 2), 0.0]])
        hand_at = site_positions(skel, forward(skel, seed[None], root, rot), hand)[0]
        # the seed's own hand (ends where it starts), a little off, far off and out of reach
        offset = [0.0, 1e-4, 0.01, 0.08, 0.3, 1.5][n % 6]
        target = hand_at + offset * rng.normal(0.0, 1.0, 3) / np.sqrt(3)
        seed[cols] += (n % 2) * rng.normal(0.0, 0.05, cols.size)  # a start off its own hand
        seed = np.clip(seed, skel.lower, skel.upper)
        want_q, want_ok = reference(skel, hand, seed, target, root, rot)
        got_q, got_ok = arm_on_site(skel, hand, seed, target, root, rot)
        assert got_q.view(np.int64).tolist() == want_q.view(np.int64).tolist()
        assert got_ok == want_ok
        held += got_ok
        moved += not np.array_equal(got_q, seed)
    assert 0 < held < 120 and moved > 0  # both verdicts, and solves that move the arm


def test_root_matrices_are_each_rows_own() -> None:
    rng = np.random.default_rng(3)
    for n in (1, 2, 5, 17, 300):
        quat = rng.normal(size=(n, 4))
        quat[: n // 2] /= np.linalg.norm(quat[: n // 2], axis=1, keepdims=True)
        whole = root_matrices(quat)
        for i in range(n):
            one = quat_to_matrix(quat[i : i + 1])
            assert whole[i : i + 1].view(np.int64).tolist() == one.view(np.int64).tolist()
    assert root_matrices(whole) is whole  # matrices pass through
