"""Expansion semantics with hand-computed expectations: MTM-1 times, composition, units."""

from __future__ import annotations

from pathlib import Path

import pytest

from mtlc.frontend import FrontendOptions, run_frontend
from mtlc.semantics import mtm
from mtlc.semantics.timeline import Timeline

TMU = 0.036


def expand(tmp_path: Path, body: str, extra: str = "", sites: str = "") -> Timeline:
    text = (
        "use stdlib.actions\nuse stdlib.elements\nuse stdlib.tools\n"
        "scene s {\n"
        # the right hand rests 0.2 m right of the root, 0.75 m up: 10 in (0.254 m) ahead of it
        "    site ahead at (-20, 75, 25.4) cm normal (0, 0, -1)\n"
        "    site far at (0, 0, 300) cm\n"
        f"{sites}}}\n{extra}"
        f"task t {{\n    scene s\n{body}}}\n"
    )
    path = tmp_path / "t.mtask"
    path.write_text(text)
    program = run_frontend([path], FrontendOptions())
    assert program.diagnostics == [], program.diagnostics
    (timeline,) = program.timelines
    return timeline


def test_mtm_tables_hand_computed() -> None:
    assert mtm.reach_tmu("B", 10 * 0.0254) == pytest.approx(11.5)
    assert mtm.reach_tmu("B", 11 * 0.0254) == pytest.approx((11.5 + 12.9) / 2)
    assert mtm.reach_tmu("A", 40 * 0.0254) == pytest.approx(17.5 + 10 * 0.4)
    assert mtm.reach_tmu("C", 4 * 0.0254) == pytest.approx(8.4)
    assert mtm.reach_tmu("E", 0.0) == pytest.approx(2.0)
    assert mtm.move_tmu("C", 30 * 0.0254) == pytest.approx(30.7)
    assert mtm.turn_tmu(3.141592653589793 / 2, 0.0) == pytest.approx(5.4)
    assert mtm.turn_tmu(3.141592653589793 * 1.5, 0.0) == pytest.approx(9.4 + 5.4)
    assert mtm.turn_tmu(3.141592653589793, 3.0) == pytest.approx(14.8)
    assert mtm.turn_tmu(3.141592653589793 / 6, 10.0) == pytest.approx(8.4)
    assert mtm.walk_tmu(3.0) == pytest.approx(4 * 15.0)
    assert mtm.grasp_tmu("G1A") == 2.0


def test_reach_time_from_hand_travel(tmp_path: Path) -> None:
    t = expand(tmp_path, "    reach(right, ahead)\n")
    (goal,) = t.primitives
    assert goal.kind == "goal" and goal.effector == "right_hand"
    assert goal.params["travel"] == pytest.approx(0.254)
    assert goal.duration == pytest.approx(11.5 * TMU)
    assert goal.params["position"] == pytest.approx((-0.2, 0.75, 0.254))
    # approach 8 cm of 25.4 cm travel: the contact (TO) phase is the last 31.5 % of the reach
    ta, to = goal.params["phases"]["TA"], goal.params["phases"]["TO"]
    assert (to[1] - to[0]) / goal.duration == pytest.approx(0.08 / 0.254)
    assert ta[1] == to[0]


def test_a_reach_past_any_arm_is_timed_as_the_longest_reach(tmp_path: Path) -> None:
    """A site 90 m off is out of reach (the motion passes say so): its reach takes the time of
    the farthest one-reach hand travel, not 72 s of a hand moving towards it."""
    sites = "    site away at (0, 75, 9000) cm\n    site edge at (-20, 75, 220) cm\n"
    t = expand(tmp_path, "    reach(right, away)\n    reach(left, edge)\n", sites=sites)
    away, edge = t.primitives
    assert away.params["travel"] == pytest.approx(90.0, abs=0.01)
    cap = mtm.reach_tmu("B", 2.5) * TMU
    assert away.duration == pytest.approx(cap)
    assert away.duration < 3.0
    # below the cap the MTM-1 rule stands: 2.24 m (left rest to the edge) is timed as itself
    assert edge.params["travel"] < 2.5
    assert edge.duration == pytest.approx(mtm.reach_tmu("B", edge.params["travel"]) * TMU)


def test_sequence_parallel_and_both_hands(tmp_path: Path) -> None:
    body = (
        "    parallel {\n"
        "        reach(right, ahead)\n"
        "        { grasp(left); release(left) }\n"
        "    }\n"
        "    reach(both, far)\n"
    )
    t = expand(tmp_path, body)
    reach, grasp, release, left, right = t.primitives
    assert reach.start == grasp.start == 0.0
    assert release.start == pytest.approx(grasp.end)
    end_parallel = max(reach.end, release.end)
    assert left.start == right.start == pytest.approx(end_parallel)
    assert {left.effector, right.effector} == {"left_hand", "right_hand"}
    assert left.params["two_handed"] and left.end == right.end


