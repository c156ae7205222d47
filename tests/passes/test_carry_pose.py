"""Issue 19: a part carried in both hands on a walk is held near the body, and the arms are
back where the place was solved from when the walk ends.

tests/data/carry holds two procedures written for it: a box taken off a shelf at shoulder
height and carried to a bench (c01), a 5 kg case lifted from a low rack to chest height and
carried to a cabinet (c02). Measured on the sampled frames: in the middle of the walk the
hands' mid-point is within 12 cm of the manikin's standing elbow height and closer to the
lumbar joint (horizontally) than when the walk started; the arms step at most 12 deg a frame
during the walk; the part keeps its length (the hands' distance); the walk's last frame has
the arms as the pass found them there.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import compile_on

from mtlc.body import forward, site_positions
from mtlc.ir.model import MotionIR
from mtlc.lint.manikins import all_manikins
from mtlc.passes.carry import carries
from mtlc.passes.carry_pose import elbow_height
from mtlc.semantics.timeline import ManikinSpec

ROOT = Path(__file__).resolve().parents[2]
PROCEDURES = sorted((ROOT / "tests" / "data" / "carry").glob("*.mtask"))
MANIKINS = [m for m in all_manikins() if (m.sex, m.percentile) in
            (("female", 5), ("male", 50), ("male", 95))]  # fmt: skip


def compile_for(path: Path, manikin: ManikinSpec, until: str | None = None) -> MotionIR:
    return compile_on(path, manikin, until=until)[0]


def carried_walk(ir: MotionIR) -> tuple[float, float]:
    spans = carries(ir)
    (walk,) = [
        (s.start, s.end)
        for s in ir.on_track("root")
        if s.kind == "locomotion" and any(c.start <= s.start and c.end >= s.end for c in spans)
    ]
    return walk


@pytest.mark.parametrize("manikin", MANIKINS, ids=lambda m: f"{m.sex}-p{m.percentile}")
@pytest.mark.parametrize("path", PROCEDURES, ids=lambda p: p.stem)
def test_the_carried_part_is_held_near_the_body_on_the_walk(
    path: Path, manikin: ManikinSpec
) -> None:
    ir = compile_for(path, manikin)
    fr, skel = ir.frames, ir.skeleton
    assert fr is not None
    start, end = carried_walk(ir)
    rows = np.flatnonzero((fr.time >= start) & (fr.time <= end))
    pose = forward(skel, fr.q[rows], fr.root_position[rows], fr.root_rotation[rows])
    hands = np.asarray(site_positions(skel, pose, ["r_hand", "l_hand"]))
    middle = hands.mean(axis=1)
    lumbar = pose.p[:, skel.joint_index("lumbar")]
    ahead = np.hypot(*(middle - lumbar)[:, [0, 2]].T)
    mid = len(rows) // 2
    assert abs(middle[mid, 1] - ir.ground - elbow_height(skel)) <= 0.12
    assert middle[0, 1] - middle[mid, 1] >= 0.15  # it came down from the shelf's height
    assert ahead[mid] <= ahead[0] + 0.01
    width = np.linalg.norm(hands[:, 0] - hands[:, 1], axis=1)
    assert np.ptp(width) <= 0.002  # the part stays rigid
    arms = [i for i, n in enumerate(skel.dof_names) if n[:2] in ("r_", "l_") and "_hip" not in n
            and "knee" not in n and "ankle" not in n and "toes" not in n]  # fmt: skip
    steps = np.degrees(np.abs(np.diff(fr.q[rows][:, arms], axis=0)))
    assert steps.max() <= 12.0


def test_the_walk_ends_with_the_arms_where_the_place_starts() -> None:
    path, manikin = PROCEDURES[0], MANIKINS[1]
    before = compile_for(path, manikin, until="hold")
    after = compile_for(path, manikin, until="carry_pose")
    start, end = carried_walk(after)
    t = after.frames.time
    last = int(np.flatnonzero(t <= end + 1e-9)[-1])
    middle = int(np.flatnonzero(t >= 0.5 * (start + end))[0])
    assert np.array_equal(after.frames.q[last + 1 :], before.frames.q[last + 1 :])
    assert np.abs(after.frames.q[last] - before.frames.q[last]).max() < 1e-3  # at rest there
    assert not np.allclose(after.frames.q[middle], before.frames.q[middle])


def test_the_procedures_are_there() -> None:
    assert [p.stem for p in PROCEDURES] == ["c01_shelf_to_bench", "c02_low_to_high"]
