"""Issue 19 on procedures none of the examples are: reaches whose approach turns the hand, and a
part held in both hands that one hand leaves (tests/data/reach). Measured on the frames a user
receives (30 fps) for three manikins."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.signal import find_peaks

from mtlc.body import forward, site_positions
from mtlc.diagnostics import DiagnosticSink
from mtlc.frontend import FrontendOptions, run_frontend
from mtlc.ir.model import MotionIR
from mtlc.passes import MotionOptions, run_motion
from mtlc.passes.carry import carries
from mtlc.passes.pace import movements
from mtlc.semantics.timeline import ManikinSpec

DATA = Path(__file__).resolve().parents[2] / "tests" / "data" / "reach"
MANIKINS = [("female", 5), ("male", 50), ("male", 95)]
TURN_DOFS = ("wrist_flex", "wrist_dev", "elbow_pro")


def _compiled(name: str, sex: str, percentile: int) -> MotionIR:
    """As `mtlc compile --manikin` makes it (the front end times the reaches for the manikin)."""
    options = FrontendOptions(manikin=ManikinSpec("gb10000_1988", sex, percentile))
    (timeline,) = run_frontend([DATA / name], options).timelines
    return run_motion(timeline, DiagnosticSink(), MotionOptions())


def _ldlj(p: np.ndarray, dt: float) -> float:
    """Log dimensionless jerk, at rest before and after (bench/human.py's definition)."""
    duration = dt * (len(p) - 1)
    p = np.concatenate([p[:1], p[:1], p, p[-1:], p[-1:]])
    speed = np.linalg.norm(np.diff(p, axis=0), axis=1) / dt
    jerk = np.diff(p, n=3, axis=0) / dt**3
    return -float(np.log(duration**3 / speed.max() ** 2 * np.sum(jerk**2) * dt))


@pytest.mark.parametrize(("sex", "percentile"), MANIKINS)
def test_reaches_that_turn_onto_their_site_are_one_bell(sex: str, percentile: int) -> None:
    """Each reach comes at its site along the site's normal, across the line from where the hand
    starts, and the last is out of reach: one speed peak each, at rest in the frame of contact,
    no joint over 12 deg in a frame, LDLJ >= -6.5 where the site is reached (-6.12 at worst;
    smoothed only by 10 % of the progress, -6.50 to -6.67 on all three) and >= -8.5 for the one
    that cannot arrive (-8.38 on female P5)."""
    ir = _compiled("r02_side_approach.mtask", sex, percentile)
    frames = ir.frames
    assert frames is not None and frames.fps == 30.0
    dt = 1.0 / frames.fps
    steps = np.degrees(np.abs(np.diff(frames.q, axis=0)))
    assert steps.max() <= 12.0, steps.max()
    pose = forward(ir.skeleton, frames.q, frames.root_position, frames.root_rotation)
    moves = movements(ir)
    assert len(moves) == 3
    for m in moves:
        (effector,) = m.effectors
        a = int(np.searchsorted(frames.time, m.start - 1e-9))
        b = int(np.searchsorted(frames.time, m.end - 1e-9))
        p = site_positions(ir.skeleton, pose, effector)[a : b + 1]
        speed = np.linalg.norm(np.diff(p, axis=0), axis=1) / dt
        peaks, _ = find_peaks(np.r_[0.0, speed, 0.0], prominence=0.1 * speed.max())
        assert len(peaks) == 1, np.round(speed * 100, 1)
        assert speed[-1] <= 0.05  # m/s in the frame where contact is made
        reached = all(s.result.get("success") for s in m.segments)
        assert _ldlj(p, dt) >= (-6.5 if reached else -8.5)


@pytest.mark.parametrize(("sex", "percentile"), MANIKINS)
def test_a_part_left_by_one_hand_is_not_held_by_both(sex: str, percentile: int) -> None:
    """pick(both) then the right hand reaches a screw before release(both): the part is held by
    both only until that reach starts (keeping it rigid after pulled the right arm back to it,
    and a shoulder stepped 15-24 deg in one frame, where the grips opened or in the reach). No
    dof steps over 12 deg a frame."""
    ir = _compiled("r01_part_then_one_hand.mtask", sex, percentile)
    (carry,) = carries(ir)
    (reach,) = [s for s in ir.segments if s.kind == "TA" and s.goal.effector.startswith("r_tool")]
    assert carry.end == pytest.approx(reach.start)
    frames = ir.frames
    assert frames is not None and frames.fps == 30.0
    steps = np.degrees(np.abs(np.diff(frames.q, axis=0)))
    # the wrist and forearm may step 20 deg in a fastener turn (issue 19, as bench/human.py)
    turn = np.zeros(len(frames.time), dtype=bool)
    for seg in ir.segments:
        if seg.goal.params.get("posture") == "twist":
            turn |= (frames.time >= seg.start - 1e-9) & (frames.time <= seg.end + 1e-9)
    in_turn = turn[:-1] | turn[1:]
    turning = [i for i, n in enumerate(ir.skeleton.dof_names) if n.endswith(TURN_DOFS)]
    limit = np.full(steps.shape, 12.0)
    limit[np.ix_(in_turn, turning)] = 20.0
    assert np.all(steps <= limit), (steps - limit).max()


@pytest.mark.parametrize(("sex", "percentile"), [("male", 1), ("male", 10), ("male", 50)])
def test_reaches_from_a_kneel_are_one_movement_while_the_trunk_leans(
    sex: str, percentile: int
) -> None:
    """Kneeling, the left hand brings a plug far ahead and the right hand reaches it to screw it
    (tests/data/reach/r03): the balance pass leans the trunk back while the right hand is on its
    way. The hand rode on the trunk and was put back on its path in the TO's first frames (male
    P1: LDLJ -9.37 at main, ddc41e4); the arm now takes its part in the correction over the
    whole movement (``balance.approach_arms``): every reach one speed peak, LDLJ >= -8 (-7.64),
    at rest in the frame of contact."""
    ir = _compiled("r03_kneel_reach_far.mtask", sex, percentile)
    frames = ir.frames
    assert frames is not None
    dt = 1.0 / frames.fps
    pose = forward(ir.skeleton, frames.q, frames.root_position, frames.root_rotation)
    moves = movements(ir)
    assert len(moves) >= 3
    for m in moves:
        (effector,) = m.effectors
        a = int(np.searchsorted(frames.time, m.start - 1e-9))
        b = int(np.searchsorted(frames.time, m.end - 1e-9))
        p = site_positions(ir.skeleton, pose, effector)[a : b + 1]
        speed = np.linalg.norm(np.diff(p, axis=0), axis=1) / dt
        if len(p) < 4 or speed.sum() * dt < 0.01:
            continue  # too short to judge (bench/human.py)
        peaks, _ = find_peaks(np.r_[0.0, speed, 0.0], prominence=0.1 * speed.max())
        assert len(peaks) == 1, (effector, np.round(speed * 100, 1))
        assert speed[-1] <= 0.05, (effector, speed[-1])
        assert _ldlj(p, dt) >= -8.0, (effector, m.start, _ldlj(p, dt))


@pytest.mark.parametrize(("sex", "percentile"), [("male", 5), ("male", 10), ("male", 50)])
def test_a_hand_resting_on_a_site_is_not_pulled_straight_by_the_lean(
    sex: str, percentile: int
) -> None:
    """Kneeling, the left hand rests on a housing low ahead while the right hand carries a
    strainer out to a bin at the side (tests/data/reach/r04): the balance pass leans the trunk
    back and the left arm, pinned on the housing, is solved again under it frame by frame. The
    lean's peak stretched that arm straight and its elbow bent back 13-17 deg in a frame (male
    P5 13.0, P10 16.9 deg at main, de4bc45); a correction that stretches a resting arm past
    ``balance.STRAIGHT_ELBOW`` now loses that contact, so the lean stops short of it. No dof
    steps over 12 deg in a frame, and the resting elbow stays bent."""
    ir = _compiled("r04_kneel_steady_and_carry.mtask", sex, percentile)
    frames = ir.frames
    assert frames is not None
    steps = np.degrees(np.abs(np.diff(frames.q, axis=0)))
    assert steps.max() <= 12.0, (steps.max(), frames.time[1 + steps.max(axis=1).argmax()])
    (move,) = [s for s in ir.segments if s.track == "r_arm" and s.kind == "TA"
               and s.goal.site == "bin"]  # fmt: skip
    during = (frames.time >= move.start) & (frames.time <= move.end)
    elbow = frames.q[during, ir.skeleton.dof_index("l_elbow_flex")]
    assert np.degrees(elbow.min()) >= 15.0, np.degrees(elbow.min())
