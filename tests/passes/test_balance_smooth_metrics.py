"""Balance, smoothing and the motion metrics, on hand-computed synthetic motions and examples."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from conftest import compiled_example
from hypothesis import given, settings
from hypothesis import strategies as st

from mtlc.body import build_manikin, center_of_mass, forward, site_positions
from mtlc.diagnostics import DiagnosticSink
from mtlc.frontend import run_frontend
from mtlc.ir.model import Frames, GoalSpec, MotionIR, Provenance, Segment, SourceRef
from mtlc.metrics import (
    Metrics,
    ldlj,
    render_metrics,
    support_margin,
    walking,
)
from mtlc.metrics import compute_metrics as metrics_of
from mtlc.passes import balance, run_motion, smooth, verify
from mtlc.passes.context import PassContext

SKEL = build_manikin("gb10000_1988", "male", 50)
REF = SourceRef("synthetic.mtask", 3, 5, 3, 20)
PROV = Provenance(("t", "a", "e"), REF, REF)


def standing(n: int, fps: float = 30.0) -> Frames:
    """The neutral pose standing on the ground (soles at y = 0), n frames."""
    q = np.zeros((n, SKEL.n_dofs))
    root = np.tile(SKEL.root_position, (n, 1))
    rot = np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))
    return Frames(fps=fps, time=np.arange(n) / fps, root_position=root, root_rotation=rot, q=q)


def compute_metrics(ir: MotionIR) -> Metrics:
    """The metrics of a synthetic motion, verified as it is now (the figures come from verify)."""
    verify.run(ir, PassContext(DiagnosticSink()))
    return metrics_of(ir)


def make_ir(frames: Frames, segments: list[Segment] | None = None) -> MotionIR:
    ir = MotionIR("t", None, "synthetic.mtask", {}, 0.0, [], segments or [], SKEL)
    ir.frames = frames
    return ir


# -- metrics ----------------------------------------------------------------------------------


def test_penetration_of_a_body_lowered_5_mm() -> None:
    f = standing(10)
    assert compute_metrics(make_ir(f)).penetration == pytest.approx(0.0, abs=1e-9)
    f.root_position[4:7, 1] -= 0.005
    m = compute_metrics(make_ir(f))
    assert m.penetration == pytest.approx(0.005, abs=1e-9)
    assert m.penetration_time == pytest.approx(4 / 30)
    assert not m.passes()["penetration"]


def test_foot_sliding_at_3_cm_per_s() -> None:
    f = standing(31)
    f.root_position[:, 0] += 0.03 * f.time  # the whole body slides along +X
    m = compute_metrics(make_ir(f))
    assert m.foot_skating == pytest.approx(0.03, rel=1e-9)
    assert not m.passes()["foot_skating"]
    # a foot in the air (a step) does not count: lift the right foot, slide only it
    f2 = standing(31)
    steps = [{"foot": "r", "t_lift": -1.0, "t_land": 2.0, "position": [0, 0, 0]}]
    seg = Segment("root", "locomotion", 0.0, 1.0, GoalSpec("root"), PROV, result={"steps": steps})
    f2.q[:, SKEL.dof_index("r_hip_abd")] = 0.05 * f2.time  # the right foot swings outwards
    m2 = compute_metrics(make_ir(f2, [seg]))
    assert m2.foot_skating == pytest.approx(0.0, abs=1e-9)


def test_support_margin_of_a_known_square() -> None:
    sq = np.array([[0.0, 0.0], [0.2, 0.0], [0.2, 0.2], [0.0, 0.2]])
    pts = np.tile(sq, (4, 1, 1))
    ok = np.ones((4, 4), dtype=bool)
    com = np.array([[0.1, 0.1], [0.05, 0.1], [0.25, 0.1], [0.23, 0.24]])
    got = support_margin(pts, ok, com)
    np.testing.assert_allclose(got, [0.1, 0.05, -0.05, -0.05], atol=1e-12)
    # points in any order, extra interior points, one point missing
    shuffled = np.array([[[0.2, 0.2], [0.1, 0.1], [0.0, 0.0], [0.0, 0.2], [0.2, 0.0]]])
    assert support_margin(shuffled, np.ones((1, 5), bool), com[2:3])[0] == pytest.approx(-0.05)
    tri = support_margin(pts[:1], np.array([[True, True, True, False]]), np.array([[0.05, 0.1]]))
    assert tri[0] == pytest.approx(-0.05 / math.sqrt(2))  # outside the hypotenuse
    # a segment has no inside; no contact at all is NaN
    seg = support_margin(pts[:1], np.array([[True, True, False, False]]), np.array([[0.1, 0.0]]))
    assert seg[0] == pytest.approx(0.0)
    assert np.isnan(support_margin(pts[:1], np.zeros((1, 4), bool), com[:1]))[0]


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), collinear=st.booleans(), count=st.sampled_from([12, 70]))
def test_the_grouped_hull_gives_the_margins_of_the_plain_one(
    seed: int, collinear: bool, count: int
) -> None:
    """``grouped_hull`` (frames grouped by their contacts, edges only) against
    ``hull`` (every pair of every frame), CoMs inside and outside; frames share a few
    contact sets, as a motion's do, and points on one line test the side tolerance. 70 points
    take the grouping by rows (a contact set of 64 or more does not fit one int's bits)."""
    from mtlc.metrics import grouped_hull, hull, hull_margin

    rng = np.random.default_rng(seed)
    pts = rng.uniform(-0.3, 0.3, (40, count, 2))
    if collinear:
        pts[:, :4, 1] = pts[:, :1, 1]  # four points on one line, the hull's edge or inside
    ok = rng.random((5, count)) < 0.6
    if count > 64:
        # sets that an int's 64 bits would merge (a bit past 63 lost or wrapped round), one of
        # every point (none is dropped: point 64 stays the 65th), and point 64 a far corner
        ok[1], ok[2], ok[3] = ok[0], ok[0], True
        ok[0, [0, 64]], ok[1, [0, 64]], ok[2, [0, 64]] = (True, False), (False, True), (True, True)
        pts[:, 64] = (0.5, 0.5)
    ok = ok[rng.integers(0, 5, 40)]
    com = rng.uniform(-0.4, 0.4, (40, 2))
    want = hull_margin(hull(pts, ok), com)
    got = hull_margin(grouped_hull(pts, ok), com)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)
    assert np.array_equal(np.isnan(got), np.isnan(want))


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), runs=st.lists(st.integers(1, 30), min_size=1, max_size=12))
def test_the_grouped_hull_of_repeated_frames_is_found_once_to_the_bit(
    seed: int, runs: list[int]
) -> None:
    """Runs of identical frames (a hold) take their run's first frame's hull: the margins are
    bit for bit those of every frame's own hull, however many frames the batch holds."""
    import mtlc.body.kinematics as kin
    from mtlc.metrics import grouped_hull, hull_margin

    rng = np.random.default_rng(seed)
    at = np.repeat(np.arange(len(runs)), runs)
    pts = rng.uniform(-0.3, 0.3, (len(runs), 22, 2))[at]
    ok = (rng.random((len(runs), 22)) < 0.5)[at]
    com = rng.uniform(-0.4, 0.4, (len(at), 2))
    got = hull_margin(grouped_hull(pts, ok), com)
    saved = kin.REPEAT_MIN_ROWS
    kin.REPEAT_MIN_ROWS = 10**9  # every frame's hull
    try:
        want = hull_margin(grouped_hull(pts, ok), com)
    finally:
        kin.REPEAT_MIN_ROWS = saved
    assert got.tobytes() == want.tobytes()


