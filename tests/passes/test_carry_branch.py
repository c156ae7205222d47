"""Issue 19: a part lifted overhead in both hands does not flip a shoulder in one frame.

The carry pass re-solves both arms on every frame of a two-handed hold; near the shoulder's
overhead singularity two neighbouring frames converged to two IK branches (a lid lifted from
85 to 185 cm: female P50's left shoulder abduction 95 deg and male P1's 101 deg in one output
frame). tests/data/overhead/o01 is that lift, on a scene written for it; the arm's dofs are
read off the output frames as in test_arm_steps.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import compile_on

from mtlc.ir.model import MotionIR
from mtlc.passes.carry import _let_go_at_branch_jumps
from mtlc.semantics.timeline import ManikinSpec

ROOT = Path(__file__).resolve().parents[2]
LID = ROOT / "tests" / "data" / "overhead" / "o01_lid_overhead.mtask"
ARM = ("clavicle_", "shoulder_", "elbow_flex", "wrist_", "elbow_pro")
STEP = 12.0  # deg between two output frames at 30 fps


def compile_for(manikin: ManikinSpec) -> MotionIR:
    return compile_on(LID, manikin)[0]


@pytest.mark.parametrize(("sex", "percentile"), [("female", 50), ("male", 1), ("female", 10)])
def test_no_shoulder_flip_on_an_overhead_lift(sex: str, percentile: int) -> None:
    ir = compile_for(ManikinSpec("gb10000_1988", sex, percentile))
    frames, names = ir.frames, ir.skeleton.dof_names
    assert frames is not None and frames.fps == 30.0
    steps = np.degrees(np.abs(np.diff(frames.q, axis=0)))
    arm = [j for j, n in enumerate(names) if n[:2] in ("r_", "l_") and any(a in n for a in ARM)]
    worst = {names[j]: round(float(steps[:, j].max()), 1) for j in arm if steps[:, j].max() > STEP}
    assert worst == {}


def test_a_branch_jump_in_the_correction_is_let_go_of_smoothly() -> None:
    t = np.arange(120) / 60.0
    correction = np.where(t[:, None] < 1.0, np.radians(-50.0), np.radians(50.0)) * np.ones((1, 3))
    out = _let_go_at_branch_jumps(t, correction)
    assert out is not None
    assert np.degrees(np.abs(np.diff(out, axis=0))).max() < 6.0  # 12 deg at 30 fps
    assert np.allclose(out[[0, -1]], correction[[0, -1]])  # far from the jump it is kept
    smooth = np.radians(np.linspace(0.0, 20.0, 120))[:, None] * np.ones((1, 3))
    assert _let_go_at_branch_jumps(t, smooth) is None  # nothing jumps: nothing to let go of
