"""The elbow's turn round the body, planned over time for a held hand (issue 19).

``clearance.swivel_plan`` chooses, per frame, one turn of the elbow about the shoulder-wrist
line from a grid, given how deep each turn leaves the forearm: the least total depth, the turn
changing by at most a few grid steps between frames. Before it, each frame's solve took the way
out nearest its own pose, and the way round a thigh flipped sides between two frames: the rack
module's low latch (tests/data/clearance/rack_module.mtask, bench/procedures' copy, female P95) turned the left shoulder
56 deg in one output frame.
"""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mtlc.body.capsules import clearance, side_limbs
from mtlc.body.ik.clearance import swivel_clearance
from mtlc.body.kinematics import forward
from mtlc.diagnostics import DiagnosticSink
from mtlc.frontend import run_frontend
from mtlc.passes import clearance as pass_clearance
from mtlc.passes import run_motion
from mtlc.passes.clearance import SWIVEL_PRICE, SWIVEL_TURNS, swivel_plan
from mtlc.passes.sample import resample
from mtlc.semantics import schedule
from mtlc.semantics.timeline import ManikinSpec

ROOT = Path(__file__).resolve().parents[2]
ZERO = int(np.flatnonzero(SWIVEL_TURNS == 0.0)[0])


def _cost(depth: np.ndarray, path: np.ndarray) -> float:
    cols = np.searchsorted(SWIVEL_TURNS, path)
    rows = np.arange(len(path))
    return float(
        (np.maximum(depth[rows, cols], 0.0) + SWIVEL_PRICE * np.abs(SWIVEL_TURNS[cols])).sum()
    )


def test_the_plan_goes_round_one_side_at_a_persons_speed() -> None:
    # a run where only turns far to one side are clear in the middle frames: the plan turns
    # early enough, one grid step a frame, and comes back to no turn at the run's end
    w, g = 200, len(SWIVEL_TURNS)
    depth = np.full((w, g), -0.01)
    depth[80:120, : ZERO + 20] = 0.05  # only turns over +50 deg clear the forearm here
    path = swivel_plan(depth, 1, free_start=False, free_end=False)
    cols = np.searchsorted(SWIVEL_TURNS, path)
    assert cols[0] == ZERO and cols[-1] == ZERO
    assert np.abs(np.diff(cols)).max() <= 1
    assert (cols[80:120] >= ZERO + 20).all()  # clear through the middle, on one side
    assert np.all(np.diff(np.sign(path[path != 0.0])) == 0)


def test_a_straight_arm_is_not_turned() -> None:
    # where the elbow is on the shoulder-wrist line a turn moves nothing and twists the arm:
    # those frames keep no turn, and the turn starts from nothing where the arm bends
    w, g = 60, len(SWIVEL_TURNS)
    depth = np.full((w, g), 0.05)
    depth[:, ZERO + 10 :] = -0.01  # only turns over +25 deg are clear, everywhere
    straight = np.zeros(w, dtype=bool)
    straight[:20] = True
    path = swivel_plan(depth, 1, free_start=True, free_end=True, unturned=straight)
    cols = np.searchsorted(SWIVEL_TURNS, path)
    assert (cols[:20] == ZERO).all()
    assert np.abs(np.diff(cols)).max() <= 1
    assert cols[-1] >= ZERO + 10


def test_no_turn_where_nothing_is_inside() -> None:
    depth = np.full((50, len(SWIVEL_TURNS)), -0.02)
    assert not swivel_plan(depth, 2, free_start=True, free_end=True).any()