def one_legged(n: int, lift_deg: float = 20.0) -> Frames:
    """Standing on the right foot: the left leg abducted, its sole off the ground."""
    f = standing(n)
    f.q[:, SKEL.dof_index("l_hip_abd")] = math.radians(lift_deg)
    return f


def test_support_margin_of_the_standing_manikin() -> None:
    m = compute_metrics(make_ir(standing(3)))
    assert m.support_margin_static > 0.02  # the CoM stands well between the feet
    # on the right foot only, the CoM (near the midline) is outside the sole, beyond the
    # edge from the heel to the inner ball: hand-computed distance to that segment
    f = one_legged(2)
    pose = forward(SKEL, f.q, f.root_position, f.root_rotation)
    com = center_of_mass(SKEL, pose)[0, [0, 2]]
    heel, ball = site_positions(SKEL, pose, ["r_heel", "r_ball_med"])[0][:, [0, 2]]
    s = np.clip(np.dot(com - heel, ball - heel) / np.dot(ball - heel, ball - heel), 0, 1)
    expected = -np.linalg.norm(com - (heel + s * (ball - heel)))
    m = compute_metrics(make_ir(f))
    assert expected < -0.05
    np.testing.assert_allclose(m.support_margin, expected, atol=1e-12)
    assert not m.passes()["support_margin"]


def minimum_jerk(t: np.ndarray, amplitude: float, duration: float) -> np.ndarray:
    s = t / duration
    x = amplitude * (10 * s**3 - 15 * s**4 + 6 * s**5)
    return np.stack([x, 0.5 * x, np.zeros_like(x)], axis=1)


def test_ldlj_of_minimum_jerk_and_jerky_paths() -> None:
    t = np.linspace(0.0, 1.0, 241)
    smooth = minimum_jerk(t, 0.4, 1.0)
    # minimum jerk: T³/v_peak² ∫|jerk|² dt = 720 / 1.875² (independent of amplitude and time)
    assert ldlj(smooth, t) == pytest.approx(-math.log(720 / 1.875**2), abs=0.05)
    assert ldlj(minimum_jerk(t * 2, 0.1, 2.0), t * 2) == pytest.approx(ldlj(smooth, t), abs=0.02)
    jerky = smooth + 0.003 * np.sin(2 * np.pi * 8 * t)[:, None]
    assert ldlj(jerky, t) < ldlj(smooth, t) - 1.0
    assert math.isnan(ldlj(np.zeros((20, 3)), t[:20]))


def test_joint_limit_violations_count_and_worst() -> None:
    f = standing(10)
    k = SKEL.dof_index("r_knee_flex")
    f.q[2:5, k] = SKEL.upper[k] + math.radians(10)
    f.q[7, k] = SKEL.upper[k] + math.radians(3)
    m = compute_metrics(make_ir(f))
    assert m.limit_count == 4
    assert m.limit_worst_deg == pytest.approx(10.0)
    assert m.limit_worst_dof == "r_knee_flex"


def test_contact_error_at_the_end_of_to() -> None:
    f = standing(31)
    pose = forward(SKEL, f.q[:1], f.root_position[:1], f.root_rotation[:1])
    hand = site_positions(SKEL, pose, "r_hand")[0]
    near = GoalSpec("r_hand", "bolt", hand + np.array([0.0, 0.0, 0.0007]))
    far = GoalSpec("r_hand", "far_bolt", hand + np.array([0.0, 0.5, 0.0]))
    segs = [
        Segment("r_arm", "TO", 0.2, 0.5, near, PROV),
        Segment("r_arm", "TO", 0.6, 0.9, far, PROV, result={"reachable": False}),
    ]
    m = compute_metrics(make_ir(f, segs))
    assert [c.site for c in m.contact_errors] == ["bolt", "far_bolt"]
    assert m.contact_errors[0].error == pytest.approx(0.0007)
    assert m.contact_errors[1].error == pytest.approx(0.5)
    assert m.contact_error == pytest.approx(0.0007)  # the unreachable site does not count
    assert m.passes()["contact_error"]


def test_render_metrics_is_plain_text() -> None:
    f = standing(10)
    f.root_position[:, 1] -= 0.002
    text = render_metrics(
        [("a", compute_metrics(make_ir(f))), ("b", compute_metrics(make_ir(standing(5))))]
    )
    assert "\x1b" not in text
    assert "penetration (mm)" in text and "2.00 FAIL" in text


