"""The balance pass's cheaper solves: the solve grid (``SOLVE_EVERY``) and the legs left unsolved
where a pinned hand is lost."""

from __future__ import annotations

import math

import numpy as np

from mtlc.body import build_manikin, forward, site_positions, site_rotation
from mtlc.ir.model import Frames, MotionIR
from mtlc.passes import balance

SKEL = build_manikin("gb10000_1988", "male", 50)


def test_the_grid_solves_every_stride_th_frame_of_each_run_and_its_last() -> None:
    rows = np.array([0, 1, 2, 3, 4, 5, 6, 10, 11, 12, 20])
    t = rows / 60.0
    grid = balance.solve_grid(rows, t, 3)
    assert np.flatnonzero(grid.solved).tolist() == [0, 3, 6, 7, 9, 10]
    between = np.flatnonzero(~grid.solved)
    assert between.tolist() == [1, 2, 4, 5, 8]
    assert grid.before[between].tolist() == [0, 0, 3, 3, 7]
    assert grid.after[between].tolist() == [3, 3, 6, 6, 9]
    np.testing.assert_allclose(grid.weight[between], [1 / 3, 2 / 3, 1 / 3, 2 / 3, 0.5])
    assert np.all(grid.weight[grid.solved] == 0.0)
    assert balance.solve_grid(rows, t, 1).solved.all()
    assert balance.solve_grid(np.zeros(0, dtype=np.intp), np.zeros(0), 3).solved.size == 0


def standing(n: int, fps: float) -> Frames:
    q = np.zeros((n, SKEL.n_dofs))
    root = np.tile(SKEL.root_position, (n, 1))
    rot = np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))
    return Frames(fps=fps, time=np.arange(n) / fps, root_position=root, root_rotation=rot, q=q)


def test_a_lost_hand_leaves_its_rows_legs_unsolved_and_the_others_as_they_were() -> None:
    f = standing(2, 60.0)
    f.q[:, SKEL.dof_index("r_shoulder_flex")] = math.radians(60)
    f.q[:, SKEL.dof_index("r_elbow_flex")] = math.radians(40)
    ir = MotionIR("t", None, "synthetic.mtask", {}, 0.0, [], [], SKEL)
    pose = forward(SKEL, f.q, f.root_position, f.root_rotation)
    feet = {
        name: (site_positions(SKEL, pose, name), site_rotation(SKEL, pose, name), np.ones(2, bool))
        for name in balance.FEET_SITES
    }
    hand = site_positions(SKEL, pose, "r_hand")
    hand[1, 2] += 1.0  # a metre past the second row's reach
    hands = {"r_hand": (np.ones(2, dtype=bool), hand)}
    root = f.root_position + np.array([0.03, 0.0, 0.0])  # the pelvis 3 cm sideways
    # (a knee may start from its seed flexion, ``SEED_FLEX``: the hips and ankles are the test)
    legs = SKEL.dofs_of_joints([f"{s}_{j}" for s in "rl" for j in ("hip", "ankle")])
    q1, r1, w1 = balance.restore_contacts(ir, f.q, root, f.root_rotation, feet, hands)
    q2, r2, w2 = balance.restore_contacts(
        ir, f.q, root, f.root_rotation, feet, hands, solve_lost=True
    )
    assert w1[0] <= balance.POSITION_TOL < w1[1]
    assert np.any(q2[1, legs] != f.q[1, legs])  # solved, the legs follow the pelvis...
    np.testing.assert_array_equal(q1[1, legs], f.q[1, legs])  # ...left: they do not
    np.testing.assert_allclose(q1[0], q2[0], atol=1e-12)
    np.testing.assert_allclose(r1[0], r2[0], atol=1e-12)
    assert w2[1] >= w1[1]  # its error is the hand's, no less


def test_a_lean_at_60_fps_is_solved_on_the_grid_and_balanced_on_every_frame(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    n = 61
    f = standing(n, 60.0)
    f.q[:, SKEL.dof_index("l_hip_abd")] = np.radians(np.linspace(15, 25, n))  # on the right foot
    ir = MotionIR("t", None, "synthetic.mtask", {}, 0.0, [], [], SKEL)
    ir.frames = f
    sizes: list[int] = []
    solve = balance.restore_contacts

    def counted(*args, **kw):  # type: ignore[no-untyped-def]
        sizes.append(len(args[1]))
        return solve(*args, **kw)

    monkeypatch.setattr(balance, "restore_contacts", counted)
    before, after, failed = balance.balance_frames(ir, f)
    assert before.max() < -0.05
    stride = round(balance.SOLVE_EVERY * f.fps)
    assert stride == 3
    assert sizes[0] == len(range(0, n, stride))  # the pelvis's first round: the grid alone
    assert not failed.any()
    assert after.min() >= balance.MARGIN - 5e-4
    assert np.abs(np.diff(f.root_position[:, 0])).max() < 0.01  # no jump between grid frames
