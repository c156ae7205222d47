"""A part picked up and then taken somewhere goes with the body through the postures between.

Before, a squat, kneel or stand with a hand closed on a part kept the hand on the part's site
whatever came next: picking a panel off the floor and standing up dragged the hand along the
floor while the body rose (MT0511: 1.45 m for a male P50 in bench/procedures'
aircraft_panel_sideways, fingertips 15-40 mm under the floor, MT0512). The rule
(``hold.carried_postures``): a closed grip that takes its part somewhere before it opens (a
move, or a walk) carries it through every posture on the way; one that nothing takes anywhere
(a handle held through a kneel) keeps it where it is (tests/passes/test_holds.py's kneel).
Measured on the sampled frames by forward kinematics.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mtlc.body import forward, site_positions
from mtlc.frontend import run_frontend
from mtlc.passes import run_motion
from mtlc.semantics import schedule
from mtlc.semantics.timeline import ManikinSpec

PICK_UP = """use stdlib.actions
use stdlib.elements

scene store {
    ground 0 cm
    site here at (0, 0, 0) cm
    site box at (10, 3, 45) cm normal (0, 1, 0)
    site shelf at (-15, 110, 40) cm normal (0, 1, 0)
}

task pick_up "Pick a box off the floor, stand, put it on a shelf" {
    manikin gb10000_1988 male p50
    scene store
    squat()
    pick(right, box)
    stand()
    place(right, shelf)
}
"""
PICK_LINE = 15


@pytest.mark.parametrize("sex,pct", [("female", 5), ("male", 50), ("male", 95)])
def test_a_part_picked_off_the_floor_rises_with_the_body(
    tmp_path: Path, sex: str, pct: int
) -> None:
    path = tmp_path / "pick_up.mtask"
    path.write_text(PICK_UP, encoding="utf-8")
    program = run_frontend([path])
    (timeline,) = program.timelines
    timeline = schedule.for_manikin(timeline, ManikinSpec("gb10000_1988", sex, pct))
    ir = run_motion(timeline, program.sink)
    f = ir.frames
    assert f is not None
    found = {(d.code, d.span.line) for d in program.sink.items}
    assert ("MT0511", PICK_LINE) not in found  # no slip claimed: the part goes with the hand
    assert not {c for c, _ in found} & {"MT0512", "MT0900"}  # no finger under the floor
    (stand,) = [s for s in ir.segments if s.goal.params.get("posture") == "stand"]
    pose = forward(ir.skeleton, f.q, f.root_position, f.root_rotation)
    hand = site_positions(ir.skeleton, pose, "r_hand")
    before = int(np.searchsorted(f.time, stand.start - 1e-9))
    after = int(np.searchsorted(f.time, stand.end - 1e-9))
    # the hand holding the box comes up with the body (the pelvis rises ~0.3-0.5 m)
    assert hand[after, 1] - hand[before, 1] > 0.2
    # and no frame puts the hand's site under the floor
    assert hand[:, 1].min() > -1e-3


def test_a_box_picked_off_the_floor_comes_up_below_the_shoulder(tmp_path: Path) -> None:
    """Seen in the preview: a person stands up with a box at about waist height, not overhead."""
    path = tmp_path / "pick_up.mtask"
    path.write_text(PICK_UP, encoding="utf-8")
    program = run_frontend([path])
    (timeline,) = program.timelines
    timeline = schedule.for_manikin(timeline, ManikinSpec("gb10000_1988", "male", 50))
    ir = run_motion(timeline, program.sink)
    f = ir.frames
    assert f is not None
    (stand,) = [s for s in ir.segments if s.goal.params.get("posture") == "stand"]
    end = int(np.searchsorted(f.time, stand.end - 1e-9))
    pose = forward(ir.skeleton, f.q[end : end + 1], f.root_position[end : end + 1],
                   f.root_rotation[end : end + 1])  # fmt: skip
    hand = site_positions(ir.skeleton, pose, "r_hand")[0]
    shoulder = pose.p[0, ir.skeleton.joint_index("r_shoulder")]
    assert hand[1] < shoulder[1]
