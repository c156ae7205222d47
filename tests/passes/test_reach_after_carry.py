"""A reach after a posture that carried a part is one movement (issue 19).

tests/data/lift/l04 picks a panel off the floor in one hand, stands with it (the carry pose
takes the hand to forearm height over the stand, ``carry_pose.carry_posture``) and moves it onto
its frame. The carry pose is let go of over that move (``settle.keep_until_keyed``). On main it
was let go of over the approach (TA) alone while pace times the approach and the contact (TO)
as one bell, and the hold then put the hand onto the site as a step on its first frame: LDLJ
-7.8 to -7.9 for these three manikins, and two speed bells on all 14 in bench/procedures'
aircraft_panel_sideways. Now the correction fades over the whole reach, the reach is re-timed
on one minimum-jerk bell (``settle.repace``) and the hold's first correction is eased in over
the contact (``hold._ease_in``). Measured on the output frames with bench/human.py's
definitions (the path at rest before and after it; peaks of at least 10 % of the top speed).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy.signal import find_peaks

from mtlc.body import part_site_positions
from mtlc.diagnostics import DiagnosticSink
from mtlc.frontend import run_frontend
from mtlc.passes import MotionOptions, run_motion
from mtlc.semantics import schedule
from mtlc.semantics.timeline import ManikinSpec

PROCEDURE = Path(__file__).resolve().parents[1] / "data" / "lift" / "l04_stand_then_move.mtask"
MANIKINS = [("female", 5), ("male", 50), ("male", 95)]
GOOD_LDLJ = -7.0  # issue 19: >= -7 for 90 % of reaches (minimum jerk is about -5.3)


def bench_ldlj(p: np.ndarray, dt: float) -> float:
    """bench/human.py's LDLJ: the path at rest one frame before and after, finite differences."""
    duration = dt * (len(p) - 1)
    p = np.concatenate([p[:1], p[:1], p, p[-1:], p[-1:]])
    speed = np.linalg.norm(np.diff(p, axis=0), axis=1) / dt
    jerk = np.diff(p, n=3, axis=0) / dt**3
    return -math.log(duration**3 / float(speed.max()) ** 2 * float(np.sum(jerk**2)) * dt)


def speed_peaks(speed: np.ndarray) -> int:
    padded = np.concatenate([[0.0], speed, [0.0]])
    found, _ = find_peaks(padded, prominence=0.1 * float(speed.max()))
    return len(found)


@pytest.mark.parametrize(("sex", "pct"), MANIKINS)
def test_the_move_after_a_carried_stand_is_one_smooth_bell(sex: str, pct: int) -> None:
    program = run_frontend([PROCEDURE])
    (timeline,) = program.timelines
    timeline = schedule.for_manikin(timeline, ManikinSpec("gb10000_1988", sex, pct))
    ir = run_motion(timeline, DiagnosticSink(), MotionOptions())
    f = ir.frames
    assert f is not None
    reach = [s for s in ir.segments if s.track == "l_arm" and s.kind in ("TA", "TO")][-2:]
    assert [s.kind for s in reach] == ["TA", "TO"]
    a = int(np.searchsorted(f.time, reach[0].start - 1e-9))
    b = int(np.searchsorted(f.time, reach[1].end - 1e-9))
    rows = slice(a, b + 1)
    hand = part_site_positions(
        ir.skeleton, f.q[rows], f.root_position[rows], f.root_rotation[rows], ["l_hand"]
    )[:, 0]
    dt = float(np.median(np.diff(f.time)))
    speed = np.linalg.norm(np.diff(hand, axis=0), axis=1) / dt
    assert float(np.sum(speed) * dt) > 0.2  # a real move, not a twitch
    assert speed_peaks(speed) == 1
    assert bench_ldlj(hand, dt) >= GOOD_LDLJ
