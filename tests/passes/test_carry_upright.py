"""Issue 19: a walk that carries a part is made upright, the part near the body.

A walk kept the trunk the lift before it left: 46 of 140 carried walks on bench/procedures and
the examples went bent more than 10 deg from start to end. tests/data/carry_upright holds two
procedures written for this: a toolbox picked off a low step in one hand (u01) and a crate taken
off a low shelf in both hands (u02), each carried a few metres. Measured on the sampled frames:
in the middle of the walk the trunk is within 5 deg of its rest pose and a hand carrying on its
own has the elbow near 90 deg; no arm or trunk dof steps more than 12 deg a frame over the walk;
the walk's first and last frames are the pass's input there (the place after it starts where it
was solved from).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import compile_on

from mtlc.ir.model import MotionIR
from mtlc.lint.manikins import all_manikins
from mtlc.passes.carry_pose import carried_alone
from mtlc.passes.settle import TRUNK
from mtlc.semantics.timeline import ManikinSpec

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT / "tests" / "data" / "carry_upright"
PROCEDURES = sorted(DATA.glob("*.mtask"))
MANIKINS = [m for m in all_manikins() if (m.sex, m.percentile) in
            (("female", 5), ("male", 50), ("male", 95))]  # fmt: skip
UPPER = ("lumbar", "thorax", "neck", "r_shoulder", "l_shoulder", "r_elbow", "l_elbow", "r_wrist",
         "l_wrist", "r_clavicle", "l_clavicle")  # fmt: skip


def carried_walk(ir: MotionIR) -> tuple[float, float, list[str]]:
    """The walk during which a hand holds a part, and the arms that hold it."""
    (walk,) = [
        (s.start, s.end, carried_alone(ir, s.start, s.end))
        for s in ir.on_track("root")
        if s.kind == "locomotion" and carried_alone(ir, s.start, s.end)
    ]
    return walk


@pytest.mark.parametrize("manikin", MANIKINS, ids=lambda m: f"{m.sex}-p{m.percentile}")
@pytest.mark.parametrize("path", PROCEDURES, ids=lambda p: p.stem)
def test_the_carried_walk_is_upright(path: Path, manikin: ManikinSpec) -> None:
    ir = compile_on(path, manikin)[0]
    fr, skel = ir.frames, ir.skeleton
    assert fr is not None and skel is not None
    start, end, tracks = carried_walk(ir)
    rows = np.flatnonzero((fr.time >= start) & (fr.time <= end))
    mid = rows[len(rows) // 2]
    trunk = [skel.dof_index(n) for n in TRUNK]
    rest = np.asarray(skel.q_comfort, dtype=float)
    assert np.degrees(np.abs(fr.q[mid, trunk] - rest[trunk])).max() <= 5.0
    before = np.degrees(np.abs(fr.q[rows[0], trunk] - rest[trunk])).max()
    assert before >= 15.0  # the lift left it bent: the test would pass on nothing otherwise
    if len(tracks) == 1:  # one hand: the elbow bent at the carry pose
        elbow = skel.dof_index(f"{tracks[0][0]}_elbow_flex")
        assert abs(np.degrees(fr.q[mid, elbow]) - 90.0) <= 10.0
    upper = [i for i, n in enumerate(skel.dof_names) if n.startswith(UPPER)]
    steps = np.degrees(np.abs(np.diff(fr.q[rows][:, upper], axis=0)))
    assert steps.max() <= 12.0


def test_the_walk_ends_where_the_place_was_solved_from() -> None:
    """The pass's ramps end inside the walk: after it the frames are what the pass found."""
    path, manikin = PROCEDURES[0], MANIKINS[1]
    before = compile_on(path, manikin, until="hold")[0]
    after = compile_on(path, manikin, until="carry_pose")[0]
    start, end, _ = carried_walk(after)
    t = after.frames.time
    last = int(np.flatnonzero(t <= end + 1e-9)[-1])
    first = int(np.flatnonzero(t >= start - 1e-9)[0])
    assert np.array_equal(after.frames.q[last + 1 :], before.frames.q[last + 1 :])
    assert np.abs(after.frames.q[last] - before.frames.q[last]).max() < 1e-3  # at rest there
    assert np.array_equal(after.frames.q[:first], before.frames.q[:first])
    assert np.abs(after.frames.q[first] - before.frames.q[first]).max() < 1e-3
    middle = int(np.flatnonzero(t >= 0.5 * (start + end))[0])
    assert not np.allclose(after.frames.q[middle], before.frames.q[middle])


def test_the_procedures_are_there() -> None:
    assert [p.stem for p in PROCEDURES] == ["u01_toolbox_from_floor", "u02_crate_from_low_shelf"]
