"""Issue 19: a reach that the corrections after pace bent is one bell of hand speed again.

tests/data/retime/r01 (a copy of bench/procedures/aircraft_panel_sideways): the right hand's
reach back to the relay behind the panel (line 33), female P90. Pace timed it as one bell
(LDLJ -6.6); clearance, pushing the forearm out of the trunk on the way, left the hand dipping
from 94 to 49 cm/s and back (-9.6). Measured on the output frames with bench/human.py's LDLJ:
re-timed, the reach scores better than -8 and better than without the pass by a point, no arm
joint in it turns faster than issue 19's 360 deg/s, and its first and last frames are those
clearance left.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from conftest import bench_human, compile_on, hands_apart, reach_on_frames

from mtlc import passes
from mtlc.body import forward, site_positions
from mtlc.ir.model import Frames, MotionIR
from mtlc.passes import retime
from mtlc.passes.sample import resample

ROOT = Path(__file__).resolve().parents[2]
RELAY = ROOT / "tests" / "data" / "retime" / "r01_relay_behind_panel.mtask"


@dataclass
class Relay:
    """The relay task compiled once (female P90): its output and the dense frames just before
    and just after the retime pass."""

    ir: MotionIR
    before: Frames
    after: Frames


@pytest.fixture(scope="module")
def relay() -> Relay:
    seen: dict[str, Frames] = {}
    at = [name for name, _ in passes.MOTION_PASSES].index("retime")

    def spy(ir: MotionIR, ctx: object) -> MotionIR:
        seen["before"] = copy.deepcopy(ir.frames)
        out = retime.run(ir, ctx)  # type: ignore[arg-type]
        seen["after"] = copy.deepcopy(out.frames)
        return out

    kept = passes.MOTION_PASSES[at]
    passes.MOTION_PASSES[at] = ("retime", spy)
    try:
        ir, _ = compile_on(RELAY, ("female", 90))
    finally:
        passes.MOTION_PASSES[at] = kept
    return Relay(ir, seen["before"], seen["after"])


def _relay_reach(ir: MotionIR, frames: Frames) -> tuple[float, float]:
    """LDLJ of the right hand over the reach of line 33 and its fastest arm joint (deg/s), on
    ``frames`` (the output's, or others at its rate)."""
    rows, _, dt, _ = reach_on_frames(ir, "relay", line=33)
    pose = forward(ir.skeleton, frames.q[rows], frames.root_position[rows],
                   frames.root_rotation[rows], with_axes=False)  # fmt: skip
    hand = np.asarray(site_positions(ir.skeleton, pose, ["r_hand"]))[:, 0]
    arm = [i for i, n in enumerate(ir.skeleton.dof_names) if n.startswith("r_")
           and not n.startswith(("r_hip", "r_knee", "r_ankle"))]  # fmt: skip
    speed = np.degrees(np.abs(np.diff(frames.q[np.ix_(rows, arm)], axis=0)).max()) / dt
    return bench_human()._ldlj(hand, dt), float(speed)


def test_the_relay_reach_is_one_bell_again(relay: Relay) -> None:
    out = relay.ir.frames
    assert out is not None
    now, speed = _relay_reach(relay.ir, out)
    assert now >= -8.0, f"LDLJ {now:.2f}"
    assert speed <= 360.0
    # the same reach as the frames came to the pass, at the output's rate
    was, _ = _relay_reach(relay.ir, resample(relay.before, out.fps))
    assert was < now - 1.0, f"{was:.2f} -> {now:.2f}"


def test_the_reach_keeps_its_ends(relay: Relay) -> None:
    fb, fa = relay.before, relay.after
    assert np.array_equal(fb.time, fa.time)
    (ta,) = [s for s in relay.ir.segments if s.kind == "TA" and s.goal.site == "relay"
             and s.provenance.origin.line == 33]  # fmt: skip
    (to,) = [s for s in relay.ir.segments if s.kind == "TO" and s.track == ta.track
             and abs(s.start - ta.end) < 1e-6]  # fmt: skip
    rows = np.flatnonzero((fa.time >= ta.start - 1e-9) & (fa.time <= to.end + 1e-9))
    assert np.array_equal(fa.q[rows[[0, -1]]], fb.q[rows[[0, -1]]])
    assert not np.array_equal(fa.q[rows], fb.q[rows])  # the pass re-timed it
    # the legs keep balance's clock, everywhere
    legs = [
        i
        for i, n in enumerate(relay.ir.skeleton.dof_names)
        if n[2:].startswith(("hip", "knee", "ankle"))
    ]
    assert np.array_equal(fa.q[:, legs], fb.q[:, legs])


BATTERY = ROOT / "tests" / "data" / "retime" / "r02_battery_to_bench.mtask"


def _battery_move(ir: MotionIR) -> tuple[float, float, float]:
    """Over the move onto the bench (line 18): the hands' worst LDLJ, the farthest a sole
    point goes (m) and how much the hands' distance changes (m)."""
    from mtlc.metrics import foot_points

    fr = ir.frames
    assert fr is not None
    rows, right, dt, _ = reach_on_frames(ir, "bench_top", line=18)
    _, left, _, _ = reach_on_frames(ir, "bench_top", line=18, effector="l_hand")
    pose = forward(ir.skeleton, fr.q[rows], fr.root_position[rows], fr.root_rotation[rows],
                   with_axes=False)  # fmt: skip
    soles = foot_points(ir.skeleton, pose)
    slip = float(np.linalg.norm(soles - soles[:1], axis=-1).max())
    ldlj = min(bench_human()._ldlj(right, dt), bench_human()._ldlj(left, dt))
    return ldlj, slip, float(np.ptp(hands_apart(ir, rows)))


def test_a_load_set_down_after_a_walk_is_one_bell_of_the_whole_body(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """tests/data/retime/r02 (bench/procedures/vehicle_battery's carry onto the bench), male
    P50: balance moved the pelvis back under the 14 kg as the arms set it down, and the hands,
    riding on the pelvis, started at 34 cm/s with a second peak (LDLJ -8.6). The whole body is
    run along its own poses again: one bell, the soles where they were, the battery as long."""
    ir, _ = compile_on(BATTERY, ("male", 50))
    now, slip, squeeze = _battery_move(ir)
    assert now >= -7.5, f"LDLJ {now:.2f}"
    assert slip <= 1e-3, f"soles moved {slip * 1000:.2f} mm"
    assert squeeze <= 1e-3, "the battery was squeezed"
    monkeypatch.setattr(retime, "_warpable", lambda ir, m: False)
    before, _ = compile_on(BATTERY, ("male", 50))
    was, _, _ = _battery_move(before)
    assert was < -8.0 and now > was + 1.0, f"{was:.2f} -> {now:.2f}"
