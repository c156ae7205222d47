"""A gait a gait lab would recognise (issue 19): the steps' time from stature and step length
(``semantics.gait``), and on the output frames of short walks, a turn and a carry: cadence,
swing time, pelvis excursion, ankle speed and the first frame's joint step. The old gait took
a 0.6 m walk in 0.54 s (222 steps/min, 0.2 s swings, the knee 5° -> 81° in the first frame)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from mtlc.body import forward
from mtlc.frontend import FrontendOptions, run_frontend
from mtlc.ir.model import MotionIR
from mtlc.metrics import foot_points
from mtlc.passes import run_motion
from mtlc.semantics import gait, schedule
from mtlc.semantics.timeline import ManikinSpec

SCENE = """use stdlib.actions
use stdlib.elements

scene floor {{
    ground 0 cm
    site near at (0, 0, 30) cm
    site metre at (30, 0, 130) cm
    site shelf at (35, 110, 185) cm normal (0, 0, -1)
    site side at (300, 100, 130) cm
    site box at (0, 95, 45) cm frame (0, 180, 0) deg
}}

task t {{
    scene floor
{body}
}}
"""
SWING_HEIGHT = 5e-3  # m: a foot whose lowest sole point is higher swings (bench/human.py)


def _compile(tmp_path: Path, body: str, sex: str, percentile: int) -> MotionIR:
    path = tmp_path / "walk.mtask"
    path.write_text(SCENE.format(body=body), encoding="utf-8")
    spec = ManikinSpec("gb10000_1988", sex, percentile)
    program = run_frontend([path], FrontendOptions(manikin=spec))
    assert not program.sink.has_errors
    return run_motion(program.timelines[0], program.sink)


def _gait_figures(ir: MotionIR) -> list[dict[str, float]]:
    """Per walk, from the output frames: steps (swing phases), cadence, shortest swing,
    pelvis excursion and fastest ankle (bench/human.py's definitions)."""
    f, skel = ir.frames, ir.skeleton
    assert f is not None and skel is not None
    pose = forward(skel, f.q, f.root_position, f.root_rotation)
    soles = foot_points(skel, pose)[..., 1] - ir.ground  # (N, 8): right foot's 4, left's 4
    dt = float(np.median(np.diff(f.time)))
    ankles = [pose.p[:, skel.joint_index(f"{s}_ankle")] for s in ("r", "l")]
    out = []
    for seg in ir.segments:
        if seg.kind != "locomotion" or seg.end - seg.start < dt:
            continue
        a = int(np.searchsorted(f.time, seg.start - 1e-9))
        b = min(int(np.searchsorted(f.time, seg.end - 1e-9)), len(f.time) - 1)
        swings = []
        for k in range(2):
            up = soles[a : b + 1, 4 * k : 4 * k + 4].min(axis=1) > SWING_HEIGHT
            edges = np.flatnonzero(np.diff(np.r_[0, up.astype(int), 0]))
            swings += [(j - i) * dt for i, j in zip(edges[::2], edges[1::2], strict=True)]
        pelvis = f.root_position[a : b + 1, 1]
        speed = max(
            float(np.max(np.linalg.norm(np.diff(p[a : b + 1], axis=0), axis=1))) / dt
            for p in ankles
        )
        out.append(
            {
                "steps": len(swings),
                "cadence": 60 * len(swings) / (seg.end - seg.start),
                "swing": min(swings),
                "pelvis": float(pelvis.max() - pelvis.min()),
                "ankle": speed,
            }
        )
    return out


def test_cadence_from_stature_and_step_length() -> None:
    """Rowe et al. 2011: 113 steps/min at 152 cm, 90 at 198 cm; shorter steps are slower (walk
    ratio), start, closing and pivot steps at 95 steps/min."""
    assert gait.free_cadence(1.52) == pytest.approx(113.0)
    assert gait.free_cadence(1.75) == pytest.approx(101.5)
    assert gait.free_cadence(2.1) == gait.SLOW_CADENCE
    full = gait.step_length(1.75, "male")
    assert full == pytest.approx(0.415 * 1.75)
    steady = gait.step_seconds(gait.WALK, full, full, 1.75)
    assert steady == pytest.approx(60 / 101.5)
    assert gait.step_seconds(gait.WALK, 0.9 * full, full, 1.75) > steady
    assert gait.step_seconds(gait.WALK, 0.1 * full, full, 1.75) == pytest.approx(60 / 95)
    assert gait.step_seconds(gait.PIVOT, 0.0, full, 1.75) == pytest.approx(60 / 95)
    assert gait.step_seconds(gait.START, full, full, 1.75) > gait.step_seconds(
        gait.CLOSE, full, full, 1.75
    )


def test_a_short_walk_takes_a_step_and_a_closing_step_at_a_human_cadence() -> None:
    """0.6 m: the MTM pace (0.54 s) was 222 steps/min for the two steps; now 93."""
    seconds = gait.walk_seconds(0.6, [], 1.57, "female", 0.02)
    assert seconds == pytest.approx((1.1 + 0.95) * 60 / 95)
    assert 90 <= 60 * 2 / seconds <= 125
    turn = gait.walk_seconds(0.0, [math.pi / 2], 1.57, "female", 0.02)
    assert turn == pytest.approx(4.1 * 60 / 95)  # three pivots and a closing step


@pytest.mark.parametrize(
    ("sex", "percentile"), [("female", 5), ("male", 95)], ids=["female-p5", "male-p95"]
)
def test_short_walks_on_the_frames_are_a_human_gait(
    tmp_path: Path, sex: str, percentile: int
) -> None:
    """0.3 m from rest, then 1 m to a shelf, and the first frame: the old gait failed every
    one of these (222 steps/min, 0.2 s swings, a 58-77° knee jump at frame 0)."""
    ir = _compile(tmp_path, "    walk_to(near)\n    walk_to(metre)\n    press(right, shelf)", sex,
                  percentile)  # fmt: skip
    f = ir.frames
    assert f is not None
    first = np.degrees(np.abs(f.q[1] - f.q[0])).max()
    assert first <= 12.0
    walks = _gait_figures(ir)
    assert len(walks) == 2
    assert walks[0]["steps"] == 2  # a step and a closing step, fewer than the metre's
    assert walks[1]["steps"] > walks[0]["steps"]
    for w in walks:
        assert 90.0 <= w["cadence"] <= 125.0, w
        assert w["swing"] >= 0.35, w
        assert w["pelvis"] <= 0.06, w
        assert w["ankle"] <= 5.0, w
    # the short walk's steps are slower than the metre's
    assert walks[0]["cadence"] <= walks[1]["cadence"] + 1e-9


def test_a_turn_in_place_and_a_carry_are_timed_as_steps(tmp_path: Path) -> None:
    """A 90° turn in place had MTM's 1.34 s for four pivot steps (179 steps/min)."""
    body = (
        "    reach(both, box)\n    grasp(both)\n    carry(both, metre, 6 kg)\n"
        "    travel_facing(metre, side)\n    release(both)"
    )
    ir = _compile(tmp_path, body, "female", 50)
    walks = _gait_figures(ir)
    assert len(walks) == 2
    for w in walks:
        assert 90.0 <= w["cadence"] <= 125.0, w
        assert w["swing"] >= 0.35, w
        assert w["pelvis"] <= 0.06, w


def test_a_walk_given_more_time_than_its_steps_takes_one_more_not_slower_ones() -> None:
    """A walk whose time (the front end's, for a longer distance) its steps would fill only
    below 90 steps/min takes one step more: the footing pass moved the access panel's bench
    stance 12 cm back for the 50th-percentile man and the walk there kept 7 steps in 5.15 s
    (81.6 steps/min)."""

    from mtlc.diagnostics import DiagnosticSink
    from mtlc.passes import MotionOptions

    root = Path(__file__).resolve().parents[2]
    (timeline,) = run_frontend([root / "examples" / "remove_access_panel_cad.mtask"]).timelines
    man = ManikinSpec("gb10000_1988", "male", 50)
    ir = run_motion(schedule.for_manikin(timeline, man), DiagnosticSink(), MotionOptions())
    walks = [s for s in ir.segments if s.kind == "locomotion" and s.result.get("steps")]
    assert any(s.result.get("stance_moved") for s in walks)  # the case this is about
    for seg in walks:
        cadence = 60.0 * len(seg.result["steps"]) / (seg.end - seg.start)
        assert 90.0 <= cadence <= 125.0, (seg.start, cadence)