@settings(max_examples=60, deadline=None)
@given(
    st.integers(2, 6),
    st.lists(st.floats(-0.02, 0.05), min_size=6 * 5, max_size=6 * 5),
    st.booleans(),
    st.booleans(),
)
def test_the_plan_is_the_best_path_through_the_grid(
    w: int, values: list[float], free_start: bool, free_end: bool
) -> None:
    # on a grid of five turns about no turn, against every path (brute force)
    g = len(SWIVEL_TURNS)
    depth = np.full((w, g), 1.0)  # the turns outside the five: never the best
    depth[:, ZERO - 2 : ZERO + 3] = np.array(values[: w * 5]).reshape(w, 5)
    path = swivel_plan(depth, 1, free_start, free_end)
    cols = np.searchsorted(SWIVEL_TURNS, path)
    assert np.abs(np.diff(cols)).max(initial=0) <= 1
    assert free_start or cols[0] == ZERO
    assert free_end or cols[-1] == ZERO
    best = np.inf
    for combo in itertools.product(range(ZERO - 2, ZERO + 3), repeat=w):
        c = np.array(combo)
        if np.abs(np.diff(c)).max(initial=0) > 1:
            continue
        if (not free_start and c[0] != ZERO) or (not free_end and c[-1] != ZERO):
            continue
        best = min(best, _cost(depth, SWIVEL_TURNS[c]))
    assert _cost(depth, path) == pytest.approx(best, abs=1e-12)


def test_no_turn_measures_the_forearm_as_clearance_does() -> None:
    # the turned elbow's depth at no turn is the clearance pass's own measure of the forearm
    (timeline,) = run_frontend(
        [ROOT / "tests" / "data" / "clearance" / "rack_module.mtask"]
    ).timelines
    # female P99: the clearance pass still turns this arm there (38 deg); female P95's, where the
    # shoulder once turned 56 deg in a frame, is kept clear by the approach since the clearance
    # measures the forearm where it is deepest (session 22)
    timeline = schedule.for_manikin(timeline, ManikinSpec("gb10000_1988", "female", 99))
    ir = run_motion(timeline, DiagnosticSink(), until="carry")
    assert ir.frames is not None
    f = ir.frames
    rows = np.arange(0, len(f.time), 25)
    root = (f.root_position[rows], f.root_rotation[rows])
    turned, offset = swivel_clearance(ir.skeleton, f.q[rows], root, "l", np.array([0.0, 1.0]))
    pose = forward(ir.skeleton, f.q[rows], *root, with_axes=False)
    forearm = tuple(limb for limb in side_limbs("l") if limb.name.endswith("forearm"))
    assert turned[:, 0] == pytest.approx(clearance(ir.skeleton, pose, forearm).max(axis=1))
    bent = offset > 0.03
    assert bent.any()
    assert not np.allclose(turned[bent, 1], turned[bent, 0])  # a turn moves a bent forearm


@pytest.fixture(scope="module")
def rack() -> tuple[object, object]:
    (timeline,) = run_frontend(
        [ROOT / "tests" / "data" / "clearance" / "rack_module.mtask"]
    ).timelines
    # female P99: the clearance pass still turns this arm there (38 deg); female P95's, where the
    # shoulder once turned 56 deg in a frame, is kept clear by the approach since the clearance
    # measures the forearm where it is deepest (session 22)
    timeline = schedule.for_manikin(timeline, ManikinSpec("gb10000_1988", "female", 99))
    before = run_motion(timeline, DiagnosticSink(), until="carry")
    after = run_motion(timeline, DiagnosticSink(), until="clearance")
    return before, after


def test_the_low_latchs_shoulder_turns_no_faster_than_a_person(rack: tuple) -> None:
    before, after = rack
    fa = resample(after.frames, 30.0)
    names = after.skeleton.dof_names
    j = names.index("l_shoulder_rot")
    # the reach to the low latch, around its TA's end (25.03 s was asked for when the walk to
    # the bench stood on the bench's footprint)
    (latch,) = [s for s in after.segments if s.kind == "TA" and s.goal.site == "latch_low"
                and s.goal.effector == "l_hand"]  # fmt: skip
    near = np.flatnonzero(np.abs(fa.time - latch.end) <= 0.5)
    steps = np.degrees(np.abs(np.diff(fa.q[near, j])))
    assert steps.max() <= 12.0, f"{steps.max():.1f} deg in one output frame"
    # and the arm was corrected there: the case is still a case
    fb = resample(before.frames, 30.0)
    assert np.degrees(np.abs(fa.q[near, j] - fb.q[near, j])).max() > 5.0
    assert pass_clearance.SWIVEL_STEP > 0.0
