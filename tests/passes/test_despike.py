"""The despike pass (issue 19): a few frames of the upper body out and back faster than a person
moves are given the straight way between their neighbours, the hands with goals kept on it."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from mtlc.body.kinematics import forward, site_positions
from mtlc.frontend import FrontendOptions, run_frontend
from mtlc.passes import MOTION_PASSES, run_motion
from mtlc.passes.despike import SPIKE_SPEED, SPIKE_TIME, spikes, straight, upper_body
from mtlc.semantics.timeline import ManikinSpec

ROOT = Path(__file__).resolve().parents[2]
LIMIT = math.radians(360.0)
T = np.arange(40) / 60.0


def test_a_two_frame_spike_is_found_between_its_neighbours() -> None:
    q = np.zeros((40, 2))
    q[:, 0] = np.linspace(0.0, 0.5, 40)  # a motion at 45 deg/s
    q[20:22, 0] += math.radians(27.0)  # out and back in two frames
    assert spikes(q, T, LIMIT, SPIKE_TIME) == [(19, 22)]
    fixed = q.copy()
    fixed[20:22] = straight(q, T, 19, 22)
    assert np.allclose(fixed[:, 0], np.linspace(0.0, 0.5, 40))


def test_a_fast_ramp_is_no_spike() -> None:
    """A joint that turns fast one way (a jump, not out and back) cannot be mended by its
    neighbours: it is left to the passes that time the motion."""
    q = np.zeros((40, 1))
    q[20:, 0] = math.radians(14.0)
    assert spikes(q, T, LIMIT, SPIKE_TIME) == []
    q = np.cumsum(np.full((40, 1), math.radians(7.0)), axis=0)  # 420 deg/s throughout
    assert spikes(q, T, LIMIT, SPIKE_TIME) == []


def test_a_longer_excursion_is_not_taken_for_a_spike() -> None:
    q = np.zeros((40, 1))
    q[10:30, 0] = math.radians(20.0)  # out for a third of a second: a movement
    assert spikes(q, T, LIMIT, SPIKE_TIME) == []


@settings(max_examples=60, deadline=None)
@given(
    start=st.integers(1, 30),
    width=st.integers(1, 5),
    height=st.floats(8.0, 90.0),
    sign=st.sampled_from([-1.0, 1.0]),
)
def test_every_short_spike_on_a_slow_motion_is_found_and_straightened(
    start: int, width: int, height: float, sign: float
) -> None:
    q = np.linspace(0.0, 0.3, 40)[:, None]
    q = np.hstack([q, -q])
    q[start : start + width, 1] += sign * math.radians(height)
    runs = spikes(q, T, LIMIT, SPIKE_TIME)
    assert runs == [(start - 1, start + width)]
    a, b = runs[0]
    q[a + 1 : b] = straight(q, T, a, b)
    steps = np.abs(np.diff(q, axis=0))
    assert steps.max() <= LIMIT / 60.0


def test_the_upper_body_is_the_spine_the_neck_and_the_arms() -> None:
    prog = run_frontend([ROOT / "examples" / "remove_access_panel.mtask"])
    ir = run_motion(prog.timelines[0], prog.sink, until="manikin")
    names = [ir.skeleton.dof_names[j] for j in upper_body(ir.skeleton)]
    assert "lumbar_flex" in names and "l_wrist_dev" in names and "neck_rot" in names
    assert not any(n.split("_")[1] in ("hip", "knee", "ankle", "toes") for n in names)


def test_the_pump_kneels_wrist_no_longer_turns_out_and_back() -> None:
    """bench/procedures/pump_low_kneel, female P90: balance put the right hand back on the
    filter with the arm on its other branch for two frames (the wrist 27 deg out and back in
    two output frames). Now no upper-body dof steps over 12 deg in an output frame there, and
    the right hand still comes to rest on the filter as it did (the pass keeps it on the way
    between its neighbours' places: 1.4 and 0.8 cm in the two output frames before, 1.2 and
    0.9 now)."""
    # after every pass that moves an arm on the dense frames (clearance, retime), before sample
    names = [n for n, _ in MOTION_PASSES]
    assert names.index("clearance") < names.index("retime") < names.index("despike")
    assert names.index("despike") == names.index("sample") - 1
    options = FrontendOptions(manikin=ManikinSpec("gb10000_1988", "female", 90))
    prog = run_frontend([ROOT / "bench" / "procedures" / "pump_low_kneel.mtask"], options)
    ir = run_motion(prog.timelines[0], prog.sink)
    f = ir.frames
    assert f is not None
    sel = np.flatnonzero(np.abs(f.time - 27.3) < 0.2)
    cols = upper_body(ir.skeleton)
    steps = np.degrees(np.abs(np.diff(f.q[sel][:, cols], axis=0)))
    assert steps.max() <= 12.0, steps.max()
    pose = forward(ir.skeleton, f.q[sel], f.root_position[sel], f.root_rotation[sel])
    hand = site_positions(ir.skeleton, pose, "r_hand")
    moves = np.linalg.norm(np.diff(hand, axis=0), axis=1)  # m per output frame
    arrived = np.flatnonzero(f.time[sel][1:] > 27.4)
    assert moves[arrived].max() < 0.015, moves
    assert SPIKE_SPEED == LIMIT
