"""settle.kept_rows bounds the frames ``keep_until_keyed`` changes: the settle pass copies those
(not every frame of the motion, per walk and arm) to undo a let-down that goes into the body."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from mtlc.diagnostics import DiagnosticSink
from mtlc.frontend import run_frontend
from mtlc.passes import MotionOptions, run_motion
from mtlc.passes.hold import ARM_HAND, _arm_dofs
from mtlc.passes.settle import keep_until_keyed, kept_rows
from mtlc.semantics import schedule
from mtlc.semantics.timeline import ManikinSpec

STEPS = """use stdlib.actions
use stdlib.elements

scene bench {
    ground 0 cm
    site a at (0, 0, 0) cm
    site b at (120, 0, 0) cm
    site c at (240, 0, 0) cm
    site bolt at (125, 100, 55) cm normal (0, 0, -1)
    site tray at (215, 90, 40) cm normal (0, 1, 0)
}

task steps "Walk, reach, walk" {
    manikin gb10000_1988 female p5
    scene bench
    walk_to(b)
    reach(right, bolt)
    walk_to(c)
    reach(left, tray)
    walk_to(a)
}
"""


def test_keep_until_keyed_changes_no_frame_outside_kept_rows(tmp_path: Path) -> None:
    path = tmp_path / "steps.mtask"
    path.write_text(STEPS)
    program = run_frontend([path])
    assert not program.sink.has_errors, [d.message for d in program.sink.items]
    (timeline,) = program.timelines
    timeline = schedule.for_manikin(timeline, ManikinSpec("gb10000_1988", "female", 5))
    ir = run_motion(timeline, DiagnosticSink(), MotionOptions(), until="carry_pose")
    assert ir.frames is not None
    skel, frames = ir.skeleton, ir.frames
    walks = [(s.start, s.end) for s in ir.segments if s.kind == "locomotion"]
    assert len(walks) == 3
    checked = 0
    for start, end in walks:
        for hand in ARM_HAND.values():
            dofs = _arm_dofs(skel, hand)
            offset = np.full(len(dofs), 0.3)  # a large correction: every row it reaches moves
            rise = (start, start + 0.5 * (end - start))
            before = frames.q.copy()
            keep_until_keyed(skel, ir, frames, dofs, offset, rise)
            changed = np.flatnonzero((frames.q != before).any(axis=1))
            kept = kept_rows(skel, ir, frames, dofs, rise)
            frames.q[:] = before
            assert changed.size > 0
            assert kept.start <= changed[0] and changed[-1] < kept.stop, (start, hand)
            checked += 1
    assert checked == 6
