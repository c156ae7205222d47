"""A released arm with nothing to do for a while comes down (passes/rest.py).

The right hand turns a knob overhead and lets go; the left hand then works for seconds. Before,
the right arm stayed up at the knob (shoulder flexed 130° for 15 s over an overhead hatch) and
ergonomics scored an arm doing nothing. Not an example: a procedure made for this.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mtlc.body import part_site_positions
from mtlc.diagnostics import DiagnosticSink
from mtlc.frontend import run_frontend
from mtlc.lint.manikins import parse_selection
from mtlc.passes import run_motion
from mtlc.passes.rest import REST_TIME
from mtlc.semantics import schedule

PROCEDURE = """use stdlib.actions
use stdlib.elements

scene panel {{
    site spot at (0, 0, 0) cm
    site knob at (20, 135, 38) cm normal (0, 0, -1)
    site switch at (-25, 120, 45) cm normal (0, 0, -1)
}}

task knobs {{
    manikin gb10000_1988 male p50
    scene panel
    walk_to(spot)
{before}    reach(right, knob)
    grasp(right)
    turn(right, 90 deg)
    release(right)
{between}    reach(right, knob)
    grasp(right)
    release(right)
}}
"""
LEFT_WORK = "    press(left, switch)\n    inspect(switch, 3 s)\n"


def _compile(tmp_path: Path, between: str, before: str = "", manikin: str | None = None):  # type: ignore[no-untyped-def]
    path = tmp_path / "rest.mtask"
    path.write_text(PROCEDURE.format(before=before, between=between), encoding="utf-8")
    program = run_frontend([path])
    assert not program.sink.has_errors
    (timeline,) = program.timelines
    if manikin is not None:
        timeline = schedule.for_manikin(timeline, parse_selection(manikin)[0])
    sink = DiagnosticSink()
    return timeline, run_motion(timeline, sink), sink


def _rests(ir) -> list:  # type: ignore[no-untyped-def]
    return [s for s in ir.segments if s.kind == "rest"]


@pytest.mark.parametrize(
    "manikin", ["gb10000_1988:female:50", "gb10000_1988:male:50", "gb10000_1988:male:95"]
)
def test_an_idle_released_arm_comes_down_and_reaches_again_from_there(
    tmp_path: Path, manikin: str
) -> None:
    _, ir, sink = _compile(tmp_path, LEFT_WORK, manikin=manikin)
    (rest,) = [s for s in _rests(ir) if s.track == "r_arm"]
    f = ir.frames
    cols = [ir.skeleton.dof_index(n) for n in ("r_shoulder_flex", "r_shoulder_abd")]
    flex = np.degrees(f.q[:, cols]).max(axis=1)  # the arm's elevation, forward or sideways
    (second,) = [s for s in ir.segments if s.kind == "TA" and s.track == "r_arm"][1:]
    idle = (f.time > rest.end + 0.05) & (f.time < second.start - 0.05)
    assert idle.any() and flex[idle].max() < 30.0  # down at the side, not up at the knob
    assert flex[f.time < rest.start].max() > 40.0  # it was up there
    steps = np.degrees(np.abs(np.diff(f.q, axis=0))).max(axis=1)
    way = (f.time[1:] >= rest.start) & (f.time[1:] <= rest.end)
    assert steps[way].max() <= 12.0  # a person's pace down, no jump
    assert rest.end - rest.start == pytest.approx(REST_TIME)
    assert not [d for d in sink.items if d.code in ("MT0501", "MT0510", "MT0514")]


def test_the_reach_after_the_rest_is_timed_from_the_side(tmp_path: Path) -> None:
    """The front end times the second reach as a reach from the hand's side (longer), where
    right after the release it is a reach from the knob to itself (no travel)."""
    rested, _, _ = _compile(tmp_path, LEFT_WORK)
    quick, _, _ = _compile(tmp_path, "")

    def second_reach(timeline) -> float:  # type: ignore[no-untyped-def]
        goals = [p for p in timeline.primitives if p.kind == "goal" and p.params["site"] == "knob"]
        return goals[-1].end - goals[-1].start

    assert second_reach(rested) > second_reach(quick) + 0.1


def test_a_short_pause_keeps_the_arm_where_it_is(tmp_path: Path) -> None:
    _, ir, _ = _compile(tmp_path, "    inspect(switch, 0.5 s)\n")
    assert [s for s in _rests(ir) if s.track == "r_arm"] == []


def test_an_arm_beside_a_leaned_trunk_stays_where_it_is(tmp_path: Path) -> None:
    """Female P5 leans her trunk 30° sideways to the knob, and the reach's lean stays: an arm
    let down beside it would go into the thigh (the tutorial's lamp: 16 mm), so it is kept
    (``posture.REST_TRUNK_LEAN``), with no finding either way."""
    _, ir, sink = _compile(tmp_path, LEFT_WORK, manikin="gb10000_1988:female:5")
    (rest,) = [s for s in _rests(ir) if s.track == "r_arm"]
    kf = rest.keyframes
    assert kf is not None and np.abs(kf.q - kf.q[0]).max() == 0.0
    assert not [d for d in sink.items if d.code == "MT0514"]


def test_a_squatting_body_does_not_hang_its_arm(tmp_path: Path) -> None:
    """Squatting, a hanging arm goes into the thighs: the squat places free arms itself."""
    _, ir, _ = _compile(tmp_path, LEFT_WORK, before="    squat(20 cm)\n")
    assert _rests(ir) == []  # neither arm


def test_the_grasp_after_a_rest_starts_where_the_rest_left_the_arm() -> None:
    """tests/data/arms/a01 (female P5): the right arm rests between two presses and then grasps a
    knob across the body, reached with the arm alone. The rest segment used to key the clavicle
    too: restated after the contacts had moved it, the grasp ended 81 mm off the knob and the
    hold's re-solve stepped the shoulder 19 deg in one frame."""
    path = Path(__file__).parents[1] / "data" / "arms" / "a01_across_body.mtask"
    program = run_frontend([path])
    (timeline,) = program.timelines
    timeline = schedule.for_manikin(timeline, parse_selection("gb10000_1988:female:5")[0])
    ir = run_motion(timeline, DiagnosticSink())
    assert [s for s in ir.segments if s.kind == "rest" and s.track == "r_arm"]
    skel, f = ir.skeleton, ir.frames
    arm = [i for i, n in enumerate(skel.dof_names) if n.startswith("r_") and "leg" not in n]
    arm = [i for i in arm if skel.dof_names[i].split("_")[1] in ("clavicle", "shoulder", "elbow")]
    steps = np.degrees(np.abs(np.diff(f.q[:, arm], axis=0)))
    assert steps.max() < 12.0, steps.max()
    grasp = next(s for s in ir.segments if s.kind == "TO" and s.goal.site == "knob_left_mid")
    k = int(np.argmin(np.abs(f.time - grasp.end)))
    rows = slice(k, k + 1)
    hand = part_site_positions(
        skel, f.q[rows], f.root_position[rows], f.root_rotation[rows], ["r_hand"]
    )
    assert np.linalg.norm(hand[0, 0] - grasp.goal.position) < 0.005  # on the frames, not the solve
