"""The locomotion pass: footsteps, planted feet, step segmentation (seed 004 claim 2), clips."""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import numpy as np
import pytest

from mtlc.body import build_manikin, forward, site_positions, site_rotation
from mtlc.frontend import run_frontend
from mtlc.ir.model import MotionIR, yaw_quaternion
from mtlc.passes import MotionOptions, run_motion
from mtlc.passes.locomotion import (
    STEP_LENGTH_RATIO,
    Gait,
    _ry,
    default_gait,
    leg_ik,
    leg_model,
    plan_footsteps,
    segment_steps,
    stance_at,
)

ROOT = Path(__file__).resolve().parents[2]
WALKING_EXAMPLES = ["remove_access_panel", "remove_avionics_unit"]
SKATE_LIMIT = 0.02  # m/s: the foot-skating bound in stance
CONTACT_POINTS = ("heel", "toe", "ball_med", "ball_lat")


def _compile(name: str, options: MotionOptions | None = None) -> MotionIR:
    program = run_frontend([ROOT / "examples" / f"{name}.mtask"])
    assert not program.sink.has_errors
    return run_motion(program.timelines[0], program.sink, options or MotionOptions())


@pytest.fixture(scope="module")
def compiled() -> dict[str, MotionIR]:
    return {name: _compile(name) for name in WALKING_EXAMPLES}


def _walks(ir: MotionIR) -> list:
    return [s for s in ir.segments if s.kind == "locomotion"]


# --------------------------------------------------------------------------- leg IK


def test_leg_ik_is_exact_against_forward_kinematics() -> None:
    sk = build_manikin("gb10000_1988", "female", 5)
    legs = leg_model(sk)
    rng = np.random.default_rng(4)
    n = 40
    root = np.c_[rng.uniform(-1, 1, n), rng.uniform(0.66, 0.72, n), rng.uniform(-1, 1, n)]
    heading = rng.uniform(-3, 3, n)
    for side in ("r", "l"):
        hip = root + np.einsum("nij,j->ni", _ry(heading), legs.hip[side])
        ankle = hip + np.c_[rng.uniform(-0.15, 0.15, n), np.zeros(n), rng.uniform(-0.15, 0.2, n)]
        ankle[:, 1] = legs.ankle_height + rng.uniform(0.0, 0.05, n)
        foot_heading = heading + rng.uniform(-0.3, 0.3, n)
        pitch = rng.uniform(0.0, 0.3, n)
        q6 = leg_ik(legs, side, root, heading, ankle, foot_heading, pitch)
        assert np.all(q6 >= legs.lower[side] - 1e-12) and np.all(q6 <= legs.upper[side] + 1e-12)
        q = np.tile(sk.q_comfort, (n, 1))
        q[:, legs.dofs[side]] = q6
        pose = forward(sk, q, root, yaw_quaternion(heading))
        inside = np.all((q6 > legs.lower[side] + 1e-9) & (q6 < legs.upper[side] - 1e-9), axis=1)
        assert inside.sum() > n // 2  # most random targets are reachable within the limits
        got = site_positions(sk, pose, f"{side}_foot")
        np.testing.assert_allclose(got[inside], ankle[inside], atol=1e-9)
        want_R = _ry(foot_heading) @ np.stack(
            [np.array([[1, 0, 0], [0, math.cos(p), -math.sin(p)], [0, math.sin(p), math.cos(p)]])
             for p in pitch]
        )  # fmt: skip
        np.testing.assert_allclose(
            site_rotation(sk, pose, f"{side}_foot")[inside], want_R[inside], atol=1e-9
        )


# --------------------------------------------------------------------------- footstep plans


def test_step_length_is_the_stature_rule() -> None:
    for sex in ("female", "male"):
        sk = build_manikin("gb10000_1988", sex, 50)
        gait = default_gait(sk)
        assert gait.step_length == pytest.approx(STEP_LENGTH_RATIO[sex] * sk.dims.stature)
        assert 0.41 * sk.dims.stature <= gait.step_length <= 0.45 * sk.dims.stature


@pytest.mark.parametrize("distance", [0.3, 0.6, 1.45, 3.0, 5.2])
def test_straight_walk_alternates_and_takes_distance_over_step_length(distance: float) -> None:
    gait = Gait(step_length=0.62, step_height=0.07)
    stance = stance_at(np.zeros(3), 0.0, 0.08)
    goal = np.array([0.0, 0.0, distance])
    steps = plan_footsteps(stance, goal, 0.0, 0.0, gait, 0.08)
    feet = [s.foot for s in steps]
    assert all(a != b for a, b in itertools.pairwise(feet))
    moving = len(steps) - 1  # the last step closes the feet together
    assert moving == math.ceil(distance / gait.step_length)
    assert abs(moving - distance / gait.step_length) < 1.0
    lengths = [abs(s.end.position[2] - s.start.position[2]) for s in steps]
    assert max(lengths) <= 2 * gait.step_length + 1e-9  # one foot passes the other
    # ends standing side by side at the goal, facing the way it walked
    last = {s.foot: s.end for s in steps}
    centre = (last["r"].position + last["l"].position) / 2
    np.testing.assert_allclose(centre, goal, atol=1e-9)
    assert last["r"].heading == last["l"].heading == 0.0


