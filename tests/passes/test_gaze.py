"""The gaze pass keeps the eyes on the work: the head follows every reach no look covers."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from conftest import example_until
from hypothesis import given, settings
from hypothesis import strategies as st

from mtlc.frontend import run_frontend
from mtlc.ir.model import GoalSpec, Keyframes, MotionIR, Provenance, Segment, SourceRef
from mtlc.lint import LintConfig, lint_paths
from mtlc.passes import run_motion
from mtlc.passes.gaze import (
    SAMPLE_STEP,
    TURN_MAX,
    TURN_MIN,
    Stretch,
    aim_errors,
    body_at,
    sample_times,
    target_at,
    targets_at,
    turn_time,
)

ROOT = Path(__file__).resolve().parents[2]
ONE_DEG = math.radians(1.0)

# A knob reached without a look, a dial looked at while the other hand sets off (the look wins
# over the reach it overlaps), and a shelf behind the manikin that no neck turns far enough for.
KNOB = """\
use stdlib.actions
use stdlib.elements

scene bench {
    ground 0 cm
    site knob at (25, 110, 40) cm normal (0, 0, -1)
    site dial at (-30, 95, 35) cm normal (0, 0, -1)
    site shelf at (0, 150, -40) cm normal (0, 1, 0)
}

task turn_knob "Reach a knob without looking first" {
    manikin gb10000_1988 male p50
    scene bench
    reach(right, knob)
    parallel {
        look(dial)
        reach(left, dial)
    }
    release(right)
    reach(right, shelf)
}
"""
SHELF_LINE = 20


def compile_until_gaze(path: Path) -> MotionIR:
    prog = run_frontend([path])
    assert prog.timelines, [d.message for d in prog.diagnostics]
    return run_motion(prog.timelines[0], prog.sink, until="gaze")


@pytest.fixture(scope="module")
def knob_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("gaze") / "knob.mtask"
    path.write_text(KNOB, encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def knob(knob_file: Path) -> MotionIR:
    return compile_until_gaze(knob_file)


def implicit(ir: MotionIR, site: str | None = None) -> list[Segment]:
    return [
        s
        for s in ir.segments
        if s.kind == "gaze" and s.goal.params.get("implicit") and site in (None, s.goal.site)
    ]


def angles_at(ir: MotionIR, times: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Angle (rad) between the head's axis and the line to ``target``, as interpolated."""
    body = body_at(ir, np.asarray(times, dtype=float))
    targets = np.broadcast_to(target, (len(times), 3))
    return aim_errors(ir.skeleton, body.q, body.root_position, body.root_rotation, targets)


def contact_times(ir: MotionIR, site: str) -> tuple[np.ndarray, np.ndarray]:
    """Every keyframe time of the TO segments on ``site``, and the site's position."""
    tos = [s for s in ir.segments if s.kind == "TO" and s.goal.site == site]
    assert tos and all(s.keyframes is not None for s in tos)
    times = np.concatenate([s.keyframes.time for s in tos if s.keyframes is not None])
    return times, np.asarray(tos[0].goal.position, dtype=float)


def test_head_follows_a_reach_nobody_looked_at(knob: MotionIR) -> None:
    (seg,) = implicit(knob, "knob")
    assert seg.result["success"] and seg.result["angle_error"] <= ONE_DEG
    times, site = contact_times(knob, "knob")
    assert len(times) >= 5
    assert angles_at(knob, times, site).max() <= ONE_DEG
    # the trunk moves during the reach: the head is solved along it, not only at its end
    kf = seg.keyframes
    assert kf is not None and np.diff(kf.time[1:]).max() <= SAMPLE_STEP + 1e-9  # after the turn


def test_tracking_holds_at_every_contact_keyframe_of_the_examples() -> None:
    """Access panel (5th-percentile woman): the bolts and the handle are within the neck's
    range, so the head is on them at every keyframe of every TO."""
    ir, _ = example_until(ROOT / "examples" / "remove_access_panel.mtask", "gaze")
    for site in ("bolt_upper_left", "bolt_lower_right", "panel_handle"):
        heads = implicit(ir, site)
        assert heads and all(s.result["success"] for s in heads)
        times, _ = contact_times(ir, site)
        aimed = np.asarray(heads[-1].goal.position)  # two hands on the handle: their midpoint
        assert angles_at(ir, times, aimed).max() <= ONE_DEG, site


