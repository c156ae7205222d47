"""``passes.chain_ik`` (the wrench keys' scalar solver) is ``solve_ta`` for one row of position
goals: the same poses to 1e-12 rad from the same starts, with and without restarts."""

from __future__ import annotations

import numpy as np
import pytest

from mtlc.body import build_manikin, forward, site_positions
from mtlc.body.ik import Goal, prepare, solve_ta
from mtlc.passes.chain_ik import ScalarChain, solve_chain
from mtlc.passes.tool import with_tools

WRENCH = {"kind": "wrench", "grip": (0.0, 0.0, 0.0), "tip": (0.0, -0.18, 0.0)}
ROOT = (np.array([0.1, 0.95, -0.2]), np.array([0.9, 0.0, 0.3, 0.0]))


def wrench_chain(spec: tuple[str, int], reach: str):  # type: ignore[no-untyped-def]
    """A manikin holding the wrench, its one-row chain from the comfortable pose at ``ROOT``,
    and where the hand and the wrench's tip are there."""
    skel = with_tools(build_manikin("gb10000_1988", *spec), {"r_tool_wrench": WRENCH})
    sites = ["r_hand", "r_tool_wrench"]
    q0 = np.asarray(skel.q_comfort, dtype=float).copy()
    model = prepare(skel, sites, q0[None], reach=reach, root_position=ROOT[0][None],
                    root_rotation=ROOT[1][None])  # fmt: skip
    pose = forward(skel, q0[None], ROOT[0][None], ROOT[1][None])
    hand, tip = site_positions(skel, pose, sites)[0]
    return skel, sites, q0, model, ScalarChain(skel, model, ROOT), hand, tip


@pytest.mark.parametrize("spec", [("female", 5), ("male", 95)])
@pytest.mark.parametrize("reach", ["arm", "torso"])
@pytest.mark.parametrize("restarts", [0, 2])
def test_the_scalar_chain_solves_as_solve_ta(spec, reach, restarts) -> None:
    skel, sites, q0, model, chain, hand, tip = wrench_chain(spec, reach)
    root, act = ROOT, model.active
    rng = np.random.default_rng(7)
    compared = 0
    for _ in range(10):
        shift = rng.normal(0.0, 0.12, 3)  # near (a key's next step) to out of reach
        goals = [Goal(sites[0], position=(hand + shift)[None]),
                 Goal(sites[1], position=(tip + shift)[None])]  # fmt: skip
        start = q0.copy()
        start[act] += rng.normal(0.0, 0.05, len(act))
        ref = solve_ta(skel, goals, start[None], model=model, restarts=restarts, tol=2e-4,
                       root_position=root[0][None], root_rotation=root[1][None]).q[0]  # fmt: skip
        got = solve_chain(chain, np.concatenate([hand + shift, tip + shift]).tolist(),
                          start[act], model.lower, model.upper, skel.q_comfort[act],
                          tol=2e-4, restarts=restarts)  # fmt: skip
        np.testing.assert_allclose(got, ref[act], rtol=0.0, atol=1e-12)
        compared += 1
    assert compared == 10


@pytest.mark.parametrize("spec", [("female", 5), ("male", 95)])
@pytest.mark.parametrize("reach", ["arm", "torso"])
@pytest.mark.parametrize("null_gain", [0.0, 0.05])
def test_the_row_chain_solves_as_solve_ta(spec, reach, null_gain) -> None:
    """``solve_rows`` is ``solve_ta(..., restarts=0)`` over rows, each from its own start
    (their trunks differing by rounding errors, as ``tool._even_out``'s blended guesses do)."""
    from mtlc.passes.chain_ik import RowChain, solve_rows

    skel = with_tools(build_manikin("gb10000_1988", *spec), {"r_tool_wrench": WRENCH})
    sites = ["r_hand", "r_tool_wrench"]
    rng = np.random.default_rng(11)
    b = 40  # past the 32 rows from which solve_ta's model evaluates by columns
    q0 = np.tile(np.asarray(skel.q_comfort, dtype=float), (b, 1))
    root = ROOT
    rp, rr = np.tile(root[0], (b, 1)), np.tile(root[1], (b, 1))
    model = prepare(skel, sites, q0, reach=reach, root_position=rp, root_rotation=rr)
    act = model.active
    pose = forward(skel, q0, rp, rr)
    targets = site_positions(skel, pose, sites) + rng.normal(0.0, 0.1, (b, 1, 3))
    start = q0.copy()
    start[:, act] += rng.normal(0.0, 0.05, (b, len(act)))
    start *= 1.0 + 1e-16 * rng.integers(-2, 3, start.shape)  # trunks a rounding error apart
    goals = [Goal(sites[0], position=targets[:, 0]), Goal(sites[1], position=targets[:, 1])]
    ref = solve_ta(skel, goals, start, model=model, restarts=0, null_gain=null_gain, tol=2e-4,
                   root_position=rp, root_rotation=rr).q  # fmt: skip
    got = solve_rows(RowChain(skel, model, root), targets.reshape(b, 6), start, model.lower,
                     model.upper, skel.q_comfort[act], tol=2e-4, null_gain=null_gain)  # fmt: skip
    np.testing.assert_allclose(got, ref, rtol=0.0, atol=1e-12)
    assert not np.array_equal(got, start)


