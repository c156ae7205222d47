"""Issue 19: an arm does not jump between two output frames, on procedures written for it.

tests/data/arms holds reaches across the body (a01), a box held in both hands moved from a low
shelf to a high one and down (a02) and fasteners turned at awkward sites, with a wrench and by
hand (a03), wrench strokes at arm's length and to the sides (a04). Each is compiled for the 14 GB 10000-88 manikins and the arm's dofs (clavicle,
shoulder, elbow, wrist, forearm) are read off the sampled output frames: no step over 12° from
one frame to the next at 30 fps, the wrist and forearm inside a fastener turn up to 20°
(bench/human.py's goal). What broke it: the two hands' part axis turning end over end when
interpolation brought the hands together (carry), and the IK's random restarts putting an arm
on another branch (the contact pass's torso line).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from mtlc.diagnostics import DiagnosticSink
from mtlc.frontend import run_frontend
from mtlc.ir.model import MotionIR
from mtlc.lint.manikins import all_manikins
from mtlc.passes import MotionOptions, run_motion
from mtlc.semantics.timeline import ManikinSpec

ROOT = Path(__file__).resolve().parents[2]
PROCEDURES = sorted((ROOT / "tests" / "data" / "arms").glob("*.mtask"))
ARM = ("clavicle_", "shoulder_", "elbow_flex", "wrist_", "elbow_pro")
TURNING = ("wrist_", "elbow_pro")
STEP = 12.0  # deg between two output frames
TURN_STEP = 20.0  # deg: the wrist and forearm inside a fastener turn

# (procedure, manikin) whose arm still steps further, and why (docs/passes.md, "Joint speed",
# "Arm branches": left); strict: a fix makes them pass and the entry goes
SHORT_TIME = (
    "the reach's time, paced by the hand's path, is short of what the arm's swing needs "
    "at 360 deg/s"
)
STROKES = (
    "a wrench's stroke keeps its MTM-1 time (0.54-0.59 s), short of what its joints need at "
    "330 deg/s (tool.phase_shares: the low side nut's swing alone needs 1.6x the stroke)"
)
FREE_ARM = (
    "the clearance pass's per-frame solve flicks the free left wrist one way and the other "
    "(+10, -13, +8 deg in three dense frames): its correction changes sign, which "
    "joint_speed.speed_limited cannot widen away"
)
KNOWN: dict[tuple[str, str], str] = {
    ("a01_across_body", "male-p95"): SHORT_TIME,  # 12.3 deg, the elbow
    ("a01_across_body", "female-p1"): SHORT_TIME,  # 18.7 deg: overhead to mid in 0.41 s
    **{("a03_awkward_turns", m): STROKES for m in ("male-p50", "male-p90", "male-p95")},
    ("a03_awkward_turns", "male-p99"): STROKES,
    ("a03_awkward_turns", "female-p5"): STROKES,
    # 12.1-13.6 deg (the far bolt's shoulder rotation; female P5 and P10: 21 deg of forearm roll
    # in the first stroke, the reach's end pose 65 deg of roll from the seated stroke's)
    **{("a04_wrench_strokes", m): STROKES for m in ("male-p5", "female-p1", "female-p5")},
    ("a04_wrench_strokes", "female-p10"): STROKES,
    ("a03_awkward_turns", "female-p90"): STROKES,  # 12.7 deg
    ("a03_awkward_turns", "female-p95"): STROKES,  # 15.3 deg, and the free wrist 20.9
    ("a03_awkward_turns", "female-p99"): FREE_ARM,  # 20.7 deg
}


def compile_for(path: Path, manikin: ManikinSpec) -> MotionIR:
    (timeline,) = run_frontend([path]).timelines
    timeline = dataclasses.replace(timeline, manikin=manikin)
    return run_motion(timeline, DiagnosticSink(), MotionOptions())


def turning_steps(ir: MotionIR) -> np.ndarray:
    """(N - 1,) steps between output frames that fall inside a fastener turn."""
    t = ir.frames.time  # type: ignore[union-attr]
    out = np.zeros(len(t) - 1, dtype=bool)
    for seg in ir.segments:
        if "turn_fastener" in seg.provenance.path:
            out |= (t[1:] > seg.start - 1e-9) & (t[:-1] < seg.end + 1e-9)
    return out


def arm_steps_over(ir: MotionIR) -> list[str]:
    """Every arm dof's steps over its limit: "dof at t: step"."""
    frames, names = ir.frames, ir.skeleton.dof_names
    assert frames is not None and frames.fps == 30.0
    steps = np.degrees(np.abs(np.diff(frames.q, axis=0)))
    turning = turning_steps(ir)
    over = []
    for j, name in enumerate(names):
        if name[:2] not in ("r_", "l_") or not any(a in name for a in ARM):
            continue
        limit = np.where(turning & any(a in name for a in TURNING), TURN_STEP, STEP)
        for i in np.flatnonzero(steps[:, j] > limit):
            over.append(f"{name} at {frames.time[i + 1]:.2f} s: {steps[i, j]:.1f} deg")
    return over


CASES = [
    pytest.param(
        path,
        m,
        id=f"{path.stem}-{m.sex}-p{m.percentile}",
        marks=[pytest.mark.xfail(strict=True, reason=KNOWN[(path.stem, key)])]
        if (key := f"{m.sex}-p{m.percentile}") and (path.stem, key) in KNOWN
        else [],
    )
    for path in PROCEDURES
    for m in all_manikins()
]


@pytest.mark.parametrize(("path", "manikin"), CASES)
def test_no_arm_jumps_between_frames(path: Path, manikin: ManikinSpec) -> None:
    ir = compile_for(path, manikin)
    assert arm_steps_over(ir) == []


def test_the_procedures_are_there() -> None:
    assert [p.stem for p in PROCEDURES] == [
        "a01_across_body",
        "a02_two_hands_high_low",
        "a03_awkward_turns",
        "a04_wrench_strokes",
    ]
