"""Tool operation: stdlib tools, the tool's tip as the goal, a wrench's strokes, the tool's mass.

Expected values are computed by hand from stdlib/tools.mtask (docs/tools.md).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mtlc.body import build_manikin, center_of_mass, forward, site_positions
from mtlc.diagnostics import DiagnosticSink
from mtlc.frontend import run_frontend
from mtlc.ir.model import MotionIR
from mtlc.passes import run_motion
from mtlc.passes import tool as tool_pass
from mtlc.passes.tool import arc_points, radius, stroke_plan, with_tools
from mtlc.semantics import schedule
from mtlc.semantics.expand import _strokes
from mtlc.semantics.timeline import ManikinSpec, Timeline

MAN = ManikinSpec("gb10000_1988", "male", 50)
WRENCH_10 = {
    "name": "wrench_10mm",
    "kind": "wrench",
    "mass": 0.06,
    "grip": (0.0, 0.0, 0.0),
    "tip": (0.115, 0.0, 0.0),
    "axis": (0.0, -1.0, 0.0),
}

TASK = """use stdlib.actions
use stdlib.tools

scene bay {{
    site front at (0, 0, 60) cm
    site bolt at (20, 135, 112) cm normal (0, 0, -1)
}}

task turn_bolt {{
    scene bay
    {setting}
    walk_to(front)
    unscrew(right, bolt, turns: {turns}{args})
}}
"""


def _timeline(
    tmp: Path, setting: str = "tool wrench_10mm", turns: int = 3, args: str = ""
) -> Timeline:
    path = tmp / "t.mtask"
    path.write_text(TASK.format(setting=setting, turns=turns, args=args), encoding="utf-8")
    program = run_frontend([path])
    assert not program.sink.has_errors, program.diagnostics
    (timeline,) = program.timelines
    return schedule.for_manikin(timeline, MAN)


def _diagnostics(tmp: Path, setting: str, args: str) -> list[str]:
    path = tmp / "t.mtask"
    path.write_text(TASK.format(setting=setting, turns=1, args=args), encoding="utf-8")
    return [d.code for d in run_frontend([path]).diagnostics]


@pytest.fixture(scope="module")
def wrench_ir(tmp_path_factory: pytest.TempPathFactory) -> MotionIR:
    timeline = _timeline(tmp_path_factory.mktemp("wrench"))
    return run_motion(timeline, DiagnosticSink(), until="tool")


def _strokes_of(ir: MotionIR) -> list:
    return sorted((s for s in ir.segments if "stroke" in s.goal.params), key=lambda s: s.start)


# ------------------------------------------------------------------ geometry by hand
def test_wrench_10mm_radius_is_grip_to_tip_across_the_axis() -> None:
    # tip (11.5, 0, 0) cm, grip at the origin, axis along y: r = 11.5 cm
    assert radius(WRENCH_10) == pytest.approx(0.115, abs=1e-12)


def test_ring_wrench_radius_ignores_the_crank_along_the_axis() -> None:
    # tip (11.5, 1.5, 0) cm: the 1.5 cm lies along the axis, the radius stays 11.5 cm
    ring = {**WRENCH_10, "tip": (0.115, 0.015, 0.0)}
    assert radius(ring) == pytest.approx(0.115, abs=1e-12)


def test_three_turns_at_60_degrees_are_18_strokes() -> None:
    strokes = _strokes(-3 * 2 * math.pi, math.radians(60))
    assert len(strokes) == 18
    assert sum(strokes) == pytest.approx(-6 * math.pi)


@given(
    turns=st.floats(0.1, 10.0),
    swing=st.floats(math.radians(5), math.pi),
)
@settings(max_examples=60, deadline=None)
def test_strokes_never_exceed_the_swing_and_sum_to_the_turn(turns: float, swing: float) -> None:
    angle = -turns * 2 * math.pi
    strokes = _strokes(angle, swing)
    assert all(abs(a) <= swing + 1e-9 for a in strokes)
    assert sum(strokes) == pytest.approx(angle, rel=1e-9)
    assert len(strokes) == math.ceil(abs(angle) / swing - 1e-9)


def test_arc_points_lie_at_the_radius_about_the_axis() -> None:
    centre = np.array([0.2, 1.35, 1.12])
    pts = arc_points(centre, (0.0, 0.0, -1.0), 0.115, np.linspace(0, 1, 7))
    d = pts - centre
    assert np.allclose(d[:, 2], 0.0, atol=1e-12)  # in the plane across the axis
    assert np.allclose(np.linalg.norm(d, axis=1), 0.115, atol=1e-12)


def test_stroke_plan_swings_through_the_stroke_and_returns() -> None:
    frac, theta, lift = stroke_plan(0.3, math.radians(60), ratchet=False)
    assert frac[0] == 0.0 and frac[-1] == 1.0 and np.all(np.diff(frac) > 0)
    engaged = theta[lift == 0]
    assert engaged.max() - engaged.min() == pytest.approx(math.radians(60))
    assert theta[-1] == pytest.approx(theta[0])  # re-engaged where it started
    assert lift.max() == 1.0  # lifted off to swing back


# ------------------------------------------------------------------ compiled strokes
def test_compiled_strokes_count_and_swing_limit(wrench_ir: MotionIR) -> None:
    strokes = _strokes_of(wrench_ir)
    assert len(strokes) == 18
    assert all(s.goal.effector == "r_tool_wrench_10mm" for s in strokes)
    assert all(abs(s.goal.params["angle"]) <= math.radians(60) + 1e-9 for s in strokes)


def test_user_swing_limits_the_strokes(tmp_path: Path) -> None:
    timeline = _timeline(tmp_path, turns=1, args=", swing: 45 deg")
    twists = [p for p in timeline.primitives if p.params.get("posture") == "stroke"]
    assert len(twists) == 8  # 360 / 45
    assert all(abs(p.params["angle"]) == pytest.approx(math.radians(45)) for p in twists)


def _keyframe_points(ir: MotionIR, seg, names: list[str]) -> np.ndarray:
    """(K, len(names), 3) site positions at each keyframe of a segment, from the state."""
    from mtlc.passes.state import PoseState

    state = PoseState(ir)
    kf = seg.keyframes
    out = []
    for t in kf.time:
        q = state.q_at(float(t))
        root = state.root_at(float(t))
        out.append([state.site(n, q, root) for n in names])
    return np.array(out)


def test_tip_stays_on_the_fastener_and_hand_on_the_arc(wrench_ir: MotionIR) -> None:
    # every keyframe of the seat and the swing (the tool engaged), and the re-seat at the end
    bolt = np.array([0.2, 1.35, 1.12])
    for seg in _strokes_of(wrench_ir)[:3]:
        swing_end = seg.result["phases"]["swing"][1]
        pts = _keyframe_points(wrench_ir, seg, ["r_tool_wrench_10mm", "r_hand"])
        engaged = (seg.keyframes.time <= swing_end + 1e-9) | (seg.keyframes.time >= seg.end - 1e-9)
        assert engaged.sum() >= 10
        tip_err = np.linalg.norm(pts[engaged, 0] - bolt, axis=1)
        assert tip_err.max() <= 1e-3
        # the hand's distance to the bolt's axis (along z) is the radius, 11.5 cm
        axis_dist = np.hypot(*(pts[engaged, 1] - bolt)[:, :2].T)
        assert np.allclose(axis_dist, 0.115, atol=1e-3)


def _peaks(speed: np.ndarray) -> int:
    """Maxima of a speed series (zero before and after) with 10 % of its top as prominence."""
    from scipy.signal import find_peaks

    found, _ = find_peaks(np.r_[0.0, speed, 0.0], prominence=0.1 * speed.max())
    return len(found)


def test_each_swing_and_return_is_one_bell_and_the_tip_reseats_slowly(wrench_ir: MotionIR) -> None:
    # issue 19: the hand swings the handle in one movement from rest to rest, returns in
    # another, and the tip comes back onto the bolt at <= 5 cm/s over the last 1/30 s
    for seg in _strokes_of(wrench_ir):
        kf = seg.keyframes
        pts = _keyframe_points(wrench_ir, seg, ["r_tool_wrench_10mm", "r_hand"])
        dt = np.diff(kf.time)
        hand = np.linalg.norm(np.diff(pts[:, 1], axis=0), axis=1) / dt
        tip = np.linalg.norm(np.diff(pts[:, 0], axis=0), axis=1) / dt
        mid = 0.5 * (kf.time[1:] + kf.time[:-1])
        for name in ("swing", "return"):
            a, b = seg.result["phases"][name]
            inside = (mid > a) & (mid < b)
            assert _peaks(hand[inside]) == 1, (seg.goal.params["stroke"], name)
            assert hand[inside][0] < 0.1 * hand[inside].max()  # from rest
            assert hand[inside][-1] < 0.1 * hand[inside].max()  # to rest
        last = kf.time >= seg.end - 1.0 / 30.0 - 1e-9
        reseat = np.linalg.norm(pts[-1, 0] - pts[last][0, 0]) / (kf.time[-1] - kf.time[last][0])
        assert reseat <= 0.05
        assert tip[-1] <= 0.05


def test_stroke_joints_move_at_most_20_degrees_a_frame(wrench_ir: MotionIR) -> None:
    # issue 19: the wrist and forearm in a fastener turn turn at most 20 deg in 1/30 s (the
    # keys are solved as one chain: no other forearm roll between neighbours, no 24 deg seat)
    for seg in _strokes_of(wrench_ir):
        kf = seg.keyframes
        turn = [
            i for i, n in enumerate(kf.dofs) if n.endswith(("wrist_flex", "wrist_dev", "elbow_pro"))
        ]
        speed = np.abs(np.diff(kf.q[:, turn], axis=0)) / np.diff(kf.time)[:, None]
        assert np.degrees(speed.max()) / 30.0 <= 20.0, seg.goal.params["stroke"]


def test_key_times_are_the_paced_strokes_passing_times() -> None:
    frac, _, _ = tool_pass.stroke_plan(0.3, -math.radians(60.0), ratchet=False)
    times = tool_pass.key_times(frac, lifted=True)
    assert np.all(np.diff(times[1:]) > 0) and times[-1] == pytest.approx(1.0)
    phases = np.isin(np.round(frac, 9), [0.1, 0.6])
    assert np.allclose(times[phases], frac[phases])  # the phase ends keep their times
    swing = (frac > 0.1) & (frac < 0.6)
    # minimum-jerk progress: the keys near the swing's ends are passed later/earlier than a
    # path-proportional clock would
    assert times[swing][0] > frac[swing][0] and times[swing][-1] < frac[swing][-1]


def test_phase_shares_give_the_return_the_time_its_joints_need() -> None:
    # one dof: 0.1 rad in the swing, 0.8 rad out and back in the return; at 1 rad/s (a
    # stroke of 1 s) the fixed 40 % left the return's joint at about 4 rad/s
    frac, _, _ = tool_pass.stroke_plan(0.3, -math.radians(60.0), ratchet=False)
    q = np.zeros((len(frac), 1))
    swing = (frac > 0.1) & (frac <= 0.6 + 1e-9)
    q[swing, 0] = 0.1 * (frac[swing] - 0.1) / 0.5
    back = frac > 0.6 + 1e-9
    q[back, 0] = (
        0.1 + 0.8 * np.sin(np.pi * (frac[back] - 0.6) / 0.4) - 0.1 * (frac[back] - 0.6) / 0.4
    )
    speed = np.array([4.0])  # rad per stroke: the joint may turn 4 rad/s in a stroke of 1 s
    windows = tool_pass.phase_shares(frac, q, True, speed)
    assert windows[0][0] == 0.0 and windows[-1][1] == 1.0
    assert all(a < b for a, b in windows[1:])
    assert windows[2][1] - windows[2][0] > 0.4  # the return took time from the swing
    times, poses = tool_pass.paced_stroke(frac, q, 0.0, 1.0, True, windows)
    fast = np.abs(np.diff(poses[:, 0])) / np.diff(times)
    assert fast.max() <= 4.0 * 1.02  # within the dense grid's sampling of the bell
    still = tool_pass.phase_shares(frac, np.zeros_like(q), True, speed)
    assert np.allclose(still, tool_pass.PHASES)  # nothing moves: the nominal shares


def test_stroke_arm_joints_turn_at_most_12_degrees_a_frame(wrench_ir: MotionIR) -> None:
    # issue 19: outside the wrist and forearm, no joint of a stroke turns faster than 360 deg/s
    for seg in _strokes_of(wrench_ir):
        kf = seg.keyframes
        arm = [i for i, n in enumerate(kf.dofs) if not any(d in n for d in tool_pass.TURNING_DOFS)]
        speed = np.abs(np.diff(kf.q[:, arm], axis=0)) / np.diff(kf.time)[:, None]
        assert np.degrees(speed.max()) / 30.0 <= 12.0, seg.goal.params["stroke"]


def test_stroke_phases_keep_the_stroke_time(wrench_ir: MotionIR) -> None:
    # seat, swing and return tile the stroke (its MTM time unchanged), keys on both ends
    for seg in _strokes_of(wrench_ir):
        ph = seg.result["phases"]
        assert ph["seat"][0] == seg.start and ph["return"][1] == pytest.approx(seg.end)
        assert ph["seat"][1] == ph["swing"][0] and ph["swing"][1] == ph["return"][0]
        assert seg.keyframes.time[0] == seg.start
        assert seg.keyframes.time[-1] == pytest.approx(seg.end, abs=1e-9)


def test_reused_strokes_equal_the_solved_ones(
    wrench_ir: MotionIR, monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    # the 18 strokes of one bolt repeat one solved stroke; solving each afresh gives the same
    monkeypatch.setattr(tool_pass, "REUSE_STROKES", False)
    fresh = run_motion(_timeline(tmp_path), DiagnosticSink(), until="tool")
    reused, solved = _strokes_of(wrench_ir), _strokes_of(fresh)
    assert len(reused) == len(solved) == 18
    for a, b in zip(reused, solved, strict=True):
        assert a.keyframes.dofs == b.keyframes.dofs
        assert np.allclose(a.keyframes.time, b.keyframes.time, atol=1e-12)
        assert np.abs(a.keyframes.q - b.keyframes.q).max() <= 1e-9


def test_strokes_start_where_the_motion_before_them_ends(wrench_ir: MotionIR) -> None:
    # no jump at a stroke's start: its first keyframe is the pose the reach or stroke left
    from mtlc.passes.state import PoseState

    state = PoseState(wrench_ir)
    strokes = _strokes_of(wrench_ir)
    for seg in strokes:
        before = state.q_at(seg.start, skip=seg)
        idx = [state.skel.dof_index(n) for n in seg.keyframes.dofs]
        assert np.abs(seg.keyframes.q[0] - before[idx]).max() <= 1e-9
    last = strokes[-1]
    first = state.q_at(strokes[0].start, skip=strokes)
    idx = [state.skel.dof_index(n) for n in last.keyframes.dofs]
    assert np.abs(last.keyframes.q[-1] - first[idx]).max() <= 1e-9  # back at the reach pose


def test_reach_addresses_the_tool_tip(wrench_ir: MotionIR) -> None:
    reach = [
        s for s in wrench_ir.segments if s.kind in ("TA", "TO") and "stroke" not in s.goal.params
    ]
    assert reach and all(s.goal.effector == "r_tool_wrench_10mm" for s in reach)
    to = next(s for s in reach if s.kind == "TO")
    assert to.result["distance"] <= 1e-3


def test_no_tool_keeps_the_quarter_turns(tmp_path: Path) -> None:
    timeline = _timeline(tmp_path, setting="", turns=3)
    twists = [p for p in timeline.primitives if p.params.get("posture") == "twist"]
    assert len(twists) == 12
    assert all(p.params["angle"] == pytest.approx(-math.pi / 2) for p in twists)
    goals = [p for p in timeline.primitives if p.kind == "goal"]
    assert all("tool" not in p.params for p in goals)


def test_screwdriver_turns_the_forearm_with_the_tip_as_goal(tmp_path: Path) -> None:
    timeline = _timeline(tmp_path, setting="tool screwdriver_flat", turns=1)
    twists = [p for p in timeline.primitives if p.params.get("posture") == "twist"]
    assert len(twists) == 4 and all(p.params["tool"]["name"] == "screwdriver_flat" for p in twists)
    goal = next(p for p in timeline.primitives if p.kind == "goal")
    assert goal.params["tool"]["kind"] == "screwdriver"


def test_screwdriver_tip_lies_on_the_forearm_axis() -> None:
    # tip 15 cm along the hand, in line with the forearm: a pronation turns it in place
    skel = with_tools(
        build_manikin(), {"r_tool_s": {"name": "s", "tip": (0, 0.15, 0), "mass": 0.0}}
    )
    q = skel.q_comfort.copy()
    q[skel.dof_index("r_wrist_flex")] = q[skel.dof_index("r_wrist_dev")] = 0.0
    tips = []
    for pro in (-0.6, 0.0, 0.6):
        q[skel.dof_index("r_elbow_pro")] = pro
        tips.append(site_positions(skel, forward(skel, q[None]), "r_tool_s")[0])
    assert np.ptp(np.array(tips), axis=0).max() <= 1e-9


def test_screwdriver_reach_puts_the_tool_axis_on_the_screw_axis(tmp_path: Path) -> None:
    # the grip is a goal 15 cm behind the tip on the site's normal (0, 0, -1): the tool's axis
    # (tip to grip) is the normal within 5 deg at the end of the reach, the tip within 1 mm
    from mtlc.passes.state import PoseState
    from mtlc.passes.tool import axis_angle

    sink = DiagnosticSink()
    timeline = _timeline(tmp_path, setting="tool screwdriver_flat", turns=1)
    ir = run_motion(timeline, sink, until="contact")  # a screwdriver compiles: no crash
    assert not [d for d in sink.sorted() if d.code == "MT0501"]
    state = PoseState(ir)
    to = next(s for s in ir.segments if s.kind == "TO" and s.track == "r_arm")
    q, root = state.q_at(to.end), state.root_at(to.end)
    pose = forward(ir.skeleton, q[None], root[0][None], root[1][None])
    angle = axis_angle(ir.skeleton, pose, to.goal.effector, (0.0, 0.0, -1.0))[0]
    assert math.degrees(angle) <= 5.0
    tip = state.site("r_tool_screwdriver_flat", q, root)
    assert np.linalg.norm(tip - np.array([0.20, 1.35, 1.12])) <= 1e-3
    grip = state.site("r_hand", q, root)
    assert np.linalg.norm(grip - tip) == pytest.approx(0.15, abs=1e-9)


@pytest.fixture(scope="module")
def screwdriver_ir(tmp_path_factory: pytest.TempPathFactory) -> tuple[MotionIR, list[str]]:
    """The test scene turned one turn with a screwdriver, every pass run, and its codes."""
    sink = DiagnosticSink()
    timeline = _timeline(tmp_path_factory.mktemp("screw"), "tool screwdriver_flat", turns=1)
    ir = run_motion(timeline, sink)
    return ir, [d.code for d in sink.sorted()]


def _twist_frames(ir: MotionIR, times: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Tip distance to the screw (m), tool-axis angle to its normal (rad) and hand roll about
    the normal (rad, from the first time) at ``times``."""
    from mtlc.body import site_rotation
    from mtlc.passes.state import PoseState
    from mtlc.passes.tool import axis_angle, roll_about

    skel, state = ir.skeleton, PoseState(ir)
    assert skel is not None
    q = np.stack([state.q_at(float(t)) for t in times])
    roots = [state.root_at(float(t)) for t in times]
    pose = forward(skel, q, np.stack([r[0] for r in roots]), np.stack([r[1] for r in roots]))
    tip = site_positions(skel, pose, "r_tool_screwdriver_flat")
    n = np.array([0.0, 0.0, -1.0])
    rot = site_rotation(skel, pose, "r_hand")
    return (
        np.linalg.norm(tip - np.array([0.20, 1.35, 1.12]), axis=1),
        axis_angle(skel, pose, "r_tool_screwdriver_flat", n),
        roll_about(rot @ rot[0].T, n),
    )