@pytest.mark.parametrize("spec", [("female", 5), ("male", 95)])
@pytest.mark.parametrize("reach", ["arm", "torso"])
def test_a_resumed_solve_is_a_fresh_one_to_the_bit(spec, reach) -> None:
    """``ChainSolve.run(2)`` after ``run(0)`` (``tool._chain``'s retry of a key left short)
    gives the very angles of a fresh ``solve_chain(..., restarts=2)``: the warm-started attempt
    is not repeated, and the restarts draw the same seeded numbers."""
    from mtlc.passes.chain_ik import ChainSolve

    skel, _, q0, model, chain, hand, tip = wrench_chain(spec, reach)
    act = model.active
    rng = np.random.default_rng(13)
    resumed = 0
    for k in range(12):
        shift = rng.normal(0.0, 0.05 + 0.1 * k, 3)  # near to out of reach: some stall
        targets = np.concatenate([hand + shift, tip + shift]).tolist()
        start = q0[act] + rng.normal(0.0, 0.05, len(act))
        args = (chain, targets, start, model.lower, model.upper, skel.q_comfort[act])
        solver = ChainSolve(*args, tol=2e-4)
        first = list(solver.run(0))
        assert first == solve_chain(*args, tol=2e-4, restarts=0)
        resumed += solver.stalled
        assert solver.run(2) == solve_chain(*args, tol=2e-4, restarts=2)
        assert solver.run(2) == solve_chain(*args, tol=2e-4, restarts=2)  # nothing more to do
    assert resumed >= 3  # the resume itself was exercised


@pytest.mark.parametrize("spec", [("female", 5), ("male", 95)])
def test_evening_out_stops_at_a_fixed_point_with_the_poses_of_all_rounds(spec, monkeypatch):
    """``tool._even_out`` ends its rounds once one moves no key, and solves again only the
    keys whose guess moved; the keys are those of all ``EVEN_ROUNDS`` rounds of every key to
    the bit (a wrench swung about a fastener out of reach)."""
    import types

    from mtlc.passes import tool

    skel = with_tools(build_manikin("gb10000_1988", *spec), {"r_tool_wrench": WRENCH})
    sites = ["r_hand", "r_tool_wrench"]
    root = ROOT
    q0 = np.asarray(skel.q_comfort, dtype=float).copy()
    hand, tip = site_positions(skel, forward(skel, q0[None], root[0][None], root[1][None]),
                               sites)[0]  # fmt: skip
    k, ang = 12, np.linspace(0.0, 1.2, 12)
    tips = tip + [0.6, 0.1, 0.3] + 0.1 * np.stack([np.cos(ang), np.zeros(k), np.sin(ang)], 1)
    hands = tips + (hand - tip)
    state = types.SimpleNamespace(skel=skel)
    keys = tool._chain(state, sites, hands, tips, q0, root, "arm")
    rounds = []
    solve_rows = tool.solve_rows
    monkeypatch.setattr(
        tool, "solve_rows", lambda *a, **kw: rounds.append(1) or solve_rows(*a, **kw)
    )
    clock = np.linspace(0.0, 1.0, k)
    got = tool._even_out(state, sites, hands, tips, keys, root, "arm", clock)
    stopped_after = len(rounds)
    monkeypatch.setattr(tool, "_unmoved", lambda *a: False)  # every round, as before
    # and every key in each (a key whose guess repeats is otherwise not solved again)
    monkeypatch.setattr(tool, "bits_differ", lambda a, b: np.ones(np.shape(a), dtype=bool))
    ref = tool._even_out(state, sites, hands, tips, keys, root, "arm", clock)
    assert len(rounds) - stopped_after == tool.EVEN_ROUNDS
    assert stopped_after < tool.EVEN_ROUNDS
    assert np.array_equal(got, ref)
    assert not np.array_equal(got, keys)  # the rounds moved the keys