def test_head_turns_over_a_realistic_time(knob: MotionIR) -> None:
    """The first reach starts at 0 s with the head straight ahead: it holds, then turns for
    at least TURN_MIN before it is on the knob; the turn is spread over the samples between."""
    (seg,) = implicit(knob, "knob")
    kf = seg.keyframes
    assert kf is not None
    np.testing.assert_allclose(kf.q[0], knob.skeleton.q_comfort[[
        knob.skeleton.dof_index(n) for n in kf.dofs]], atol=1e-12)  # fmt: skip
    assert kf.time[1] - kf.time[0] >= TURN_MIN - 1e-9
    late = angles_at(knob, kf.time[1:], np.asarray(seg.goal.position))
    assert late.max() <= ONE_DEG


def test_head_keyframes_stay_within_the_neck_limits(knob: MotionIR) -> None:
    skel = knob.skeleton
    segs = [s for s in knob.segments if s.kind == "gaze"]
    assert len(segs) == 3  # knob; the look at the dial; the dial then the shelf (one stretch)
    for seg in segs:
        kf = seg.keyframes
        assert kf is not None
        idx = [skel.dof_index(n) for n in kf.dofs]
        assert set(kf.dofs) == {"neck_flex", "neck_lat", "neck_rot", "head_flex", "head_lat"}
        assert (kf.q >= skel.lower[idx] - 1e-9).all() and (kf.q <= skel.upper[idx] + 1e-9).all()


def test_site_behind_stays_out_of_view_and_lint_reports_it(knob: MotionIR, knob_file: Path) -> None:
    (seg,) = implicit(knob, "shelf")
    assert seg.result["success"] is False and seg.result["angle_error"] > math.radians(30)
    found = lint_paths([knob_file], LintConfig()).findings
    lines = {f.span.line for f in found if f.code == "MT0607"}
    assert SHELF_LINE in lines
    (shelf,) = [f for f in found if f.code == "MT0607" and f.span.line == SHELF_LINE]
    assert "`shelf`" in shelf.message


def test_explicit_look_wins_where_it_overlaps_a_reach(knob: MotionIR) -> None:
    (look,) = [s for s in knob.segments if s.kind == "gaze" and not s.goal.params]
    assert look.goal.site == "dial"
    for seg in implicit(knob):
        kf = seg.keyframes
        assert kf is not None
        inside = (kf.time > look.start + 1e-9) & (kf.time < look.end - 1e-9)
        assert not inside.any(), seg.goal.site
    (after,) = implicit(knob, "shelf")  # the dial's reach, a release, the shelf: one stretch
    assert after.start == pytest.approx(look.end)  # the work's head takes over where it ends
    assert look.result["angle_error"] <= ONE_DEG


def test_same_input_gives_the_same_head(knob: MotionIR, knob_file: Path) -> None:
    again = compile_until_gaze(knob_file)
    for a, b in zip(implicit(knob), implicit(again), strict=True):
        assert a.keyframes is not None and b.keyframes is not None
        assert a.keyframes.time.tobytes() == b.keyframes.time.tobytes()
        assert a.keyframes.q.tobytes() == b.keyframes.q.tobytes()


# -- the parts, without a body -----------------------------------------------------------------


def reach(kind: str, start: float, end: float, at: tuple[float, float, float]) -> Segment:
    ref = SourceRef("t.mtask", 1, 1, 1, 2)
    goal = GoalSpec("r_hand", "s", np.array(at, dtype=float))
    kf = Keyframes(time=np.linspace(start, end, 3))
    return Segment("r_arm", kind, start, end, goal, Provenance(("t",), ref, ref), kf)


def test_target_prefers_contact_then_the_midpoint() -> None:
    a = reach("TA", 0.0, 1.0, (0.0, 1.0, 0.5))
    b = reach("TA", 0.0, 1.0, (0.4, 1.0, 0.5))
    c = reach("TO", 0.5, 1.0, (1.0, 2.0, 0.5))
    hit = target_at([a, b], 0.2)
    assert hit is not None
    np.testing.assert_allclose(hit[0], [0.2, 1.0, 0.5])
    hit = target_at([a, b, c], 0.7)
    assert hit is not None and hit[1] is c
    np.testing.assert_allclose(hit[0], [1.0, 2.0, 0.5])
    twin = reach("TA", 0.0, 1.0, (0.0, 1.0, 0.5))
    hit = target_at([a, twin], 0.5)  # one site is not averaged with itself
    assert hit is not None
    np.testing.assert_allclose(hit[0], [0.0, 1.0, 0.5])
    assert target_at([a], 1.5) is None


