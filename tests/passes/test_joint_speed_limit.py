"""The joint-speed pass (passes/joint_speed.py): poses kept, the clock stretched where a joint
would outrun a person."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from mtlc.diagnostics import DiagnosticSink
from mtlc.ir.model import (
    Frames,
    GoalSpec,
    Keyframes,
    MotionIR,
    Provenance,
    RootPlan,
    Segment,
    SourceRef,
)
from mtlc.passes import joint_speed
from mtlc.passes.context import PassContext
from mtlc.passes.interpolate import interpolate_naive

DOFS = ("r_shoulder_flex", "r_elbow_flex", "r_wrist_flex")
REF = SourceRef("t.mtask", 1, 1, 1, 2)
FPS = 60.0


def segment(path: tuple[str, ...], times: np.ndarray, q: np.ndarray, **result: object) -> Segment:
    """A segment keying DOFS at ``times``."""
    return Segment(
        track="r_arm",
        kind="TO",
        start=float(times[0]),
        end=float(times[-1]),
        goal=GoalSpec(effector="r_hand"),
        provenance=Provenance(path, REF, REF),
        keyframes=Keyframes(time=np.asarray(times, float), dofs=DOFS, q=np.asarray(q, float)),
        result=dict(result),
    )


def motion(*segments: Segment) -> MotionIR:
    ir = MotionIR(task="t", title=None, file="t.mtask", manikin={}, ground=0.0, sites=[])
    ir.skeleton = SimpleNamespace(
        dof_names=DOFS, q_comfort=np.zeros(3), dof_index=DOFS.index, root_position=[0, 1, 0]
    )
    ir.segments = list(segments)
    end = max(s.end for s in segments)
    ir.root_plan = RootPlan(np.array([0.0, end]), np.zeros((2, 3)), np.zeros(2))
    return ir


def run(ir: MotionIR) -> MotionIR:
    return joint_speed.run(ir, PassContext(DiagnosticSink()))


def dense(ir: MotionIR) -> Frames:
    return interpolate_naive(ir)


def fastest(ir: MotionIR) -> float:
    """rad/s of the fastest dof over any dense interval."""
    f = dense(ir)
    return float(np.max(np.abs(np.diff(f.q, axis=0)) / np.diff(f.time)[:, None]))


def test_a_motion_within_a_persons_speed_keeps_its_times() -> None:
    t = np.linspace(0.0, 1.0, 11)
    q = np.stack([np.sin(t), 0.5 * t, 0.2 * np.cos(t)], axis=1)  # at most 1 rad/s
    ir = run(motion(segment(("t", "reach", "reach"), t, q)))
    assert ir.segments[0].keyframes is not None
    assert np.array_equal(ir.segments[0].keyframes.time, t)
    assert ir.segments[0].end == 1.0


def test_keys_too_close_for_a_persons_arm_are_moved_apart() -> None:
    t = np.array([0.0, 0.5, 0.52, 1.0])  # 90 deg in 20 ms between the middle keys
    q = np.zeros((4, 3))
    q[2:, 0] = math.radians(90.0)
    ir = run(motion(segment(("t", "reach", "reach"), t, q)))
    kf = ir.segments[0].keyframes
    assert kf is not None
    assert fastest(ir) <= joint_speed.LIMIT * 1.02
    # the poses stay, in order; the time between the two grows to at least a movement's at the limit
    assert np.array_equal(kf.q, q)
    assert kf.time[2] - kf.time[1] >= math.radians(90.0) / joint_speed.LIMIT
    assert math.isclose(ir.segments[0].end, float(kf.time[-1]), rel_tol=1e-12)
    # whole output frames added: what came after stays on the 30 fps grid
    added = (ir.segments[0].end - 1.0) * 30.0
    assert abs(added - round(added)) < 1e-9


def test_two_segments_that_meet_in_two_poses_are_parted_by_a_pause() -> None:
    """Keys at one instant with two poses (one segment's end, the next one's start): no
    stretching of time can part them, a pause opened for what starts there does."""
    a = segment(("t", "reach", "reach"), np.array([0.0, 0.49, 0.5]), np.zeros((3, 3)))
    b_q = np.tile([math.radians(70.0), 0.0, 0.0], (2, 1))
    b = segment(("t", "reach", "reach"), np.array([0.5, 1.0]), b_q)
    ir = run(motion(a, b))
    assert fastest(ir) <= joint_speed.LIMIT * 1.02
    assert ir.segments[0].end == 0.5  # what ends at the cut stays
    # the later segment starts at the cut from the pose before it; its own keys follow the pause
    kf = ir.segments[1].keyframes
    assert kf is not None and ir.segments[1].start == 0.5
    assert kf.time[0] == 0.5 and np.array_equal(kf.q[0], np.zeros(3))
    gap = kf.time[1] - 0.5
    assert gap >= math.radians(70.0) / joint_speed.LIMIT
    assert np.array_equal(kf.q[1:], b_q)
    assert math.isclose(ir.segments[1].end, 1.0 + gap, rel_tol=1e-12)


def test_a_fast_movement_is_slowed_and_the_slowing_fades_in_and_out() -> None:
    t = np.linspace(0.0, 2.0, 121)
    q = np.zeros((121, 3))
    q[:, 1] = 0.3 * t  # an elbow at a person's pace throughout
    q[:, 0] = np.radians(60.0) * np.clip((t - 0.9) / 0.1, 0.0, 1.0)  # 600 deg/s for 0.1 s
    ir = run(motion(segment(("t", "reach", "reach"), t, q)))
    assert fastest(ir) <= joint_speed.LIMIT * 1.02
    f = dense(ir)
    elbow = (np.diff(f.q[:, 1]) / np.diff(f.time))[:-3]  # (it comes to rest at its last key)
    assert np.max(np.abs(np.diff(elbow))) <= 0.3 * 0.25  # slowed over RAMP, never at once
    assert ir.segments[0].end > 2.0 + 0.1 * (600 / 340 - 1)


def test_times_in_segment_results_move_with_the_keys() -> None:
    t = np.array([0.0, 0.5, 0.52, 1.0])
    q = np.zeros((4, 3))
    q[2:, 0] = math.radians(45.0)
    seg = segment(
        ("t", "walk_to", "walk"),
        t,
        q,
        steps=[{"foot": "r", "t_heel_off": 0.1, "t_lift": 0.2, "t_land": 0.9, "from": [0.1, 0, 0]}],
        feet_held_until=0.95,
        phases={"seat": [0.1, 0.2], "swing": [0.2, 0.8]},
        rolls=[{"foot": "l", "from": 0.3, "to": 0.7}],
    )
    ir = run(motion(seg))
    r = ir.segments[0].result
    assert r["steps"][0]["t_heel_off"] == 0.1 and r["steps"][0]["from"] == [0.1, 0, 0]
    assert r["steps"][0]["t_land"] > 0.9 + 0.1 and r["feet_held_until"] > 0.95 + 0.1
    assert r["phases"]["swing"][1] > 0.8 + 0.1 and r["rolls"][0]["to"] > 0.7 + 0.1
    assert r["phases"]["seat"] == [0.1, 0.2]


def test_the_wrist_in_a_fastener_turn_keeps_the_tools_pace() -> None:
    t = np.linspace(0.0, 1.0, 11)
    q = np.zeros((11, 3))
    q[:, 2] = np.radians(450.0) * t  # over LIMIT, under TURN_LIMIT
    turning = run(motion(segment(("t", "unscrew", "turn_fastener"), t, q)))
    reaching = run(motion(segment(("t", "reach", "reach"), t, q)))
    assert turning.segments[0].end <= 1.0 + 2.0 / 30 + 1e-9  # (PCHIP stops it at 590 deg/s)
    assert reaching.segments[0].end > 1.2  # 450 / 340


@settings(max_examples=40, deadline=None)
@given(
    st.lists(
        st.tuples(st.floats(0.01, 0.5), st.floats(-3.0, 3.0), st.floats(-3.0, 3.0)),
        min_size=2,
        max_size=12,
    )
)
def test_any_keys_keep_their_poses_in_order_and_only_slow_down(rows: list) -> None:
    gaps = np.array([r[0] for r in rows])
    t = np.concatenate([[0.0], np.cumsum(gaps[1:])])
    q = np.array([[r[1], r[2], 0.0] for r in rows])
    before = fastest(motion(segment(("t", "reach", "reach"), t, q)))
    ir = run(motion(segment(("t", "reach", "reach"), t, q)))
    kf = ir.segments[0].keyframes
    assert kf is not None
    assert np.array_equal(kf.q, q)  # the poses are the keys' own
    assert np.all(np.diff(kf.time) >= np.diff(t) - 1e-12)  # time only ever grows
    assert fastest(ir) <= max(before, joint_speed.LIMIT) * (1 + 1e-9)


@settings(max_examples=25, deadline=None)
@given(
    st.lists(st.floats(-0.4, 0.4), min_size=3, max_size=40),
    st.lists(st.floats(-0.4, 0.4), min_size=3, max_size=40),
)
def test_dense_keys_come_out_within_the_limit(a: list, b: list) -> None:
    """Keys on the 60 fps grid, as the pace pass writes a reach's: up to 24 rad/s a step."""
    n = min(len(a), len(b))
    q = np.stack([np.cumsum(a[:n]), np.cumsum(b[:n]), np.zeros(n)], axis=1)
    t = np.arange(n) / 60.0
    ir = run(motion(segment(("t", "reach", "reach"), t, q)))
    assert fastest(ir) <= joint_speed.LIMIT * 1.05


