"""Balance, smoothing and the motion metrics, on hand-computed synthetic motions and examples."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mtlc.body import build_manikin, center_of_mass, forward, site_positions
from mtlc.ir.model import Frames, GoalSpec, MotionIR, Provenance, Segment, SourceRef
from mtlc.metrics import (
    compute_metrics,
    ldlj,
    render_metrics,
    support_margin,
)

SKEL = build_manikin("gb10000_1988", "male", 50)
REF = SourceRef("synthetic.mtask", 3, 5, 3, 20)
PROV = Provenance(("t", "a", "e"), REF, REF)


def standing(n: int, fps: float = 30.0) -> Frames:
    """The neutral pose standing on the ground (soles at y = 0), n frames."""
    q = np.zeros((n, SKEL.n_dofs))
    root = np.tile(SKEL.root_position, (n, 1))
    rot = np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))
    return Frames(fps=fps, time=np.arange(n) / fps, root_position=root, root_rotation=rot, q=q)


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