# -- balance ----------------------------------------------------------------------------------

SOLES = [f"{s}_{p}" for s in "rl" for p in ("heel", "toe", "ball_med", "ball_lat")]


def run_pass(fn, ir: MotionIR) -> list[tuple[str, int, int]]:  # type: ignore[no-untyped-def]
    sink = DiagnosticSink()
    ctx = PassContext(sink)
    fn(ir, ctx)
    ctx.flush_claims()  # the pass's own words: no verify ran after it
    return [(d.code, d.span.line, d.span.column) for d in sink.sorted()]


def test_balance_pulls_a_one_legged_lean_back_over_the_foot() -> None:
    f = one_legged(20)
    f.q[:, SKEL.dof_index("l_hip_abd")] = np.radians(np.linspace(15, 25, 20))
    ir = make_ir(f)
    before = compute_metrics(ir).support_margin
    pose = forward(SKEL, f.q, f.root_position, f.root_rotation)
    right0 = site_positions(SKEL, pose, SOLES[:4])
    assert before.max() < -0.05
    assert run_pass(balance.run, ir) == []
    after = compute_metrics(ir)
    assert np.all(after.support_margin >= balance.MARGIN - 5e-4)
    pose = forward(SKEL, f.q, f.root_position, f.root_rotation)
    right1 = site_positions(SKEL, pose, SOLES[:4])
    assert np.abs(right1 - right0).max() < 1e-3  # the standing foot stays put
    assert after.penetration < 1e-3
    assert after.limit_count == 0
    assert np.all(f.root_position[:, 0] < -0.05)  # the pelvis moved over the right foot


def test_balance_keeps_the_hand_on_its_site_and_leaves_balanced_frames() -> None:
    f = standing(30)
    f.q[:, SKEL.dof_index("r_shoulder_flex")] = math.radians(60)
    f.q[:, SKEL.dof_index("r_elbow_flex")] = math.radians(40)
    f.q[15:, SKEL.dof_index("l_hip_abd")] = math.radians(20)  # from frame 15 on one foot
    pose = forward(SKEL, f.q, f.root_position, f.root_rotation)
    hand = site_positions(SKEL, pose, "r_hand")
    seg = Segment("r_arm", "TO", 0.0, 0.1, GoalSpec("r_hand", "bolt", hand[0]), PROV)
    ir = make_ir(f, [seg])
    q0, root0 = f.q.copy(), f.root_position.copy()
    assert run_pass(balance.run, ir) == []
    # the correction starts ahead of the lift (at most 2 x BLEND_FRAMES), not before
    early = 15 - 2 * balance.BLEND_FRAMES
    np.testing.assert_array_equal(f.q[:early], q0[:early])
    np.testing.assert_array_equal(f.root_position[:early], root0[:early])
    assert np.abs(np.diff(f.root_position[:, 0])).max() < 0.03  # no jump: ramps in
    pose = forward(SKEL, f.q, f.root_position, f.root_rotation)
    assert np.abs(site_positions(SKEL, pose, "r_hand") - hand).max() < 1e-3
    assert compute_metrics(ir).support_margin[15:].min() > 0.0


def test_balancing_some_frames_blends_each_run_of_frames_by_itself() -> None:
    """``balance_frames(only=...)`` (the smoothing pass's re-balance): frames far apart in time
    are no neighbours. A balanced frame 1 s before a corrected run kept its pose; it took the
    run's pelvis shift when the frames were blended as one array (fuel filter, a walking frame
    at 1.17 s and the kneel at 1.87 s)."""
    f = standing(40)
    f.q[30:, SKEL.dof_index("l_hip_abd")] = math.radians(20)  # from frame 30 on one foot
    ir = make_ir(f)
    q0, root0 = f.q.copy(), f.root_position.copy()
    before, after, failed = balance.balance_frames(ir, f, np.array([2, 3, *range(30, 36)]))
    assert before.shape == after.shape == failed.shape == (8,)
    np.testing.assert_array_equal(f.q[:30], q0[:30])  # the standing frames: untouched
    np.testing.assert_array_equal(f.root_position[:30], root0[:30])
    assert np.all(f.root_position[30:36, 0] < root0[30:36, 0] - 0.02)  # the run: corrected
    assert np.all(after[2:] >= balance.ACCEPT_MARGIN) and not failed.any()


def test_only_hands_on_their_site_or_holding_a_part_are_pinned() -> None:
    """A TO that left the hand short of its site (MT0501) pins nothing while its grip is open:
    the hand rests on nothing; with a closed grip it holds its part, so it stays pinned."""
    site = np.zeros(3)

    def reach(track: str, effector: str, start: float, short: float) -> Segment:
        seg = Segment(track, "TO", start, start + 0.5, GoalSpec(effector, "s", site), PROV)
        seg.result = {"distance": short}
        return seg

    right = reach("r_arm", "r_hand", 0.0, 0.0)  # reached
    left = reach("l_arm", "l_hand", 0.0, 2.0)  # 2 m short, grip open
    ir = make_ir(standing(3), [right, left])
    t = np.array([0.2, 0.6, 1.0])
    all_pins = balance.hand_pins(ir, t)
    held = balance.hand_pins(ir, t, balance.pin_windows(ir, reached_only=True))
    assert all_pins["l_hand"].all() and all_pins["r_hand"].all()
    assert held["r_hand"].all() and not held["l_hand"].any()
    grasp = Segment(
        "l_hand", "grip", 0.4, 0.5, GoalSpec("l_hand", params={"state": "closed"}), PROV
    )
    ir.segments.append(grasp)
    held = balance.hand_pins(ir, t, balance.pin_windows(ir, reached_only=True))
    assert held["l_hand"].all()


