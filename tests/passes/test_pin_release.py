"""A hand that holds its part short of the part's site is free once it lets go (issue 19).

``balance.pin_windows(reached_only=True)`` pins a hand from its contact (TO) until the next
segment of its arm. A hand left short of its site (MT0501) is pinned only while its grip holds
the part; before, "holds" was "closed at some time in the window", so a panel placed 15 mm
short of the floor pinned the hand there through the release, a stand, three reaches and a
squat, and smoothing re-pinned it: the left elbow went 34 -> 0 deg in one output frame
(bench/procedures/aircraft_panel_sideways.mtask, female P10 and P5).
"""

from __future__ import annotations

import numpy as np
import pytest

from mtlc.ir.model import GoalSpec, MotionIR, Provenance, Segment, SourceRef
from mtlc.passes.balance import pin_windows
from mtlc.passes.hold import REPORT_TOL, last_opening

REF = SourceRef("t.mtask", 1, 1, 1, 2)
PROV = Provenance(("t", "a", "e"), REF, REF)


def grip(start: float, state: str) -> Segment:
    goal = GoalSpec("l_hand", params={"state": state})
    return Segment("l_hand", "grip", start, start + 0.1, goal, PROV)


def contact(start: float, end: float, short: float) -> Segment:
    goal = GoalSpec("l_hand", "spot", np.zeros(3))
    return Segment("l_arm", "TO", start, end, goal, PROV, result={"distance": short})


def ir_of(*segments: Segment) -> MotionIR:
    return MotionIR("t", None, "t.mtask", {}, 0.0, [], segments=list(segments))


def test_last_opening() -> None:
    grips = [grip(1.0, "closed"), grip(5.0, "open")]
    assert last_opening(grips, 2.0, 10.0) == 5.0  # let go at 5 s
    assert last_opening(grips, 6.0, 10.0) == 10.0  # never closed in it
    assert last_opening([*grips, grip(7.0, "closed")], 2.0, 10.0) == 10.0  # holds again
    assert last_opening(grips[:1], 2.0, 10.0) == 10.0  # still holding


@pytest.mark.parametrize("short", [0.015, 0.0])
def test_a_hand_short_of_its_site_is_free_once_it_lets_go(short: float) -> None:
    ir = ir_of(
        grip(1.0, "closed"),
        contact(4.0, 5.0, short),
        grip(5.0, "open"),
        contact(9.0, 9.5, 0.0),  # the arm's next goal
    )
    lo, hi = pin_windows(ir, reached_only=True)["l_hand"]
    if short > REPORT_TOL:  # it never got there: pinned while it held the part, to the release
        assert (lo[0], hi[0]) == pytest.approx((4.0, 5.0), abs=1e-6)
    else:  # on its site: it rests there until the arm's next segment
        assert (lo[0], hi[0]) == pytest.approx((4.0, 9.0), abs=1e-6)


def body_move(start: float, kind: str = "posture") -> Segment:
    return Segment("root", kind, start, start + 2.0, GoalSpec("root"), PROV)


@pytest.mark.parametrize("kind", ["posture", "locomotion"])
def test_a_resting_hand_lets_go_when_the_body_moves(kind: str) -> None:
    # on its site with the grip open, it rests there until the body stands up or walks (kept
    # there, a stand stretched the arm from a low filter bowl: 13 deg a frame, issue 19)
    ir = ir_of(contact(4.0, 5.0, 0.0), body_move(7.0, kind), contact(9.0, 9.5, 0.0))
    lo, hi = pin_windows(ir, reached_only=True)["l_hand"]
    assert (lo[0], hi[0]) == pytest.approx((4.0, 7.0), abs=1e-6)
    # a hand that grips what it rests on holds it through the move (a kneel holding a rail)
    held = ir_of(grip(4.5, "closed"), contact(4.0, 5.0, 0.0), body_move(7.0, kind),
                 contact(9.0, 9.5, 0.0))  # fmt: skip
    lo, hi = pin_windows(held, reached_only=True)["l_hand"]
    assert (lo[0], hi[0]) == pytest.approx((4.0, 9.0), abs=1e-6)
    # a root hold (inspect) is no move
    still = ir_of(contact(4.0, 5.0, 0.0), body_move(7.0, "hold"), contact(9.0, 9.5, 0.0))
    assert pin_windows(still, reached_only=True)["l_hand"][1][0] == pytest.approx(9.0, abs=1e-6)
