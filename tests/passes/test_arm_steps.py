"""Issue 19: an arm does not jump between two output frames, on procedures written for it.

tests/data/arms holds reaches across the body (a01), a box held in both hands moved from a low
shelf to a high one and down (a02) and fasteners turned at awkward sites, with a wrench and by
hand (a03), wrench strokes at arm's length and to the sides (a04). Each is compiled for 10 of the 14 GB 10000-88 manikins (``PERCENTILES``) and the arm's dofs (clavicle,
shoulder, elbow, wrist, forearm) are read off the sampled output frames: no step over 12° from
one frame to the next at 30 fps, the wrist and forearm inside a fastener turn up to 20°
(bench/human.py's goal). What broke it: the two hands' part axis turning end over end when
interpolation brought the hands together (carry), the IK's random restarts putting an arm
on another branch (the contact pass's torso line), and a wrench's strokes swinging the shoulder
faster than a person's in the stroke's MTM time (the joint_speed pass gives them the time).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import compile_on

from mtlc.ir.model import MotionIR
from mtlc.lint.manikins import all_manikins
from mtlc.semantics.timeline import ManikinSpec

ROOT = Path(__file__).resolve().parents[2]
PROCEDURES = sorted((ROOT / "tests" / "data" / "arms").glob("*.mtask"))
ARM = ("clavicle_", "shoulder_", "elbow_flex", "wrist_", "elbow_pro")
TURNING = ("wrist_", "elbow_pro")
STEP = 12.0  # deg between two output frames
TURN_STEP = 20.0  # deg: the wrist and forearm inside a fastener turn

# (procedure, manikin) whose arm still steps further, and why; strict: a fix makes them pass
# and the entry goes. None left since the joint_speed pass (the strokes' and reaches' time from
# what their joints need), the speed-limited corrections of balance and clearance, and the
# two envelopes of speed_limited clamped where their signs overlap (a03 female P99's wrist).
KNOWN: dict[tuple[str, str], str] = {}
# the extremes and the middle of each sex (10 of the 14 manikins: the suite's time; bench/motion.py
# measures every manikin's steps on the examples and the bench's procedures)
PERCENTILES = (1, 5, 50, 95, 99)


def compile_for(path: Path, manikin: ManikinSpec) -> MotionIR:
    return compile_on(path, manikin)[0]


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
    if m.percentile in PERCENTILES
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