def test_balance_lost_reports_mt0502_once_per_segment() -> None:
    # on one foot, the right arm straight up with the hand held on a site: the pelvis cannot
    # move over the foot without pulling the hand off the site
    f = one_legged(10)
    f.q[:, SKEL.dof_index("r_shoulder_flex")] = SKEL.upper[SKEL.dof_index("r_shoulder_flex")]
    f.q[:, SKEL.dof_index("r_elbow_flex")] = 0.0
    pose = forward(SKEL, f.q, f.root_position, f.root_rotation)
    hand = site_positions(SKEL, pose, "r_hand")
    soles = site_positions(SKEL, pose, SOLES[:4])
    seg = Segment("r_arm", "TO", 0.0, 0.3, GoalSpec("r_hand", "bolt", hand[0]), PROV)
    ir = make_ir(f, [seg])
    before = compute_metrics(ir).support_margin
    assert run_pass(balance.run, ir) == [("MT0502", 3, 5)]  # ten frames, one segment, once
    after = compute_metrics(ir).support_margin
    assert np.all(after < 0) and np.all(after >= before - 1e-9)  # better, not enough
    pose = forward(SKEL, f.q, f.root_position, f.root_rotation)  # the contacts win
    assert np.abs(site_positions(SKEL, pose, "r_hand") - hand).max() < 1e-3
    assert np.abs(site_positions(SKEL, pose, SOLES[:4]) - soles).max() < 1e-3


# -- smoothing ------------------------------------------------------------------------------


def test_smoothing_blends_a_step_offset_with_the_claims_schedule() -> None:
    f = standing(100, fps=60.0)
    k = SKEL.dof_index("r_elbow_flex")
    f.q[:, k] = 0.5
    f.q[40:, k] += 0.2  # a jump of 0.2 rad between frames 39 and 40
    boundary = (f.time[39] + f.time[40]) / 2
    segs = [  # a whole-body posture starting where another left an offset
        Segment("root", "posture", 0.0, boundary, GoalSpec("body"), PROV),
        Segment("root", "posture", boundary, 100 / 60, GoalSpec("body"), PROV),
    ]
    ir = make_ir(f, segs)
    assert run_pass(smooth.run, ir) == []
    want = 0.5 + 0.2 * np.r_[np.zeros(40), 0.02 * np.arange(50), np.ones(10)]
    np.testing.assert_allclose(f.q[:, k], want, atol=1e-12)
    assert f.q[39, k] == f.q[40, k]  # no jump left
    assert np.diff(f.q[:, k]).max() == pytest.approx(0.2 * 0.02)


def test_smoothing_respects_limits_and_keeps_contacts() -> None:
    f = standing(90, fps=60.0)
    k = SKEL.dof_index("r_knee_flex")
    e = SKEL.dof_index("l_elbow_flex")
    f.q[:30, e] = SKEL.lower[e] + 0.3
    f.q[30:, e] = SKEL.lower[e] + 0.05  # a jump down of 0.25: blending it would cross 0
    f.root_position[30:, 2] += 0.01  # and the pelvis jumps 1 cm forward
    f.q[:, SKEL.dof_index("r_shoulder_flex")] = math.radians(50)
    f.q[:, SKEL.dof_index("r_elbow_flex")] = math.radians(40)
    pose = forward(SKEL, f.q, f.root_position, f.root_rotation)
    hand = site_positions(SKEL, pose, "r_hand")
    soles = site_positions(SKEL, pose, SOLES)
    segs = [
        Segment("root", "hold", 0.0, 0.5, GoalSpec("body"), PROV),
        Segment("root", "hold", 0.5, 1.5, GoalSpec("body"), PROV),
        Segment("r_arm", "TO", 0.0, 1.5, GoalSpec("r_hand", "bolt", hand[0]), PROV),
    ]
    ir = make_ir(f, segs)
    run_pass(smooth.run, ir)
    assert SKEL.within_limits(f.q).all()
    assert f.q[30, e] == pytest.approx(SKEL.lower[e] + 0.3, abs=1e-3)  # offset subtracted...
    assert f.q[:, e].min() >= SKEL.lower[e]  # ...but never past the limit
    assert f.root_position[30, 2] == pytest.approx(f.root_position[29, 2], abs=1e-3)
    pose = forward(SKEL, f.q, f.root_position, f.root_rotation)
    assert np.abs(site_positions(SKEL, pose, "r_hand") - hand).max() < 1e-3
    # stance feet (heel/toe points that touched) stay where they were
    assert np.abs(site_positions(SKEL, pose, SOLES) - soles).max() < 1e-3
    assert f.q[:, k].min() >= 0.0


# -- every example, after the whole pipeline ----------------------------------------------------

EXAMPLES = sorted((Path(__file__).parents[2] / "examples").glob("*.mtask"))
_compiled: dict[Path, list[tuple[str, Metrics]]] = {}


_codes: dict[Path, set[str]] = {}


def compiled(path: Path) -> list[tuple[str, Metrics]]:
    """The example's metrics per task, from its compile the test run shares
    (``conftest.compiled_example``), and the codes it reported."""
    if path not in _compiled:
        done = compiled_example(path)
        assert done.ok
        _compiled[path] = [(ir.task, compute_metrics(ir)) for ir in done.motions]
        _codes[path] = {d.code for d in done.program.sink.items}
    return _compiled[path]


# Properties other passes do not deliver yet (they are being written alongside): the example
# stem and property, with the reason measured on the current pipeline.
PENDING: dict[tuple[str, str], str] = {}


def _case(path: Path, prop: str) -> object:
    reason = PENDING.get((path.stem, prop))
    marks = [pytest.mark.xfail(strict=False, reason=reason)] if reason else []
    return pytest.param(path, id=f"{path.stem}-{prop}", marks=marks)


@pytest.mark.parametrize("path", [_case(p, "penetration") for p in EXAMPLES])
def test_examples_do_not_go_below_the_ground(path: Path) -> None:
    for task, m in compiled(path):
        assert m.penetration <= 1e-3, f"{task}: {m.penetration * 1e3:.2f} mm"


