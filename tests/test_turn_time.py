"""Turn time of walks: MTM-1 turn body (TBC2, 37.2 TMU per started 90°) for the turns the gait
steps in place, hand-computed, unless the pivot steps need longer at a human cadence
(``semantics.gait``: 95 steps/min); and the motion of a turn-only walk stands on planted feet."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from mtlc.frontend import run_frontend
from mtlc.metrics import compute_metrics
from mtlc.passes import run_motion
from mtlc.semantics import turning
from mtlc.semantics.timeline import Timeline

TMU = 0.036
TBC2_S = 37.2 * TMU  # MTM-1 turn body 45-90°, case 2
PACE_S = 15.0 * TMU  # MTM-1 W-P
PIVOT_S = 60 / 95  # a pivot step at semantics.gait.SLOW_CADENCE


def timeline_of(tmp_path: Path, body: str, extra: str = "") -> Timeline:
    text = (
        "use stdlib.actions\nuse stdlib.elements\n"
        "scene s {\n"
        "    site here at (0, 0, 0) m\n"
        "    site east at (2, 1, 0) m\n"
        "    site behind at (0, 1, -2) m\n"
        "    site ahead at (0, 1, 2) m\n"
        "    site far at (0, 0, 3) m\n"
        "    site near_east at (0.5, 1.2, 0) m normal (-1, 0, 0)\n"
        "}\n"
        f"{extra}task t {{\n    manikin gb10000_1988 female p50\n    scene s\n{body}}}\n"
    )
    path = tmp_path / "t.mtask"
    path.write_text(text, encoding="utf-8")
    program = run_frontend([path])
    assert program.diagnostics == [], program.diagnostics
    (timeline,) = program.timelines
    return timeline


def walks(t: Timeline) -> list:
    return [p for p in t.primitives if p.kind == "locomotion"]


@pytest.mark.parametrize(
    ("facing", "tbc2", "steps"),
    [("east", TBC2_S, 3 + 1), ("behind", 2 * TBC2_S, 5 + 1)],  # pivots of <= 40°, closing step
    ids=["90deg", "180deg"],
)
def test_a_turn_only_walk_lasts_its_pivot_steps_not_less(
    tmp_path: Path, facing: str, tbc2: float, steps: int
) -> None:
    """MTM's turn body time (1.3392 s for 90°) gave four pivot steps 179 steps/min; the walk now
    lasts what its steps need at 95 steps/min, the first a tenth longer (2.59 s, 3.85 s), MTM's
    time still recorded."""
    t = timeline_of(tmp_path, f"    travel_facing(here, {facing})\n")
    (walk,) = walks(t)
    assert walk.params["distance"] == pytest.approx(0.0)
    assert walk.params["turn_time"] == pytest.approx(tbc2)
    need = (steps + 0.1) * PIVOT_S  # the first step, from standing, a tenth longer
    assert walk.duration == pytest.approx(need)
    assert walk.params["gait_time"] == pytest.approx(need)
    assert 90 <= 60 * steps / walk.duration <= 95


def test_a_straight_walk_with_no_turn_keeps_its_pace_time(tmp_path: Path) -> None:
    t = timeline_of(tmp_path, "    travel_facing(far, far)\n    walk_to(far)\n")
    straight, in_place = walks(t)
    # 3 m: 4 MTM paces (2.16 s) would be 108 steps/min for the 6 steps of a 1.57 m woman (step
    # 0.648 m: 5 steps of 0.6 m and a closing step); the steps' own time is longer
    assert 4 * PACE_S < straight.duration == pytest.approx(straight.params["gait_time"])
    cadence = 113 - 0.5 * (157 - 152)  # steps/min at the full step (Rowe et al. 2011)
    walking = 60 / (cadence * 0.6 / (0.413 * 1.57))
    assert straight.duration == pytest.approx(1.1 * PIVOT_S + 4 * walking + 0.95 * PIVOT_S)
    assert "turn_time" not in straight.params
    assert in_place.duration == pytest.approx(0.0)  # no length and no turn: no time


def test_a_walk_facing_its_next_work_turns_toward_it(tmp_path: Path) -> None:
    """No `facing`: the next reach's site sets the arrival heading (90° here)."""
    t = timeline_of(tmp_path, "    walk_to(here)\n    reach(right, near_east)\n")
    (walk,) = walks(t)
    assert walk.params["turn_time"] == pytest.approx(TBC2_S)
    assert walk.duration == pytest.approx(4.1 * PIVOT_S)  # 3 pivots of 30°, a closing step


def test_what_follows_a_turning_walk_moves_later_with_its_windows(tmp_path: Path) -> None:
    t = timeline_of(tmp_path, "    travel_facing(here, east)\n    reach(right, near_east)\n")
    walk, goal = t.primitives
    assert goal.start == pytest.approx(walk.end) and walk.end == pytest.approx(4.1 * PIVOT_S)
    ta, to = goal.params["phases"]["TA"], goal.params["phases"]["TO"]
    assert ta[0] == pytest.approx(goal.start) and to[1] == pytest.approx(goal.end)
    assert ta[1] == pytest.approx(to[0]) and goal.start < ta[1] < goal.end


def test_a_walk_with_a_stated_time_gets_no_turn_time(tmp_path: Path) -> None:
    turn = "element turn_in(s: Site, f: Site) {\n    walk to s facing f over 0.7 s\n}\n"
    t = timeline_of(tmp_path, "    turn_in(here, east)\n", turn)
    (walk,) = walks(t)
    assert walk.duration == pytest.approx(0.7)


def test_turns_the_gait_steps() -> None:
    """Start pivots over 30°, the end's turn beyond the closing steps' 35° twist, more than 3°."""
    q = math.pi / 2
    assert turning.stepped_turns(0.0, 0.0, q, 0.0) == [pytest.approx(q)]  # in place
    assert turning.stepped_turns(0.0, 0.0, 0.0, 3.0) == []  # straight on
    assert turning.stepped_turns(0.0, q, q, 3.0) == [pytest.approx(q)]  # off to the side
    rest = turning.stepped_turns(0.0, 0.0, q, 3.0)
    assert rest == [pytest.approx(q - math.radians(35))]  # arrives turning toward the work
    assert turning.turn_body_seconds([q]) == pytest.approx(TBC2_S)
    assert turning.turn_body_seconds([q + 1e-3, 0.1]) == pytest.approx(3 * TBC2_S)


@pytest.mark.parametrize("facing", ["east", "behind"])
def test_a_turn_only_walk_pivots_on_planted_feet(tmp_path: Path, facing: str) -> None:
    """With no time the pivot steps turned the feet on the spot (57 cm/s measured)."""
    t = timeline_of(tmp_path, f"    travel_facing(here, {facing})\n")
    ir = run_motion(t, run_frontend([tmp_path / "t.mtask"]).sink)
    (seg,) = [s for s in ir.segments if s.kind == "locomotion"]
    assert len(seg.result["steps"]) >= 4  # pivots of at most 40°, then a closing step
    m = compute_metrics(ir)
    assert m.foot_skating < 0.02  # m/s
    assert m.penetration <= 1e-3  # m