def test_screwdriver_quarter_turns_turn_the_screw_a_quarter_each(screwdriver_ir) -> None:
    # unscrew: each twist asks -90 deg, loosening: +90 deg about the normal (0, 0, -1),
    # counter-clockwise seen from the front like a wrench. The turn made is the roll gained
    # while gripping (the legs rolling the loosening way; a released hand rolls back)
    ir, codes = screwdriver_ir
    assert "MT0501" not in codes  # the whole turn is made: nothing reported short
    twists = [s for s in ir.segments if s.goal.params.get("posture") == "twist"]
    assert len(twists) == 4
    for seg in twists:
        tip, axis, roll = _twist_frames(ir, seg.keyframes.time)
        steps = np.diff(roll)
        assert math.degrees(steps[steps > 0].sum()) == pytest.approx(90.0, abs=5.0)
        assert math.degrees(seg.result["turned"]) == pytest.approx(90.0, abs=1e-6)
        assert seg.result["grips"] >= 1
        assert math.degrees(axis.max()) <= 2.0  # the tool's axis on the screw's
        assert tip.max() <= 1e-3  # the tip on the screw at every keyframe


def test_screwdriver_tip_stays_on_the_screw_between_keyframes(screwdriver_ir) -> None:
    # sampled at 30 fps through the twists, every pass run: the tip within 1 mm of the screw
    ir, _ = screwdriver_ir
    twists = [s for s in ir.segments if s.goal.params.get("posture") == "twist"]
    t0, t1 = twists[0].start, twists[-1].end
    times = np.arange(math.ceil(t0 * 30), math.floor(t1 * 30) + 1) / 30.0
    tip, axis, _ = _twist_frames(ir, times)
    assert len(times) >= 20 and tip.max() <= 1e-3
    assert math.degrees(axis.max()) <= 2.0