@pytest.mark.parametrize("spec", [("female", 5), ("male", 95)])
@pytest.mark.parametrize("reach", ["arm", "torso"])
def test_no_pose_of_the_chain_is_beyond_its_reach(spec, reach) -> None:
    """``ScalarChain.beyond`` is a bound (``tool._chain`` skips restarts where it holds, so it
    must never call a reachable goal out of reach): the sites of random poses of the chain,
    limits or not, are within it; a goal a little past it, and one metres away, are not."""
    skel, sites, q0, model, chain, hand, tip = wrench_chain(spec, reach)
    act = model.active
    rng = np.random.default_rng(3)
    q = np.tile(q0, (400, 1))
    q[:, act] = rng.uniform(-np.pi, np.pi, (400, len(act)))
    pose = forward(skel, q, np.tile(ROOT[0], (400, 1)), np.tile(ROOT[1], (400, 1)))
    pts = site_positions(skel, pose, sites)  # (400, 2, 3)
    assert not any(chain.beyond(p.ravel().tolist(), 0.0) for p in pts)
    reach_of = np.linalg.norm(pts - chain.base, axis=2).max(axis=0) / np.asarray(chain.reach)
    assert reach_of.max() <= 1.0 and reach_of.min() > 0.5  # a bound, and not a loose one
    away = (tip - chain.base) / np.linalg.norm(tip - chain.base)
    past = chain.base + away * (chain.reach[1] + 0.01)
    assert chain.beyond(np.concatenate([hand, past]).tolist(), 0.005)
    assert not chain.beyond(np.concatenate([hand, past]).tolist(), 0.02)
    assert chain.beyond(np.concatenate([hand + 5.0, tip]).tolist(), 1e-3)


@pytest.mark.parametrize("spec", [("female", 5), ("male", 95)])
@pytest.mark.parametrize("reach", ["arm", "torso"])
def test_the_best_error_is_the_distance_at_the_best_pose(spec, reach) -> None:
    """``ChainSolve.best_err`` (``tool._short`` decides with it) is the sites' largest distance
    to their targets at the angles ``run`` returns, as forward kinematics measures it."""
    from mtlc.passes.chain_ik import ChainSolve

    skel, sites, q0, model, chain, hand, tip = wrench_chain(spec, reach)
    act = model.active
    rng = np.random.default_rng(17)
    for k in range(8):
        shift = rng.normal(0.0, 0.05 + 0.1 * k, 3)  # near to out of reach
        start = q0[act] + rng.normal(0.0, 0.05, len(act))
        solver = ChainSolve(chain, np.concatenate([hand + shift, tip + shift]).tolist(), start,
                            model.lower, model.upper, skel.q_comfort[act], tol=2e-4)  # fmt: skip
        for restarts in (0, 2):
            q = q0.copy()
            q[act] = solver.run(restarts)
            pose = forward(skel, q[None], ROOT[0][None], ROOT[1][None])
            got = site_positions(skel, pose, sites)[0]
            want = np.array([hand + shift, tip + shift])
            dist = float(np.linalg.norm(got - want, axis=1).max())
            assert abs(solver.best_err - dist) <= 1e-12


@pytest.mark.parametrize("reach", ["arm", "torso"])
def test_a_row_solves_alone_as_in_a_batch(reach) -> None:
    """Each row of ``solve_rows`` is its own arithmetic: solved alone or with others, to the
    bit (``tool._rows_solved`` looks rows up one by one)."""
    from mtlc.passes.chain_ik import RowChain, solve_rows

    skel = with_tools(build_manikin("gb10000_1988", "female", 5), {"r_tool_wrench": WRENCH})
    sites = ["r_hand", "r_tool_wrench"]
    rng = np.random.default_rng(19)
    b = 12
    q0 = np.tile(np.asarray(skel.q_comfort, dtype=float), (b, 1))
    rp, rr = np.tile(ROOT[0], (b, 1)), np.tile(ROOT[1], (b, 1))
    model = prepare(skel, sites, q0, reach=reach, root_position=rp, root_rotation=rr)
    act = model.active
    targets = site_positions(skel, forward(skel, q0, rp, rr), sites) + rng.normal(
        0.0, 0.2, (b, 1, 3)
    )
    start = q0.copy()
    start[:, act] += rng.normal(0.0, 0.05, (b, len(act)))
    chain = RowChain(skel, model, ROOT)

    def solve(rows):  # type: ignore[no-untyped-def]
        return solve_rows(chain, targets.reshape(b, 6)[rows], start[rows], model.lower,
                          model.upper, skel.q_comfort[act], tol=2e-4, null_gain=0.0)  # fmt: skip

    together = solve(np.arange(b))
    assert not np.array_equal(together, start)
    for i in range(b):
        assert np.array_equal(solve([i])[0], together[i])
    assert np.array_equal(solve([3, 7, 1]), together[[3, 7, 1]])