def test_targets_at_many_times_is_target_at_each() -> None:
    """The batched look-up gives what one look-up a time gives, at the windows' edges too."""
    a = reach("TA", 0.0, 1.0, (0.0, 1.0, 0.5))
    b = reach("TA", 0.5, 1.5, (0.4, 1.0, 0.5))
    c = reach("TO", 0.75, 1.0, (1.0, 2.0, 0.5))
    times = np.r_[np.linspace(-0.2, 1.8, 81), 1.0 + 1e-10, 1.5 + 2e-9, 0.5 - 1e-10]
    got = targets_at([a, b, c], times)
    for t, hit in zip(times, got, strict=True):
        want = target_at([a, b, c], float(t))
        assert (hit is None) == (want is None)
        if hit is not None and want is not None:
            assert hit[1] is want[1] and np.array_equal(hit[0], want[0])
    assert sum(h is None for h in got) > 0 and len({id(h[1]) for h in got if h}) == 3
    assert targets_at([], times) == [None] * len(times)


@given(st.floats(0.0, math.pi))
def test_turn_time_is_between_the_bounds_and_grows(angle: float) -> None:
    t = turn_time(angle)
    assert TURN_MIN - 1e-12 <= t <= TURN_MAX + 1e-12
    assert turn_time(angle + 0.1) >= t


@settings(max_examples=50)
@given(
    st.floats(0.0, 5.0),
    st.floats(0.01, 3.0),
    st.lists(st.floats(0.0, 1.0), max_size=12),
)
def test_samples_cover_the_part_densely(start: float, length: float, marks: list[float]) -> None:
    end = start + length
    seg = reach("TO", start, end, (0.0, 1.0, 0.5))
    seg.keyframes = Keyframes(time=np.array([start + m * length for m in marks] or [start]))
    times = sample_times(Stretch(start, end, [seg]))
    assert times[0] == pytest.approx(start, abs=1e-8) and times[-1] == pytest.approx(end, abs=1e-8)
    assert (np.diff(times) > 0).all() and np.diff(times).max() <= SAMPLE_STEP + 1e-9
    for t in seg.keyframes.time:
        assert np.isclose(times, t, atol=1e-8, rtol=0).any()


# A valve low and to the side, then a walk away: the head turned to the valve faces ahead again
# as the walk sets off (it walked with the head on the valve before), and a stand at the end
# brings it back from a look as well.
SET_OFF = """\
use stdlib.actions
use stdlib.elements

scene yard {
    ground 0 cm
    site valve at (45, 60, 35) cm
    site door at (0, 0, 300) cm
    site gauge at (-40, 30, 40) cm
}

task set_off "Close a valve, walk to the door, squat, look at a gauge, stand" {
    manikin gb10000_1988 female p50
    scene yard
    reach(right, valve)
    grasp(right)
    release(right)
    walk_to(door)
    squat(30 cm)
    look(gauge)
    stand()
}
"""


def test_the_head_faces_ahead_when_the_body_sets_off(tmp_path: Path) -> None:
    path = tmp_path / "set_off.mtask"
    path.write_text(SET_OFF)
    program = run_frontend([path])
    assert program.timelines, [d.message for d in program.diagnostics]
    ir = run_motion(program.timelines[0], program.sink)
    skel, frames = ir.skeleton, ir.frames
    neck = [skel.dof_index(n) for n in ("neck_flex", "neck_lat", "neck_rot")]
    rest = np.asarray(skel.q_comfort)[neck]
    walk = next(s for s in ir.segments if s.kind == "locomotion")
    before = frames.q[np.searchsorted(frames.time, walk.start) - 1, neck]
    assert np.abs(before - rest).max() > math.radians(10)  # it looked at the valve
    during = (frames.time > walk.start + TURN_MAX + 0.05) & (frames.time < walk.end)
    assert during.any()
    assert np.abs(frames.q[during][:, neck] - rest).max() < ONE_DEG
    assert np.abs(frames.q[-1, neck] - rest).max() < ONE_DEG  # the stand ends looking ahead
    assert np.abs(np.diff(frames.q[:, neck], axis=0)).max() < math.radians(12)