@settings(max_examples=80, deadline=None)
@given(
    seed=st.integers(0, 2**31 - 1),
    n=st.integers(2, 300),
    density=st.sampled_from([0.0, 0.02, 0.3, 1.0]),
    pinned=st.booleans(),
)
def test_the_envelopes_are_the_frame_by_frame_sweeps_to_the_bit(
    seed: int, n: int, density: float, pinned: bool
) -> None:
    """``joint_speed.envelopes`` (both sweeps solved for all rows at once, then again where
    a row grew) against the frame-by-frame loop it replaced: the same arrays to the bit,
    signs of zeros too, with sparse and dense corrections, fast and still motions, and rows
    kept as they are."""
    from mtlc.passes.joint_speed import envelopes, sweeps_reference

    rng = np.random.default_rng(seed)
    cols = 4
    q = np.cumsum(rng.normal(0.0, 0.05, (n, cols)), axis=0)
    q[rng.random(n) < 0.3] = 0.0  # still frames and exact zeros
    t = np.cumsum(np.full(n, 1 / 120))
    done = np.where(rng.random((n, cols)) < density, rng.normal(0.0, 0.4, (n, cols)), 0.0)
    step = np.diff(q, axis=0)
    room = np.maximum(np.abs(step), 5.0 * np.diff(t)[:, None]) + 1e-9
    lo, hi = -room - step, room - step
    keep = (rng.random(n) < 0.1) if pinned else np.zeros(n, dtype=bool)
    want_up, want_down = np.maximum(done, 0.0), np.minimum(done, 0.0)
    got_up, got_down = want_up.copy(), want_down.copy()
    sweeps_reference(want_up, want_down, lo, hi, keep)
    envelopes(got_up, got_down, lo, hi, keep)
    for got, want in ((got_up, want_up), (got_down, want_down)):
        assert np.array_equal(got, want)
        assert np.array_equal(np.signbit(got), np.signbit(want))