def test_a_large_heading_change_is_stepped_in_place() -> None:
    gait = Gait(step_length=0.62, step_height=0.07)
    stance = stance_at(np.zeros(3), 0.0, 0.08)
    goal = np.array([1.2, 0.0, -0.6])  # behind and to the left: about 117 degrees
    heading = math.atan2(goal[0], goal[2])
    steps = plan_footsteps(stance, goal, heading, heading, gait, 0.08)
    pivots = [s for s in steps if np.linalg.norm(s.end.position) < 0.1]
    assert len(pivots) >= 3
    turned = [s.end.heading for s in pivots]
    assert all(
        abs(b - a) <= math.radians(40) + 1e-9 for a, b in zip([0.0, *turned], turned, strict=False)
    )
    assert pivots[-1].end.heading == pytest.approx(heading)
    assert pivots[0].foot == "l"  # turning left opens with the left foot
    feet = [s.foot for s in steps]
    assert all(a != b for a, b in itertools.pairwise(feet))


# --------------------------------------------------------------------------- the compiled walks


@pytest.mark.parametrize("name", WALKING_EXAMPLES)
def test_walks_have_alternating_footsteps(compiled: dict[str, MotionIR], name: str) -> None:
    ir = compiled[name]
    stature = ir.skeleton.dims.stature
    for seg in _walks(ir):
        steps = seg.result["steps"]
        assert steps, seg.provenance.path
        feet = [s["foot"] for s in steps]
        assert all(a != b for a, b in itertools.pairwise(feet))
        for s in steps:
            assert (
                seg.start - 1e-6 <= s["t_heel_off"] <= s["t_lift"] < s["t_land"] <= seg.end + 1e-6
            )
        assert seg.result["gait"]["step_length"] == pytest.approx(
            STEP_LENGTH_RATIO[ir.manikin["sex"]] * stature
        )
        assert seg.result["keyframes_at_limits"] == 0
        # keyframes only where interpolation would let a foot stray, never denser than its frames
        window = seg.result["feet_held_until"] - seg.start
        assert len(seg.keyframes.time) <= 60 * window + 4 * len(steps) + 4


def _foot_points(ir: MotionIR, foot: str) -> np.ndarray:
    fr = ir.frames
    pose = forward(ir.skeleton, fr.q, fr.root_position, fr.root_rotation)
    return site_positions(ir.skeleton, pose, [f"{foot}_{p}" for p in CONTACT_POINTS])


@pytest.mark.parametrize("name", WALKING_EXAMPLES)
def test_planted_feet_do_not_slide(compiled: dict[str, MotionIR], name: str) -> None:
    """Horizontal speed of every sole point of a foot in stance, on the final frames."""
    ir = compiled[name]
    fr = ir.frames
    a, b = fr.time[:-1], fr.time[1:]
    checked = 0
    for foot in ("r", "l"):
        pts = _foot_points(ir, foot)
        speed = np.linalg.norm(np.diff(pts[..., [0, 2]], axis=0), axis=-1).max(axis=1) / (b - a)
        for seg in _walks(ir):
            stance = (a >= seg.start) & (b <= seg.end)
            for s in seg.result["steps"]:
                if s["foot"] == foot:
                    stance &= ~((b > s["t_heel_off"]) & (a < s["t_land"]))
            checked += int(stance.sum())
            assert speed[stance].max(initial=0.0) < SKATE_LIMIT, (name, foot, seg.start)
            # and in stance the sole is on the ground
            assert np.abs(pts[:-1][stance][..., 1] - ir.ground).max(initial=0.0) < 2e-3
    assert checked > 10


def _sole_heights(ir: MotionIR) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    heights, where = {}, {}
    for foot in ("r", "l"):
        pts = _foot_points(ir, foot)
        low = pts[..., 1].argmin(axis=1)
        heights[foot] = pts[np.arange(len(pts)), low, 1] - ir.ground
        where[foot] = pts[np.arange(len(pts)), low]
    return heights, where


@pytest.mark.parametrize("name", WALKING_EXAMPLES)
def test_segmentation_recovers_the_generated_steps(
    compiled: dict[str, MotionIR], name: str
) -> None:
    ir = compiled[name]
    fr = ir.frames
    heights, where = _sole_heights(ir)
    for seg in _walks(ir):
        inside = (fr.time >= seg.start - 0.05) & (fr.time <= seg.end + 0.05)
        found = segment_steps(
            fr.time[inside],
            {f: h[inside] for f, h in heights.items()},
            {f: w[inside] for f, w in where.items()},
            threshold=0.004,
            min_swing=0.02,
        )
        plan = seg.result["steps"]
        assert [d.foot for d in found] == [s["foot"] for s in plan]
        frame = 1 / fr.fps
        for d, s in zip(found, plan, strict=True):
            assert abs(d.t_lift - s["t_lift"]) < 2 * frame
            assert abs(d.t_land - s["t_land"]) < 2 * frame
            np.testing.assert_allclose(
                np.asarray(d.position)[[0, 2]], np.asarray(s["position"])[[0, 2]], atol=0.25
            )
        # the pass ran the same analysis on its own dense gait
        assert len(seg.result["segmentation"]) == len(plan)


def test_segmentation_on_a_synthetic_height_signal() -> None:
    t = np.arange(0, 3, 1 / 100)
    r = np.where((t > 0.5) & (t < 0.9), 0.05 * np.sin(np.pi * (t - 0.5) / 0.4), 0.0)
    left = np.where((t > 1.3) & (t < 1.7), 0.06 * np.sin(np.pi * (t - 1.3) / 0.4), 0.0)
    rng = np.random.default_rng(0)
    r = r + rng.normal(0, 0.0005, len(t))
    r[100] += 0.03  # a one-frame spike is filtered out (claim 2, step 1.1)
    found = segment_steps(t, {"r": r, "l": left})
    assert [d.foot for d in found] == ["r", "l"]
    assert found[0].t_lift == pytest.approx(0.5, abs=0.03)
    assert found[0].t_land == pytest.approx(0.9, abs=0.03)
    assert found[1].height == pytest.approx(0.06, abs=0.002)