@pytest.mark.parametrize("path", [_case(p, "limits") for p in EXAMPLES])
def test_examples_keep_every_joint_within_its_limits(path: Path) -> None:
    for task, m in compiled(path):
        assert m.limit_count == 0, f"{task}: {m.limit_worst_deg:.2f}° {m.limit_worst_dof}"


@pytest.mark.parametrize("path", [_case(p, "skating") for p in EXAMPLES])
def test_examples_keep_standing_feet_in_place(path: Path) -> None:
    for task, m in compiled(path):
        assert not m.foot_skating > 0.02, f"{task}: {m.foot_skating * 1e2:.2f} cm/s"


@pytest.mark.parametrize("path", [_case(p, "contact") for p in EXAMPLES])
def test_examples_put_the_hands_on_reachable_sites(path: Path) -> None:
    """On the site, or MT0510 says it is not: the avionics unit's slide_out ends where the walk
    to the trolley starts, which has carried the hands 3.5 mm off by the next output frame."""
    for task, m in compiled(path):
        error = f"{task}: {m.contact_error * 1e3:.2f} mm"
        assert m.contact_error <= 1e-3 or "MT0510" in _codes[path], error
    if path.stem != "remove_avionics_unit":
        assert all(m.contact_error <= 1e-3 for _, m in compiled(path))


@pytest.mark.parametrize("path", [_case(p, "support") for p in EXAMPLES])
def test_examples_balance_in_static_postures(path: Path) -> None:
    """Balanced over the points that touch (docs/metrics.md, "Support"), or MT0502 says it is
    not: in the fuel filter's kneel the swing of the second knee's leg takes the centre of mass
    out of the narrow triangle of one kneeling leg (knee, balls, toe) for a few frames, and
    some reaches lean past the knees."""
    for task, m in compiled(path):
        margin = f"{task}: {m.support_margin_static * 1e3:.1f} mm"
        assert m.support_margin_static >= 0.0 or "MT0502" in _codes[path], margin
    if path.stem != "replace_fuel_filter":
        assert all(m.support_margin_static >= 0.0 for _, m in compiled(path))


def test_a_foot_rolling_over_its_toe_is_not_skating() -> None:
    from mtlc.metrics import FOOT_POINT_NAMES, rolling_points

    ref = SourceRef("x.mtask", 1, 1, 1, 1)
    walk = Segment("root", "locomotion", 0.0, 1.0, GoalSpec("root"), Provenance(("t",), ref, ref))
    walk.result = {"steps": [{"foot": "r", "t_heel_off": 0.2, "t_lift": 0.4, "t_land": 0.7}]}
    ir = make_ir(standing(10, fps=10.0), [walk])
    rolling = rolling_points(ir, np.array([0.1, 0.3, 0.5]))
    toe = FOOT_POINT_NAMES.index("toe")
    assert not rolling[0].any()  # before heel-off every sole point is planted
    assert rolling[1, [j for j in range(4) if j != toe]].all() and not rolling[1, toe]
    assert not rolling[1, 4:].any()  # the other foot stands
    assert not rolling[2].any()  # in the air it is the stance mask's business, not the roll's


# -- postures ---------------------------------------------------------------------------------


@settings(max_examples=12, deadline=None)
@given(depth=st.floats(0.05, 0.45), arms=st.booleans())
def test_every_pose_of_a_squat_transition_is_balanced(depth: float, arms: bool) -> None:
    from mtlc.passes.posture import HEEL_MARGIN, target_posture, transition

    stand = np.asarray(SKEL.q_comfort, dtype=float)
    free = ("r_shoulder_flex", "l_shoulder_flex") if arms else ()
    squat = target_posture(SKEL, stand, {"posture": "squat", "depth": depth}, free)
    for poses in (transition(SKEL, stand, squat, 6), transition(SKEL, squat, stand, 6)):
        pose = forward(SKEL, poses)  # the body's own frame: facing +Z
        ahead = center_of_mass(SKEL, pose)[:, 2] - site_positions(SKEL, pose, "r_heel")[:, 2]
        # in front of the heels by the margin, unless the trunk has no lean left to give
        lum, tho = SKEL.dof_index("lumbar_flex"), SKEL.dof_index("thorax_flex")
        spent = (poses[:, lum] >= SKEL.upper[lum] - 1e-6) & (
            poses[:, tho] >= SKEL.upper[tho] - 1e-6
        )
        assert np.all((ahead >= HEEL_MARGIN - 1e-3) | spent)
        assert np.all(ahead > 0.0) or depth > 0.3  # a squat this deep still leans far enough
        assert SKEL.within_limits(poses).all()


def test_a_posture_after_a_walk_moves_from_its_start() -> None:
    # the walk's last keyframe shares the kneel's start instant: it must not hold the legs
    # still until the kneel's end (they would then jump)
    program = run_frontend([EXAMPLES[[p.stem for p in EXAMPLES].index("replace_fuel_filter")]])
    ir = run_motion(program.timelines[0], program.sink, until="interpolate")
    kneel = next(s for s in ir.segments if s.goal.params.get("posture") == "kneel")
    f = ir.frames
    assert f is not None
    k = SKEL.dof_index("r_knee_flex")
    inside = (f.time > kneel.start) & (f.time < kneel.end)
    knee = f.q[inside, k]
    third = len(knee) // 3
    assert np.ptp(knee[:third]) > math.radians(20)  # the right leg steps in the first third
    assert knee[-1] > math.radians(90)  # and ends kneeling
    # no jump like the 0.65 m one of a frozen kneel (the stepping leg moves the pelvis up to
    # 4.4 cm a frame at 60 fps as the right foot swings back)
    assert np.abs(np.diff(f.root_position[inside], axis=0)).max() < 0.05


