"""Issue 19: joints move at a person's speeds. Interpolation brings every dof to rest at its last
keyframe, and the drain's valve turns (a bare hand's twist) stay under 12 deg a frame at 30 fps."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from mtlc.frontend import run_frontend
from mtlc.passes import run_motion
from mtlc.passes.interpolate import _held_curve, track

ROOT = Path(__file__).resolve().parents[2]


def test_a_dof_comes_to_rest_at_its_last_keyframe() -> None:
    """PCHIP's end slope is extrapolated from the last intervals: without the hold knot after
    the last keyframe a dof keyed 0 -> 1 -> 3 stopped dead at full speed."""
    parts = [(np.array([1.0, 2.0, 3.0]), 0, np.array([0.0, 1.0, 3.0]))]
    knots_t, knots_v = _held_curve(parts, 0.0)
    grid = np.linspace(0.0, 4.0, 4001)
    q = track(knots_t, knots_v, grid)
    speed = np.gradient(q, grid)
    at_end = np.searchsorted(grid, 3.0)
    assert q[at_end] == 3.0 and np.all(q[at_end:] == 3.0)
    assert abs(speed[at_end - 2]) < 0.05  # arriving at rest, not at 2 units/s
    assert np.all(np.diff(q[: at_end + 1]) >= 0.0)  # and no overshoot on the way


def test_the_drains_valve_turns_stay_under_12_deg_a_frame() -> None:
    program = run_frontend([ROOT / "examples" / "drain_hydraulic_reservoir.mtask"])
    ir = run_motion(program.timelines[0], program.sink)
    frames = ir.frames
    assert frames is not None and frames.fps == 30.0
    d = ir.skeleton.dof_index("r_elbow_pro")
    twists = [s for s in ir.segments if s.goal.params.get("posture") == "twist"]
    assert len(twists) == 2
    for seg in twists:
        inside = (frames.time >= seg.start - 1e-9) & (frames.time <= seg.end + 1e-9)
        steps = np.degrees(np.abs(np.diff(frames.q[inside, d])))
        turned = abs(np.degrees(frames.q[inside, d][-1] - frames.q[inside, d][0]))
        assert turned > 30.0  # the valve's quarter turn, short of it at the forearm's stop
        assert steps.max() <= 12.0, steps.max()
