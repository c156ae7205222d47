"""Root postures with hands that hold or touch something move at a person's joint speeds
(issue 19): tests/data/pose, a hand left on a screw or a box held in both hands through a
kneel, a squat from the kneel and a stand.

Before: a posture right after a kneel anchored its root on the plan's feet from its first
frame, 25-53 cm from where the kneel left the pelvis, in one frame; the smoothing pass blended
that jump out, and re-pinning the held hand through it turned a shoulder up to 135 deg in one
output frame; a fingertip lifted off the floor flipped the wrist 150 deg between frames
(docs/passes.md, "Joint speed").
"""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest

from mtlc.frontend import FrontendOptions, run_frontend
from mtlc.ir.model import MotionIR
from mtlc.passes import run_motion
from mtlc.semantics.timeline import ManikinSpec

DATA = Path(__file__).resolve().parents[1] / "data" / "pose"
STEP_LIMIT = 12.0  # degrees between two 30 fps output frames (issue 19's 360 deg/s)
TURN_LIMIT = 20.0  # ...for the wrist and forearm in a fastener turn
TURN_DOFS = ("wrist_", "elbow_pro")
ROOT_STEP = 0.015  # m between two interpolated frames (60 fps) around a posture's start


def compile_ir(name: str, sex: str, pct: int, until: str | None = None) -> MotionIR:
    options = FrontendOptions(manikin=ManikinSpec("gb10000_1988", sex, pct))
    prog = run_frontend([DATA / f"{name}.mtask"], options)
    assert prog.timelines, [d.message for d in prog.diagnostics]
    return run_motion(prog.timelines[0], prog.sink, until=until)


def worst_step(ir: MotionIR) -> tuple[float, str, float]:
    """The largest one-frame step (deg) of any dof on the output frames, its dof and time;
    the wrist and forearm inside a fastener turn count against ``TURN_LIMIT`` instead (scaled
    onto ``STEP_LIMIT``), as bench/human.py judges them."""
    frames = ir.frames
    assert frames is not None
    steps = np.degrees(np.abs(np.diff(frames.q, axis=0)))
    mid = 0.5 * (frames.time[1:] + frames.time[:-1])
    turning = np.zeros(len(mid), dtype=bool)
    for seg in ir.segments:
        if "turn_fastener" in seg.provenance.path[-1]:
            turning |= (mid >= seg.start) & (mid <= seg.end)
    turn_cols = [j for j, n in enumerate(ir.skeleton.dof_names) if n[2:].startswith(TURN_DOFS)]
    steps[np.ix_(turning, turn_cols)] *= STEP_LIMIT / TURN_LIMIT
    i, j = np.unravel_index(int(np.argmax(steps)), steps.shape)
    return float(steps[i, j]), ir.skeleton.dof_names[j], float(frames.time[i + 1])


@pytest.mark.parametrize(
    ("name", "sex", "pct"),
    [
        ("p01_screw_kneel_squat", "male", 50),
        # balance re-solved a pinned arm next to a frame that could not take the correction
        # (52 deg at de4bc45): passes since the sixth round (docs/passes.md, issue 19)
        ("p01_screw_kneel_squat", "female", 5),
        # the held box's arm stepped 19 deg at the elbow: passes since the speed limit's two
        # envelopes are clamped as a sum (joint_speed.clamped, session 12)
        ("p02_hold_squat_pick", "female", 5),
        # the pelvis correction stopped where the knee touched down (17 deg): passes since
        # the kneel's spine starts where the body really is (session 18, ``restate_kneel``)
        ("p03_hand_on_site_squat", "male", 95),
    ],
)  # fmt: skip
def test_no_dof_steps_over_12_deg_through_kneel_and_squat(name: str, sex: str, pct: int) -> None:
    step, dof, t = worst_step(compile_ir(name, sex, pct))
    assert step <= STEP_LIMIT, f"{dof} steps {step:.1f} deg at {t:.2f} s"


@pytest.mark.parametrize(
    ("name", "sex", "pct"),
    [
        ("p01_screw_kneel_squat", "female", 5),
        ("p01_screw_kneel_squat", "male", 95),
        ("p02_hold_squat_pick", "female", 50),
    ],
)
def test_a_posture_after_a_kneel_starts_where_the_kneel_left_the_pelvis(
    name: str, sex: str, pct: int
) -> None:
    """On the interpolated frames (before any correction) the root moves no more than
    ``ROOT_STEP`` a frame from the start of each posture that follows a kneel (it moved
    252-533 mm in one frame)."""
    ir = compile_ir(name, sex, pct, until="interpolate")
    frames = ir.frames
    assert frames is not None
    postures = sorted(
        (s for s in ir.on_track("root") if s.kind == "posture"), key=lambda s: s.start
    )
    after_kneel = [
        b for a, b in itertools.pairwise(postures)
        if a.goal.params.get("posture") == "kneel" and b.goal.params.get("posture") != "stand"
    ]  # fmt: skip
    assert after_kneel
    for seg in after_kneel:
        assert seg.result.get("root") == "keyed"
        # from the frame before the posture's start (the kneel's own last steps are its plan's)
        near = np.flatnonzero((frames.time >= seg.start - 0.02) & (frames.time <= seg.start + 0.1))
        moved = np.linalg.norm(np.diff(frames.root_position[near], axis=0), axis=1)
        assert moved.max() <= ROOT_STEP, f"{moved.max() * 1000:.0f} mm at {seg.start:.2f} s"


def test_a_lifted_fingertip_turns_the_wrist_one_way() -> None:
    """p03, male P50: the free left hand's fingertips go under the floor in the squat; the
    wrist lifts them turning one way (it flipped 150 deg between two frames)."""
    ir = compile_ir("p03_hand_on_site_squat", "male", 50)
    frames = ir.frames
    assert frames is not None
    k = ir.skeleton.dof_index("l_wrist_flex")
    assert np.degrees(np.abs(np.diff(frames.q[:, k]))).max() <= STEP_LIMIT