def test_a_correction_that_changes_sign_stays_within_the_speed() -> None:
    """A per-frame correction +9 deg one frame and -1 the next, on a joint already turning at
    246 deg/s (the fuel filter male P99's left shoulder, a carried cartridge's way): each sign's
    envelope keeps the slope, their sum took 6.5 deg in a 60 fps frame where 5.5 are allowed.
    The corrected joint turns no faster than the limit, or than the motion did."""
    speed = math.radians(330.0)
    t = np.arange(12) / 60.0
    q = np.radians(-4.1 * np.arange(12.0))[:, None]  # 246 deg/s
    dq = np.radians([0, 0, 14.2, 13.1, 8.8, 10.0, 6.3, -1.0, -1.4, -0.1, 0, 0])[:, None]
    out = joint_speed.speed_limited(q, dq, np.array([-10.0]), np.array([10.0]), t, speed)
    room = np.maximum(np.abs(np.diff(q, axis=0)), speed / 60.0) + 1e-7
    assert np.all(np.abs(np.diff(q + out, axis=0)) <= room)


@settings(max_examples=80, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(2, 200), density=st.sampled_from([0.05, 0.5]))
def test_any_correction_comes_out_within_the_speed(seed: int, n: int, density: float) -> None:
    """Whatever the correction (signs mixed frame to frame, sparse or dense), with no frame
    kept: no corrected dof steps more than the speed allows or than the motion itself did."""
    rng = np.random.default_rng(seed)
    cols, speed = 3, 5.0
    t = np.arange(n) / 60.0
    q = np.cumsum(rng.normal(0.0, 0.05, (n, cols)), axis=0)
    dq = np.where(rng.random((n, cols)) < density, rng.normal(0.0, 0.4, (n, cols)), 0.0)
    lim = np.full(cols, 100.0)
    out = joint_speed.speed_limited(q, dq, -lim, lim, t, speed)
    room = np.maximum(np.abs(np.diff(q, axis=0)), speed * np.diff(t)[:, None]) + 1e-7
    assert np.all(np.abs(np.diff(q + out, axis=0)) <= room)