def test_regrip_plan_winds_back_and_grips_again_by_hand() -> None:
    # wrist range -35..+5 deg, hand at 0, a 90 deg turn: 5 deg of room is less than a bite
    # (30 deg), so wind back to -35, turn 40, back, 40, back, the last 10: 3 grips
    from mtlc.passes.tool import regrip_plan

    r = math.radians
    points, grips = regrip_plan(r(-35), r(5), 0.0, r(90))
    assert np.allclose(np.degrees(points), [0, -35, 5, -35, 5, -35, -25], atol=1e-9)
    assert grips == [False, True, False, True, False, True]
    # a wide range turns at once, either way
    assert regrip_plan(r(-100), r(100), 0.0, r(90)) == ([0.0, r(90)], [True])
    points, grips = regrip_plan(r(-100), r(100), 0.0, -r(90))
    assert np.allclose(points, [0.0, -r(90)]) and grips == [True]


def test_regrip_plan_stops_after_max_grips() -> None:
    # a 20 deg range makes 4 grips of 20 deg: 80 of the 90 deg (reported short by the pass)
    from mtlc.passes.tool import MAX_GRIPS, regrip_plan

    r = math.radians
    points, grips = regrip_plan(r(-10), r(10), r(-10), r(90))
    assert sum(grips) == MAX_GRIPS == 4
    made = sum(b - a for a, b, g in zip(points[:-1], points[1:], grips, strict=True) if g)
    assert math.degrees(made) == pytest.approx(80.0, abs=1e-9)


