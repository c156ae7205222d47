"""A hand that lets go where the other hand still grips backs off (passes/withdraw.py).

Both hands at one knob on a box: the right one grips it, the left one steadies it and lets go,
then the right hand takes the knob's part away to a tray. Before the pass the left hand stayed
where the part was until its next goal, and the part went through it (the fuel filter CAD's
bowl, 50 mm in). Not an example: a procedure made for this, on two manikins.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from mtlc.body import forward, site_positions
from mtlc.diagnostics import DiagnosticSink
from mtlc.frontend import run_frontend
from mtlc.lint.manikins import parse_selection
from mtlc.passes import run_motion
from mtlc.passes.withdraw import WITHDRAW_DISTANCE

PROCEDURE = """use stdlib.actions
use stdlib.elements

scene bench {
    ground 0 cm
    box stand size (40, 80, 30) cm at (0, 40, 65) cm
    site front at (0, 0, 0) cm
    site knob at (0, 100, 50) cm normal (0, 0, -1)
    site tray at (-40, 90, 35) cm normal (0, 1, 0)
    site switch at (30, 110, 45) cm normal (0, 0, -1)
}

task steady_and_take {
    manikin gb10000_1988 female p50
    scene bench
    walk_to(front)
    reach(right, knob)
    parallel {
        grasp(right)
        reach(left, knob)
    }
    release(left)
    move(right, tray)
    release(right)
    press(left, switch)
}
"""


def _compile(tmp_path: Path, manikin: str):  # type: ignore[no-untyped-def]
    path = tmp_path / "withdraw.mtask"
    path.write_text(PROCEDURE, encoding="utf-8")
    program = run_frontend([path])
    assert not program.sink.has_errors
    (timeline,) = program.timelines
    timeline = dataclasses.replace(timeline, manikin=parse_selection(manikin)[0])
    return run_motion(timeline, DiagnosticSink())


@pytest.mark.parametrize("manikin", ["gb10000_1988:female:5", "gb10000_1988:male:95"])
def test_the_free_hand_backs_off_before_the_part_goes(tmp_path: Path, manikin: str) -> None:
    ir = _compile(tmp_path, manikin)
    (seg,) = [s for s in ir.on_track("l_arm") if s.goal.params.get("withdraw")]
    frames = ir.frames
    assert frames is not None and ir.skeleton is not None
    pose = forward(ir.skeleton, frames.q, frames.root_position, frames.root_rotation)
    left = site_positions(ir.skeleton, pose, "l_hand")
    right = site_positions(ir.skeleton, pose, "r_hand")
    t = frames.time
    at, done = np.searchsorted(t, seg.start), np.searchsorted(t, seg.end)
    # it went at least half the way (shoulder and elbow carry it: M95 5.9 of 8 cm), and away
    # from the right hand taking the part
    assert np.linalg.norm(left[done] - left[at]) >= 0.5 * WITHDRAW_DISTANCE
    assert np.linalg.norm(left[done] - right[done]) > np.linalg.norm(left[at] - right[at])
    # no one-frame jump in the arm on the way out or into its next reach (issue 19's 12 deg)
    arm = [i for i, n in enumerate(ir.skeleton.dof_names) if n.startswith("l_")]
    later = [s.start for s in ir.on_track("l_arm") if s.kind == "TA" and s.start > seg.end]
    stop = np.searchsorted(t, min(later) + 1.0)
    steps = np.abs(np.diff(frames.q[at:stop, arm], axis=0)).max()
    assert np.degrees(steps) <= 12.0
    # and the left hand still gets to the switch
    press = [s for s in ir.on_track("l_arm") if s.kind == "TO"][-1]
    assert press.result.get("distance", 1.0) <= 5e-3


def test_without_the_pass_the_free_hand_stays_in_the_parts_way(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The same procedure without the pass: the left hand keeps its pose at the knob while the
    right hand takes the part away (what the test above would catch)."""
    import mtlc.passes as passes

    without = [(name, step) for name, step in passes.MOTION_PASSES if name != "withdraw"]
    monkeypatch.setattr(passes, "MOTION_PASSES", without)
    ir = _compile(tmp_path, "gb10000_1988:female:5")
    assert not [s for s in ir.on_track("l_arm") if s.goal.params.get("withdraw")]
    frames = ir.frames
    assert frames is not None and ir.skeleton is not None
    pose = forward(ir.skeleton, frames.q, frames.root_position, frames.root_rotation)
    left = site_positions(ir.skeleton, pose, "l_hand")
    release = next(s for s in ir.on_track("l_hand") if s.kind == "grip" and
                   s.goal.params.get("state") == "open")  # fmt: skip
    at = np.searchsorted(frames.time, release.start)
    done = np.searchsorted(frames.time, release.start + 0.25)
    assert np.linalg.norm(left[done] - left[at]) < 0.01