def test_a_trunk_reach_puts_the_resting_hand_back() -> None:
    # the right hand rests on a site; a reach of the left hand leans the trunk 15° forward and
    # 10° aside: the right arm alone puts its hand back (within the IK tolerance)
    from mtlc.body.ik import Goal
    from mtlc.passes.approach import repin

    q = np.asarray(SKEL.q_comfort, dtype=float).copy()
    q[SKEL.dof_index("r_shoulder_flex")] = math.radians(50)
    q[SKEL.dof_index("r_elbow_flex")] = math.radians(60)
    root = (np.asarray(SKEL.root_position, dtype=float), np.array([1.0, 0.0, 0.0, 0.0]))
    pose = forward(SKEL, q[None], root[0][None], root[1][None])
    hand = site_positions(SKEL, pose, "r_hand")[0]
    leaned = np.tile(q, (3, 1))
    leaned[:, SKEL.dof_index("lumbar_flex")] = np.radians([5, 10, 15])
    leaned[:, SKEL.dof_index("lumbar_lat")] = np.radians([0, 5, 10])
    back = repin({}, SKEL, leaned, [Goal("r_hand", position=hand)], root)
    n = len(back)
    pose = forward(SKEL, back, np.tile(root[0], (n, 1)), np.tile(root[1], (n, 1)))
    assert np.abs(site_positions(SKEL, pose, "r_hand") - hand).max() < 1e-3
    joints = ("r_shoulder", "r_elbow", "r_wrist")
    arm = [SKEL.dof_index(d) for d in SKEL.dof_names if d.startswith(joints)]
    others = np.setdiff1d(np.arange(SKEL.n_dofs), arm)
    np.testing.assert_array_equal(back[:, others], leaned[:, others])  # only the right arm


# -- the stepping kneel and the supports it stands on ------------------------------------------


def test_a_foot_on_its_toe_stands_on_its_toe_point_alone() -> None:
    """The rigid foot touches at its toe tip only: the virtual forefoot patch (still computed,
    for the slot layout) never bears weight (docs/metrics.md, "Support")."""
    from mtlc.metrics import FOREFOOT_SLOTS, SOLE_SLOTS, forefoot_patch, support

    q = np.asarray(SKEL.q_comfort, dtype=float).copy()
    q[SKEL.dof_index("r_ankle_dorsi")] = math.radians(-35)  # right heel up, toe down
    pose = forward(SKEL, q[None], np.zeros((1, 3)))
    toe = site_positions(SKEL, pose, "r_toe")[0]
    pose = forward(SKEL, q[None], np.array([[0.0, -toe[1], 0.0]]))  # the right toe on y = 0
    corners = forefoot_patch(SKEL, pose)[0, :4]
    med, lat, toe = site_positions(SKEL, pose, ["r_ball_med", "r_ball_lat", "r_toe"])[0]
    breadth = np.linalg.norm(med - lat)
    assert np.linalg.norm(corners[0] - corners[1]) == pytest.approx(breadth, abs=1e-9)
    _, ok = support(SKEL, pose, np.ones((1, 2), dtype=bool), 0.0)
    assert not ok[0, FOREFOOT_SLOTS].any()
    assert ok[0, SOLE_SLOTS].tolist()[:4] == [False, True, False, False]  # the toe, nothing else


def test_a_kneeling_knee_and_a_resting_hand_bear_weight() -> None:
    from mtlc.metrics import HAND_SLOTS, KNEE_HALF_WIDTH, KNEE_SLOTS, hand_contacts, knee_patch

    pose = forward(SKEL, np.asarray(SKEL.q_comfort, dtype=float)[None])
    knees = knee_patch(SKEL, pose)[0]
    centre = pose.p[0, SKEL.joint_index("r_knee")]
    assert np.linalg.norm(knees[0] - knees[1]) == pytest.approx(2 * KNEE_HALF_WIDTH)
    np.testing.assert_allclose(0.5 * (knees[0] + knees[1]), centre, atol=1e-12)
    # a hand rests on its site from the end of its TO until its arm's next segment
    to = Segment("r_arm", "TO", 1.0, 2.0, GoalSpec("r_hand", "bolt"), PROV)
    nxt = Segment("r_arm", "TA", 3.0, 4.0, GoalSpec("r_hand", "nut"), PROV)
    ir = make_ir(standing(2), [to, nxt])
    rest = hand_contacts(ir, np.array([1.5, 2.0, 2.5, 3.5]))
    assert rest[:, 0].tolist() == [False, True, True, False] and not rest[:, 1].any()
    # the hull then reaches out to the hand: a CoM ahead of the feet is inside it
    from mtlc.metrics import support
    from mtlc.passes.posture import root_height

    q = np.asarray(SKEL.q_comfort, dtype=float).copy()
    q[SKEL.dof_index("r_shoulder_flex")] = math.radians(90)  # the right hand held out ahead
    pose = forward(SKEL, q[None], np.array([[0.0, root_height(SKEL, q, 0.0), 0.0]]))
    pts, ok = support(SKEL, pose, np.ones((1, 2), dtype=bool), 0.0, np.array([[True, False]]))
    assert ok[0, HAND_SLOTS].tolist() == [True, False] and not ok[0, KNEE_SLOTS].any()
    hand = pts[0, HAND_SLOTS.start]
    ahead = np.array([[0.5 * hand[0], 0.5 * hand[1]]])
    without = support_margin(pts[:, :20], ok[:, :20], ahead)
    assert support_margin(pts, ok, ahead)[0] > without[0]


