"""The IR's clock warped by the pace pass (issue 19): a reach too short for its joints lasts
longer, everything alongside it keeps its place relative to it, everything after it waits."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mtlc.diagnostics import DiagnosticSink
from mtlc.frontend import run_frontend
from mtlc.ir.model import GoalSpec, Keyframes, MotionIR, Provenance, Segment, SourceRef
from mtlc.passes import MotionOptions, run_motion
from mtlc.passes.pace import PEAK_JOINT_SPEED, ReachPath, needed_time
from mtlc.passes.timewarp import Stretch, TimeWarp, apply
from mtlc.semantics import schedule
from mtlc.semantics.timeline import ManikinSpec

ROOT = Path(__file__).resolve().parents[2]
REF = SourceRef("t.mtask", 1, 1, 1, 1)


def segment(start: float, end: float, result: dict | None = None) -> Segment:
    times = np.linspace(start, end, 5)
    return Segment(
        "r_arm", "TA", start, end, GoalSpec("r_hand"), Provenance(("t",), REF, REF),
        Keyframes(time=times, dofs=("r_elbow_flex",), q=np.zeros((5, 1))), result or {},
    )  # fmt: skip


def test_warp_scales_the_window_and_delays_what_follows() -> None:
    warp = TimeWarp.of([Stretch(2.0, 3.0, 0.5), Stretch(5.0, 6.0, 1.0)])
    t = np.array([0.0, 1.0, 2.0, 2.5, 3.0, 4.0, 5.0, 5.5, 6.0, 9.0])
    assert np.allclose(warp(t), [0.0, 1.0, 2.0, 2.75, 3.5, 4.5, 5.5, 6.5, 7.5, 10.5])
    assert warp.total == pytest.approx(1.5)
    assert np.all(np.diff(warp(np.linspace(0.0, 10.0, 1001))) > 0.0)  # still increasing


def test_overlapping_stretch_is_left_out() -> None:
    warp = TimeWarp.of([Stretch(2.0, 3.0, 0.5), Stretch(2.5, 3.5, 1.0)])
    assert warp.total == pytest.approx(0.5)


def test_apply_moves_windows_keys_and_result_times_but_not_positions() -> None:
    steps = [{"foot": "r", "t_lift": 4.0, "t_land": 4.5, "from": [4.0, 0.0, 4.0]}]
    ir = MotionIR("t", None, "t.mtask", {}, 0.0, [])
    before = segment(0.0, 1.0)
    inside = segment(1.0, 2.0)
    phases = {"seat": [3.0, 3.2], "swing": [3.2, 4.0]}  # a wrench stroke's
    after = segment(
        3.0, 5.0, {"steps": steps, "feet_held_until": 5.0, "distance": 4.0, "phases": phases}
    )
    kneel = segment(3.0, 5.0, {"phases": [{"name": "down", "start": 3.0, "end": 4.0}]})
    ir.segments = [before, inside, after, kneel]
    apply(ir, TimeWarp.of([Stretch(1.0, 2.0, 1.0)]))
    assert (before.start, before.end) == (0.0, 1.0)
    assert (inside.start, inside.end) == (1.0, 3.0)
    assert np.allclose(inside.keyframes.time, np.linspace(1.0, 3.0, 5))
    assert (after.start, after.end) == (4.0, 6.0)
    assert after.result["steps"][0]["t_lift"] == 5.0 and after.result["steps"][0]["t_land"] == 5.5
    assert after.result["steps"][0]["from"] == [4.0, 0.0, 4.0]  # a position, not a time
    assert after.result["feet_held_until"] == 6.0 and after.result["distance"] == 4.0
    assert after.result["phases"] == {"seat": [4.0, 4.2], "swing": [4.2, 5.0]}
    assert kneel.result["phases"] == [{"name": "down", "start": 4.0, "end": 5.0}]


def test_needed_time_is_the_minimum_jerk_peak_over_the_joint_speed() -> None:
    s = np.linspace(0.0, 1.0, 101)
    path = ReachPath(s, np.stack([2.0 * s, 0.5 * s], axis=1))  # 2 rad on the fastest dof
    assert needed_time(path) == pytest.approx(1.875 * 2.0 / PEAK_JOINT_SPEED, rel=1e-3)


def test_a_swing_too_fast_for_its_time_is_given_more(tmp_path: Path) -> None:
    """tests/data/arms a01 for the smallest woman: an overhead press and then a reach across the
    body took 0.41 s for 156 deg of shoulder flexion (18.7 deg a frame); now no arm dof of the
    paced reaches turns faster than 360 deg/s on the dense frames, and the task lasts longer."""
    (timeline,) = run_frontend([ROOT / "tests/data/arms/a01_across_body.mtask"]).timelines
    timeline = schedule.for_manikin(timeline, ManikinSpec("gb10000_1988", "female", 1))
    ir = run_motion(timeline, DiagnosticSink(), MotionOptions(), until="pace")
    paced = [s for s in ir.segments if s.result.get("paced")]
    assert paced
    for seg in paced:
        kf = seg.keyframes
        assert kf is not None and len(kf.time) >= 2
        rate = np.abs(np.diff(kf.q, axis=0)) / np.diff(kf.time)[:, None]
        assert np.degrees(rate.max()) <= 330.0, seg.provenance.path
    assert ir.duration > timeline_duration(timeline) + 0.3


def timeline_duration(timeline: object) -> float:
    """The timeline's own end: the MTM times before any stretch."""
    ir = run_motion(timeline, DiagnosticSink(), MotionOptions(), until="gaze")  # type: ignore[arg-type]
    return ir.duration
