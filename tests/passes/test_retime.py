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

from pathlib import Path

import numpy as np
import pytest
from conftest import bench_human, compile_on, reach_on_frames

from mtlc.passes import retime

ROOT = Path(__file__).resolve().parents[2]
RELAY = ROOT / "tests" / "data" / "retime" / "r01_relay_behind_panel.mtask"


def _relay_reach() -> tuple[float, float]:
    """LDLJ of the right hand over the reach of line 33 and its fastest arm joint (deg/s), on
    the output frames."""
    ir, _ = compile_on(RELAY, ("female", 90))
    assert ir.frames is not None
    rows, hand, dt, _ = reach_on_frames(ir, "relay", line=33)
    arm = [i for i, n in enumerate(ir.skeleton.dof_names) if n.startswith("r_")
           and not n.startswith(("r_hip", "r_knee", "r_ankle"))]  # fmt: skip
    speed = np.degrees(np.abs(np.diff(ir.frames.q[np.ix_(rows, arm)], axis=0)).max()) / dt
    return bench_human()._ldlj(hand, dt), float(speed)


def test_the_relay_reach_is_one_bell_again(monkeypatch: pytest.MonkeyPatch) -> None:
    now, speed = _relay_reach()
    assert now >= -8.0, f"LDLJ {now:.2f}"
    assert speed <= 360.0
    monkeypatch.setattr(retime, "RETIME_FROM", -np.inf)
    was, _ = _relay_reach()
    assert was < now - 1.0, f"{was:.2f} -> {now:.2f}"


def test_the_reach_keeps_its_ends() -> None:
    before, _ = compile_on(RELAY, ("female", 90), until="clearance")
    after, _ = compile_on(RELAY, ("female", 90), until="retime")
    fb, fa = before.frames, after.frames
    assert fb is not None and fa is not None
    assert np.array_equal(fb.time, fa.time)
    rows, _, _, _ = reach_on_frames(after, "relay", line=33)
    assert np.array_equal(fa.q[rows[[0, -1]]], fb.q[rows[[0, -1]]])
    assert not np.array_equal(fa.q[rows], fb.q[rows])  # the pass re-timed it
    # the legs keep balance's clock, everywhere
    legs = [
        i
        for i, n in enumerate(after.skeleton.dof_names)
        if n[2:].startswith(("hip", "knee", "ankle"))
    ]
    assert np.array_equal(fa.q[:, legs], fb.q[:, legs])
