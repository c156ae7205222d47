"""Posture, TA, TO and gaze passes on the examples: contact, monotone paths, limits, MT0501."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from conftest import example_until

from mtlc.body import build_manikin, forward, site_direction, site_positions
from mtlc.body.ik import Goal, prepare, solve_ta
from mtlc.frontend import run_frontend
from mtlc.ir.model import Frames, MotionIR, Segment
from mtlc.passes import run_motion
from mtlc.passes.interpolate import correct_base, interpolate_joints, interpolate_root
from mtlc.passes.posture import KNEE_HEIGHT, root_height, target_posture
from mtlc.passes.state import PoseState, solved

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = sorted((ROOT / "examples").glob("*.mtask"))
MM = 1e-3


def compile_file(path: Path) -> tuple[MotionIR, list]:
    ir, sink = example_until(path, "gaze")
    return ir, sink.sorted()


@pytest.fixture(scope="module", params=EXAMPLES, ids=lambda p: p.stem)
def compiled(request: pytest.FixtureRequest) -> tuple[MotionIR, list]:
    return compile_file(request.param)


def short_lines(diags: list) -> set[int]:
    return {d.span.line for d in diags if d.code == "MT0501"}


def reachable_to(ir: MotionIR, diags: list) -> list[Segment]:
    bad = short_lines(diags)
    return [s for s in ir.segments if s.kind == "TO" and s.provenance.origin.line not in bad]


def frame_at(ir: MotionIR, t: float) -> Frames:
    """The whole body at time ``t`` through the real interpolation and base correction."""
    grid = np.array([t])
    position, rotation = interpolate_root(ir, grid)
    frames = Frames(30.0, grid, position, rotation, interpolate_joints(ir, grid))
    correct_base(ir, frames)
    return frames


def test_every_example_has_contacts(compiled: tuple[MotionIR, list]) -> None:
    ir, diags = compiled
    assert any(s.kind == "TO" for s in ir.segments)
    assert reachable_to(ir, diags), "every TO of an example is unreachable"


def test_reachable_sites_are_touched_within_1mm(compiled: tuple[MotionIR, list]) -> None:
    ir, diags = compiled
    for seg in reachable_to(ir, diags):
        assert seg.keyframes is not None
        assert seg.result["distance"] <= MM
        fr = frame_at(ir, seg.end)
        pose = forward(ir.skeleton, fr.q, fr.root_position, fr.root_rotation)
        hand = site_positions(ir.skeleton, pose, seg.goal.effector)[0]
        err = float(np.linalg.norm(hand - seg.goal.position))
        assert err <= MM, f"{seg.goal.site} at {seg.end:.2f} s: {err * 1000:.2f} mm"


def test_to_keyframes_never_move_away(compiled: tuple[MotionIR, list]) -> None:
    ir, _ = compiled
    state = PoseState(ir)
    # a wrench's strokes lift the tool off the fastener on purpose (tests/test_tools.py)
    for seg in (s for s in ir.segments if s.kind == "TO" and "stroke" not in s.goal.params):
        kf = seg.keyframes
        assert kf is not None and 2 <= len(kf.time) <= 13
        assert np.all(np.diff(kf.time) >= 0) and kf.time[0] == seg.start and kf.time[-1] == seg.end
        root = state.root_at(seg.end)
        q = np.tile(state.q_at(seg.start), (len(kf.time), 1))
        q[:, [ir.skeleton.dof_index(n) for n in kf.dofs]] = kf.q
        pose = forward(ir.skeleton, q, np.tile(root[0], (len(q), 1)), np.tile(root[1], (len(q), 1)))
        d = np.linalg.norm(
            site_positions(ir.skeleton, pose, seg.goal.effector) - seg.goal.position, axis=-1
        )
        assert np.all(np.diff(d) <= 1e-9), d


def test_every_keyframe_within_limits(compiled: tuple[MotionIR, list]) -> None:
    ir, _ = compiled
    skel = ir.skeleton
    for seg in ir.segments:
        if seg.keyframes is None or not seg.keyframes.dofs:
            continue
        idx = [skel.dof_index(n) for n in seg.keyframes.dofs]
        q = seg.keyframes.q
        assert np.all(q >= skel.lower[idx] - 1e-9) and np.all(q <= skel.upper[idx] + 1e-9), (
            seg.kind,
            seg.goal.site,
        )


def test_segments_start_where_the_body_is(compiled: tuple[MotionIR, list]) -> None:
    """Each TA starts from the pose the previous segments left (no jump at the boundary).

    The pose before a segment ignores every segment starting with it: the two arms of a
    two-handed reach both hold the trunk at their start, and agreeing with each other is no
    evidence that they agree with the pose before them."""
    ir, _ = compiled
    state = PoseState(ir)
    for seg in (s for s in ir.segments if s.kind in ("TA", "posture", "gaze")):
        kf = seg.keyframes
        assert kf is not None
        together = [
            s
            for s in ir.segments
            if s.kind in ("TA", "posture", "gaze") and abs(s.start - seg.start) <= 1e-9
        ]
        before = state.q_at(seg.start, skip=together)
        idx = [ir.skeleton.dof_index(n) for n in kf.dofs]
        if seg.goal.params.get("posture") == "twist":
            continue  # restated from the forearm before it: checked in the twist test
        np.testing.assert_allclose(kf.q[0], before[idx], atol=1e-9)


# spin_off's two half turns by hand and screw(turns: 2)'s eight quarter turns
TWISTS_IN_FUEL_FILTER = 2 + 8


def test_twists_turn_the_forearm_within_limits() -> None:
    # the fuel filter is turned by hand: twists of the forearm (the flagship's wrench swings)
    ir, _ = compile_file(ROOT / "examples" / "replace_fuel_filter.mtask")
    state = PoseState(ir)
    twists = [s for s in ir.segments if s.goal.params.get("posture") == "twist"]
    assert len(twists) == TWISTS_IN_FUEL_FILTER
    d = ir.skeleton.dof_index("r_elbow_pro")
    for seg in twists:
        kf = seg.keyframes
        assert kf is not None and kf.dofs == ("r_elbow_pro",)
        assert kf.q[0, 0] == pytest.approx(state.q_at(seg.start, skip=seg)[d])
        turned = abs(kf.q[1, 0] - kf.q[0, 0])
        assert turned > 0.25 * abs(seg.goal.params["angle"]) - 1e-9  # never stalls at the stop
        assert ir.skeleton.lower[d] - 1e-12 <= kf.q[1, 0] <= ir.skeleton.upper[d] + 1e-12


UNREACHABLE = """\
use stdlib.actions
use stdlib.tools