def test_repeat_and_for(tmp_path: Path) -> None:
    body = (
        "    for x in [ahead, far] {\n        repeat 3 {\n            look(x)\n        }\n    }\n"
    )
    t = expand(tmp_path, body)
    assert [p.params["site"] for p in t.primitives] == ["ahead"] * 3 + ["far"] * 3
    assert t.duration == pytest.approx(6 * 7.3 * TMU)
    assert all(
        a.end == pytest.approx(b.start)
        for a, b in zip(t.primitives, t.primitives[1:], strict=False)
    )


def test_explicit_over_and_element_time(tmp_path: Path) -> None:
    extra = "element wait_a_bit() {\n    still over 1500 ms\n}\nelement two_looks(x: Site) {\n    gaze at x\n    gaze at x over 2 s\n    time 0.5 s\n}\n"
    t = expand(tmp_path, "    wait_a_bit()\n    two_looks(ahead)\n", extra)
    assert [p.duration for p in t.primitives] == pytest.approx([1.5, 0.5, 2.0])


def test_walk_time_and_root_travel(tmp_path: Path) -> None:
    t = expand(tmp_path, "    walk_to(far)\n")
    (walk,) = t.primitives
    assert walk.kind == "locomotion" and walk.effector == "root"
    assert walk.params["distance"] == pytest.approx(3.0)
    # 4 MTM-1 paces (2.16 s) are fewer than the gait's steps take (semantics.gait): the walk
    # lasts its steps' time, recorded as its gait_time
    assert walk.duration > 4 * 15.0 * TMU
    assert walk.duration == pytest.approx(walk.params["gait_time"])


def test_turns_with_tool_mass_and_units(tmp_path: Path) -> None:
    t = expand(tmp_path, "    tool wrench_10mm\n    unscrew(right, ahead, turns: 1, load: 2 kg)\n")
    turns = [p for p in t.primitives if p.kind == "posture"]
    assert len(turns) == 6  # a wrench: strokes of at most 60° (docs/tools.md)
    assert all(p.params["angle"] == pytest.approx(-3.141592653589793 / 3) for p in turns)
    # per stroke: T 60° with 2 kg + the 0.06 kg wrench (1-5 kg column) 6.5, RL1 2.0, R-B over
    # the chord 2 x 11.5 cm x sin 30° = 4.528 in, between 4 in (6.4) and 6 in (8.6):
    # 6.4 + 0.264 x 2.2 = 6.9803, G1A 2.0
    chord = 11.5 / 2.54
    r_b = 6.4 + (chord - 4) / 2 * (8.6 - 6.4)
    assert r_b == pytest.approx(6.9803, abs=1e-4)
    assert all(p.duration == pytest.approx((6.5 + 2.0 + r_b + 2.0) * TMU) for p in turns)
    assert t.tool is not None and t.tool.properties["mass"] == pytest.approx(0.06)


def test_kneel_and_stand_use_body_motion_codes(tmp_path: Path) -> None:
    t = expand(tmp_path, "    kneel(2)\n    stand()\n    stand()\n")
    kneel, stand = t.primitives  # the second stand() finds the manikin standing: no motion
    assert kneel.duration == pytest.approx(69.4 * TMU)
    assert stand.duration == pytest.approx(76.7 * TMU)


def test_provenance_path_and_origin(tmp_path: Path) -> None:
    t = expand(tmp_path, "    pick(right, ahead)\n")
    assert [p.path for p in t.primitives] == [
        ("t", "pick", "look"),
        ("t", "pick", "reach"),
        ("t", "pick", "grasp"),
    ]
    assert {p.origin.line for p in t.primitives} == {10}  # the line of `pick` in the task
    assert t.primitives[1].span.file == "<stdlib>/elements.mtask"


def test_soft_keywords_as_names(tmp_path: Path) -> None:
    extra = "element walk(to: Site, approach: Length = 3 cm) {\n    goal right at to approach approach\n}\n"
    t = expand(tmp_path, "    walk(ahead)\n", extra)
    assert t.primitives[0].params["approach"] == pytest.approx(0.03)


def test_qualified_scene_site_and_arithmetic(tmp_path: Path) -> None:
    extra = "element near(x: Site, d: Length) {\n    goal right at x offset (0, 0, 1) * d approach d / 2\n}\n"
    t = expand(tmp_path, "    near(s.ahead, 10 cm + 50 mm)\n", extra)
    (goal,) = t.primitives
    assert goal.params["position"] == pytest.approx((-0.2, 0.75, 0.404))
    assert goal.params["approach"] == pytest.approx(0.075)


def test_enum_members_resolve_by_expected_type(tmp_path: Path) -> None:
    t = expand(tmp_path, "    reach(right, ahead, case: A)\n    move(left, ahead, C)\n")
    reach, move = t.primitives
    assert reach.duration == pytest.approx(8.7 * TMU)  # R-A at 10 in
    assert move.effector == "left_hand"


def test_rising_from_one_knee_is_ab(tmp_path: Path) -> None:
    t = expand(tmp_path, "    kneel(1)\n    stand()\n")
    kneel, stand = t.primitives
    assert kneel.duration == pytest.approx(29.0 * TMU)  # B
    assert stand.duration == pytest.approx(31.9 * TMU)  # AB, not AKBK
