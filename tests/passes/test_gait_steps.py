"""No leg dof moves more than 12° between two output frames while walking (issue 19: at
30 fps, 360°/s; a knee straightening for the landing took 12-15° a frame, the swing foot
lifted 12 cm and the knee bent to 75°, and a rear foot's limit roll jumped 4° -> 13° in a
frame). Short, long and turning walks on the smallest woman, a middle man and the largest man."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mtlc.frontend import FrontendOptions, run_frontend
from mtlc.passes import run_motion
from mtlc.semantics.timeline import ManikinSpec

WALKS = """use stdlib.actions
use stdlib.elements

scene floor {
    ground 0 cm
    site half at (0, 0, 50) cm
    site corner at (0, 0, 350) cm
    site aside at (-150, 0, 350) cm
    site wall at (-250, 100, 350) cm
    site back at (0, 0, 0) cm
}

task t {
    scene floor
    walk_to(half)
    walk_to(corner)
    travel_facing(aside, wall)
    walk_to(back)
}
"""
LEG_DOFS = ("hip_", "knee_", "ankle_")
MAX_STEP = 12.0  # degrees between two 30 fps output frames


@pytest.mark.parametrize(
    ("sex", "percentile"),
    [("female", 1), ("male", 50), ("male", 99)],
    ids=["female-p1", "male-p50", "male-p99"],
)
def test_walking_legs_move_at_most_12_degrees_a_frame(
    tmp_path: Path, sex: str, percentile: int
) -> None:
    path = tmp_path / "walks.mtask"
    path.write_text(WALKS, encoding="utf-8")
    program = run_frontend(
        [path], FrontendOptions(manikin=ManikinSpec("gb10000_1988", sex, percentile))
    )
    assert not program.sink.has_errors
    ir = run_motion(program.timelines[0], program.sink)
    f, skel = ir.frames, ir.skeleton
    assert f is not None and skel is not None
    assert float(np.median(np.diff(f.time))) == pytest.approx(1 / 30)
    dofs = list(skel.dof_names)
    legs = [j for j, n in enumerate(dofs) if n[2:].startswith(LEG_DOFS)]
    assert len(legs) == 12
    steps = np.degrees(np.abs(np.diff(f.q[:, legs], axis=0)))
    mid = (f.time[1:] + f.time[:-1]) / 2
    walks = [s for s in ir.segments if s.kind == "locomotion"]
    assert len(walks) == 4
    walking = np.zeros(len(mid), dtype=bool)
    for s in walks:
        assert s.result["steps"]  # every walk steps
        walking |= (mid >= s.start - 0.2) & (mid <= s.end + 0.2)
    worst = steps[walking].max(axis=0)
    names = [dofs[j] for j in legs]
    over = {n: round(float(w), 1) for n, w in zip(names, worst, strict=True) if w > MAX_STEP}
    assert not over, over
    assert steps[walking].max() > 3.0  # the legs do move: the bound is not met by standing
