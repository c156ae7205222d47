"""The balance pass's arms over movements to and from contacts (issue 19).

* ``kept_in_reach``: a trunk leaning back under a reach took the approaching hand's path out of
  the arm's reach; the elbow was solved straight, and bent 0 -> 15 deg in one output frame as
  the lean faded at the contact (the kneeling fuel filter, female P50). The goal is now kept
  where the elbow stays bent ``STRAIGHT_ELBOW`` (or as the arm has it).
* ``departing_arms``: a pinned arm's correction was let go at a person's fastest joint speed at
  the start of the movement that leaves the site: the hand moved 27 mm in one frame (a second
  velocity peak). It is now let go over the movement, as the movement goes on.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import compile_on
from hypothesis import given, settings
from hypothesis import strategies as st

from mtlc.body.kinematics import forward, site_positions
from mtlc.body.skeleton import build_manikin
from mtlc.ir.model import Frames, GoalSpec, MotionIR, Provenance, Segment, SourceRef
from mtlc.passes.balance import (
    LET_GO_TIME,
    STRAIGHT_ELBOW,
    arm_dofs,
    departing_arms,
    departure_windows,
    kept_in_reach,
)

ROOT = Path(__file__).resolve().parents[2]
SKEL = build_manikin("gb10000_1988", "female", 50)
REF = SourceRef("t.mtask", 1, 1, 1, 2)
PROV = Provenance(("t", "a", "e"), REF, REF)


def _posture(flex: np.ndarray) -> np.ndarray:
    q = np.zeros((flex.size, SKEL.n_dofs))
    q[:, SKEL.dof_index("r_shoulder_flex")] = np.radians(60.0)
    q[:, SKEL.dof_index("r_elbow_flex")] = flex
    return q


def _shoulder_and_reach(q: np.ndarray, root: np.ndarray, rot: np.ndarray) -> tuple:
    bent = q.copy()
    e = SKEL.dof_index("r_elbow_flex")
    bent[:, e] = np.minimum(q[:, e], STRAIGHT_ELBOW)
    pose = forward(SKEL, bent, root, rot, with_axes=False)
    shoulder = pose.p[:, SKEL.joint_index("r_shoulder")]
    return shoulder, np.linalg.norm(site_positions(SKEL, pose, "r_hand") - shoulder, axis=1)


@settings(max_examples=40, deadline=None)
@given(
    flex=st.floats(0.0, 2.0),
    direction=st.tuples(*[st.floats(-1.0, 1.0)] * 3).filter(
        lambda v: float(np.linalg.norm(v)) > 0.1
    ),
    scale=st.floats(0.1, 3.0),
)
def test_a_goal_is_kept_within_the_bent_arms_reach(
    flex: float, direction: tuple[float, float, float], scale: float
) -> None:
    q = _posture(np.array([flex]))
    root, rot = np.array([[0.0, 1.0, 0.0]]), np.eye(3)[None]
    shoulder, reach = _shoulder_and_reach(q, root, rot)
    unit = np.asarray(direction) / np.linalg.norm(direction)
    goal = shoulder + scale * reach[0] * unit
    kept = kept_in_reach(SKEL, q, root, rot, "r_hand", goal)
    away = kept - shoulder
    if scale <= 1.0:  # within reach: untouched
        np.testing.assert_allclose(kept, goal, atol=1e-12)
    else:  # beyond: on the reach, in the goal's direction from the shoulder
        assert np.linalg.norm(away) == pytest.approx(reach[0], rel=1e-9)
        np.testing.assert_allclose(away[0] / np.linalg.norm(away), unit, atol=1e-9)


def test_the_reach_is_the_arms_own_at_the_least_bend() -> None:
    # an arm bent 60 deg may straighten to STRAIGHT_ELBOW; one bent 5 deg keeps its 5 deg
    q = _posture(np.radians([60.0, 5.0]))
    root, rot = np.tile([0.0, 1.0, 0.0], (2, 1)), np.tile(np.eye(3), (2, 1, 1))
    shoulder, reach = _shoulder_and_reach(q, root, rot)
    pose = forward(SKEL, q, root, rot, with_axes=False)
    as_posed = np.linalg.norm(site_positions(SKEL, pose, "r_hand") - shoulder, axis=1)
    assert reach[0] > as_posed[0] + 0.02  # the bent arm reaches farther straightened
    assert reach[1] == pytest.approx(as_posed[1])  # the straight one no farther than it is
    far = shoulder + 5.0 * (site_positions(SKEL, pose, "r_hand") - shoulder)
    kept = kept_in_reach(SKEL, q, root, rot, "r_hand", far)
    np.testing.assert_allclose(np.linalg.norm(kept - shoulder, axis=1), reach, rtol=1e-9)


def _seg(track: str, kind: str, start: float, end: float, approach: float = 0.05) -> Segment:
    goal = GoalSpec("r_hand", "spot", np.zeros(3), approach=approach)
    return Segment(track, kind, start, end, goal, PROV)


def test_the_movement_that_leaves_a_pinned_site_is_a_departure() -> None:
    segs = [
        _seg("r_arm", "TO", 1.0, 1.5),  # pinned from 1.0 until the next arm segment (2.0)
        _seg("r_arm", "TA", 2.0, 3.0),  # leaves the site: a departure
        _seg("r_arm", "TA", 3.0, 4.0),  # starts where no pin ends
    ]
    ir = MotionIR("t", None, "t.mtask", {}, 0.0, [], segments=segs)
    pins = {"r_hand": (np.array([1.0 - 1e-9]), np.array([2.0 - 1e-9])),
            "l_hand": (np.empty(0), np.empty(0))}  # fmt: skip
    none = {h: (np.empty(0), np.empty(0)) for h in pins}
    lo, hi = departure_windows(ir, pins, none)["r_hand"]
    np.testing.assert_allclose([lo, hi], [[2.0], [3.0]], atol=1e-6)
    # a TA that starts an approach to a contact is approach_arms's, not a departure
    approaching = {**none, "r_hand": (np.array([2.0 - 1e-9]), np.array([3.5 - 1e-9]))}
    assert departure_windows(ir, pins, approaching)["r_hand"][0].size == 0
    # a TA that ends on its site (no approach) is pinned itself, no departure
    on_site = [segs[0], _seg("r_arm", "TA", 2.0, 3.0, approach=0.0)]
    ir = MotionIR("t", None, "t.mtask", {}, 0.0, [], segments=on_site)
    assert departure_windows(ir, pins, none)["r_hand"][0].size == 0
    # where the pin ends as the body stands up, the hand lets go over LET_GO_TIME of it
    stand = Segment("root", "posture", 2.0, 5.0, GoalSpec("root"), PROV)
    ir = MotionIR("t", None, "t.mtask", {}, 0.0, [], segments=[segs[0], stand])
    lo, hi = departure_windows(ir, pins, none)["r_hand"]
    np.testing.assert_allclose([lo, hi], [[2.0], [2.0 + LET_GO_TIME]], atol=1e-6)


def test_a_pinned_arms_correction_is_let_go_as_the_movement_goes_on() -> None:
    t = np.arange(0.0, 2.0, 1 / 60)
    n = t.size
    q_start = np.zeros((n, SKEL.n_dofs))
    q_start[:, SKEL.dof_index("r_shoulder_flex")] = np.radians(40.0)
    q_start[:, SKEL.dof_index("r_elbow_flex")] = np.radians(60.0)
    root = np.tile([0.0, 1.0, 0.0], (n, 1))
    rot = np.tile(np.eye(3), (n, 1, 1))
    frames = Frames(60.0, t, root.copy(), rot, q_start.copy())
    cols = arm_dofs(SKEL, "r_hand")
    held = np.zeros(len(cols))
    held[cols.index(SKEL.dof_index("r_shoulder_flex"))] = np.radians(15.0)
    held[cols.index(SKEL.dof_index("r_elbow_flex"))] = np.radians(-20.0)
    frames.q[np.ix_(np.flatnonzero(t < 1.0), cols)] += held  # the pinned arm's correction
    departing_arms(SKEL, frames, q_start, root, {"r_hand": (np.array([1.0]), np.array([1.5]))})

    def hand(q: np.ndarray) -> np.ndarray:
        return site_positions(SKEL, forward(SKEL, q, root, rot, with_axes=False), "r_hand")

    now, planned = hand(frames.q), hand(q_start)
    leave = int(np.searchsorted(t, 1.0))
    # it leaves from where the pin held it, at rest, and ends on its planned path
    assert np.linalg.norm(now[leave] - now[leave - 1]) < 1e-3
    assert np.linalg.norm(now[int(np.searchsorted(t, 1.5)) - 1] - planned[-1]) < 2e-3
    speed = np.linalg.norm(np.diff(now, axis=0), axis=1) * 60.0
    inside = speed[leave - 1 : int(np.searchsorted(t, 1.5))]
    peak = int(inside.argmax())
    assert np.all(np.diff(inside[: peak + 1]) >= -1e-3)  # one bell: up, then down
    assert np.all(np.diff(inside[peak:]) <= 1e-3)
    assert np.all(frames.q[t >= 1.5 + 1e-9] == q_start[t >= 1.5 + 1e-9])  # after it, as it was


def _largest_step(ir: MotionIR) -> tuple[float, str]:
    frames = ir.frames
    assert frames is not None and frames.fps == 30.0
    steps = np.degrees(np.abs(np.diff(frames.q, axis=0)))
    i, j = np.unravel_index(int(steps.argmax()), steps.shape)
    return float(steps[i, j]), f"{ir.skeleton.dof_names[j]} at {frames.time[i + 1]:.2f} s"


def test_a_kneeling_reach_that_loses_its_balance_fades_the_lean() -> None:
    # tests/data/balance/kneel_far.mtask, female P50: the left hand's reach to a low cap is out
    # of balance at the contact; the lean that balanced its approach stopped in one frame there
    # (lumbar 15 deg, shoulder 20 deg in one output frame). It fades, and the frames it leaves
    # outside the support are reported.
    ir, sink = compile_on(ROOT / "tests" / "data" / "balance" / "kneel_far.mtask", ("female", 50))
    step, where = _largest_step(ir)
    assert step <= 12.0, f"{step:.1f} deg, {where}"
    lost = [d for d in sink.items if d.code == "MT0502"]
    assert lost and "pick > reach" in lost[0].message


@pytest.mark.xfail(strict=True, reason="issue 19: the approaching arm turns twice as fast as "
                   "the trunk lean fading under it (r_shoulder_flex 15.5 deg in one frame)")  # fmt: skip
def test_a_kneeling_reach_beside_a_resting_hand_turns_the_shoulder_smoothly() -> None:
    ir, _ = compile_on(ROOT / "tests" / "data" / "balance" / "kneel_bowl.mtask", ("female", 1))
    step, where = _largest_step(ir)
    assert step <= 12.0, f"{step:.1f} deg, {where}"


def test_an_approach_is_held_to_its_path_only_over_its_contact() -> None:
    """``contacting``: the frames ``arms_in_time`` keeps whole on an approach are its TO's.
    Kept whole from the TA's start, the corrected trunk and the re-solved arm turned the CAD
    fuel filter's right elbow 12.7 deg in an output frame at the reach's peak (female P50)."""
    path = ROOT / "examples" / "replace_fuel_filter_cad.mtask"
    ir = compile_on(path, ("female", 50), until="hold")[0]
    from mtlc.passes.balance import approach_windows, contacting, pin_windows

    approaches = approach_windows(ir, pin_windows(ir))
    narrowed = contacting(ir, approaches)
    tos = {s.end: s.start for s in ir.segments if s.kind == "TO"}
    found = 0
    for hand, (lows, highs) in approaches.items():
        lo2, hi2 = narrowed[hand]
        assert np.array_equal(hi2, highs)
        for lo, hi, start in zip(lows, highs, lo2, strict=True):
            to_start = min((a for e, a in tos.items() if abs(e - hi) < 1e-6), default=None)
            assert to_start is not None and abs(start - max(lo, to_start - 1e-9)) < 1e-9
            found += start > lo
    assert found  # some approach has a TA before its TO


def test_the_cad_fuel_filters_reach_turns_no_joint_over_12_deg_a_frame() -> None:
    path = ROOT / "examples" / "replace_fuel_filter_cad.mtask"
    ir = compile_on(path, ("female", 50))[0]
    frames = ir.frames
    (ta,) = [s for s in ir.on_track("r_arm") if s.kind == "TA" and s.start < 11.9 < s.end]
    rows = np.flatnonzero((frames.time >= ta.start) & (frames.time <= ta.end))
    steps = np.degrees(np.abs(np.diff(frames.q[rows[0] - 1 : rows[-1] + 2], axis=0)))
    assert steps.max() <= 12.0