@pytest.mark.parametrize(("sex", "pct"), [("male", 95), ("female", 5)])
def test_the_stepping_kneel_keeps_its_balance_and_its_footing(sex: str, pct: int) -> None:
    from mtlc.metrics import CONTACT_TOL, penetration, support
    from mtlc.passes.kneel import SOLE, plan_kneel
    from mtlc.passes.posture import root_height

    skel = build_manikin("gb10000_1988", sex, pct)
    q = np.asarray(skel.q_comfort, dtype=float)
    plan = plan_kneel(skel, q, np.array([0.0, root_height(skel, q, 0.0), 0.0]), 0.0, 2, 2.5)
    t, pose = plan.time, plan.body.pose(plan.x)
    stance = np.ones((len(t), 2), dtype=bool)
    for step in plan.steps:
        k = "rl".index(step["foot"])
        stance[(t > step["t_lift"] + 1e-9) & (t < step["t_land"] - 1e-9), k] = False
    assert not stance[:, 0].all() and not stance[:, 1].all()  # each foot steps once
    # the support always has an inside: a heel-up foot stands on its balls and toes (the toes
    # bend), not on the tip of a rigid foot (with it, the body went down onto the right knee
    # on both toe tips, a segment, for 6 of 76 frames); the centre of mass stays over it but
    # for the swing of the second knee's leg, where it is up to 2 mm out (issue 18)
    pts, ok = support(skel, pose, stance, 0.0)
    margin = support_margin(pts, ok, center_of_mass(skel, pose)[:, [0, 2]])
    centre = np.einsum("np,npk->nk", ok, pts) / np.maximum(ok.sum(axis=1), 1)[:, None]
    area = support_margin(pts, ok, centre) > 1e-3
    assert not np.isnan(margin).any()
    assert area.all() and margin.min() >= -2.5e-3
    swing = (t > plan.steps[-1]["t_lift"]) & (t < plan.steps[-1]["t_land"])
    assert margin[~swing].min() >= 0.0
    # a planted point does not slide (a foot rolling on its toe keeps only its toe planted)
    rolling = np.zeros((len(t), 8), dtype=bool)
    for roll in plan.rolls:
        k = "rl".index(roll["foot"])
        inside = (t >= roll["from"]) & (t <= roll["to"])
        rolling[np.ix_(inside, [4 * k + 1, 4 * k + 2, 4 * k + 3])] = True  # SOLE: toe first
    feet = site_positions(skel, pose, [f"{s}_{n}" for s in "rl" for n in SOLE])
    planted = (feet[..., 1] <= CONTACT_TOL) & np.repeat(stance, 4, axis=1) & ~rolling
    speed = np.linalg.norm(np.diff(feet[..., [0, 2]], axis=0), axis=-1) / np.diff(t)[:, None]
    assert np.where(planted[1:] & planted[:-1], speed, 0.0).max() < 0.02
    assert penetration(skel, pose, 0.0).max() <= 1e-3
    assert skel.within_limits(plan.body.q_of(plan.x), tol=1e-6).all()
    # it ends on both knees (5 cm up) and both toes, side by side
    knees = pose.p[-1, [skel.joint_index("r_knee"), skel.joint_index("l_knee")]]
    np.testing.assert_allclose(knees[:, 1], 0.05, atol=2e-3)
    assert abs(knees[0, 2] - knees[1, 2]) < 5e-3
    np.testing.assert_allclose(feet[-1, [0, 4], 1], 0.0, atol=1e-3)  # r_toe, l_toe
    # on tucked toes: balls and toe tips on the ground, the toes bent up at the balls
    np.testing.assert_allclose(feet[-1, [0, 2, 3, 4, 6, 7], 1], 0.0, atol=2e-3)
    toes = plan.body.q_of(plan.x[-1:])[0, [skel.dof_index(f"{s}_toes_dorsi") for s in "rl"]]
    assert (toes > math.radians(60)).all()


def _runs_with_standing_frames(ir: MotionIR, rows: np.ndarray) -> np.ndarray:
    """The runs of consecutive ``rows`` that hold a frame outside a walk (the reference)."""
    runs = np.split(rows, np.flatnonzero(np.diff(rows) != 1) + 1)
    kept = [r for r in runs if r.size and not walking(ir, ir.frames.time[r]).all()]
    return np.concatenate(kept) if kept else rows[:0]


def test_smoothing_rebalances_only_runs_with_a_standing_frame() -> None:
    """Balancing the runs of walking frames only changes nothing (``balance_frames`` moves no
    walking frame unless a standing frame of its run is corrected), so the smoothing pass
    leaves them out: the frames come out the same with and without them."""
    f = standing(60)
    f.q[:, SKEL.dof_index("l_hip_abd")] = math.radians(20)  # every frame on one foot
    walk = Segment("root", "locomotion", 0.0, f.time[29], GoalSpec("body"), PROV)
    ir = make_ir(f, [walk])
    rows = np.array([*range(3, 9), *range(25, 35), *range(40, 46)])  # walking, mixed, standing
    kept = _runs_with_standing_frames(ir, rows)
    np.testing.assert_array_equal(kept, rows[6:])
    every = Frames(f.fps, f.time, f.root_position.copy(), f.root_rotation, f.q.copy())
    some = Frames(f.fps, f.time, f.root_position.copy(), f.root_rotation, f.q.copy())
    balance.balance_frames(ir, every, rows)
    balance.balance_frames(ir, some, kept)
    np.testing.assert_array_equal(every.q, some.q)
    np.testing.assert_array_equal(every.root_position, some.root_position)
    assert not np.array_equal(every.root_position, f.root_position)  # something was balanced
    assert np.array_equal(every.q[3:9], f.q[3:9])  # the walking run: untouched


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 300))
def test_the_frames_rebalanced_are_found_from_the_standing_ones(seed: int, n: int) -> None:
    """``smooth._worse_standing_runs`` measures outward from the standing frames only; it
    finds the runs of worse frames holding a standing one that measuring every frame finds."""
    rng = np.random.default_rng(seed)
    f = standing(400)
    t_walk = rng.uniform(0, 400 / 30, 2)
    walk = Segment("root", "locomotion", t_walk.min(), t_walk.max(), GoalSpec("body"), PROV)
    ir = make_ir(f, [walk])
    rows = np.sort(rng.choice(400, n, replace=False))
    if rng.random() < 0.5:  # long runs of neighbouring frames
        rows = np.unique(np.concatenate([np.arange(a, a + 40) for a in rows[:5]]) % 400)
    worse_frames = rng.random(400) < rng.uniform(0.3, 1.0)
    measured: list[np.ndarray] = []

    def fake_worse(ir_, frames_, r, q0, root0):  # type: ignore[no-untyped-def]
        measured.append(r)
        return worse_frames[r]

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(smooth, "_worse", fake_worse)
        got = smooth._worse_standing_runs(ir, f, rows, f.q, f.root_position)
    np.testing.assert_array_equal(got, _runs_with_standing_frames(ir, rows[worse_frames[rows]]))
    once = np.concatenate(measured) if measured else np.zeros(0, int)
    assert len(np.unique(once)) == len(once)  # no frame measured twice