scene bay {
    ground 0 cm
    site front at (0, 0, 60) cm
    site low_bolt at (20, 105, 112) cm normal (0, 0, -1)
    site high_bolt at (20, 250, 112) cm normal (0, 0, -1)
}

task out_of_reach "A bolt 2.5 m up" {
    manikin gb10000_1988 female p5
    scene bay
    tool wrench_10mm
    walk_to(front)
    unscrew(right, high_bolt, turns: 1)
    unscrew(right, low_bolt, turns: 1)
}
"""


def test_unreachable_site_warns_and_compiles_on(tmp_path: Path) -> None:
    src = tmp_path / "unreachable.mtask"
    src.write_text(UNREACHABLE)
    prog = run_frontend([src])
    assert prog.timelines
    ir = run_motion(prog.timelines[0], prog.sink)  # the whole pipeline
    found = [d for d in prog.sink.sorted() if d.code == "MT0501"]
    assert len(found) == 1
    assert found[0].severity.name.lower() == "warning"
    assert found[0].span.line == 16 and "high_bolt" in found[0].message
    assert "mm short" in found[0].message
    assert ir.frames is not None and len(ir.frames.time) > 10
    high = [s for s in ir.segments if s.kind == "TO" and s.goal.site == "high_bolt"]
    low = [s for s in ir.segments if s.kind == "TO" and s.goal.site == "low_bolt"]
    assert high[0].result["success"] is False and high[0].result["distance"] > 0.3
    assert low[0].result["distance"] <= MM  # the next goal is still solved


def test_squat_keeps_the_heels_on_the_ground() -> None:
    ir, _ = compile_file(ROOT / "examples" / "drain_hydraulic_reservoir.mtask")
    state = PoseState(ir)
    skel = ir.skeleton
    squats = [s for s in ir.segments if s.goal.params.get("posture") == "squat"]
    assert squats
    for seg in squats:
        kf = seg.keyframes
        assert kf is not None and kf.root_position is not None
        q = state.q_at(seg.end)
        rot = state.root_at(seg.end)[1]
        pose = forward(skel, q[None], kf.root_position[-1][None], rot[None])
        heels = site_positions(skel, pose, ["r_heel", "l_heel", "r_toe", "l_toe"])[0]
        np.testing.assert_allclose(heels[:, 1], ir.ground, atol=MM)
        stand = root_height(skel, np.zeros(skel.n_dofs), 0.0)  # legs straight
        depth = seg.goal.params["depth"]
        assert stand - (kf.root_position[-1][1] - ir.ground) == pytest.approx(depth, abs=MM)


@pytest.mark.parametrize("knees", [1, 2])
def test_kneel_puts_the_knees_on_the_ground(knees: int) -> None:
    ir, _ = compile_file(ROOT / "examples" / "replace_fuel_filter.mtask")
    skel = ir.skeleton
    q = target_posture(skel, skel.q_comfort.copy(), {"posture": "kneel", "knees": knees})
    assert skel.within_limits(q)
    h = root_height(skel, q, 0.0)
    pose = forward(skel, q[None], np.array([[0.0, h, 0.0]]), np.array([[1.0, 0, 0, 0]]))
    knee_r = pose.p[0, skel.joint_index("r_knee"), 1]
    assert knee_r == pytest.approx(KNEE_HEIGHT, abs=MM)
    if knees == 2:
        assert pose.p[0, skel.joint_index("l_knee"), 1] == pytest.approx(KNEE_HEIGHT, abs=MM)
    else:  # the left foot stands flat
        feet = site_positions(skel, pose, ["l_heel", "l_toe"])[0]
        np.testing.assert_allclose(feet[:, 1], 0.0, atol=MM)


def explicit_looks(ir: MotionIR) -> list[Segment]:
    """The ``look`` segments (the gaze pass adds implicit ones that follow the work)."""
    return [s for s in ir.segments if s.kind == "gaze" and not s.goal.params.get("implicit")]


def test_gaze_points_at_the_target(compiled: tuple[MotionIR, list]) -> None:
    """Each look ends at the angle it recorded (the implicit gazes: tests/passes/test_gaze.py)."""
    ir, _ = compiled
    state = PoseState(ir)
    skel = ir.skeleton
    assert explicit_looks(ir)
    for seg in explicit_looks(ir):
        q = state.q_at(seg.end)
        root = state.root_at(seg.end)
        pose = forward(skel, q[None], root[0][None], root[1][None])
        eye = site_positions(skel, pose, "gaze")[0]
        look = site_direction(skel, pose, "gaze")[0]
        same = [s for s in explicit_looks(ir) if s.start == seg.start]
        target = np.mean([s.goal.position for s in same], axis=0)
        want = (target - eye) / np.linalg.norm(target - eye)
        err = math.degrees(math.acos(np.clip(look @ want, -1, 1)))
        recorded = math.degrees(seg.result["angle_error"])
        assert err == pytest.approx(recorded, abs=0.01)
        if seg.result["success"]:
            assert err <= 2.0


def test_gaze_reaches_targets_within_neck_range() -> None:
    ir, _ = compile_file(ROOT / "examples" / "remove_access_panel.mtask")
    bolts = [s for s in explicit_looks(ir) if (s.goal.site or "").startswith("bolt")]
    assert len(bolts) == 4
    assert all(s.result["success"] and s.result["angle_error"] < math.radians(1) for s in bolts)


@pytest.mark.parametrize("height_cm", [3, 7, 12])
def test_the_kneeling_reach_to_a_tray_near_the_floor_arrives(
    tmp_path: Path, height_cm: int
) -> None:
    # the fuel filter's drain tray moved between 3 and 12 cm up: the kneeling right hand lays
    # flat above it (TA) and comes straight down (TO); a path that would arrive only through
    # the floor is judged cut where it meets the floor, and another one is taken
    source = (ROOT / "examples" / "replace_fuel_filter.mtask").read_text(encoding="utf-8")
    moved = source.replace(
        "site drain_tray at (-35, 5, 80)", f"site drain_tray at (-35, {height_cm}, 80)"
    )
    assert moved != source
    path = tmp_path / "fuel_filter.mtask"
    path.write_text(moved, encoding="utf-8")
    ir, diags = compile_file(path)
    to = next(s for s in ir.segments if s.kind == "TO" and s.goal.site == "drain_tray")
    assert to.provenance.origin.line not in short_lines(diags)
    assert to.result["distance"] <= MM


def test_a_repeated_solve_is_answered_from_the_compile_cache() -> None:
    """``passes.state.solved``: the same goals from the same start on the same model are solved
    once per compile (a loop repeating a reach asks again); the answer is the solver's own,
    a copy each time, and another start is solved anew."""
    skel = build_manikin("gb10000_1988", "female", 5)
    calls: list[int] = []

    def counting(*args: object, **kwargs: object) -> object:
        calls.append(1)
        return solve_ta(*args, **kwargs)  # type: ignore[arg-type]

    q0 = skel.q_comfort.copy()
    goals = [Goal("r_hand", position=np.array([0.45, 1.1, 0.25]))]
    model = prepare(skel, ["r_hand"], q0)
    cache: dict = {}
    first = solved(cache, counting, skel, goals, q0, model, tol=2e-4)
    first.q[:] = 0.0  # a caller's change must not reach the next answer
    again = solved(cache, counting, skel, goals, q0.copy(), model, tol=2e-4)
    direct = solve_ta(skel, goals, q0, model=model, tol=2e-4)
    assert len(calls) == 1
    np.testing.assert_array_equal(again.q, direct.q)
    np.testing.assert_array_equal(again.position_error, direct.position_error)
    q1 = q0.copy()
    q1[skel.dof_index("r_elbow_flex")] += 0.1
    solved(cache, counting, skel, goals, q1, model, tol=2e-4)
    solved(cache, counting, skel, goals, q0, model, tol=1e-3)  # other options: solved anew
    assert len(calls) == 3


def test_lowest_hand_points_of_many_poses_are_each_poses_to_the_bit(
    compiled: tuple[MotionIR, list],
) -> None:
    """``approach.lowest_hand_points`` poses a sweep's samples in one forward kinematics: the
    same heights, bit for bit, as ``lowest_hand_point`` of each pose alone."""
    from mtlc.passes.approach import groups, lowest_hand_point, lowest_hand_points

    ir, _ = compiled
    state = PoseState(ir)
    rng = np.random.default_rng(2)
    for segs in groups(ir, "TA")[:4]:
        root = state.root_at(segs[0].end)
        for k in (1, 7, 12):
            qs = state.skel.random_q(rng, k)
            want = [lowest_hand_point(state, segs, q, root) for q in qs]
            assert lowest_hand_points(state, segs, qs, root).tolist() == want
