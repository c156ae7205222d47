"""Issue 19: joints move at a person's speeds. Interpolation brings every dof to rest at its last
keyframe, and the drain's valve turns (a bare hand's twist) stay under 12 deg a frame at 30 fps."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from conftest import example_ir

from mtlc.passes.interpolate import _held_curve, track
from mtlc.passes.joint_speed import speed_limited

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
    ir = example_ir(ROOT / "examples" / "drain_hydraulic_reservoir.mtask")
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


def test_a_correction_is_widened_in_time_not_made_smaller() -> None:
    """A 0.4 rad correction on frames 20-29 of a still dof (60 fps), blended in over one frame,
    turned it at 24 rad/s; widened, it ramps at the speed given and covers what it covered."""
    t = np.arange(60) / 60.0
    q = np.zeros((60, 2))
    dq = np.zeros((60, 2))
    dq[20:30, 0] = 0.4
    dq[40:45, 1] = -0.2
    fixed = np.zeros(60, dtype=bool)
    fixed[45:] = True  # a held hand keeps its own correction
    lo, hi = np.full(2, -1.0), np.full(2, 1.0)
    out = speed_limited(q, dq, lo, hi, t, speed=6.0, fixed=fixed)
    steps = np.abs(np.diff(q + out, axis=0)) * 60.0
    assert steps[:, 0].max() <= 6.0 + 1e-6
    assert steps[:40, 1].max() <= 6.0 + 1e-6  # (into the held frames it cannot ramp)
    assert np.all(np.abs(out) >= np.abs(dq) - 1e-12)
    assert np.all(np.sign(out[dq != 0]) == np.sign(dq[dq != 0]))
    assert np.array_equal(out[45:], dq[45:])
    assert out[10, 0] == 0.0 and out[18, 0] > 0.0  # started where it had to, not before


def test_a_correction_slow_enough_is_kept_as_it_is() -> None:
    t = np.arange(30) / 60.0
    q = np.linspace(0.0, 1.0, 30)[:, None]  # the motion turns at 2 rad/s
    dq = 0.05 * np.sin(np.linspace(0.0, np.pi, 30))[:, None]
    out = speed_limited(q, dq, np.array([-3.0]), np.array([3.0]), t, speed=6.0)
    assert np.array_equal(out, dq)