def _all_pairs_grouped_hull(points: np.ndarray, valid: np.ndarray):  # type: ignore[no-untyped-def]
    """The grouped hull as it was before its pairs were formed per group (4cc9d5e): every
    pair's edge vector for every frame, then the groups' side tests. The reference of
    ``test_the_grouped_hull_forms_pairs_per_group_to_the_bit``."""
    from mtlc.metrics import HULL_EPS, Hull

    pts, ok = np.asarray(points, dtype=float), np.asarray(valid, dtype=bool)
    used = ok.any(axis=0)
    if used.sum() >= 3 and not used.all():
        pts, ok = pts[:, used], ok[:, used]
    ii, jj = np.triu_indices(ok.shape[1], 1)
    a, d = pts[:, ii], pts[:, jj] - pts[:, ii]
    length = np.hypot(d[..., 0], d[..., 1])
    pair_ok = ok[:, ii] & ok[:, jj] & (length > 1e-9)
    safe = np.where(length > 1e-9, length, 1.0)
    edge, orient = np.zeros(pair_ok.shape, dtype=bool), np.zeros(pair_ok.shape)
    _, first, inverse = np.unique(ok, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.ravel()
    for m, mask in enumerate(ok[first]):
        rows, cols = np.flatnonzero(inverse == m), np.flatnonzero(mask)
        pairs = np.flatnonzero(mask[ii] & mask[jj])
        if pairs.size == 0:
            continue
        sub = np.ix_(rows, pairs)
        dd, aa = d[sub], a[sub]
        normal = np.stack([-dd[..., 1], dd[..., 0]], axis=-1)
        side = normal @ np.swapaxes(pts[np.ix_(rows, cols)], 1, 2)
        side -= (dd[..., 0] * aa[..., 1] - dd[..., 1] * aa[..., 0])[..., None]
        tol = (HULL_EPS * safe[sub])[..., None]
        pos, neg = (side > tol).any(axis=-1), (side < -tol).any(axis=-1)
        edge[sub] = pair_ok[sub] & ~(pos & neg)
        orient[sub] = np.where(pos, 1.0, np.where(neg, -1.0, 0.0))
    keep = max(int(edge.sum(axis=1).max(initial=0)), 1)
    order = np.argsort(~edge, axis=1, kind="stable")[:, :keep]

    def edges(x: np.ndarray) -> np.ndarray:
        return np.take_along_axis(x, order if x.ndim == 2 else order[..., None], axis=1)

    return Hull(edges(a), edges(d), edges(safe), edges(edge), edges(orient), pts, ok)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), collinear=st.booleans(), count=st.sampled_from([8, 22]))
def test_the_grouped_hull_forms_pairs_per_group_to_the_bit(
    seed: int, collinear: bool, count: int
) -> None:
    """``grouped_hull`` forms each group's pairs for its own frames only: each frame's edges
    in the same order, and the margins and pushes read from them equal to the bit those of the
    all-pairs grouping it replaced (the padding differs, and nothing reads it)."""
    from mtlc.metrics import grouped_hull, hull_margin, support_push

    rng = np.random.default_rng(seed)
    pts = rng.uniform(-0.3, 0.3, (50, count, 2))
    if collinear:
        pts[:, :4, 1] = pts[:, :1, 1]
    ok = (rng.random((6, count)) < 0.5)[rng.integers(0, 6, 50)]
    ok[:, count - 1] = False  # a point no frame touches: the hull drops its column
    com = rng.uniform(-0.4, 0.4, (50, 2))
    got, want = grouped_hull(pts, ok), _all_pairs_grouped_hull(pts, ok)
    assert np.array_equal(got.edge, want.edge)
    assert np.array_equal(got.orient[got.edge], want.orient[want.edge])
    assert np.array_equal(hull_margin(got, com), hull_margin(want, com), equal_nan=True)
    push_got = support_push(pts, ok, com, 0.01, got)
    assert np.array_equal(push_got, support_push(pts, ok, com, 0.01, want), equal_nan=True)


def test_balancing_a_hold_measures_each_run_of_frames_once_to_the_bit() -> None:
    """A hold is thousands of copies of one frame: balance measures a run of frames alike in
    pose, stance and resting hands once (``repeated_rows``), and every corrected frame, margin
    and failure is bit for bit what measuring each frame gives."""
    import mtlc.body.kinematics as kin

    f = standing(300)
    for a, deg in ((0, 0.0), (90, 20.0), (200, 12.0), (201, 14.0)):  # three holds, one step
        f.q[a:, SKEL.dof_index("l_hip_abd")] = math.radians(deg)
    f.q[150:160, SKEL.dof_index("r_shoulder_flex")] = -0.0  # -0.0 is not 0.0 to the bits

    def balanced() -> list[np.ndarray]:
        g = Frames(f.fps, f.time.copy(), f.root_position.copy(), f.root_rotation.copy(),
                   f.q.copy())  # fmt: skip
        out = balance.balance_frames(make_ir(g), g)
        return [g.q, g.root_position, *out]

    got = balanced()
    saved = kin.REPEAT_MIN_ROWS
    kin.REPEAT_MIN_ROWS = 10**9  # every frame measured
    try:
        want = balanced()
    finally:
        kin.REPEAT_MIN_ROWS = saved
    assert not np.array_equal(got[1], f.root_position)  # the one-legged holds were corrected
    for a, b in zip(got, want, strict=True):
        assert a.tobytes() == b.tobytes()