@given(
    lo=st.floats(-math.pi, 0.0),
    hi=st.floats(0.0, math.pi),
    at=st.floats(0.0, 1.0),
    turn=st.floats(-math.pi, math.pi),
)
@settings(max_examples=200, deadline=None)
def test_regrip_plan_stays_in_range_and_turns_one_way(
    lo: float, hi: float, at: float, turn: float
) -> None:
    from mtlc.passes.tool import MAX_GRIPS, regrip_plan

    start = lo + at * (hi - lo)
    points, grips = regrip_plan(lo, hi, start, turn)
    assert all(lo - 1e-9 <= p <= hi + 1e-9 for p in points)
    d = 1.0 if turn >= 0 else -1.0
    legs = np.diff(points)
    held = np.asarray(grips, bool)
    assert np.all(d * legs[held] > 0) and np.all(d * legs[~held] < 0)  # grip turns, release back
    made = float(d * legs[held].sum())
    assert made <= abs(turn) + 1e-9 and sum(grips) <= MAX_GRIPS
    if (MAX_GRIPS - 1) * (hi - lo) >= abs(turn):
        assert made == pytest.approx(abs(turn), abs=1e-9)


def test_twist_keys_time_the_return_at_twice_the_pace() -> None:
    # path nodes every 10 deg from -20 to +20; plan 0 -> -20 released, -20 -> 20 gripping:
    # 20 deg at pace 2 costs 10, 40 deg at pace 1 costs 40: the turning point at 10/50
    from mtlc.passes.tool import RollPath, twist_keys

    r = np.radians([-20.0, -10.0, 0.0, 10.0, 20.0])
    path = RollPath(r, np.zeros((5, 3)))
    frac, rolls, held = twist_keys(path, [0.0, r[0], r[-1]], [False, True])
    assert np.allclose(np.degrees(rolls), [0, -10, -20, -10, 0, 10, 20], atol=1e-9)
    assert np.allclose(frac, [0, 0.1, 0.2, 0.4, 0.6, 0.8, 1.0], atol=1e-9)
    assert held.tolist() == [1, 0, 0, 1, 1, 1, 1]