# Looks pulled every way (a generated procedure's shape): the first at frame 0, one overhead
# while the other hand screws behind the body, two in parallel branches, a look far to the side.
LOOK_AROUND = """\
use stdlib.actions
use stdlib.elements
use stdlib.tools

scene bay {
    ground 15 cm
    site front at (-35, 113, 55) cm normal (-1, 0, 0)
    site behind at (7, 125, -59) cm normal (0, 0, -1)
    site overhead at (-15, 226, 26) cm normal (0, -1, 0)
    site side at (-88, 99, 26) cm normal (0, -1, 0)
}

task look_around "Look every way" {
    manikin gb10000_1988 female p1
    scene bay
    look(behind)
    reach(right, front, approach: 6 cm)
    press(right, overhead)
    parallel {
        {
            look(side)
            reach(left, side, approach: 3 cm)
        }
        {
            screw(right, behind, turns: 2, tool: screwdriver_flat, swing: 30 deg)
            pick(right, overhead, G1C)
        }
    }
    place(right, behind)
    look(side)
}
"""


@pytest.mark.parametrize("manikin", ["female p5", "male p95"])
def test_the_head_never_turns_faster_than_a_person(tmp_path: Path, manikin: str) -> None:
    """Issue 19: before, such looks swung the neck limit to limit, 30 deg in one frame."""
    path = tmp_path / "look_around.mtask"
    path.write_text(LOOK_AROUND.replace("female p1", manikin))
    program = run_frontend([path])
    assert program.timelines, [d.message for d in program.diagnostics]
    ir = run_motion(program.timelines[0], program.sink)
    skel, frames = ir.skeleton, ir.frames
    head = [d for d, n in enumerate(skel.dof_names) if n.startswith(("neck_", "head_"))]
    steps = np.abs(np.diff(frames.q[:, head], axis=0))
    assert np.degrees(steps.max()) <= 12.0
    looks = [s for s in ir.segments if s.kind == "gaze" and not s.goal.params.get("implicit")]
    assert len(looks) >= 4 and all(s.end - s.start >= TURN_MIN - 1e-9 for s in looks)


def test_head_solves_asked_again_are_the_solver_s_own_answer(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """``HeadSolves`` returns what ``solve_rows(..., restarts=0)`` returns, to the bit, for new
    rows and rows asked again; an arm's angle is not part of the question (the row keeps its
    own), a trunk angle, the head's start, the root and the target are (each asks anew)."""
    from mtlc.body import build_manikin
    from mtlc.passes import gaze

    skel = build_manikin()
    calls: list[int] = []
    real = gaze.solve_rows
    monkeypatch.setattr(gaze, "solve_rows", lambda *a, **kw: calls.append(1) or real(*a, **kw))
    q = np.tile(skel.q_comfort, (8, 1))
    q[1, skel.dof_index("r_shoulder_flex")] += 0.3  # an arm: not the head's question
    q[3, skel.dof_index("thorax_rot")] += 0.2  # the trunk under the neck
    q[4, skel.dof_index("neck_rot")] += 0.3  # the head's start
    q[5, skel.dof_index("lumbar_flex")] += 1e-13  # a trunk off by a rounding error
    position = np.zeros((8, 3))
    position[6, 0] = 0.05  # the root
    rotation = np.tile(np.eye(3), (8, 1, 1))
    aims = np.tile([0.1, 0.05, 1.1], (8, 1))  # a bolt near the floor ahead: past the neck
    aims[7, 1] = 0.3  # the target
    solved = gaze.HeadSolves(skel)
    heads = {}
    for row in [0, 0, 1, 2, 3, 4, 5, 6, 7, 7]:
        got = solved.solve(q[row], (position, rotation), aims, row)
        want = real(skel, q[row][None], (position, rotation), aims, [row], restarts=0)[0]
        assert np.array_equal(got, want), row
        heads[row] = got[solved.active]
    # asked anew: rows 0, 3 (trunk), 4 (start), 5 (a trunk's last bit), 6 (root), 7 (target)
    assert len(calls) == 6
    for row in (3, 4, 6, 7):  # each a question of its own, with an answer of its own
        assert not np.array_equal(heads[row], heads[0]), row
