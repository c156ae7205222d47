"""A hand that let go of its site is free when the body stands up: the stand lets the whole arm
down to the comfort pose (issue 19, "end-of-task poses return to a natural stand"). Before, only
a hand that had never reached was free, and the drain task stood up with the hand that had
released the valve above the head (shoulder flexed 118°, hand 1.45 m up for a woman P5)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mtlc.body import forward, site_positions
from mtlc.frontend import run_frontend
from mtlc.ir.model import MotionIR
from mtlc.passes import run_motion
from mtlc.passes.posture import KNEEL_ARM_PARTS

TASK = """\
use stdlib.actions
use stdlib.elements

scene bench {{
    ground 0 cm
    site plug at (10, 25, 55) cm normal (0, 1, 0)
}}

task low_plug "Touch a low plug, then stand" {{
    manikin gb10000_1988 {sex} p{pct}
    scene bench
    squat(30 cm)
    reach(right, plug)
    grasp(right)
{release}    stand()
}}
"""


def compile_task(tmp_path: Path, sex: str, pct: int, release: bool) -> MotionIR:
    path = tmp_path / f"plug_{sex}{pct}_{release}.mtask"
    path.write_text(
        TASK.format(sex=sex, pct=pct, release="    release(right)\n" if release else "")
    )
    prog = run_frontend([path])
    assert prog.timelines, [d.message for d in prog.diagnostics]
    return run_motion(prog.timelines[0], prog.sink)


def last_pose(ir: MotionIR) -> tuple[np.ndarray, np.ndarray]:
    fr = ir.frames
    pose = forward(ir.skeleton, fr.q[-1:], fr.root_position[-1:], fr.root_rotation[-1:])
    return fr.q[-1], site_positions(ir.skeleton, pose, ["r_hand", "l_hand"]).reshape(2, 3)


@pytest.mark.parametrize(("sex", "pct"), [("female", 5), ("male", 95)])
def test_released_hand_comes_down_with_the_stand(tmp_path: Path, sex: str, pct: int) -> None:
    ir = compile_task(tmp_path, sex, pct, release=True)
    q, (right, left) = last_pose(ir)
    skel = ir.skeleton
    for part in KNEEL_ARM_PARTS:
        d = skel.dof_index(f"r_{part}")
        assert q[d] == pytest.approx(skel.q_comfort[d], abs=1e-6), part
    # the two hands hang alike: same height within 1 cm, mirrored across the body
    assert abs(right[1] - left[1]) < 0.01
    assert right[1] < 1.0  # below the hip-to-chest region of any manikin


def test_held_hand_is_not_let_down(tmp_path: Path) -> None:
    """Without the release the hand still holds the plug: the stand must not swing that arm to
    its comfort pose (it keeps its pose relative to the body, as before)."""
    held = compile_task(tmp_path, "female", 50, release=False)
    freed = compile_task(tmp_path, "female", 50, release=True)
    skel = held.skeleton
    rot = skel.dof_index("r_shoulder_flex")
    assert held.frames.q[-1, rot] != pytest.approx(freed.frames.q[-1, rot], abs=1e-3)