def test_short_turn_is_reported(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # one grip a twist: the wrist's 40 deg range cannot make a quarter turn: MT0501 says how much
    monkeypatch.setattr(tool_pass, "MAX_GRIPS", 1)
    sink = DiagnosticSink()
    timeline = _timeline(tmp_path, setting="tool screwdriver_flat", turns=1)
    ir = run_motion(timeline, sink, until="tool")
    (short,) = [d for d in sink.sorted() if d.code == "MT0501"]  # once for the screw's 4 twists
    assert "cannot turn the screw at site `bolt` by 90 deg" in short.message
    twists = [s for s in ir.segments if s.goal.params.get("posture") == "twist"]
    assert all(abs(s.result["turned"]) < math.radians(85.0) for s in twists)


def test_only_tool_sites_are_added_for_a_screwdriver_twist() -> None:
    # a twist names the screwdriver but addresses the hand: the hand is not a tool site
    from types import SimpleNamespace

    tool = {"name": "screwdriver_flat", "kind": "screwdriver", "tip": (0.0, 0.15, 0.0)}
    segs = [
        SimpleNamespace(goal=SimpleNamespace(effector=eff, params={"tool": tool}))
        for eff in ("r_hand", "r_tool_screwdriver_flat")
    ]
    ir = SimpleNamespace(segments=segs)
    assert list(tool_pass.held_tools(ir)) == ["r_tool_screwdriver_flat"]


def test_explicit_tool_argument_overrides_the_task(tmp_path: Path) -> None:
    timeline = _timeline(tmp_path, setting="", turns=1, args=", tool: wrench_13mm")
    strokes = [p for p in timeline.primitives if p.params.get("posture") == "stroke"]
    assert len(strokes) == 6 and strokes[0].params["tool"]["name"] == "wrench_13mm"


def test_unknown_tool_and_bad_swing_are_diagnosed(tmp_path: Path) -> None:
    assert _diagnostics(tmp_path, "", ", tool: wrench_11mm") == ["MT0201"]  # unknown name
    assert "MT0309" in _diagnostics(tmp_path, "tool wrench_10mm", ", swing: 200 deg")
    # under a 120-position ratchet's click: 0.5 deg made 2,160 strokes of three turns (fuzz)
    assert "MT0309" in _diagnostics(tmp_path, "tool wrench_10mm", ", swing: 0.5 deg")
    assert "MT0309" not in _diagnostics(tmp_path, "tool wrench_10mm", ", swing: 3 deg")
    assert _diagnostics(tmp_path, "tool wrench_10mm", ", swing: 3 cm") == ["MT0302"]  # not an angle


# ------------------------------------------------------------------ mass
def test_tool_mass_moves_the_centre_of_mass_only_while_held(wrench_ir: MotionIR) -> None:
    from mtlc.passes.tool import carried_com, held_spans

    skel = wrench_ir.skeleton
    assert skel is not None
    assert skel.total_mass == pytest.approx(build_manikin().total_mass, abs=1e-12)  # not on it
    ((site, tool, start, end),) = held_spans(wrench_ir)
    assert site == "r_tool_wrench_10mm" and tool["mass"] == 0.06
    tooled = [s for s in wrench_ir.segments if "tool" in s.goal.params]
    assert start == min(s.start for s in tooled) and end == max(s.end for s in tooled)
    time = np.array([start - 0.5, start, 0.5 * (start + end), end, end + 0.5])
    pose = forward(skel, np.tile(skel.q_comfort, (len(time), 1)))
    bare = center_of_mass(skel, pose)
    com = carried_com(wrench_ir, pose, time)
    # the tool's centre: the middle of grip and tip, 5.75 cm from the grip toward the thumb
    hand = site_positions(skel, pose, "r_hand")
    tip = site_positions(skel, pose, "r_tool_wrench_10mm")
    middle = 0.5 * (hand + tip)
    m, big_m = 0.06, skel.total_mass
    held = np.array([False, True, True, True, False])
    expected = np.where(held[:, None], (big_m * bare + m * middle) / (big_m + m), bare)
    assert np.allclose(com, expected, atol=1e-12)
    assert np.allclose(com[~held], bare[~held], atol=0.0)  # zero shift outside the window
    shift = np.linalg.norm(com[held] - bare[held], axis=1)
    assert np.all(shift > 1e-4) and np.all(shift < 1e-3)  # 60 g on 59 kg: under 1 mm
    assert np.allclose(np.linalg.norm(tip - hand, axis=1), 0.115, atol=1e-9)


# ------------------------------------------------------------------ RULA's force/load score
def test_force_score_follows_the_rula_table() -> None:
    from mtlc.ergonomics.rula import force_score

    kg = np.array([1.99, 0.0, 2.0, 0.0, 5.0, 0.0, 10.0, 0.0, 10.5])
    time = np.arange(len(kg)) * 100.0  # each load for an instant, put down between: intermittent
    assert force_score(kg, time).tolist() == [0, 0, 1, 0, 1, 0, 1, 0, 3]
    t = np.linspace(0.0, 61.0, 123)
    assert force_score(np.full(len(t), 5.0), t).tolist() == [2] * len(t)  # held a minute: static
    t = np.linspace(0.0, 59.0, 119)
    assert force_score(np.full(len(t), 5.0), t).tolist() == [1] * len(t)


def test_held_load_is_the_tool_while_held_plus_the_load(tmp_path: Path) -> None:
    from mtlc.ergonomics.rula import force_scores, held_load
    from mtlc.passes import lower

    ir = lower(_timeline(tmp_path, turns=1, args=", load: 3 kg"))
    tooled = [s for s in ir.segments if "tool" in s.goal.params]
    strokes = _strokes_of(ir)
    start, end = min(s.start for s in tooled), max(s.end for s in tooled)
    # the load is in the hand from the grasp before the turning to the end of the release after
    (grasp,) = [s for s in ir.segments if s.kind == "grip" and s.goal.params["state"] == "closed"]
    (release,) = [s for s in ir.segments if s.kind == "grip" and s.goal.params["state"] == "open"]
    t = np.linspace(0.0, max(s.end for s in ir.segments) + 1.0, 400)
    kg = held_load(ir, t)
    tool = (t >= start) & (t <= end)
    load = (t >= grasp.start) & (t <= release.end)
    in_stroke = np.any([(t >= s.start) & (t <= s.end) for s in strokes], axis=0)
    assert in_stroke[load].sum() == in_stroke.sum() and (load & ~in_stroke).any()
    assert np.allclose(kg["r"][~tool & ~load], 0.0) and np.allclose(kg["l"], 0.0)
    assert np.allclose(kg["r"][tool & ~load], 0.06)  # the wrench alone, reaching with it
    assert np.allclose(kg["r"][tool & load], 3.06)  # and the load from the grasp on
    assert np.allclose(kg["r"][load & ~tool], 3.0)  # the load until the hand has opened
    force = force_scores(ir, t)
    # 2-10 kg, under a minute but repeated: 6 strokes in seconds (tests/test_rula.py)
    assert force["r"][in_stroke].tolist() == [2] * int(in_stroke.sum())
    assert force["r"][~load].max() == 0 and force["l"].max() == 0


def test_score_frames_raises_each_side_by_its_own_force() -> None:
    from mtlc.ergonomics.rula import grand_score, score_frames

    skel = build_manikin()
    q = np.tile(skel.q_comfort, (3, 1))
    pose = forward(skel, q)
    feet = np.ones(3, dtype=bool)
    bare = score_frames(skel, pose, q, feet)
    force = {"r": np.array([0, 1, 3]), "l": np.zeros(3, dtype=np.int64)}
    loaded = score_frames(skel, pose, q, feet, force=force)
    expected = grand_score(bare["r"].score_a, bare["r"].score_b, 0, force["r"])
    assert loaded["r"].grand.tolist() == expected.tolist()
    assert loaded["l"].grand.tolist() == bare["l"].grand.tolist()
    assert loaded["r"].grand[2] > bare["r"].grand[2]


# ------------------------------------------------------------------ lint: reaches with a tool
def test_lint_sweep_reaches_with_the_tool(tmp_path: Path) -> None:
    """Every manikin of a lint sweep is compiled in full holding the same tool: the tall one's
    wrench tip lands on a bolt at 1.8 m, the small one's MT0501 names the wrench."""
    from mtlc.lint import LintConfig, lint_paths
    from mtlc.lint.manikins import parse_selection

    path = tmp_path / "t.mtask"
    high = TASK.replace("(20, 135, 112)", "(20, 180, 100)")  # a bolt at 1.8 m
    path.write_text(high.format(setting="tool wrench_10mm", turns=1, args=""), encoding="utf-8")
    two = parse_selection("gb10000_1988:male:95,gb10000_1988:female:5")
    result = lint_paths([path], LintConfig(select=frozenset({"MT0501"})), manikins=two, jobs=1)
    (short,) = [f for f in result.findings if f.code == "MT0501"]
    assert short.manikins == ("gb10000_1988:female:5",)  # the tall manikin reaches it
    assert short.message.startswith("the wrench_10mm in the right hand cannot reach")


def test_a_twist_takes_the_time_a_forearm_needs(tmp_path: Path) -> None:
    """Issue 19: MTM-1's T90S (5.4 TMU, 0.19 s) would turn a forearm at 700 deg/s at its peak;
    a bare hand's quarter turn takes 1.5 x 90 deg / 340 deg/s, a screwdriver's / 570 deg/s."""
    bare = _timeline(tmp_path, setting="", turns=1)
    (d_bare,) = {
        round(p.duration, 9) for p in bare.primitives if p.params.get("posture") == "twist"
    }
    assert d_bare == pytest.approx(1.5 * 90.0 / 340.0)
    driver = _timeline(tmp_path, setting="tool screwdriver_flat", turns=1)
    (d_tool,) = {
        round(p.duration, 9) for p in driver.primitives if p.params.get("posture") == "twist"
    }
    assert d_tool == pytest.approx(1.5 * 90.0 / 570.0)


def test_a_repeated_series_is_solved_once_and_moves_as_solved_afresh(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # a loop unscrewing one bolt twice asks ``_solve_keys`` the same question for the second
    # series (the same reach pose, arc and clock): answered from the compile's cache, it must
    # give the motion solving it again gives, and the cache must hand out copies
    path = tmp_path / "t.mtask"
    path.write_text(TASK.format(setting="tool wrench_10mm", turns=1, args="").replace(
        "    unscrew(right, bolt, turns: 1)", "    repeat 2 {\n        unscrew(right, bolt, turns: 1)\n    }"
    ), encoding="utf-8")  # fmt: skip
    program = run_frontend([path])
    assert not program.sink.has_errors, program.diagnostics
    timeline = schedule.for_manikin(program.timelines[0], MAN)
    calls: list[int] = []
    solve_keys = tool_pass._solve_keys

    def counted(*args, **kw):  # type: ignore[no-untyped-def]
        calls.append(1)
        return solve_keys(*args, **kw)

    monkeypatch.setattr(tool_pass, "_solve_keys", counted)
    cached = run_motion(timeline, DiagnosticSink(), until="tool")
    n_cached = len(calls)
    monkeypatch.setattr(tool_pass, "_keys_solved", lambda cache, *a: tool_pass._solve_keys(*a))
    fresh = run_motion(timeline, DiagnosticSink(), until="tool")
    assert n_cached < len(calls) - n_cached  # the second series was not solved again
    a, b = _strokes_of(cached), _strokes_of(fresh)
    assert len(a) == len(b) == 12
    for x, y in zip(a, b, strict=True):
        assert x.keyframes.dofs == y.keyframes.dofs
        assert np.array_equal(x.keyframes.time, y.keyframes.time)
        assert np.array_equal(x.keyframes.q, y.keyframes.q)


def test_evening_out_solves_again_only_keys_whose_guess_moved(
    wrench_ir: MotionIR, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # ``_even_out`` reuses a key's last solve where its guess repeats to the bit; solving
    # every key in every round (the guess called new each time) must give the same strokes
    monkeypatch.setattr(tool_pass, "bits_differ", lambda a, b: np.ones(np.shape(a), dtype=bool))
    every = run_motion(_timeline(tmp_path), DiagnosticSink(), until="tool")
    a, b = _strokes_of(wrench_ir), _strokes_of(every)
    assert len(a) == len(b) == 18
    for x, y in zip(a, b, strict=True):
        assert np.array_equal(x.keyframes.q, y.keyframes.q)
