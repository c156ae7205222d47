"""`stand()` after a reach that leaned the trunk: the body straightens, over the stand's time.

The front end dropped a `stand()` whenever no posture had bent the body, so after a reach to the
floor (the trunk leaned 90° by the reach itself) the manikin stayed bent for the rest of the
task. And the posture pass, solved before the reaches, keyed the stand from an upright trunk:
the restated first key took the lean, and the trunk came up 60° in the 0.3 s to the next key.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mtlc.diagnostics import DiagnosticSink
from mtlc.frontend import run_frontend
from mtlc.lint.manikins import parse_selection
from mtlc.passes import run_motion
from mtlc.semantics import schedule

PROCEDURE = """use stdlib.actions
use stdlib.elements

scene store {{
    site spot at (0, 0, 0) cm
    site low at (10, 30, 45) cm normal (0, 1, 0)
    site high at (0, 190, 40) cm
}}

task reach_low {{
    manikin gb10000_1988 male p50
    scene store
    walk_to(spot)
{steps}
}}
"""
LOW = "    reach(right, low)\n    grasp(right)\n    release(right)\n"
TRUNK = ("lumbar_flex", "thorax_flex")


def _compile(tmp_path: Path, steps: str, manikin: str | None = None):  # type: ignore[no-untyped-def]
    path = tmp_path / "stand.mtask"
    path.write_text(PROCEDURE.format(steps=steps), encoding="utf-8")
    program = run_frontend([path])
    assert not program.sink.has_errors
    (timeline,) = program.timelines
    if manikin is not None:
        timeline = schedule.for_manikin(timeline, parse_selection(manikin)[0])
    return timeline, run_motion(timeline, DiagnosticSink())


def _stands(timeline) -> list:  # type: ignore[no-untyped-def]
    return [p for p in timeline.primitives if p.params.get("posture") == "stand"]


def test_a_stand_after_a_walk_alone_is_no_motion(tmp_path: Path) -> None:
    timeline, _ = _compile(tmp_path, "    stand()\n")
    assert _stands(timeline) == []


def test_a_stand_after_a_reach_is_a_posture(tmp_path: Path) -> None:
    timeline, _ = _compile(tmp_path, LOW + "    stand()\n")
    assert len(_stands(timeline)) == 1


@pytest.mark.parametrize("manikin", ["gb10000_1988:female:5", "gb10000_1988:male:95"])
def test_the_trunk_a_reach_leaned_comes_up_over_the_stand(tmp_path: Path, manikin: str) -> None:
    _, ir = _compile(tmp_path, LOW + "    stand()\n    look(high)\n", manikin)
    (stand,) = [s for s in ir.segments if s.kind == "posture" and s.track == "root"]
    f = ir.frames
    cols = [ir.skeleton.dof_index(n) for n in TRUNK]
    trunk = np.degrees(f.q[:, cols].sum(axis=1))
    at = lambda t: int(np.argmin(np.abs(f.time - t)))  # noqa: E731
    leaned = trunk[at(stand.start)]
    assert leaned > 30.0  # the reach to 30 cm leaned it
    assert abs(trunk[-1]) < 2.0  # and the body stands straight at the end
    # over the stand's time, not in its first fifth: a third of the lean is left at 40 %
    assert trunk[at(stand.start + 0.4 * (stand.end - stand.start))] > leaned / 3
    steps = np.abs(np.diff(trunk[at(stand.start) : at(stand.end) + 1]))
    assert steps.max() < 6.0, steps.max()  # degrees per output frame
